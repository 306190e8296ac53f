"""Closed-loop evaluation of a pilot on simulated tracks, in simulated time.

One episode per track seed: the pilot gets each camera frame (and whatever other memory keys it
lists in ``pilot.inputs``), its (angle, throttle) drives the simulated car for one step of
``1 / DRIVE_LOOP_HZ`` seconds, and so on until it completes the laps asked for or the episode's
time limit is reached. Leaving the road counts as an intervention: the car is re-centred on the
road next to where it left (what a person would do) and the episode goes on. Metrics follow
docs/simulator.md (DAVE-2 autonomy, time-weighted |CTE| over autonomous frames, ...).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from parts.sim.expert import Expert
from parts.sim.simulator import OUTPUTS, SimCar

logger = logging.getLogger(__name__)

#: most trajectory points kept per episode (for the PNG; positions are subsampled beyond this)
MAX_TRAJECTORY_POINTS = 3000
#: simulated seconds allowed per lap when no max_time is given
SECONDS_PER_LAP_LIMIT = 60.0


@dataclass
class _Episode:
    """What one episode records, step by step."""

    cte: list[float] = field(default_factory=list)
    off: list[bool] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    angle: list[float] = field(default_factory=list)
    pos: list[tuple[float, float]] = field(default_factory=list)
    events: list[tuple[float, float]] = field(default_factory=list)  # where the car left the road
    distance: float = 0.0  # odometer, m


def _default_config() -> Any:
    from vehicle.config import Config

    return Config.defaults()


def resolve_pilot(pilot: Any) -> tuple[Any, str, bool]:
    """(pilot object or "expert", display name, whether we loaded it and must shut it down)."""
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
             on_step: Callable[[SimCar], None] | None = None) -> dict[str, Any]:
    """Drive ``pilot`` for ``laps`` laps on each track seed and return the report (a JSON-able dict).

    Args:
        pilot: "expert", a model file path (loaded with ``parts.pilots.load_pilot``), or any object
            with ``run(*inputs) -> (angle, throttle)`` and optionally ``inputs`` (memory keys,
            default ``["cam/image_array"]``).
        seeds: track seeds (use tracks the pilot was not trained on).
        laps: laps per track.
        cfg: a Config (default: package defaults); SIM_* settings shape tracks, camera and car.
        max_time: simulated seconds per episode at most (default SIM_EVAL_MAX_TIME, else 60 s/lap).
        penalty_s: seconds charged per intervention (default SIM_INTERVENTION_PENALTY, DAVE-2: 6).
        fixed_throttle: drive at this throttle and use only the pilot's steering (local_angle);
            otherwise the pilot's throttle is scaled by AI_THROTTLE_MULT as in "local" mode.
        extra_inputs: values for memory keys the pilot needs that the simulator does not make.
        on_step: called with the sim car after every step (e.g. to show or record frames).

    Returns:
        ``{"pilot", "laps", "seeds", "settings", "tracks": [per-track metrics], "overall": {...}}``.
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

    driver, name, owned = resolve_pilot(pilot)
    started = time.perf_counter()
    results = []
    pooled: list[np.ndarray] = []  # |cte| of autonomous frames, for the overall percentile
    try:
        for seed in seeds:
            res, abs_cte = _episode(driver, seed, laps, cfg, max_time, penalty, fixed_throttle,
                                    extra_inputs or {}, on_step)
            pooled.append(abs_cte)
            logger.info("eval %s on track %d: autonomy %.1f %%, %d/%d laps, mean |cte| %.3f m, %d off-track",
                        name, seed, res["autonomy"], res["laps_completed"], laps, res["mean_abs_cte"] or 0.0,
                        res["interventions"])
            results.append(res)
    finally:
        if owned and callable(getattr(driver, "shutdown", None)):
            driver.shutdown()
    return {
        "pilot": name,
        "laps": laps,
        "seeds": seeds,
        "settings": {"dt": 1.0 / cfg.DRIVE_LOOP_HZ, "penalty_s": penalty, "max_time_s": max_time,
                     "fixed_throttle": fixed_throttle, "road_width_m": cfg.SIM_ROAD_WIDTH,
                     "lanes": cfg.SIM_LANES, "image": [cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H],
                     "off_track_cte_m": cfg.SIM_OFF_TRACK_CTE, "track_size_m": cfg.SIM_TRACK_SIZE},
        "tracks": results,
        "overall": _overall(results, penalty, np.concatenate(pooled)),
        "wall_time_s": round(time.perf_counter() - started, 3),
    }


