"""Assembly of the built-in simulator: the simulated car, the expert driver and its noise.

Order in a simulator car's loop: ``add_simulator`` first (it produces the camera frame and applies
the commands of the previous loop, declared as feedback), then a controller or ``add_expert``,
drive mode, then ``add_expert_noise`` (it perturbs the executed ``angle`` after drive mode, so the
tub records the expert's clean ``user/angle``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def add_simulator(V: Any, cfg: Any, seeds: Sequence[int] | None = None) -> Any:
    """Add the simulated car: in ``angle``, ``throttle``, ``sim/reset``; out ``cam/image_array``,
    ``cam/timestamp``, ``sim/*`` telemetry and ``enc/speed``. Drives the tracks of SIM_TRACK_SEEDS
    unless ``seeds``. A part that sets ``sim/reset`` True (e.g. a button) puts the car back on the
    start line. With CAMERA_UNDISTORT the frames are undistorted next (see ``add_undistort``)."""
    from parts.sim.simulator import SimCar
    from vehicle.app.assembly.camera import add_undistort

    sim = SimCar.from_config(cfg, seeds=seeds)
    V.add(sim)
    add_undistort(V, cfg)  # a simulated lens (SIM_CAMERA_DISTORTION) is undistorted like a real one
    return sim


def add_expert(V: Any, cfg: Any, sim: Any) -> Any:
    """Add the pure-pursuit expert driving ``sim``: out ``user/angle``, ``user/throttle``,
    ``user/mode`` (always "user") and ``recording`` (always True). On two-lane tracks with
    TRAIN_BEHAVIORS it reads ``behavior/state`` (add the behaviour part first) and keeps to, or
    changes to, the lane of the active behaviour."""
    from parts.sim.expert import Expert

    expert = Expert.from_config(cfg, sim)
    # following behaviours, it reads the active one (add_behavior before add_expert)
    V.add(expert, inputs=["behavior/state"] if expert.behavior_lanes is not None else None)
    return expert


def add_expert_noise(V: Any, cfg: Any, inputs: Sequence[str] = ("angle", "throttle")) -> Any | None:
    """Add noise injection on the executed commands (after drive mode); None when SIM_EXPERT_NOISE
    is 0. ``inputs`` are the command keys it reads; it always writes ``angle``, ``throttle``."""
    if cfg.SIM_EXPERT_NOISE <= 0:
        return None
    from parts.sim.expert import NoiseInjector

    noise = NoiseInjector(cfg.SIM_EXPERT_NOISE, cfg.SIM_EXPERT_NOISE_EVERY, cfg.SIM_EXPERT_NOISE_DURATION,
                          dt=1.0 / cfg.DRIVE_LOOP_HZ, seed=cfg.SIM_SEED)
    V.add(noise, inputs=list(inputs))
    return noise
