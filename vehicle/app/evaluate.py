"""Closed-loop evaluation of a pilot on simulated tracks, on the car's own loop in simulated time.

One episode per track seed, each a real :class:`vehicle.Vehicle` on a
:class:`vehicle.clock.SimulatedClock` with the parts ``manage.py drive --model`` uses::

    SimCar ─► driver engaged (user/mode "local") ─► PilotCondition ─► pilot ─► DriveMode ─► EpisodeMetrics
     ▲                                                                          │
     └──────────────────────── angle, throttle (next loop) ◄────────────────────┘

so what is evaluated is what drives: the pilot's outputs go through the same DriveMode (a NaN or
None command becomes centre and zero throttle, AI_THROTTLE_MULT scales the throttle) before the
simulated car applies them. Leaving the road counts as an intervention: the car is re-centred on the
road next to where it left (what a person would do) and the episode goes on. Metrics:
:mod:`parts.sim.metrics` (DAVE-2 autonomy, time-weighted |CTE| over autonomous frames, ...).

With ``workers > 1`` the tracks run in parallel worker processes, each with its own simulator and
its own copy of the pilot (loaded from the model file, or the expert), torch and OpenCV limited to
``cores // workers`` threads so the workers do not oversubscribe the machine. Every episode depends
only on its seed, so the report is the serial one (a test checks they are identical).
"""

from __future__ import annotations

import logging
import os
import pickle
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from parts.drive.modes import PilotCondition
from parts.sim.expert import Expert
from parts.sim.metrics import EpisodeMetrics, overall
from parts.sim.simulator import SimCar
from vehicle import Vehicle
from vehicle.app.assembly.drive import add_drive_mode
from vehicle.clock import SimulatedClock
from vehicle.keys import Mode
from vehicle.part import part_name

logger = logging.getLogger(__name__)

#: simulated seconds allowed per lap when no max_time is given
SECONDS_PER_LAP_LIMIT = 60.0
#: what a pilot reads when it declares nothing
DEFAULT_PILOT_INPUTS = ("cam/image_array",)


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
        self.INPUTS = tuple(getattr(pilot, "INPUTS", None) or getattr(pilot, "inputs", None)  # noqa: N815
                            or DEFAULT_PILOT_INPUTS)
        self.OPTIONAL_INPUTS = tuple(getattr(pilot, "OPTIONAL_INPUTS", ()))  # noqa: N815
        self.OUTPUTS = ("pilot/angle", "pilot/throttle")  # noqa: N815


def _default_config() -> Any:
    from vehicle.config import Config

    return Config.defaults()


def resolve_pilot(pilot: Any) -> tuple[Any, str, bool]:
    """(pilot part or "expert", display name, whether we loaded it and must shut it down)."""
    if isinstance(pilot, str) and pilot == "expert":
        return "expert", "expert", False
    if isinstance(pilot, str | Path):
        path = Path(pilot).expanduser()
        if not path.exists():
            raise FileNotFoundError(f"pilot model {path} does not exist: pass 'expert' or the path of a "
                                    "trained model file (see `manage.py train`)")
        from parts.pilots import load_pilot

        return load_pilot(path), path.name, True
    if callable(getattr(pilot, "run", None)):
        return pilot, getattr(pilot, "name", None) or type(pilot).__name__, False
    raise TypeError(f"pilot must be 'expert', a model path or an object with run(), got {type(pilot).__name__}")