def _episode(driver: Any, seed: int, laps: int, cfg: Any, max_time: float, penalty: float,
             fixed_throttle: float | None, extra: dict[str, Any],
             on_step: Callable[[SimCar], None] | None) -> tuple[dict[str, Any], np.ndarray]:
    # image jitter stays as configured: a pilot is judged on the images it will get
    sim = SimCar.from_config(cfg, seeds=[seed], reset_off_track=True, reset_to="nearest", realtime=False)
    if driver == "expert":
        expert = Expert.from_config(cfg, sim)
        keys: list[str] = []

        def act(*_: Any) -> tuple[float, float]:
            return expert.command()
    else:
        keys = list(getattr(driver, "inputs", None) or ["cam/image_array"])
        mult = float(getattr(cfg, "AI_THROTTLE_MULT", 1.0))

        def act(*inputs: Any) -> tuple[Any, Any]:
            out = driver.run(*inputs)
            angle, throttle = (out[0], out[1]) if isinstance(out, tuple | list) else (out, None)
            # as DriveMode does in "local" mode on the car
            return angle, None if throttle is None else float(throttle) * mult
    mem: dict[str, Any] = {"user/mode": "local", "run_pilot": True, "recording": False,
                           "user/speed_limit": None, **extra}
    mem.update(zip(OUTPUTS, sim.observe(), strict=True))
    missing = [k for k in keys if k not in mem]
    if missing:
        raise ValueError(f"the pilot needs memory keys {missing} that the simulator does not produce; "
                         f"pass them in extra_inputs (available: {sorted(mem)})")
    ep = _Episode()
    warned = False
    while sim.tracker.laps < laps and sim.time < max_time - 1e-9:
        angle, throttle = act(*[mem[k] for k in keys])
        if fixed_throttle is not None:
            throttle = fixed_throttle
        if (angle is None or throttle is None) and not warned:
            logger.warning("pilot returned None for angle or throttle on track %d: treated as 0", seed)
            warned = True
        angle = 0.0 if angle is None else max(-1.0, min(1.0, float(angle)))
        throttle = 0.0 if throttle is None else float(throttle)
        before = (sim.car.state.x, sim.car.state.y)
        frame = sim.step(angle, throttle)
        ep.distance += abs(frame.speed) * sim.dt
        ep.cte.append(frame.cte)
        ep.off.append(frame.off_track)
        ep.speed.append(frame.speed)
        ep.angle.append(angle)
        ep.pos.append(frame.pos)
        if frame.off_track_event:
            ep.events.append(before)
        mem.update(zip(OUTPUTS, sim.observe(), strict=True))
        if on_step is not None:
            on_step(sim)
    metrics = _metrics(sim, ep, seed, laps, penalty, timed_out=sim.tracker.laps < laps)
    return metrics, np.abs(np.asarray(ep.cte))[~np.asarray(ep.off, bool)]


def _stats(values: np.ndarray) -> dict[str, float | None]:
    if values.size == 0:
        return {"mean_abs_cte": None, "rms_cte": None, "p95_abs_cte": None, "max_abs_cte": None}
    a = np.abs(values)
    return {"mean_abs_cte": _r(a.mean()), "rms_cte": _r(np.sqrt((values**2).mean())),
            "p95_abs_cte": _r(np.percentile(a, 95)), "max_abs_cte": _r(a.max())}


def _r(x: float | None, nd: int = 4) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)


