"""Kinematic bicycle model of a 1:10 RC car: steering servo, motor with drag, brake and reverse.

Commands follow the drivetrain's convention: ``angle`` in [-1, 1] (-1 = full left), ``throttle``
in [-1, 1] (negative = brake while rolling forward, then reverse, like a hobby ESC). The state is
integrated with a fixed step, several sub-steps per loop step, so a run is deterministic for a
given command sequence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class CarParams:
    """Physical parameters of the simulated car (SI units)."""

    wheelbase: float = 0.26  # m, axle to axle
    max_steer: float = math.radians(25.0)  # rad, front wheel angle at |angle| = 1
    steer_rate: float = math.radians(400.0)  # rad/s, servo speed
    max_accel: float = 4.0  # m/s^2 at full throttle from standstill
    drag: float = 0.8  # 1/s, deceleration per unit speed
    rolling: float = 0.3  # m/s^2, rolling resistance
    brake: float = 6.0  # m/s^2 at full brake
    max_speed: float = 4.0  # m/s
    max_reverse_speed: float = 1.0  # m/s

    def __post_init__(self) -> None:
        for name in ("wheelbase", "max_steer", "steer_rate", "max_accel", "brake", "max_speed"):
            if getattr(self, name) <= 0:
                raise ValueError(f"car parameter {name} must be > 0, got {getattr(self, name)}")
        for name in ("drag", "rolling", "max_reverse_speed"):
            if getattr(self, name) < 0:
                raise ValueError(f"car parameter {name} must be >= 0, got {getattr(self, name)}")

    @classmethod
    def from_config(cls, cfg: Any) -> CarParams:
        """The car parameters of a Config (SIM_WHEELBASE, SIM_MAX_STEER_DEG, ...)."""
        return cls(wheelbase=cfg.SIM_WHEELBASE, max_steer=math.radians(cfg.SIM_MAX_STEER_DEG),
                   steer_rate=math.radians(cfg.SIM_STEER_RATE_DEG), max_accel=cfg.SIM_MAX_ACCEL,
                   drag=cfg.SIM_DRAG, rolling=cfg.SIM_ROLLING_DECEL, brake=cfg.SIM_BRAKE_DECEL,
                   max_speed=cfg.SIM_MAX_SPEED, max_reverse_speed=cfg.SIM_MAX_REVERSE_SPEED)


@dataclass
class CarState:
    """Pose and motion of the car: rear-axle position (m), heading (rad), speed (m/s), wheel angle."""

    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    speed: float = 0.0  # signed, negative = reversing
    steer: float = 0.0  # front wheel angle, rad, positive = left


class Car:
    """The kinematic bicycle: ``step(angle, throttle, dt)`` advances the state by ``dt`` seconds."""

    def __init__(self, params: CarParams | None = None, state: CarState | None = None,
                 substeps: int = 4) -> None:
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps}")
        self.params = params or CarParams()
        self.state = state or CarState()
        self.substeps = substeps

    def place(self, x: float, y: float, heading: float) -> None:
        """Put the car at a pose, standing still with straight wheels."""
        self.state = CarState(float(x), float(y), float(heading), 0.0, 0.0)

    def acceleration(self, throttle: float, v: float) -> float:
        """Longitudinal acceleration (m/s^2) for a throttle at speed ``v`` (m/s, signed)."""
        p = self.params
        if v > 0.0:  # rolling forward: positive throttle drives, negative brakes
            drive = throttle * (p.max_accel if throttle >= 0.0 else p.brake)
            return drive - p.drag * v - p.rolling
        if v < 0.0:  # reversing: negative throttle drives backwards, positive brakes
            drive = throttle * (p.max_accel if throttle <= 0.0 else p.brake)
            return drive - p.drag * v + p.rolling
        drive = throttle * p.max_accel  # at rest, rolling resistance holds a weak command
        return 0.0 if abs(drive) <= p.rolling else drive - math.copysign(p.rolling, drive)

    def step(self, angle: float, throttle: float, dt: float) -> CarState:
        """Apply commands for ``dt`` seconds and return the new state (commands clipped to [-1, 1])."""
        if not dt > 0:
            raise ValueError(f"time step must be > 0 s, got {dt}")
        p = self.params
        angle = min(1.0, max(-1.0, float(angle)))
        throttle = min(1.0, max(-1.0, float(throttle)))
        st = self.state
        target = -angle * p.max_steer  # angle -1 = full left = positive wheel angle
        h = dt / self.substeps
        for _ in range(self.substeps):
            max_turn = p.steer_rate * h
            st.steer += min(max_turn, max(-max_turn, target - st.steer))
            v0 = st.speed
            v1 = v0 + self.acceleration(throttle, v0) * h
            if v0 * v1 < 0.0:
                v1 = 0.0  # brakes and friction stop the car; reversing starts from rest
            v1 = min(p.max_speed, max(-p.max_reverse_speed, v1))
            v = 0.5 * (v0 + v1)  # midpoint rule for position
            yaw_rate = v * math.tan(st.steer) / p.wheelbase
            mid_heading = st.heading + 0.5 * yaw_rate * h
            st.x += v * math.cos(mid_heading) * h
            st.y += v * math.sin(mid_heading) * h
            st.heading = (st.heading + yaw_rate * h + math.pi) % (2 * math.pi) - math.pi
            st.speed = v1
        return st