def evaluate(pilot: Any, seeds: Sequence[int], laps: int = 2, *, cfg: Any = None,
             max_time: float | None = None, penalty_s: float | None = None,
             fixed_throttle: float | None = None, extra_inputs: dict[str, Any] | None = None,
             on_step: Callable[[SimCar], None] | None = None, workers: int = 1) -> dict[str, Any]:
    """Drive ``pilot`` for ``laps`` laps on each track seed and return the report (a JSON-able dict).

    Args:
        pilot: "expert", a model file path (loaded with ``parts.pilots.load_pilot``), or a pilot
            part: an object with ``run(*inputs) -> (angle, throttle)`` and optionally ``INPUTS`` (or
            ``inputs``: memory keys, default ``["cam/image_array"]``).
        seeds: track seeds (use tracks the pilot was not trained on).
        laps: laps per track.
        cfg: a Config (default: package defaults); SIM_* settings shape tracks, camera and car.
        max_time: simulated seconds per episode at most (default SIM_EVAL_MAX_TIME, else 60 s/lap).
        penalty_s: seconds charged per intervention (default SIM_INTERVENTION_PENALTY, DAVE-2: 6).
        fixed_throttle: drive at this throttle and use only the pilot's steering ("local_angle");
            otherwise the pilot drives ("local": its throttle scaled by AI_THROTTLE_MULT).
        extra_inputs: values for memory keys the pilot needs that the simulator does not make.
        on_step: called with the sim car after every step (e.g. to show or record frames).
        workers: processes running tracks in parallel (0: one per core; capped at the number of
            tracks). Needs ``pilot`` to be "expert" or a model file (a worker loads its own copy)
            and no ``on_step``; otherwise the tracks run one after another.

    Returns:
        ``{"pilot", "laps", "seeds", "settings", "tracks": [per-track metrics], "overall": {...}}``.

    Raises:
        ValueError: bad arguments, or the pilot reads keys nothing produces (a WiringError).
    """
    cfg = cfg if cfg is not None else _default_config()
    seeds = [seeds] if isinstance(seeds, int) else list(seeds)
    if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
        raise ValueError(f"seeds must be a non-empty list of ints, got {seeds!r}")
    if not isinstance(laps, int) or isinstance(laps, bool) or laps < 1:
        raise ValueError(f"laps must be an int >= 1, got {laps!r}")
    if max_time is None:
        max_time = cfg.SIM_EVAL_MAX_TIME or SECONDS_PER_LAP_LIMIT * laps
    if max_time <= 0:
        raise ValueError(f"max_time must be > 0 s, got {max_time}")
    penalty = cfg.SIM_INTERVENTION_PENALTY if penalty_s is None else penalty_s
    if fixed_throttle is not None and not -1.0 <= fixed_throttle <= 1.0:
        raise ValueError(f"fixed_throttle must be in [-1, 1], got {fixed_throttle}")

    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 0:
        raise ValueError(f"workers must be an int >= 0 (0 = one per core), got {workers!r}")
    n_workers = min(workers or os.cpu_count() or 1, len(seeds))
    episode = {"max_time": max_time, "penalty_s": penalty, "fixed_throttle": fixed_throttle,
               "extra_inputs": extra_inputs}
    started = time.perf_counter()
    if n_workers > 1 and on_step is None and (pilot == "expert" or isinstance(pilot, str | Path)):
        # loaded here once too, so a missing or broken model file fails with its own message
        driver, name, owned = resolve_pilot(pilot)
        if owned and callable(getattr(driver, "shutdown", None)):
            driver.shutdown()
        episodes = _run_parallel(pilot, seeds, laps, cfg, n_workers, episode)
    else:
        if n_workers > 1:
            logger.info("evaluating the tracks one after another: parallel workers need 'expert' or a model "
                        "file (each loads its own copy) and no on_step callback")
        driver, name, owned = resolve_pilot(pilot)
        try:
            episodes = []
            for seed in seeds:
                metrics = run_episode(driver, seed, laps, cfg, **episode, on_step=on_step)
                episodes.append((metrics.result(), metrics.autonomous_abs_cte()))
                _log_track(name, laps, episodes[-1][0])
        finally:
            if owned and callable(getattr(driver, "shutdown", None)):
                driver.shutdown()
    results = [res for res, _ in episodes]
    pooled = [abs_cte for _, abs_cte in episodes]  # |cte| of autonomous frames, for the overall percentile
    return {
        "pilot": name,
        "laps": laps,
        "seeds": seeds,
        "settings": {"dt": 1.0 / cfg.DRIVE_LOOP_HZ, "penalty_s": penalty, "max_time_s": max_time,
                     "fixed_throttle": fixed_throttle, "road_width_m": cfg.SIM_ROAD_WIDTH,
                     "lanes": cfg.SIM_LANES, "image": [cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H],
                     "off_track_cte_m": cfg.SIM_OFF_TRACK_CTE, "track_size_m": cfg.SIM_TRACK_SIZE},
        "tracks": results,
        "overall": overall(results, penalty, np.concatenate(pooled)),
        "wall_time_s": round(time.perf_counter() - started, 3),
    }


