"""Record expert demonstrations in the simulator into a tub, in simulated time.

The vehicle is the simulator car's usual loop: sim car → expert (user/angle, user/throttle,
recording=True) → DriveMode → executed command (optionally perturbed by noise injection) → tub
writer. The tub stores the expert's clean command as the label, so with SIM_EXPERT_NOISE > 0 the
data shows how to recover from the perturbed poses.

With ``lane_changes`` (two-lane tracks), a :class:`parts.drive.behavior.BehaviorSchedule` steps the
behaviour (BEHAVIOR_LIST, e.g. Left_Lane / Right_Lane) at seeded random times, the expert moves
to the lane of the active behaviour, and every record carries ``behavior/state``,
``behavior/label`` and ``behavior/one_hot_state_array``: the thesis's lane-change data.

With SIM_SIDE_CAMERAS_OFFSET every record also holds the side cameras' frames
(``cam/image_array_left``, ``cam/image_array_right``): the three_camera model's data. The sensors
the car's settings switch on (HAVE_ODOM, HAVE_IMU, HAVE_GPS, USE_LIDAR) are recorded as
``manage.py drive`` records them.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from vehicle.errors import UserError

logger = logging.getLogger(__name__)

#: what a demonstration record holds (memory key, tub type); cam/timestamp becomes _timestamp_ms
RECORD_FIELDS: tuple[tuple[str, str], ...] = (
    ("cam/image_array", "image_array"),
    ("user/angle", "float"),
    ("user/throttle", "float"),
    ("user/mode", "str"),
    ("cam/timestamp", "float"),
    ("sim/cte", "float"),
    ("sim/speed", "float"),
    ("sim/track", "int"),
)


class WaitForTubWriter:
    """Part: in simulated time the loop outruns the disk; wait (wall time) until the writer keeps up.

    Its class name is what the timing report at the stop shows (the time spent waiting for the disk).
    """

    def __init__(self, writer: Any) -> None:
        self.writer = writer
        self.limit = max(1, int(getattr(writer, "queue_size", 100)) // 2)

    def run(self) -> None:
        while self.writer.pending() >= self.limit:
            time.sleep(0.001)


def _as_config(cfg_or_car: Any) -> Any:
    if isinstance(cfg_or_car, str | os.PathLike):
        from vehicle.config import load_config

        return load_config(car_path=cfg_or_car)
    if cfg_or_car is None:
        from vehicle.config import Config

        return Config.defaults()
    return cfg_or_car


def record_expert(cfg: Any, seeds: Sequence[int] | None, n_records: int, tub_path: str | os.PathLike[str] | None = None,
                  *, noise: float | None = None, lane_changes: int | None = None) -> Path:
    """Let the expert drive and record ``n_records`` records; returns the tub's path.

    Args:
        cfg: the car's Config (or a car folder, loaded with its myconfig.py).
        seeds: track seeds (None: SIM_TRACK_SEEDS); the records are spread evenly over them, in the
            themes of SIM_THEME dealt in turn, randomised by SIM_RANDOMIZE.
        n_records: records to write (one per loop of 1 / DRIVE_LOOP_HZ simulated seconds).
        tub_path: the tub folder to write (created; an existing tub is appended to). None: a new tub
            in the car's data folder, as ``manage.py drive`` records.
        noise: steering noise amplitude for noise injection (None: SIM_EXPERT_NOISE).
        lane_changes: commanded lane changes spread at random over the recording (two-lane tracks:
            SIM_LANES = 2; turns TRAIN_BEHAVIORS on). None or 0: the behaviour stays BEHAVIOR_INITIAL
            (still recorded with TRAIN_BEHAVIORS).

    Raises:
        ValueError: n_records < 1 or bad seeds.
        UserError: lane changes on one-lane tracks, or more than fit into the recording.
    """
    from parts.sim.themes import theme_list
    from vehicle.app.assembly.drive import add_drive_mode, add_obstacle_stop, add_speed_limit
    from vehicle.app.assembly.sim import add_expert, add_expert_noise, add_simulator
    from vehicle.clock import SimulatedClock
    from vehicle.vehicle import Vehicle

    if not isinstance(n_records, int) or isinstance(n_records, bool) or n_records < 1:
        raise ValueError(f"n_records must be an int >= 1, got {n_records!r}")
    cfg = _as_config(cfg)
    seeds = list(seeds) if seeds is not None else list(cfg.SIM_TRACK_SEEDS)
    overrides: dict[str, Any] = {
        "SIM_REALTIME": False,
        "METADATA": [*cfg.METADATA, "source:sim expert", f"tracks:{','.join(map(str, seeds))}",
                     f"themes:{','.join(theme_list(cfg.SIM_THEME))}", f"randomize:{cfg.SIM_RANDOMIZE}"]}
    if noise is not None:
        overrides["SIM_EXPERT_NOISE"] = float(noise)
    if lane_changes:
        if cfg.SIM_LANES != 2:
            raise UserError(f"lane changes need two-lane tracks: set SIM_LANES = 2 in myconfig.py (it is "
                            f"{cfg.SIM_LANES})")
        overrides["TRAIN_BEHAVIORS"] = True
        overrides["METADATA"] = [*overrides["METADATA"], f"lane_changes:{lane_changes}"]
    if cfg.SIM_ROAD_SURFACE_SHARE:
        overrides["METADATA"] = [*overrides["METADATA"], f"road_surfaces:{cfg.SIM_ROAD_SURFACE_SHARE}"]
    cfg = cfg.replace(**overrides)

    V = Vehicle(clock=SimulatedClock())
    sim = add_simulator(V, cfg, seeds=seeds)
    if len(seeds) > 1:
        sim.switch_every = math.ceil(n_records / len(seeds))
    if cfg.TRAIN_BEHAVIORS:
        from parts.drive.behavior import BehaviorSchedule, behavior_lane, random_change_times
        from vehicle.app.assembly.drive import add_behavior

        dt = 1.0 / cfg.DRIVE_LOOP_HZ
        try:
            times = random_change_times(int(lane_changes or 0), n_records * dt, seed=cfg.SIM_SEED)
        except ValueError as exc:
            raise UserError(f"--lane-changes {lane_changes}: {exc}") from None
        V.add(BehaviorSchedule(times, dt), outputs=list(BehaviorSchedule.OUTPUTS))
        part = add_behavior(V, cfg)
        lane = behavior_lane(part.behaviors[part.state])
        if lane is not None and cfg.SIM_LANES == 2:  # start in the lane of the initial behaviour
            sim.start_offset = sim.track.lane_offset(lane)
            sim.select_track(sim.seeds[0])
    add_expert(V, cfg, sim)
    add_drive_mode(V, cfg)  # user mode: the expert's command, clamped, as on the car
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    add_expert_noise(V, cfg)  # perturbs the executed command; the tub keeps the expert's label
    from vehicle.app.assembly.tub import add_tub_writer, recorded_extras

    # what a drive records beside the demonstration: the sensors switched on, the side cameras'
    # frames (SIM_SIDE_CAMERAS_OFFSET), the behaviour keys (TRAIN_BEHAVIORS)
    fields = [*RECORD_FIELDS, *recorded_extras(V, cfg, [k for k, _ in RECORD_FIELDS])]
    keys = [k for k, _ in fields]
    types = [t for _, t in fields]
    if tub_path is not None:  # record exactly there: the data folder is the tub
        cfg = cfg.replace(DATA_PATH=str(Path(tub_path).expanduser().absolute()), AUTO_CREATE_NEW_TUB=False)

    writer = add_tub_writer(V, cfg, inputs=keys, types=types)
    # the writer is last in the loop: wait for it before the next loop's frame is queued
    V.add(WaitForTubWriter(writer))
    t0 = time.perf_counter()
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=n_records)
    path = Path(writer.path)
    logger.info("recorded %d expert records on tracks %s into %s in %.1f s (%d laps, %d resets)",
                n_records, seeds, path, time.perf_counter() - t0, sim.tracker.laps, sim.resets)
    return path

