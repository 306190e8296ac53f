"""Path follow in the built-in simulator: record a lap with the expert, and follow a path as
:func:`vehicle.app.evaluate.evaluate`'s pilot, so path follow and learned pilots share one report.

The simulated sensors (parts.sim.sensors: encoder ticks, GPS with its Gauss-Markov noise) feed the
same odometry and :class:`parts.path.localizer.Localizer` as on a real car. The path frames:
odometry and fused start at the car's start pose (x forward, y left); GPS is east/north around
GPS_ORIGIN, which these runs set to the simulator's origin when it is None, so a GPS path stays
valid between runs. The recording runs with SIM_SEED + :data:`RECORD_SEED_OFFSET`: its GPS noise
is not the noise of the runs that follow the path.
"""

from __future__ import annotations

import logging
import math
from typing import Any, ClassVar

import numpy as np

from parts.path.localizer import SOURCES, Localizer
from parts.path.metrics import PathDistance
from parts.path.pathfile import Path
from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: the recording's noise seed is SIM_SEED plus this (the following runs use SIM_SEED)
RECORD_SEED_OFFSET = 1000
#: the simulator's GPS origin (parts.sim.sensors.SimSensors' default): the track's (0, 0)
SIM_GPS_ORIGIN = (48.1351, 11.5820)
#: LOC_ODOM_DRIFT of the simulated car, metres of error per metre driven: its wheels do not slip,
#: so its odometry drifts ~4x less than LOC_ODOM_DRIFT's real-car default (0.02) assumes; with that
#: default the fused filter trusts a 1 m GPS too much and leaves a 0.8 m road (docs/path_follow.md)
SIM_ODOM_DRIFT = 0.005


def sensor_config(cfg: Any, localizer: str) -> Any:
    """``cfg`` with the simulated sensors a localiser needs switched on (HAVE_ODOM, HAVE_GPS),
    GPS_ORIGIN fixed (the simulator's origin when None) and LOC_ODOM_DRIFT the simulated car's
    (:data:`SIM_ODOM_DRIFT`) unless the car's myconfig.py sets it."""
    if localizer not in SOURCES:
        raise UserError(f"localizer {localizer!r}: use one of {', '.join(SOURCES)}")
    return cfg.replace(HAVE_ODOM=cfg.HAVE_ODOM or localizer != "gps", HAVE_GPS=cfg.HAVE_GPS or localizer != "odometry",
                       GPS_ORIGIN=cfg.GPS_ORIGIN if cfg.GPS_ORIGIN is not None else SIM_GPS_ORIGIN,
                       PATH_LOOP=True if cfg.PATH_LOOP is None else cfg.PATH_LOOP,
                       LOC_ODOM_DRIFT=cfg.LOC_ODOM_DRIFT if "LOC_ODOM_DRIFT" in cfg.overridden else SIM_ODOM_DRIFT)


class _Once:
    """Part: ``path/command`` "record" in the first loop, None after."""

    OUTPUTS: ClassVar[tuple[str, ...]] = ("path/command",)

    def __init__(self, command: str) -> None:
        self.command: str | None = command

    def run(self) -> str | None:
        command, self.command = self.command, None
        return command


class _StopAfterLaps:
    INPUTS: ClassVar[tuple[str, ...]] = ("sim/lap",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, laps: int, stop: Any) -> None:
        self.laps, self.stop = laps, stop

    def run(self, lap: Any) -> None:
        if lap is not None and lap >= self.laps:
            self.stop()


def record_path(cfg: Any, seed: int, localizer: str = "odometry", laps: int = 1) -> Path:
    """The path the expert drives in ``laps`` lap(s) of track ``seed``, recorded as a user records it
    (PATH_MIN_DIST apart, the measured speed), in ``localizer``'s frame."""
    from parts.path.recorder import PathRecorder
    from parts.sim.simulator import SimCar
    from vehicle import Vehicle
    from vehicle.app.assembly.drive import add_drive_mode, add_obstacle_stop, add_speed_limit
    from vehicle.app.assembly.path import speed_wiring
    from vehicle.app.assembly.pilot import speed_key_of
    from vehicle.app.assembly.sim import add_expert, add_sim_sensors
    from vehicle.clock import SimulatedClock

    cfg = sensor_config(cfg, localizer).replace(SIM_SEED=cfg.SIM_SEED + RECORD_SEED_OFFSET, TRAIN_BEHAVIORS=False)
    sim = SimCar.from_config(cfg, seeds=[seed], reset_off_track=True, reset_to="nearest", realtime=False,
                             render=False, measured_speed=not cfg.HAVE_ODOM)
    V = Vehicle(clock=SimulatedClock())
    V.add(sim)
    add_sim_sensors(V, cfg, sim)
    add_expert(V, cfg, sim)
    V.add(_Once("record"))
    V.add(Localizer.from_config(cfg, localizer))
    recorder = PathRecorder("unsaved.csv", cfg.PATH_MIN_DIST, load=False)
    V.add(recorder, **speed_wiring(PathRecorder, speed_key_of(V, cfg)))
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    V.add(_StopAfterLaps(laps, V.stop))
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=int(120 * laps * cfg.DRIVE_LOOP_HZ), log_summary=False)
    logger.info("recorded %d points (%.1f m) on track %d with %s", len(recorder.path), recorder.path.length, seed,
                localizer)
    return recorder.path