def _metrics(sim: SimCar, ep: _Episode, seed: int, laps: int, penalty: float,
             timed_out: bool) -> dict[str, Any]:
    """Per-track metrics (docs/simulator.md gives the definitions)."""
    t = sim.time
    dt = sim.dt
    n_int = len(ep.events)
    cte = np.asarray(ep.cte)
    off = np.asarray(ep.off, bool)
    speed = np.asarray(ep.speed)
    auto = ~off  # autonomous frames: the car is on the road under the pilot's control
    laps_driven = sim.tracker.best / sim.track.length  # fractional laps of forward progress
    lap_times = sim.tracker.lap_times
    steer = np.asarray(ep.angle)
    km = ep.distance / 1000.0
    step = max(1, math.ceil(len(ep.pos) / MAX_TRAJECTORY_POINTS))
    return {
        "seed": seed,
        "track_length_m": _r(sim.track.length, 2),
        "elapsed_s": _r(t, 3),
        "interventions": n_int,
        "autonomy": _r(max(0.0, 1.0 - n_int * penalty / t) * 100.0 if t > 0 else 0.0, 2),
        "laps_completed": sim.tracker.laps,
        "laps_driven": _r(laps_driven, 3),
        "success": sim.tracker.laps >= laps and n_int == 0,
        "timed_out": timed_out,
        **_stats(cte[auto]),
        "off_track_per_lap": _r(n_int / laps_driven, 3) if laps_driven > 0.01 else None,
        "off_track_per_km": _r(n_int / km, 3) if km > 0 else None,
        "distance_m": _r(ep.distance, 2),
        "mean_distance_between_interventions_m": _r(ep.distance / n_int, 2) if n_int else None,
        "lap_times_s": [_r(x, 3) for x in lap_times],
        "best_lap_s": _r(min(lap_times), 3) if lap_times else None,
        "mean_lap_s": _r(float(np.mean(lap_times)), 3) if lap_times else None,
        "std_lap_s": _r(float(np.std(lap_times)), 3) if lap_times else None,
        "mean_speed": _r(float(speed[auto].mean()), 3) if auto.any() else None,
        "steering_smoothness": _r(float(np.abs(np.diff(steer)).mean() / dt), 4) if steer.size > 1 else None,
        "progress": _r(sim.frame.progress if sim.frame else 0.0, 3),
        "frames": int(cte.size),
        "autonomous_frames": int(auto.sum()),
        "trajectory": [[_r(x, 3), _r(y, 3)] for x, y in ep.pos[::step]],
        "off_track_at": [[_r(x, 3), _r(y, 3)] for x, y in ep.events],
    }


def _overall(results: list[dict[str, Any]], penalty: float, abs_cte: np.ndarray) -> dict[str, Any]:
    """Aggregate over tracks: sums, and means weighted by frames / time / distance."""
    t = sum(r["elapsed_s"] for r in results)
    n_int = sum(r["interventions"] for r in results)
    laps_driven = sum(r["laps_driven"] for r in results)
    dist = sum(r["distance_m"] for r in results)
    auto_frames = sum(r["autonomous_frames"] for r in results)
    frames = sum(r["frames"] for r in results)

    def weighted(key: str, weight: str) -> float | None:
        pairs = [(r[key], r[weight]) for r in results if r[key] is not None and r[weight]]
        total = sum(w for _, w in pairs)
        return _r(sum(v * w for v, w in pairs) / total) if total else None

    lap_times = [x for r in results for x in r["lap_times_s"]]
    return {
        "tracks": len(results),
        "elapsed_s": _r(t, 3),
        "interventions": n_int,
        "autonomy": _r(max(0.0, 1.0 - n_int * penalty / t) * 100.0 if t > 0 else 0.0, 2),
        "laps_completed": sum(r["laps_completed"] for r in results),
        "success_rate": _r(sum(r["success"] for r in results) / len(results), 3),
        "mean_abs_cte": weighted("mean_abs_cte", "autonomous_frames"),
        "rms_cte": _r(math.sqrt(sum((r["rms_cte"] or 0) ** 2 * r["autonomous_frames"] for r in results)
                                / auto_frames)) if auto_frames else None,
        "p95_abs_cte": _r(np.percentile(abs_cte, 95)) if abs_cte.size else None,
        "max_abs_cte": _r(max((r["max_abs_cte"] for r in results if r["max_abs_cte"] is not None),
                              default=None)),
        "off_track_per_lap": _r(n_int / laps_driven, 3) if laps_driven > 0.01 else None,
        "off_track_per_km": _r(n_int / (dist / 1000.0), 3) if dist > 0 else None,
        "distance_m": _r(dist, 2),
        "mean_distance_between_interventions_m": _r(dist / n_int, 2) if n_int else None,
        "mean_lap_s": _r(float(np.mean(lap_times)), 3) if lap_times else None,
        "best_lap_s": _r(min(lap_times), 3) if lap_times else None,
        "mean_speed": weighted("mean_speed", "autonomous_frames"),
        "steering_smoothness": weighted("steering_smoothness", "frames"),
        "frames": frames,
    }
