"""Closed-loop evaluation of a pilot on simulated tracks, on the car's own loop in simulated time.

One episode per track seed, each a real :class:`vehicle.Vehicle` on a
:class:`vehicle.clock.SimulatedClock` with the parts ``manage.py drive --model`` uses::

    SimCar ─► driver engaged (user/mode "local") ─► PilotCondition ─► pilot ─► DriveMode ─► EpisodeMetrics
     ▲                                                                          │
     └──────────────────────── angle, throttle (next loop) ◄────────────────────┘

so what is evaluated is what drives: the pilot's outputs go through the same DriveMode (a NaN or
None command becomes centre and zero throttle, AI_THROTTLE_MULT scales the throttle) before the
simulated car applies them, and the pilot sees the frames the car drives with (undistorted after
the simulator with CAMERA_UNDISTORT, as ``add_simulator`` does). Leaving the road counts as an
intervention: the car is re-centred on the road next to where it left (what a person would do) and
the episode goes on. Metrics:
:mod:`parts.sim.metrics` (DAVE-2 autonomy, time-weighted |CTE| over autonomous frames, ...).

The same loop drives the other simulators (``sim="donkey"`` / ``"udacity"``): ``vehicle sim serve``
in synchronous steps of 1 / DRIVE_LOOP_HZ (it says it can step), the Donkey simulator in real time
(its step mode only pauses it), one episode per scene, an off-track event answered with
``reset_car`` (back to the start line: the simulator cannot re-centre); the Udacity simulator in
real time on the track it shows, where the user's manual
overrides (W/S held) are the interventions and only frames that arrived are scored. What a
simulator does not report (stock Udacity: CTE, laps, progress, position) is named in the report as
unavailable, never counted as zero.

A behaviour pilot on two-lane tracks (SIM_LANES = 2, a pilot reading
``behavior/one_hot_state_array``) is also commanded to change lanes, the thesis's experiment: a
:class:`parts.drive.behavior.BehaviorSchedule` steps the behaviour at seeded times
(SIM_EVAL_LANE_CHANGE_EVERY), and :class:`parts.sim.lane_metrics.LaneMetrics` scores lane keeping
and every change (success within SIM_EVAL_LANE_CHANGE_TIME_LIMIT, time to change, wrong-lane
time); the report gets a ``lanes`` section per track and overall.

On the built-in simulator, with ``workers > 1`` the tracks run in parallel worker processes, each
with its own simulator and its own copy of the pilot (loaded from the model file, or the expert),
torch and OpenCV limited to ``cores // workers`` threads so the workers do not oversubscribe the
machine. Every episode depends only on its seed, so the report is the serial one (a test checks
they are identical).
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from parts.drive.behavior import BehaviorSchedule, behavior_lane, periodic_change_times
from parts.drive.modes import PilotCondition
from parts.sim.episode import ResetOnOffTrack, StopIfNoSimulator
from parts.sim.lane_metrics import CommandedLane, LaneMetrics, overall_lane_metrics
from parts.sim.metrics import EpisodeMetrics, overall
from parts.sim.randomize import check_ranges
from parts.sim.simulator import SimCar
from parts.sim.themes import theme_list, theme_of
from parts.sim.world import prefetch_world, world_params
from vehicle import Vehicle
from vehicle.app.assembly.camera import add_undistort
from vehicle.app.assembly.drive import add_behavior, add_drive_mode, add_obstacle_stop, add_speed_limit
from vehicle.app.assembly.pilot import BEHAVIOR_KEY, check_behavior_input, pilot_inputs
from vehicle.app.assembly.sim import add_expert
from vehicle.app.failure_moments import ChangeLimits, GallerySpec, with_commands
from vehicle.app.failure_moments import attach as attach_recorder
from vehicle.clock import SimulatedClock
from vehicle.errors import UserError
from vehicle.keys import Mode, rename
from vehicle.part import part_name

logger = logging.getLogger(__name__)

#: simulated seconds allowed per lap when no max_time is given
SECONDS_PER_LAP_LIMIT = 60.0
#: what a pilot reads when it declares nothing
DEFAULT_PILOT_INPUTS = ("cam/image_array",)
#: simulators evaluate() drives
SIMULATORS = ("builtin", "donkey", "udacity")
#: seconds an evaluation waits for the Udacity simulator to send its first frame
UDACITY_WAIT_S = 120.0


class Engaged:
    """Part: the driver who engaged the pilot and keeps off the controls.

    ``user/mode`` is "local" (the pilot steers and drives) or, with a fixed throttle, "local_angle"
    (the pilot steers, the throttle stays where the driver holds it).
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/angle", "user/throttle")

    def __init__(self, fixed_throttle: float | None = None) -> None:
        self.mode = Mode.LOCAL if fixed_throttle is None else Mode.LOCAL_ANGLE
        self.throttle = 0.0 if fixed_throttle is None else float(fixed_throttle)

    def run(self) -> tuple[str, float, float]:
        return self.mode.value, 0.0, self.throttle