class _StaticPath:
    """Part: a fixed path as the recorder would publish it."""

    OUTPUTS: ClassVar[tuple[str, ...]] = ("path/xy", "path/speed", "path/version", "path/recording")

    def __init__(self, path: Path) -> None:
        self.path = path

    def run(self) -> tuple[Any, ...]:
        return self.path.xy, self.path.speed, 1, False


class PathDriver:
    """A recorded path and a localiser as :func:`vehicle.app.evaluate.evaluate`'s pilot.

    Per episode (:meth:`prepare_episode`) it adds the simulated sensors, the odometry, the localiser,
    the path and :class:`parts.path.metrics.PathDistance`; as the pilot it runs, round the path
    (the recorded lap; PATH_LOOP = False stops at its end),
    :class:`parts.path.follower.PathFollower`. Each track's report gains ``mean_path_distance``,
    ``p95_path_distance``, ``max_path_distance`` (true distance to the recorded path, m) and
    ``localizer``.
    """

    #: the follower's (parts.path.follower.PathFollower; a test keeps them equal)
    INPUTS: ClassVar[tuple[str, ...]] = ("loc/x", "loc/y", "loc/angle", "loc/ok", "path/xy", "path/speed",
                                         "path/version", "path/recording", "user/mode", "enc/speed")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)

    def __init__(self, path: Path, localizer: str, cfg: Any, name: str | None = None) -> None:
        from parts.path.follower import PathFollower

        if len(path) < 2:
            raise UserError("the path has fewer than 2 points: record one first")
        self.path, self.localizer = path, localizer
        self.cfg = sensor_config(cfg, localizer)
        self.name = name or f"path ({localizer})"
        self.follower = PathFollower.from_config(self.cfg)
        self.distance: PathDistance | None = None

    def episode_config(self, cfg: Any) -> Any:
        """The settings an episode runs with: the car's, with this localiser's sensors on."""
        return sensor_config(cfg, self.localizer)

    def prepare_episode(self, V: Any, cfg: Any, sim: Any) -> None:
        """Add sensors, localiser and path after the simulated car (a fresh follower state)."""
        from parts.path.follower import PathFollower
        from vehicle.app.assembly.sim import add_sim_sensors

        cfg = self.episode_config(cfg)
        add_sim_sensors(V, cfg, sim)
        V.add(Localizer.from_config(cfg, self.localizer))
        V.add(_StaticPath(self.path))
        self.follower = PathFollower.from_config(cfg)
        st = sim.car.state
        if self.localizer == "gps":
            world = self.path.xy  # GPS_ORIGIN is the track's (0, 0): east/north = the track's x/y
        else:  # odometry's frame: the start pose
            c, s = math.cos(st.heading), math.sin(st.heading)
            p = self.path.xy.astype(np.float64)
            world = np.stack([st.x + c * p[:, 0] - s * p[:, 1], st.y + s * p[:, 0] + c * p[:, 1]], axis=1)
        self.distance = PathDistance(world, closed=self.follower.loop if self.follower.loop is not None
                                     else self.path.is_closed(cfg.PATH_LOOP_CLOSE_DIST))

    def add_metrics(self, V: Any) -> None:
        """Add the distance to the path (after drive mode, as the episode's metrics)."""
        if self.distance is not None:
            V.add(self.distance)

    def episode_result(self, result: dict[str, Any]) -> dict[str, Any]:
        """The episode's metrics with the path distances and the localiser."""
        if self.distance is not None:
            result.update(self.distance.result())
        result["localizer"] = self.localizer
        return result

    def run(self, *inputs: Any) -> tuple[float, float]:
        """(pilot/angle, pilot/throttle) of the follower."""
        angle, throttle, *_ = self.follower.run(*inputs)
        return angle, throttle
