"""The simulated car's sensors: wheel encoder ticks, IMU, GPS and a 2-D LiDAR, from its true motion.

:class:`SimSensors` runs right after :class:`parts.sim.simulator.SimCar` and writes the keys a real
car's sensor parts write (``enc/ticks``, ``imu/*``, ``gps/*``, ``lidar/*``), so the odometer, the
speed controller, obstacle stop and a path follower run unchanged in simulation. Noise is seeded
(SIM_SEED): a run is reproducible.

- Encoder: ticks = floor(signed distance driven / metres per tick), as a quadrature encoder counts.
- IMU (mounted x forward, y left, z up): longitudinal acceleration dv/dt, lateral v x yaw rate, z
  +1 g (an accelerometer at rest reads the reaction to gravity); gyro z = yaw rate; white noise.
- GPS: a fix every 1 / rate seconds; the error is a first-order Gauss-Markov process (correlated
  over ``gps_tau`` seconds, like a real receiver's wander) of standard deviation ``gps_noise``
  metres; latitude/longitude around ``gps_origin``; x/y in a local frame with its origin at the
  first fix, or at ``gps_origin`` with ``gps_fixed_origin`` (GPS_ORIGIN set), as
  :class:`parts.sensors.gps.GPS` does.
- LiDAR: one ray per bin from a point ``lidar_forward`` metres ahead of the rear axle against the
  world's walls (the backdrop's box) and distractors (their bounding circles) and any extra
  segments given; nearest hit per bin, 0.0 beyond ``lidar_range``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from parts.sensors.gps import LocalFrame
from vehicle.config import check_settings

G = 9.80665
Segment = tuple[tuple[float, float], tuple[float, float]]


def ray_distances(origin: tuple[float, float], angles: np.ndarray, segments: np.ndarray, circles: np.ndarray,
                  max_range: float) -> np.ndarray:
    """Distance along each ray (world angle, rad) to the nearest segment (S, 4: x0 y0 x1 y1) or circle
    (C, 3: x y r); ``inf`` where nothing lies within ``max_range``."""
    ox, oy = origin
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    best = np.full(len(angles), np.inf)
    if len(segments):
        px, py = segments[:, 0][None], segments[:, 1][None]
        ex, ey = (segments[:, 2] - segments[:, 0])[None], (segments[:, 3] - segments[:, 1])[None]
        denom = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((px - ox) * ey - (py - oy) * ex) / denom
            u = ((px - ox) * dy - (py - oy) * dx) / denom
        hit = (np.abs(denom) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
    if len(circles):
        cx, cy, r = circles[:, 0][None] - ox, circles[:, 1][None] - oy, circles[:, 2][None]
        b = dx * cx + dy * cy
        disc = b * b - (cx * cx + cy * cy - r * r)
        with np.errstate(invalid="ignore"):
            t = b - np.sqrt(disc)
        inside = cx * cx + cy * cy <= r * r
        t = np.where(inside, 0.0, t)
        best = np.minimum(best, np.where((disc >= 0) & (t >= 0), t, np.inf).min(axis=1))
    best[best > max_range] = np.inf
    return best


class SimSensors:
    """Part: the sensors of a :class:`~parts.sim.simulator.SimCar` (see the module docstring).

    ``run() -> values of OUTPUTS``; which keys depends on the sensors switched on.

    Args:
        sim: the simulated car (read, never changed).
        encoder: publish ``enc/ticks, enc/timestamp, enc/ok``; ``m_per_tick`` metres per tick.
        imu: publish ``imu/acl_*, imu/gyr_*, imu/ok``; noise ``imu_accel_noise`` m/s^2 and
            ``imu_gyro_noise`` rad/s (standard deviations per reading).
        gps: publish ``gps/*`` as :class:`parts.sensors.gps.GPS` does, ``gps_hz`` fixes per second;
            ``gps_fixed_origin``: x/y around ``gps_origin`` (the track's (0, 0)), not the first fix.
        lidar: publish ``lidar/dist_array, lidar/ok`` with ``lidar_bins`` bins.
        obstacles: extra wall segments ((x0, y0), (x1, y1)) in track coordinates, metres.
        seed: seed of the noise (SIM_SEED).
    """

    def __init__(self, sim: Any, *, encoder: bool = True, m_per_tick: float = 0.005, imu: bool = False,
                 imu_accel_noise: float = 0.05, imu_gyro_noise: float = 0.005, gps: bool = False,
                 gps_hz: float = 5.0, gps_noise: float = 0.5, gps_tau: float = 10.0,
                 gps_origin: tuple[float, float] = (48.1351, 11.5820), gps_fixed_origin: bool = False,
                 lidar: bool = False, lidar_bins: int = 360,
                 lidar_range: float = 12.0, lidar_noise: float = 0.01, lidar_forward: float = 0.15,
                 obstacles: Sequence[Segment] = (), seed: int = 0) -> None:
        check_settings(MM_PER_TICK=m_per_tick * 1000.0, SIM_GPS_HZ=gps_hz, SIM_GPS_NOISE=gps_noise,
                       LIDAR_BINS=lidar_bins, LIDAR_MAX_RANGE=lidar_range)
        if not gps_tau > 0:
            raise ValueError(f"SimSensors: gps_tau must be > 0 s, got {gps_tau!r}")
        self.sim = sim
        self.encoder, self.imu, self.gps, self.lidar = bool(encoder), bool(imu), bool(gps), bool(lidar)
        self.m_per_tick = float(m_per_tick)
        self.imu_noise = (float(imu_accel_noise), float(imu_gyro_noise))
        self.gps_period, self.gps_noise, self.gps_tau = 1.0 / gps_hz, float(gps_noise), float(gps_tau)
        self.geo = LocalFrame(*gps_origin)
        self.lidar_bins, self.lidar_range = int(lidar_bins), float(lidar_range)
        self.lidar_noise, self.lidar_forward = float(lidar_noise), float(lidar_forward)
        self.obstacles = np.array([[*a, *b] for a, b in obstacles], dtype=float).reshape(-1, 4)
        self.rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5E7502])
        outputs: list[str] = []
        if self.encoder:
            outputs += ["enc/ticks", "enc/timestamp", "enc/ok"]
        if self.imu:
            outputs += ["imu/acl_x", "imu/acl_y", "imu/acl_z", "imu/gyr_x", "imu/gyr_y", "imu/gyr_z", "imu/ok"]
        if self.gps:
            outputs += ["gps/x", "gps/y", "gps/latitude", "gps/longitude", "gps/accuracy", "gps/speed", "gps/ok"]
        if self.lidar:
            outputs += ["lidar/dist_array", "lidar/ok"]
        if not outputs:
            raise ValueError("SimSensors: no sensor switched on")
        self._outputs = tuple(outputs)
        self.distance = 0.0  # signed metres driven (the encoder's truth)
        self._prev: tuple[float, float, float, float, int, int] | None = None  # x, y, heading, speed, resets, seed
        self._gps_error = np.zeros(2)
        self._gps_next = 0.0
        self._gps_frame: LocalFrame | None = self.geo if gps_fixed_origin else None
        self._gps_started = False
        self._gps_values: tuple[Any, ...] = (None,) * 6
        self._walls_of: Any = self  # the world the walls below belong to (self: none computed yet)
        self._walls = np.zeros((0, 4))
        self._circles = np.zeros((0, 3))

    @property
    def OUTPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The keys of the sensors switched on, in the order of :meth:`run`'s values."""
        return self._outputs

    @property
    def RECORDED(self) -> dict[str, str]:  # noqa: N802 - the part declaration read by Vehicle.recorded
        """What the real sensors record, of the keys this part writes (the odometer records the
        encoder's distance and speed)."""
        from parts.sensors.gps import GPS
        from parts.sensors.imu import IMU
        from parts.sensors.lidar import RPLidar

        return {k: t for cls in (IMU, GPS, RPLidar) for k, t in cls.RECORDED.items() if k in self._outputs}

    @classmethod
    def from_config(cls, cfg: Any, sim: Any) -> SimSensors | None:
        """The simulated sensors a simulator car's settings switch on (HAVE_ODOM, HAVE_IMU,
        HAVE_GPS, USE_LIDAR, with MM_PER_TICK, LIDAR_BINS, LIDAR_MAX_RANGE and the SIM_*_NOISE
        settings); None when none is."""
        if not (cfg.HAVE_ODOM or cfg.HAVE_IMU or cfg.HAVE_GPS or cfg.USE_LIDAR):
            return None
        origin = tuple(cfg.GPS_ORIGIN) if cfg.GPS_ORIGIN is not None else (48.1351, 11.5820)
        return cls(sim, encoder=cfg.HAVE_ODOM, m_per_tick=cfg.MM_PER_TICK / 1000.0, imu=cfg.HAVE_IMU,
                   imu_accel_noise=cfg.SIM_IMU_ACCEL_NOISE, imu_gyro_noise=cfg.SIM_IMU_GYRO_NOISE, gps=cfg.HAVE_GPS,
                   gps_hz=cfg.SIM_GPS_HZ, gps_noise=cfg.SIM_GPS_NOISE, gps_origin=origin,  # type: ignore[arg-type]
                   gps_fixed_origin=cfg.GPS_ORIGIN is not None,
                   lidar=cfg.USE_LIDAR, lidar_bins=cfg.LIDAR_BINS, lidar_range=cfg.LIDAR_MAX_RANGE,
                   lidar_noise=cfg.SIM_LIDAR_NOISE, seed=cfg.SIM_SEED)

    # -- ground truth -----------------------------------------------------------------------------
    def _motion(self) -> tuple[float, float, float]:
        """(distance this step, yaw rate, acceleration) from the car's state; a reset is no motion."""
        st, dt = self.sim.car.state, self.sim.dt
        now = (st.x, st.y, st.heading, st.speed, self.sim.resets, self.sim.seed)
        prev, self._prev = self._prev, now
        if prev is None or prev[4:] != now[4:]:
            return 0.0, 0.0, 0.0
        step = math.hypot(st.x - prev[0], st.y - prev[1])
        direction = 1.0 if st.speed + prev[3] >= 0 else -1.0
        turn = (st.heading - prev[2] + math.pi) % (2 * math.pi) - math.pi
        return direction * step, turn / dt, (st.speed - prev[3]) / dt

    # -- sensors --------------------------------------------------------------------------------
    def _imu(self, yaw_rate: float, accel: float) -> tuple[Any, ...]:
        a_sd, g_sd = self.imu_noise
        na, ng = self.rng.normal(0.0, a_sd, 3), self.rng.normal(0.0, g_sd, 3)
        v = self.sim.car.state.speed
        return (accel + na[0], v * yaw_rate + na[1], G + na[2], ng[0], ng[1], yaw_rate + ng[2], True)

    def _gps(self) -> tuple[Any, ...]:
        t = self.sim.time
        if t + 1e-9 >= self._gps_next:
            self._gps_next = t + self.gps_period
            draw = self.rng.normal(0.0, self.gps_noise, 2)
            if not self._gps_started:  # the first fix: the error's stationary distribution
                self._gps_started = True
                self._gps_error = draw
            else:  # Gauss-Markov: keeps the standard deviation, correlated over gps_tau seconds
                a = math.exp(-self.gps_period / self.gps_tau)
                self._gps_error = a * self._gps_error + math.sqrt(1 - a * a) * draw
            st = self.sim.car.state
            lat, lon = self.geo.to_latlon(st.x + self._gps_error[0], st.y + self._gps_error[1])
            if self._gps_frame is None:
                self._gps_frame = LocalFrame(lat, lon)
            x, y = self._gps_frame.to_xy(lat, lon)
            speed = abs(st.speed) + float(self.rng.normal(0.0, 0.05))
            self._gps_values = (x, y, lat, lon, self.gps_noise or None, max(0.0, speed))
        return (*self._gps_values, True)

    def _geometry(self) -> tuple[np.ndarray, np.ndarray]:
        world = getattr(self.sim, "world", None)
        if world is not self._walls_of:  # a new track: its walls and distractors
            self._walls_of = world
            segments, circles = [self.obstacles], np.zeros((0, 3))
            scenery = getattr(world, "scenery", None)
            if scenery is not None and scenery.backdrop is not None:
                x0, y0, x1, y1 = scenery.backdrop.bounds
                segments.append(np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]))
            if scenery is not None and scenery.distractors:
                circles = np.array([[d.x, d.y, d.radius] for d in scenery.distractors])
            self._walls, self._circles = np.concatenate(segments), circles
        return self._walls, self._circles

    def scan(self) -> list[float]:
        """One LiDAR turn at the car's current pose: ``lidar/dist_array`` (see :func:`bin_scan`)."""
        st = self.sim.car.state
        origin = (st.x + self.lidar_forward * math.cos(st.heading), st.y + self.lidar_forward * math.sin(st.heading))
        rel = (np.arange(self.lidar_bins) + 0.5) * (2 * math.pi / self.lidar_bins)
        segments, circles = self._geometry()
        d = ray_distances(origin, st.heading + rel, segments, circles, self.lidar_range)
        if self.lidar_noise > 0:
            d = d + self.rng.normal(0.0, self.lidar_noise, len(d))
        d[~np.isfinite(d)] = 0.0
        return np.clip(d, 0.0, None).tolist()

    def run(self) -> tuple[Any, ...]:
        """This loop's sensor values, in the order of ``OUTPUTS``."""
        step, yaw_rate, accel = self._motion()
        self.distance += step
        out: list[Any] = []
        if self.encoder:
            out += [math.floor(self.distance / self.m_per_tick + 1e-9), self.sim.time, True]
        if self.imu:
            out += self._imu(yaw_rate, accel)
        if self.gps:
            out += self._gps()
        if self.lidar:
            out += [self.scan(), True]
        return tuple(out)
