"""Assembly of the built-in simulator: the simulated car, the expert driver and its noise.

Order in a simulator car's loop: ``add_simulator`` first (it produces the camera frame and applies
the commands of the previous loop, declared as feedback), then a controller or ``add_expert``,
drive mode, then ``add_expert_noise`` (it perturbs the executed ``angle`` after drive mode, so the
tub records the expert's clean ``user/angle``).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from parts.bridges.registry import SIMULATORS
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: the simulators a car can drive (SIM_TYPE, ``--sim``): the rows of the simulator table
SIM_TYPES: tuple[str, ...] = tuple(SIMULATORS)


def resolve_sim_type(cfg: Any, sim_type: str | None = None) -> str:
    """The simulator a car drives: ``sim_type`` (``--sim``) if given, else SIM_TYPE."""
    kind = sim_type or cfg.SIM_TYPE
    if kind not in SIM_TYPES:
        raise UserError(f"unknown simulator {kind!r}: use one of {', '.join(SIM_TYPES)} (SIM_TYPE or --sim)")
    return kind


def sim_clock(cfg: Any, sim_type: str | None = None) -> Any:
    """The clock of a simulator car's Vehicle: simulated time (as fast as the CPU allows) for the
    built-in simulator with SIM_REALTIME False, else the wall clock (None). An external simulator
    runs in real time, so its car always paces itself."""
    if resolve_sim_type(cfg, sim_type) == "builtin" and not cfg.SIM_REALTIME:
        from vehicle.clock import SimulatedClock

        return SimulatedClock()
    return None


def add_simulator(V: Any, cfg: Any, seeds: Sequence[int] | None = None, sim_type: str | None = None) -> Any:
    """Add the simulated car, chosen by SIM_TYPE (or ``sim_type``, the ``--sim`` option).

    In: ``angle``, ``throttle`` (the previous loop's commands), ``sim/reset``; out:
    ``cam/image_array``, ``cam/timestamp``, ``sim/*`` telemetry and ``enc/speed`` (the true speed;
    with HAVE_ODOM the odometer's, from simulated encoder ticks), and the simulated sensors the
    car's settings switch on (see :func:`add_sim_sensors`).

    - "builtin": our simulator in this process, on the tracks of SIM_TRACK_SEEDS unless ``seeds``.
    - "udacity": :class:`parts.bridges.udacity_sim.UdacitySim`, the server the Udacity simulator
      connects to (UDACITY_*); also ``cam/ok``, ``sim/manual``, ``sim/steering_deg``.
    - "donkey": :class:`parts.bridges.donkey_client.DonkeySim`, connected to SIM_HOST:SIM_PORT
      (DONKEY_GYM_ENV_NAME, GYM_CONF, DONKEY_MAX_CTE); also ``cam/ok``, ``sim/hit``.

    The external simulators' parts are threaded: the loop never waits for them, and a stale camera
    (SIM_TIMEOUT_S) makes ``cam/ok`` False for :func:`add_camera_watchdog`. A rising ``sim/reset``
    puts the car back on its start line (the Udacity simulator cannot: it has no reset). With
    CAMERA_UNDISTORT the frames are undistorted next (see ``add_undistort``).

    Raises:
        UserError: a setting is out of range, the port is taken, the Donkey simulator cannot be
            reached or lacks the scene (the message names the setting).
    """
    from vehicle.app.assembly.camera import add_undistort

    kind = resolve_sim_type(cfg, sim_type)
    if kind == "builtin":
        # with a (simulated) encoder the odometer measures enc/speed, as on a real car
        sim = SIMULATORS.from_config(cfg, "builtin", seeds=seeds, measured_speed=not cfg.HAVE_ODOM)
        V.add(sim)
        add_sim_sensors(V, cfg, sim)
        # a simulated lens (SIM_CAMERA_DISTORTION) is undistorted like a real one
        add_undistort(V, cfg, (cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H), "SIM_CAMERA_W x SIM_CAMERA_H")
        return sim
    if seeds:
        logger.warning("--tracks applies to the built-in simulator only; the %s simulator chooses its own "
                       "track%s", kind, " (DONKEY_GYM_ENV_NAME)" if kind == "donkey" else "")
    if kind == "donkey" and cfg.DONKEY_SIM_PATH not in (None, "remote"):
        from parts.bridges.sim_process import SimulatorProcess

        # started before the bridge (parts start in order) and ended after it (shutdown in reverse)
        V.add(SimulatorProcess(cfg.DONKEY_SIM_PATH, cfg.SIM_HOST, cfg.SIM_PORT, timeout_s=cfg.DONKEY_SIM_START_TIMEOUT,
                               log_file=cfg.path("LOGS_PATH") / "unitylog.txt"), threaded=True)
    sim = make_bridge(cfg, kind)
    V.add(sim, threaded=True)
    add_undistort(V, cfg, *bridge_frame_size(cfg, kind))
    return sim


def add_sim_sensors(V: Any, cfg: Any, sim: Any) -> Any:
    """Add the simulated car's sensors right after it (HAVE_ODOM, HAVE_IMU, HAVE_GPS, USE_LIDAR:
    the keys a real car's sensors write, see :mod:`parts.sim.sensors`) and the odometry on its
    encoder ticks. Returns the SimSensors part, or None when no sensor is switched on."""
    from parts.sim.sensors import SimSensors
    from vehicle.app.assembly.sensors import add_odometry

    if cfg.HAVE_ODOM_2:
        logger.warning("HAVE_ODOM_2: the simulated car has one encoder (a car, not a differential drive)")
    part = SimSensors.from_config(cfg, sim)
    if part is None:
        return None
    V.add(part)
    add_odometry(V, cfg)
    return part


def bridge_frame_size(cfg: Any, sim_type: str) -> tuple[tuple[int, int], str]:
    """(width, height) of the frames an external simulator delivers, and what sets it: the Donkey
    simulator renders IMAGE_W x IMAGE_H, the Udacity simulator always 320 x 160."""
    if sim_type == "udacity":
        from parts.bridges.udacity_protocol import FRAME_SIZE

        return FRAME_SIZE, "fixed by the Udacity simulator, 320 x 160"
    return (cfg.IMAGE_W, cfg.IMAGE_H), "IMAGE_W x IMAGE_H"


def add_simulator_commands(V: Any) -> Any:
    """Add, last in the loop, the part that sends this loop's ``angle``/``throttle`` to the Udacity
    or Donkey simulator at once (:class:`parts.bridges.commands.SendCommands`); without it they
    leave one loop later. Returns the part, or None for the built-in simulator (it applies the
    commands at its next step, in simulated time) or a car without a simulator.
    """
    from parts.bridges.commands import SendCommands
    from parts.bridges.donkey_client import DonkeySim
    from parts.bridges.udacity_sim import UdacitySim

    bridges = V.find(UdacitySim) + V.find(DonkeySim)
    if not bridges:
        return None
    part = SendCommands(bridges[0])
    V.add(part)
    return part


def make_bridge(cfg: Any, sim_type: str, **options: Any) -> Any:
    """The part of an external simulator ("udacity" or "donkey") built from the car's settings (its
    row of :data:`parts.bridges.registry.SIMULATORS`), not added to a vehicle; ``options`` go to the
    part (e.g. ``synchronous=True`` for the Donkey simulator's step mode).

    Raises:
        ConfigError: a setting is out of range (the message names it).
        UserError: ``sim_type`` is not an external simulator.
    """
    if sim_type == "builtin" or sim_type not in SIMULATORS:
        raise UserError(f"{sim_type!r} is not an external simulator: use udacity or donkey")
    return SIMULATORS.from_config(cfg, sim_type, **options)


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