def _log_track(name: str, laps: int, res: dict[str, Any]) -> None:
    logger.info("eval %s on track %d: autonomy %.1f %%, %d/%d laps, mean |cte| %.3f m, %d off-track",
                name, res["seed"], res["autonomy"], res["laps_completed"], laps, res["mean_abs_cte"] or 0.0,
                res["interventions"])


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
                 threads: int, laps: int, episode: dict[str, Any]) -> None:
    """Runs once in each worker: thread limits, the parent's hand-made tracks, settings, pilot."""
    import sys

    import cv2

    from parts.sim.simulator import register_track
    from vehicle.config import Config

    cv2.setNumThreads(threads)
    for track in tracks.values():
        register_track(track)
    driver, name, _ = resolve_pilot(pilot)
    if "torch" in sys.modules:  # a model pilot loaded it; the expert needs none (0.75 s to import)
        sys.modules["torch"].set_num_threads(threads)
    _WORKER.update(cfg=Config(*config), driver=driver, name=name, laps=laps, episode=episode)


def _worker_episode(seed: int) -> tuple[dict[str, Any], np.ndarray]:
    w = _WORKER
    metrics = run_episode(w["driver"], seed, w["laps"], w["cfg"], **w["episode"])
    return metrics.result(), metrics.autonomous_abs_cte()


def _run_parallel(pilot: Any, seeds: list[int], laps: int, cfg: Any, n_workers: int,
                  episode: dict[str, Any]) -> list[tuple[dict[str, Any], np.ndarray]]:
    """The episodes of ``seeds`` in ``n_workers`` processes, in seed order."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from parts.sim.simulator import registered_tracks

    threads = max(1, (os.cpu_count() or 1) // n_workers)
    name = "expert" if pilot == "expert" else Path(pilot).name
    logger.info("evaluating %d tracks in %d worker processes (%d thread(s) each)", len(seeds), n_workers, threads)
    # spawn, not fork: a forked copy of a process whose OpenMP threads already ran can hang
    context = multiprocessing.get_context("spawn")
    pilot_arg = pilot if pilot == "expert" else str(Path(pilot).expanduser().resolve())
    initargs = (pilot_arg, _sendable_config(cfg), registered_tracks(), threads, laps, episode)
    episodes = []
    with ProcessPoolExecutor(n_workers, mp_context=context, initializer=_init_worker, initargs=initargs) as pool:
        for res, abs_cte in pool.map(_worker_episode, seeds):
            _log_track(name, laps, res)
            episodes.append((res, abs_cte))
    return episodes


def run_episode(driver: Any, seed: int, laps: int, cfg: Any, *, max_time: float, penalty_s: float,
                fixed_throttle: float | None = None, extra_inputs: dict[str, Any] | None = None,
                on_step: Callable[[SimCar], None] | None = None) -> EpisodeMetrics:
    """One episode on track ``seed``: build the loop, run it to the end, return its metrics part.

    ``driver`` is "expert" or a pilot part; a pilot with a ``reset()`` (sequence models) starts the
    episode with no memory of the previous track, so every track is scored on its own.
    """
    # image jitter stays as configured: a pilot is judged on the images it will get
    sim = SimCar.from_config(cfg, seeds=[seed], reset_off_track=True, reset_to="nearest", realtime=False)
    V = Vehicle(clock=SimulatedClock())
    V.mem.update(extra_inputs or {})  # seeded: keys the simulator does not make
    V.add(sim)
    if driver == "expert":
        V.add(Expert.from_config(cfg, sim))  # user mode: the expert is the "human"
        if fixed_throttle is not None:
            V.add(lambda: fixed_throttle, outputs=["user/throttle"])
    else:
        if callable(getattr(driver, "reset", None)):
            driver.reset()
        V.add(Engaged(fixed_throttle))
        V.add(PilotCondition())
        V.add(Lent(driver), run_condition="run_pilot")
    add_drive_mode(V, cfg)
    metrics = EpisodeMetrics(sim.dt, laps, max_time, penalty_s, stop=V.stop, seed=seed,
                             track_length=sim.track.length,
                             on_step=(lambda: on_step(sim)) if on_step is not None else None)
    V.add(metrics)
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, log_summary=False)
    return metrics