class Lent:
    """The pilot part, lent to one episode's vehicle: the vehicle runs it but does not shut it down
    (the evaluation does, once, after the last track); its declarations are the pilot's."""

    def __init__(self, pilot: Any) -> None:
        self.pilot = pilot
        self.name = part_name(pilot)
        self.run = pilot.run

    OUTPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle", "pilot/throttle")

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The pilot's inputs (``INPUTS``, else a loaded model's ``inputs``, else the frame)."""
        inputs = getattr(self.pilot, "INPUTS", None)
        if inputs is None:
            inputs = getattr(self.pilot, "inputs", None)
        return tuple(DEFAULT_PILOT_INPUTS if inputs is None else inputs)

    @property
    def OPTIONAL_INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration
        """The pilot's optional inputs."""
        return tuple(getattr(self.pilot, "OPTIONAL_INPUTS", ()))

    @property
    def FEEDBACK(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration
        """The pilot's feedback inputs."""
        return tuple(getattr(self.pilot, "FEEDBACK", ()))


def _default_config() -> Any:
    from vehicle.config import Config

    return Config.defaults()


def resolve_pilot(pilot: Any, cfg: Any = None, sim: str = "builtin") -> tuple[Any, str, bool]:
    """(pilot part or "expert", display name, whether we loaded it and must shut it down).

    A model file is loaded as ``manage.py drive --model`` loads it, with the car's back-end and
    speed-control settings (``cfg``; default: the package defaults), and refused unless it takes the
    frames of simulator ``sim``.
    """
    if isinstance(pilot, str) and pilot == "expert":
        return "expert", "expert", False
    if isinstance(pilot, str | Path):
        path = Path(pilot).expanduser()
        if not path.exists():
            raise FileNotFoundError(f"pilot model {path} does not exist: pass 'expert' or the path of a "
                                    "trained model file (see `manage.py train`)")
        from vehicle.app.assembly.pilot import make_pilot, sim_frames

        cfg = cfg if cfg is not None else _default_config()
        shape, hint = sim_frames(cfg, sim)
        return make_pilot(cfg, path, measured_speed_key="sim/speed", frame_shape=shape, frame_hint=hint), \
            path.name, True
    if callable(getattr(pilot, "run", None)):
        return pilot, getattr(pilot, "name", None) or type(pilot).__name__, False
    raise TypeError(f"pilot must be 'expert', a model path or an object with run(), got {type(pilot).__name__}")


def evaluate(pilot: Any, seeds: Sequence[int] | None = None, laps: int = 2, *, cfg: Any = None,
             max_time: float | None = None, penalty_s: float | None = None,
             fixed_throttle: float | None = None, extra_inputs: dict[str, Any] | None = None,
             on_step: Callable[[SimCar], None] | None = None, sim: str = "builtin",
             scenes: Sequence[str] | None = None, lane_changes: bool | None = None,
             workers: int = 1, gallery: GallerySpec | None = None) -> dict[str, Any]:
    """Drive ``pilot`` for ``laps`` laps on each track seed and return the report (a JSON-able dict).

    Args:
        pilot: "expert", a model file path (loaded with ``parts.pilots.load_pilot``), or a pilot
            part: an object with ``run(*inputs) -> (angle, throttle)`` and optionally ``INPUTS`` (or
            ``inputs``: memory keys, default ``["cam/image_array"]``).
        seeds: track seeds of the built-in simulator (use tracks the pilot was not trained on).
        laps: laps per track.
        cfg: a Config (default: package defaults); SIM_* settings shape tracks, camera and car;
            SIM_THEME deals themes to the seeds in turn, SIM_RANDOMIZE draws the conditions (use a
            theme or a randomisation seed the pilot was not trained on to measure transfer).
        max_time: simulated seconds per episode at most (default SIM_EVAL_MAX_TIME, else 60 s/lap).
        penalty_s: seconds charged per intervention (default SIM_INTERVENTION_PENALTY, DAVE-2: 6).
        fixed_throttle: drive at this throttle and use only the pilot's steering ("local_angle");
            otherwise the pilot drives ("local": its throttle scaled by AI_THROTTLE_MULT).
        extra_inputs: values for memory keys the pilot needs that the simulator does not make.
        on_step: called with the sim car after every step (e.g. to show or record frames).
        sim: "builtin", "donkey" (SIM_HOST:SIM_PORT) or "udacity" (UDACITY_PORT).
        scenes: Donkey scenes, one episode each (default DONKEY_GYM_ENV_NAME).
        lane_changes: command lane changes and score them (see the module docstring); None: when
            SIM_LANES = 2 and the pilot reads the behaviour (or is the expert with TRAIN_BEHAVIORS)
            and ``extra_inputs`` does not fix it.
        workers: built-in simulator: processes running tracks in parallel (0: one per core;
            capped at the number of tracks). Needs ``pilot`` to be "expert" or a model file (a
            worker loads its own copy) and no ``on_step``; otherwise the tracks run one after
            another. The report is the same either way.
        gallery: write a failure gallery (:mod:`vehicle.app.gallery`) of a model file's
            interventions and worst |CTE| moments into ``gallery.folder`` (which must not exist),
            built-in simulator only; the report's ``gallery`` names its page.

    Returns:
        ``{"pilot", "simulator", "laps", "seeds", "conditions", "settings", "tracks": [per-track
        metrics, with the theme, look and drawn conditions of each built-in track], "overall": {...}}``;
        each track's and the overall ``unavailable`` name the metrics the
        simulator cannot give.
        With lane changes each track and the overall dict also hold ``"lanes"``
        (:func:`parts.sim.lane_metrics.lane_metrics`).

    Raises:
        ValueError: bad arguments, or the pilot reads keys nothing produces (a WiringError; a
            three_camera model needs SIM_SIDE_CAMERAS_OFFSET in the built-in simulator).
        parts.bridges.errors.BridgeError: the Donkey or Udacity simulator cannot be reached.
    """
    cfg = cfg if cfg is not None else _default_config()
    if sim not in SIMULATORS:
        raise ValueError(f"unknown simulator {sim!r}: use one of {', '.join(SIMULATORS)}")
    episodes = _episodes(sim, seeds, scenes, cfg)
    if not isinstance(laps, int) or isinstance(laps, bool) or laps < 1:
        raise ValueError(f"laps must be an int >= 1, got {laps!r}")
    if max_time is None:
        max_time = cfg.SIM_EVAL_MAX_TIME or SECONDS_PER_LAP_LIMIT * laps
    if max_time <= 0:
        raise ValueError(f"max_time must be > 0 s, got {max_time}")
    penalty = cfg.SIM_INTERVENTION_PENALTY if penalty_s is None else penalty_s
    if fixed_throttle is not None and not -1.0 <= fixed_throttle <= 1.0:
        raise ValueError(f"fixed_throttle must be in [-1, 1], got {fixed_throttle}")

    themes = theme_list(cfg.SIM_THEME)
    check_ranges(cfg.SIM_RANDOMIZE_RANGES)
    if gallery is not None:
        gallery = _check_gallery(gallery, pilot, sim)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 0:
        raise ValueError(f"workers must be an int >= 0 (0 = one per core), got {workers!r}")
    n_workers = min(workers or os.cpu_count() or 1, len(episodes)) if sim == "builtin" else 1
    parallel = n_workers > 1 and on_step is None and (pilot == "expert" or isinstance(pilot, str | Path))
    if n_workers > 1 and not parallel:
        logger.info("evaluating the tracks one after another: parallel workers need 'expert' or a model "
                    "file (each loads its own copy) and no on_step callback")

    started = time.perf_counter()
    modes: dict[str, Any] = {}  # what the bridge episodes found out (Donkey: stepped or real time)
    outcomes, name, lanes_on = _drive_episodes(
        pilot, episodes, laps, cfg, sim, themes, parallel=parallel, n_workers=n_workers, on_step=on_step,
        lane_changes=lane_changes, modes=modes, episode_args={"max_time": max_time, "penalty_s": penalty,
                                                              "fixed_throttle": fixed_throttle,
                                                              "extra_inputs": extra_inputs, "gallery": gallery})
    results = [res for res, _ in outcomes]
    gallery_tracks = [res.pop("_gallery") for res in results if "_gallery" in res]
    pooled = [abs_cte for _, abs_cte in outcomes]  # |cte| of autonomous frames, for the overall percentile
    settings = _report_settings(cfg, sim, penalty, max_time, fixed_throttle, modes)
    report = {
        "pilot": name,
        "simulator": sim,
        "laps": laps,
        "seeds": episodes,
        "conditions": describe_conditions(cfg, themes) if sim == "builtin" else None,
        "settings": settings,
        "tracks": results,
        "overall": {**overall(results, penalty, np.concatenate(pooled)), **_path_overall(results),
                    **({"lanes": overall_lane_metrics([r["lanes"] for r in results])} if lanes_on else {})},
        "wall_time_s": round(time.perf_counter() - started, 3),
    }
    if gallery is not None:
        from vehicle.app.gallery import write_gallery

        report["gallery"] = str(write_gallery(gallery, report, gallery_tracks))
        settings["gallery"] = str(Path(gallery.folder).resolve())
        report["wall_time_s"] = round(time.perf_counter() - started, 3)
    return report


def _episodes(sim: str, seeds: Any, scenes: Sequence[str] | None, cfg: Any) -> list[Any]:
    """What an evaluation drives: the built-in simulator's track seeds (checked), the Donkey
    scenes, or the one track the Udacity simulator shows."""
    if sim == "builtin":
        seeds = [seeds] if isinstance(seeds, int) else list(seeds or [])
        if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
            raise ValueError(f"seeds must be a non-empty list of ints, got {seeds!r}")
        episodes: list[Any] = list(seeds)
    elif sim == "donkey":
        episodes = list(scenes or [cfg.DONKEY_GYM_ENV_NAME])
    else:
        episodes = ["udacity"]  # the track the simulator shows
    return episodes


def _drive_episodes(pilot: Any, episodes: list[Any], laps: int, cfg: Any, sim: str, themes: list[str], *,
                    parallel: bool, n_workers: int, on_step: Callable[[SimCar], None] | None,
                    lane_changes: bool | None, modes: dict[str, Any],
                    episode_args: dict[str, Any]) -> tuple[list[Any], str, bool]:
    """Drive every episode (in worker processes when ``parallel``): (the outcomes, the pilot's
    name, whether lane changes were commanded)."""
    extra_inputs = episode_args["extra_inputs"]
    max_time, penalty, fixed_throttle = episode_args["max_time"], episode_args["penalty_s"], \
        episode_args["fixed_throttle"]
    # loaded here also for a parallel run: a missing or broken model file fails with its own message,
    # and the pilot's inputs decide the lane changes
    driver, name, owned = resolve_pilot(pilot, cfg, sim)
    try:
        if driver == "expert" and sim != "builtin":
            raise ValueError(f"the expert drives the built-in simulator only: pass a model file to evaluate on "
                             f"the {sim} simulator")
        if driver != "expert":
            _check_views(driver, name, cfg, sim, extra_inputs)
        lanes_on = sim == "builtin" and _lane_changes(driver, cfg, extra_inputs, lane_changes)
        if driver != "expert" and not lanes_on and BEHAVIOR_KEY not in (extra_inputs or {}):
            try:  # as manage.py drive: the user's setting, not the wiring
                check_behavior_input(driver, cfg)
            except UserError as exc:
                raise ValueError(str(exc)) from None
        if lanes_on:
            _check_change_schedule(cfg)
        episode_args = {**episode_args, "lanes": lanes_on}
        if parallel:
            if owned and callable(getattr(driver, "shutdown", None)):
                owned = False
                driver.shutdown()
            outcomes = _run_parallel(pilot, episodes, laps, cfg, n_workers, episode_args, name,
                                     [theme_of(themes, i) for i in range(len(episodes))])
        else:
            outcomes = []
            for i, episode in enumerate(episodes):
                if sim == "builtin":
                    if driver != "expert" and i + 1 < len(episodes):
                        # the next track is drawn in the background while this one is driven
                        prefetch_world(episodes[i + 1], theme=theme_of(themes, i + 1), **world_params(cfg))
                    outcomes.append(_builtin_episode(driver, episode, laps, cfg, episode_args, on_step,
                                                     theme=theme_of(themes, i)))
                else:
                    metrics = run_bridge_episode(driver, sim, episode, laps, cfg, max_time=max_time,
                                                 penalty_s=penalty, fixed_throttle=fixed_throttle,
                                                 extra_inputs=extra_inputs, info=modes)
                    outcomes.append((metrics.result(), metrics.autonomous_abs_cte()))
                _log_episode(name, episode, laps, outcomes[-1][0])
    finally:
        if owned and callable(getattr(driver, "shutdown", None)):
            driver.shutdown()
    return outcomes, name, lanes_on


def _report_settings(cfg: Any, sim: str, penalty: float, max_time: float, fixed_throttle: float | None,
                     modes: dict[str, Any]) -> dict[str, Any]:
    """The settings an evaluation ran with, as its report records them."""
    settings: dict[str, Any] = {"dt": 1.0 / cfg.DRIVE_LOOP_HZ, "penalty_s": penalty, "max_time_s": max_time,
                                "fixed_throttle": fixed_throttle}
    if sim == "builtin":
        settings.update({"road_width_m": cfg.SIM_ROAD_WIDTH, "lanes": cfg.SIM_LANES,
                         "image": [cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H], "off_track_cte_m": cfg.SIM_OFF_TRACK_CTE,
                         "track_size_m": cfg.SIM_TRACK_SIZE})
    elif sim == "donkey":
        settings.update({"host": cfg.SIM_HOST, "port": cfg.SIM_PORT, "synchronous": modes.get("synchronous", False),
                         "max_cte": cfg.DONKEY_MAX_CTE, "image": [cfg.IMAGE_W, cfg.IMAGE_H]})
    else:
        settings.update({"port": cfg.UDACITY_PORT, "realtime": True, "interventions": "manual overrides"})
    return settings


def _check_gallery(spec: GallerySpec, pilot: Any, sim: str) -> GallerySpec:
    """The gallery asked for, checked (ValueError, one line), with the model file's full path."""
    from dataclasses import replace

    from vehicle.app.gallery import check_new_folder

    if sim != "builtin":
        raise ValueError(f"a gallery shows the built-in simulator's frames: drop it with the {sim} simulator")
    if not isinstance(pilot, str | Path) or pilot == "expert":
        raise ValueError("a gallery shows where a model looks: evaluate a model file, not the expert or a part")
    spec.check()
    folder = check_new_folder(spec.folder)
    return replace(spec, folder=str(folder), model=str(Path(pilot).expanduser().resolve()))


def _path_overall(results: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """A path follower's distance to its recorded path over all tracks (mean weighted by frames);
    nothing for a pilot."""
    rows = [r for r in results if r.get("mean_path_distance") is not None]
    if not rows:
        return {}
    frames = sum(r["autonomous_frames"] for r in rows) or len(rows)
    mean = sum(r["mean_path_distance"] * (r["autonomous_frames"] or 1) for r in rows) / frames
    return {"mean_path_distance": round(mean, 4), "max_path_distance": max(r["max_path_distance"] for r in rows),
            "localizer": rows[0].get("localizer")}


def describe_conditions(cfg: Any, themes: Sequence[str] | None = None) -> dict[str, Any]:
    """The conditions of a built-in simulator evaluation, as the report names them."""
    return {"themes": list(themes if themes is not None else theme_list(cfg.SIM_THEME)),
            "randomize": cfg.SIM_RANDOMIZE, "ranges": {k: list(v) for k, v in cfg.SIM_RANDOMIZE_RANGES.items()},
            "distractors": cfg.SIM_DISTRACTORS if cfg.SIM_RANDOMIZE is None else "randomised",
            "lanes": cfg.SIM_LANES}


def _log_episode(name: str, episode: Any, laps: int, res: dict[str, Any]) -> None:
    logger.info("eval %s on %s: autonomy %.1f %%, %s/%d laps, mean |cte| %s, %d interventions",
                name, episode, res["autonomy"], res["laps_completed"], laps,
                "-" if res["mean_abs_cte"] is None else f"{res['mean_abs_cte']:.3f}", res["interventions"])


def _builtin_episode(driver: Any, seed: int, laps: int, cfg: Any, episode_args: dict[str, Any],
                     on_step: Callable[[SimCar], None] | None = None,
                     theme: str | None = None) -> tuple[dict[str, Any], np.ndarray]:
    """One built-in episode's (metrics, |cte| of its autonomous frames) on track ``seed`` in
    ``theme``, lane metrics included when ``episode_args["lanes"]``."""
    args = dict(episode_args)
    lane_part = None
    changes = None
    if args.pop("lanes"):
        lane_part = LaneMetrics.from_config(cfg)
        changes = ChangeLimits(lane_part.lane_width, lane_part.time_limit, lane_part.hold)
    gallery: GallerySpec | None = args.pop("gallery", None)
    recorders: list[Any] = []
    after = None
    if gallery is not None and driver != "expert":
        def after(V: Vehicle, sim: SimCar) -> None:
            recorders.append(attach_recorder(V, sim, cfg, Lent(driver).INPUTS, gallery, changes))
    metrics = run_episode(driver, seed, laps, cfg, **args, on_step=on_step, lanes=lane_part, theme=theme,
                          after=after)
    res = metrics.result()
    if lane_part is not None:
        res["lanes"] = lane_part.result()
    if hasattr(driver, "episode_result"):
        res = driver.episode_result(res)
    if recorders:
        from vehicle.app.gallery import render_track

        moments = recorders[0].moments()
        if lane_part is not None:  # a failed change's moment carries the command's record
            with_commands(moments, res["lanes"]["commands"], lane_part.dt)
        res["_gallery"] = render_track(moments, gallery,  # type: ignore[arg-type]
                                       {**res, "randomize": cfg.SIM_RANDOMIZE})
    return res, metrics.autonomous_abs_cte()


# -- parallel evaluation -----------------------------------------------------------------------------
# State of a worker process, set once by _init_worker: the pilot, the settings, what each episode gets.
_WORKER: dict[str, Any] = {}


def _sendable_config(cfg: Any) -> tuple[dict[str, Any], frozenset[str], Any]:
    """The Config's values for a worker process; a value that cannot be pickled (a function defined
    in myconfig.py, e.g. TRAIN_FILTER) takes its default, which evaluation never reads anyway."""
    from vehicle.config import Config

    values = dict(cfg.items())
    defaults: Config | None = None
    for key, value in values.items():
        try:
            pickle.dumps(value)
        except Exception:  # noqa: BLE001 - any reason a value cannot travel
            defaults = defaults or Config.defaults()
            values[key] = defaults[key]
    return values, frozenset(getattr(cfg, "overridden", ())), getattr(cfg, "source", None)


def _init_worker(pilot: Any, config: tuple[dict[str, Any], frozenset[str], Any], tracks: dict[int, Any],
                 threads: int, laps: int, episode_args: dict[str, Any]) -> None:
    """Runs once in each worker: thread limits, the parent's hand-made tracks, settings, pilot."""
    import signal
    import sys

    import cv2

    from parts.sim.simulator import register_track
    from vehicle.config import Config

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C reaches us too: the parent stops us
    cv2.setNumThreads(threads)
    for track in tracks.values():
        register_track(track)
    cfg = Config(*config)
    driver, _, _ = resolve_pilot(pilot, cfg)
    if "torch" in sys.modules:  # a model pilot loaded it; the expert needs none (0.75 s to import)
        sys.modules["torch"].set_num_threads(threads)
    _WORKER.update(cfg=cfg, driver=driver, laps=laps, episode_args=episode_args)


def _worker_episode(seed: int, theme: str) -> tuple[dict[str, Any], np.ndarray]:
    w = _WORKER
    return _builtin_episode(w["driver"], seed, w["laps"], w["cfg"], w["episode_args"], theme=theme)


def _run_parallel(pilot: Any, seeds: list[int], laps: int, cfg: Any, n_workers: int,
                  episode_args: dict[str, Any], name: str,
                  themes: list[str]) -> list[tuple[dict[str, Any], np.ndarray]]:
    """The episodes of ``seeds`` (each in its theme of ``themes``) in ``n_workers`` processes, in
    seed order."""
    from parts.sim.simulator import registered_tracks
    from vehicle.app.worker_pool import WorkerPool
    from vehicle.vehicle import stop_signals_raise

    threads = max(1, (os.cpu_count() or 1) // n_workers)
    logger.info("evaluating %d tracks in %d worker processes (%d thread(s) each)", len(seeds), n_workers, threads)
    pilot_arg = pilot if pilot == "expert" else str(Path(pilot).expanduser().resolve())
    initargs = (pilot_arg, _sendable_config(cfg), registered_tracks(), threads, laps, episode_args)
    outcomes = []
    # spawn, not fork: a forked copy of a process whose OpenMP threads already ran can hang; a
    # Ctrl-C, SIGTERM or a failed episode kills the workers (simulated cars: nothing to bring to
    # neutral), and so does our death (they watch for it)
    with stop_signals_raise(), WorkerPool(_worker_episode, n_workers, _init_worker, initargs, context="spawn") as pool:
        with _ctrl_c_deferred():  # the workers are born deaf to a terminal's Ctrl-C
            pool.start()
        for seed, (res, abs_cte) in zip(seeds, pool.map(list(zip(seeds, themes, strict=True))), strict=True):
            _log_episode(name, seed, laps, res)
            outcomes.append((res, abs_cte))
    return outcomes


@contextlib.contextmanager
def _ctrl_c_deferred() -> Iterator[None]:
    """Block SIGINT while worker processes start: they inherit the mask, so a terminal's Ctrl-C in
    their first seconds (before ``_init_worker`` ignores it) cannot print a traceback per worker;
    here a Ctrl-C meanwhile stays pending and arrives when the block ends (ignoring it instead
    would lose it, and the evaluation would run on)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # multiprocessing starts its resource tracker before a process's first spawned child and then
    # unblocks SIGINT and SIGTERM (CPython 3.8+): started here first, it cannot undo the block
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def add_engaged_pilot(V: Vehicle, driver: Any, fixed_throttle: float | None) -> None:
    """The driver engages the pilot (``user/mode`` local, or local_angle with a fixed throttle) and
    the pilot part runs; a pilot with ``reset()`` (sequence models) starts with no memory of the
    previous episode."""
    if callable(getattr(driver, "reset", None)):
        driver.reset()
    V.add(Engaged(fixed_throttle))
    V.add(PilotCondition())
    V.add(Lent(driver), run_condition="run_pilot")


def _check_views(driver: Any, name: str, cfg: Any, sim: str, extra_inputs: dict[str, Any] | None) -> None:
    """WiringError (one line) when the pilot takes camera frames the simulator does not make: the
    three_camera model's side frames come from the built-in simulator with SIM_SIDE_CAMERAS_OFFSET."""
    from parts.sim.simulator import SIDE_OUTPUTS
    from vehicle.app.assembly.pilot import check_views

    inputs = tuple(getattr(driver, "INPUTS", None) or getattr(driver, "inputs", None) or DEFAULT_PILOT_INPUTS)
    made = {"cam/image_array", *(extra_inputs or {})}
    if sim == "builtin" and cfg.SIM_SIDE_CAMERAS_OFFSET is not None:
        made.update(SIDE_OUTPUTS)
    views = [key for key in inputs if key.startswith("cam/image_array")]
    check_views(name, views, made.__contains__, sim)


def _lane_changes(driver: Any, cfg: Any, extra_inputs: dict[str, Any] | None, asked: bool | None) -> bool:
    """Whether the episodes command lane changes (see :func:`evaluate`)."""
    if asked is False:
        return False
    reads = "behavior/one_hot_state_array" in tuple(getattr(driver, "INPUTS", None) or getattr(driver, "inputs", None)
                                                    or ())
    if asked is None:
        fixed = bool(extra_inputs) and "behavior/one_hot_state_array" in extra_inputs
        return cfg.SIM_LANES == 2 and not fixed and (reads or (driver == "expert" and cfg.TRAIN_BEHAVIORS))
    if cfg.SIM_LANES != 2:
        raise ValueError(f"lane changes need two-lane tracks: SIM_LANES = 2 (it is {cfg.SIM_LANES})")
    if driver != "expert" and not reads:
        raise ValueError("lane changes are commanded through behavior/one_hot_state_array, which this pilot does "
                         "not read: evaluate a behaviour model (types behavior, lanes)")
    return True


def _check_change_schedule(cfg: Any) -> None:
    """Raise ValueError when commanded lane changes may come closer together than one change is
    given to succeed (time limit, then hold): one would be judged while the next is under way."""
    every = tuple(cfg.SIM_EVAL_LANE_CHANGE_EVERY)
    needed = cfg.SIM_EVAL_LANE_CHANGE_TIME_LIMIT + cfg.SIM_EVAL_LANE_CHANGE_HOLD
    if len(every) != 2 or not 0 < every[0] <= every[1]:
        raise ValueError(f"SIM_EVAL_LANE_CHANGE_EVERY = {every!r}: give (min, max) seconds with 0 < min <= max")
    if every[0] < needed:
        raise ValueError(f"SIM_EVAL_LANE_CHANGE_EVERY = {every!r} may command a change {every[0]:g} s after the last, "
                         f"before that one is judged (SIM_EVAL_LANE_CHANGE_TIME_LIMIT + SIM_EVAL_LANE_CHANGE_HOLD = "
                         f"{needed:g} s): raise its minimum to at least {needed:g}")


def run_episode(driver: Any, seed: int, laps: int, cfg: Any, *, max_time: float, penalty_s: float,
                fixed_throttle: float | None = None, extra_inputs: dict[str, Any] | None = None,
                on_step: Callable[[SimCar], None] | None = None, lanes: LaneMetrics | None = None,
                theme: str | None = None,
                after: Callable[[Vehicle, SimCar], None] | None = None) -> EpisodeMetrics:
    """One episode on track ``seed`` (in ``theme``, default the first of SIM_THEME): build the loop,
    run it to the end, return its metrics part (its result names the track's theme and conditions).

    ``driver`` is "expert" or a pilot part; a pilot with a ``reset()`` (sequence models) starts the
    episode with no memory of the previous track, so every track is scored on its own. With
    ``lanes`` (a :class:`LaneMetrics`, filled by the episode) the behaviour is stepped at seeded
    times (SIM_EVAL_LANE_CHANGE_EVERY) and the car starts in the initial behaviour's lane. ``after``
    adds parts at the end of the loop (a failure gallery's recorder).
    """
    # image effects stay as configured: a pilot is judged on the images it will get; the expert
    # drives from the map, so its episodes draw no images
    # a driver with its own sensors (a path follower) drives with the settings that switch them on
    episode_cfg = driver.episode_config(cfg) if hasattr(driver, "episode_config") else cfg
    sim = SimCar.from_config(cfg, seeds=[seed], themes=[theme or theme_list(cfg.SIM_THEME)[0]],
                             reset_off_track=True, reset_to="nearest", realtime=False,
                             render=driver != "expert" and getattr(driver, "needs_camera", True),
                             measured_speed=not episode_cfg.HAVE_ODOM)
    V = Vehicle(clock=SimulatedClock())
    V.mem.update(extra_inputs or {})  # seeded: keys the simulator does not make
    V.add(sim)
    # as add_simulator: the pilot sees what the car drives with
    add_undistort(V, cfg, (cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H), "SIM_CAMERA_W x SIM_CAMERA_H")
    if hasattr(driver, "prepare_episode"):  # its sensors and localiser, after the simulated car
        driver.prepare_episode(V, cfg, sim)
    if lanes is not None:
        cfg = cfg.replace(TRAIN_BEHAVIORS=True)
        times = periodic_change_times(max_time, tuple(cfg.SIM_EVAL_LANE_CHANGE_EVERY),
                                      seed=(cfg.SIM_SEED * 1_000_003 + seed))
        V.add(BehaviorSchedule(times, sim.dt))
        behavior = add_behavior(V, cfg)
        lane = behavior_lane(behavior.behaviors[behavior.state])
        if lane is not None:  # start in the initial behaviour's lane
            sim.start_offset = sim.track.lane_offset(lane)
            sim.select_track(seed)
        V.add(CommandedLane(sim))
        lanes.on_track(sim.track)  # where each command is given: the curvature ahead
    elif driver != "expert" and BEHAVIOR_KEY in pilot_inputs(driver) and BEHAVIOR_KEY not in V.mem:
        add_behavior(V, cfg)  # TRAIN_BEHAVIORS (checked before): BEHAVIOR_INITIAL all along, as a drive
    if driver == "expert":
        # user mode: the expert is the "human"; it follows behaviours only when they are commanded
        add_expert(V, cfg if lanes is not None else cfg.replace(TRAIN_BEHAVIORS=False), sim)
        if fixed_throttle is not None:
            V.add(lambda: fixed_throttle, outputs=["user/throttle"])
    else:
        add_engaged_pilot(V, driver, fixed_throttle)
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    details: dict[str, Any] = {"theme": sim.conditions.theme, "conditions": sim.conditions.summary()}
    if sim.world is not None:
        details["look"] = sim.world.look.summary()
        details["distractors"] = [d.kind for d in sim.world.scenery.distractors]
    metrics = EpisodeMetrics(sim.dt, laps, max_time, penalty_s, stop=V.stop, seed=seed,
                             track_length=sim.track.length,
                             on_step=(lambda: on_step(sim)) if on_step is not None else None, details=details)
    V.add(metrics)
    if lanes is not None:
        V.add(lanes)
    if hasattr(driver, "add_metrics"):  # a path follower: the distance to its recorded path
        driver.add_metrics(V)
    if after is not None:
        after(V, sim)
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, log_summary=False)
    return metrics


def run_bridge_episode(driver: Any, sim_type: str, scene: str, laps: int, cfg: Any, *, max_time: float,
                       penalty_s: float, fixed_throttle: float | None = None,
                       extra_inputs: dict[str, Any] | None = None,
                       info: dict[str, Any] | None = None) -> EpisodeMetrics:
    """One episode on the Donkey simulator (scene ``scene``) or the Udacity simulator (real time):
    the same loop as :func:`run_episode` around the bridge part.

    Donkey: in synchronous steps of 1 / DRIVE_LOOP_HZ where the server steps (``vehicle sim
    serve``), else in real time with the threaded part; ``info["synchronous"]`` says which.
    """
    from vehicle.app.assembly.sim import add_simulator, add_simulator_commands, bridge_frame_size, make_bridge

    dt = 1.0 / cfg.DRIVE_LOOP_HZ
    stepped = False
    if sim_type == "donkey":
        bridge = make_bridge(cfg.replace(DONKEY_GYM_ENV_NAME=scene), "donkey", synchronous=True, time_step=dt)
        bridge.start()  # connect now: an unreachable simulator is an error, not a failed loop
        stepped = bridge.synchronous
        if info is not None:
            info["synchronous"] = stepped
        if stepped:
            V = Vehicle(clock=SimulatedClock())  # each loop is one synchronous simulator step
            V.add(bridge, feedback=("angle", "throttle", "sim/reset"))  # run(): send, then wait for the step
        else:
            V = Vehicle()  # the Donkey simulator runs in real time: the loop paces itself
            V.add(bridge, threaded=True, feedback=("angle", "throttle", "sim/reset"))
        add_undistort(V, cfg, *bridge_frame_size(cfg, "donkey"))  # as add_simulator
    else:
        V = Vehicle()  # the Udacity simulator runs in real time
        add_simulator(V, cfg, sim_type="udacity")
    V.mem.update(extra_inputs or {})
    if BEHAVIOR_KEY in pilot_inputs(driver) and BEHAVIOR_KEY not in V.mem:
        add_behavior(V, cfg)  # TRAIN_BEHAVIORS (checked before): BEHAVIOR_INITIAL all along, as a drive
    add_engaged_pilot(V, driver, fixed_throttle)
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    metrics = EpisodeMetrics(dt, laps, max_time, penalty_s, stop=V.stop, seed=scene)  # type: ignore[arg-type]
    waiter = None
    if sim_type == "donkey":
        # in real time, score only loops with a live frame (the part says so with cam/ok)
        V.add(metrics, run_condition=None if stepped else "cam/ok")
        V.add(ResetOnOffTrack())
        if not stepped:
            add_simulator_commands(V)
    else:
        # score only frames that arrived; the user's manual overrides are the interventions
        V.add(metrics, inputs=list(rename(EpisodeMetrics.INPUTS, {"sim/off_track": "sim/manual"})),
              run_condition="cam/ok")
        waiter = StopIfNoSimulator(UDACITY_WAIT_S, V.stop)
        V.add(waiter)
        add_simulator_commands(V)
        logger.info("evaluation: start the Udacity simulator in Autonomous Mode on the track to drive")
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, log_summary=False)
    if waiter is not None and waiter.gave_up:
        raise ValueError(f"no frame from the Udacity simulator within {UDACITY_WAIT_S:.0f} s: start it, choose "
                         f"Autonomous Mode, and check it connects to port {cfg.UDACITY_PORT}")
    return metrics
