"""``vehicle demo --lanes``: the thesis's experiment (seed 002, ch. 9-10) in one command, on a CPU.

    vehicle demo --lanes                          # works in ./demo_lanes
    vehicle demo --lanes --records 8000 --lane-changes 50 --epochs 12
    vehicle demo --lanes --seed 2 --draws 3       # another recording and training seed; hidden draws

1. The expert drives two-lane training tracks and the behaviour (Left_Lane / Right_Lane) flips at
   random times; the expert changes lanes smoothly, waiting in tight corners. Frames, commands and
   behaviour are recorded (the thesis: ~10,000 records with ~20 lane changes, then 25,000 with 50).
2. The two-stream ``lanes`` model (raw frame + lane image + behaviour) and the single-stream
   ``behavior`` model train on the same tub.
3. Both are exported to ONNX when onnx and onnxruntime are installed.
4. Both, and the expert, drive tracks none of them saw while the lane is changed on command every
   SIM_EVAL_LANE_CHANGE_EVERY seconds; the tables compare lane-change success, time to change,
   lane keeping, wrong-lane time and off-track events. The thesis's claim: every commanded change
   succeeds and the car never leaves the road. With ``--draws N`` both models also drive under N
   hidden randomisation draws (their failed changes in failure galleries, ``eval/gallery/<type>``).

``--seed N`` means what it means for the plain demo (1: the demo as it always ran): the recording's
effects, steering-noise and lane-change seed (SIM_SEED) is (N - 1) * SEED_STRIDE and TRAIN_SEED
42 + N - 1. ``vehicle sim robustness --lanes`` runs it over seeds and precisions.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

from vehicle.app.demo import DEMO_SETTINGS, say

#: the lane demo's settings on top of the demo's; each a normal setting (docs/config.md)
LANE_SETTINGS: dict[str, Any] = {
    "SIM_LANES": 2,
    "TRAIN_BEHAVIORS": True,  # BEHAVIOR_LIST: Left_Lane, Right_Lane
    # the simulator's white lines have almost no saturation: the thesis's S threshold marks the
    # grass beside the road, the white mask adds the lines
    "LANE_COLOR_MASK": "white",
    # the lane experiment runs on plain roads: the demo's themes, randomisation and hue
    # augmentation (tape of any colour) would change what the white-line mask sees
    "SIM_THEME": "road",
    "SIM_RANDOMIZE": None,
    "AUGMENTATIONS": ["flip", "shift", "brightness", "shadow"],
}
DEFAULTS = {"records": 6000, "lane_changes": 40, "epochs": 10, "noise": 0.4,
            "train_tracks": [1, 2, 3, 4, 5, 6, 7, 8], "eval_tracks": [101, 102, 103, 104, 105], "laps": 2,
            "types": ["lanes", "behavior"]}


def lane_demo_settings() -> dict[str, Any]:
    """DEMO_SETTINGS + LANE_SETTINGS + the lane-extraction points for the simulated camera (a true
    bird's-eye view of the ground from 0.3 to 1.2 m ahead, ±0.5 m)."""
    from parts.sim.camera import camera_from_config, lane_region_points
    from vehicle.config import Config

    settings = {**DEMO_SETTINGS, **LANE_SETTINGS}
    points = lane_region_points(camera_from_config(Config.defaults(**settings)))
    settings["LANE_SOURCE_POINTS"] = [tuple(p) for p in points["LANE_SOURCE_POINTS"]]
    settings["LANE_DESTINATION_POINTS"] = [tuple(p) for p in points["LANE_DESTINATION_POINTS"]]
    settings["LANE_POINTS_SIZE"] = tuple(points["LANE_POINTS_SIZE"])
    return settings


def run_lanes_demo(out: Path, *, records: int, lane_changes: int, epochs: int, noise: float,
                   train_tracks: list[int], eval_tracks: list[int], laps: int,
                   types: list[str] | None = None, seed: int = 1, precision: str = "auto",
                   draws: int = 0) -> dict[str, Any]:
    """Run the four steps in ``out``; returns ``{"reports": {name: report}, "models": {type: path},
    "metrics": {type: training metrics}, "seconds": {step: s}, "seed", "precision", ...}``, with
    ``draws`` > 0 also ``"draws": {type: report}`` (:func:`vehicle.app.lanes_robustness.lane_draws`).
    ``seed`` and ``precision`` as in :func:`vehicle.app.demo.run_demo`. Raises ValueError on bad arguments."""
    from vehicle.app.demo import BASE_TRAIN_SEED, MAX_SEED, SEED_STRIDE, train_or_stop, train_seed, write_myconfig
    from vehicle.app.record import record_expert
    from vehicle.config import Config

    types = list(types or DEFAULTS["types"])
    if not 1 <= seed <= MAX_SEED:
        raise ValueError(f"--seed {seed}: use 1 .. {MAX_SEED}")
    if set(train_tracks) & set(eval_tracks):
        raise ValueError(f"evaluation tracks {sorted(set(train_tracks) & set(eval_tracks))} are also training "
                         "tracks: evaluate on tracks the pilots never saw")
    if records < 100 or epochs < 1 or laps < 1 or lane_changes < 1:
        raise ValueError(f"need records >= 100, lane changes >= 1, epochs >= 1 and laps >= 1 (got {records}, "
                         f"{lane_changes}, {epochs}, {laps})")
    out = out.resolve()
    settings = lane_demo_settings()
    # written only where they differ from the defaults: --seed 1 writes today's myconfig.py
    if train_seed(seed) != BASE_TRAIN_SEED:
        settings["TRAIN_SEED"] = train_seed(seed)
    if precision != "auto":
        settings["TRAIN_PRECISION"] = precision
    cfg = Config.defaults(CAR_PATH=str(out), **settings)
    sim_seed = cfg.SIM_SEED + (seed - 1) * SEED_STRIDE  # the recording's only: evaluation keeps its schedule
    write_myconfig(out, settings, "vehicle demo --lanes")
    tub = out / "data" / "lanes_tub"
    if tub.exists():
        shutil.rmtree(tub)  # recorded afresh each run; the demo never touches other folders
    seconds: dict[str, float] = {}

    t = time.perf_counter()
    say(f"[1/4] the expert drives two-lane tracks {train_tracks}: {records} records, {lane_changes} commanded "
        f"lane changes, steering noise {noise} ...")
    record_expert(cfg.replace(SIM_SEED=sim_seed), train_tracks, records, tub, noise=noise, lane_changes=lane_changes)
    seconds["record"] = time.perf_counter() - t

    models: dict[str, Path] = {}
    metrics: dict[str, Any] = {}
    for i, model_type in enumerate(types, 1):
        t = time.perf_counter()
        path = out / "models" / f"demo_{model_type}.pt"
        say(f"[2/4] training the {model_type} model ({i} of {len(types)}) for up to {epochs} epochs ...")
        metrics[model_type] = train_or_stop(cfg, [tub], path, model_type_name=model_type, epochs=epochs,
                                            comment="vehicle demo --lanes")
        seconds[f"train {model_type}"] = time.perf_counter() - t
        m = metrics[model_type]
        say(f"      best val_loss {m['best_val_loss']:.5f} at epoch {m['best_epoch']} of {m['epochs']} "
            f"({seconds[f'train {model_type}']:.0f} s)")
        models[model_type] = path

    t = time.perf_counter()
    from vehicle.app.demo import export_onnx

    for path in models.values():
        export_onnx(path)
    seconds["export"] = time.perf_counter() - t

    t = time.perf_counter()
    say(f"[4/4] driving {laps} laps on each of the unseen tracks {eval_tracks}, changing lanes on command ...")
    reports, by_draw = evaluate_models(models, eval_tracks, laps, cfg, out, draws)
    seconds["evaluate"] = time.perf_counter() - t
    say("\n" + comparison_table(reports))
    if by_draw is not None:
        say("\nunder hidden randomisation draws:\n" + comparison_table(
            {f"{k} model": {"overall": r["overall"]} for k, r in by_draw.items()}))
    return {"reports": reports, "models": models, "metrics": metrics, "seconds": seconds, "seed": seed,
            "precision": precision, "train_seed": train_seed(seed), "sim_seed": sim_seed,
            "eval_tracks": list(eval_tracks), "laps": laps, **({"draws": by_draw} if by_draw is not None else {})}


def evaluate_models(models: dict[str, Path], eval_tracks: list[int], laps: int, cfg: Any, out: Path,
                    draws: int) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """Step 4: each model and the expert with commanded lane changes in the demo's own look (reports
    by driver, each written to ``out/eval/<stem>.json`` and ``.png`` and printed), and with ``draws``
    > 0 each model under that many hidden draws (:func:`vehicle.app.lanes_robustness.lane_draws`,
    ``out/eval/<type>_draws.json``; else None)."""
    from parts.sim.eval_report import format_table, write_json, write_png
    from vehicle.app.evaluate import evaluate

    reports: dict[str, Any] = {}
    for name, pilot in [*((f"{k} model", p) for k, p in models.items()), ("expert", "expert")]:
        report = evaluate(pilot, eval_tracks, laps, cfg=cfg, lane_changes=True)
        reports[name] = report
        stem = name.split()[0]
        write_json(report, out / "eval" / f"{stem}.json")
        write_png(report, out / "eval" / f"{stem}.png", cfg)
        say(f"\n{name} on unseen tracks:")
        say(format_table(report))
    if not draws:
        return reports, None
    from vehicle.app.lanes_robustness import lane_draws

    say(f"      and under {draws} hidden randomisation draw(s), failed changes in galleries ...")
    by_draw = lane_draws(models, eval_tracks, laps, cfg, draws, out / "eval" / "gallery")
    for model_type, report in by_draw.items():
        write_json(report, out / "eval" / f"{model_type}_draws.json")
    return reports, by_draw


def comparison_table(reports: dict[str, Any]) -> str:
    """One row per driver: the lane-change figures the thesis's claim is about."""
    headers = ["driver", "changes ok", "success", "mean change s", "lane |err| m", "wrong lane s", "off-track",
               "autonomy %", "laps"]
    rows = []
    for name, r in reports.items():
        o, lanes = r["overall"], r["overall"]["lanes"]
        rate = lanes["lane_change_success_rate"]
        rows.append([name, f"{lanes['lane_changes_ok']}/{lanes['lane_changes']}",
                     "-" if rate is None else f"{rate:.0%}",
                     "-" if lanes["mean_time_to_change_s"] is None else f"{lanes['mean_time_to_change_s']:.2f}",
                     "-" if lanes["lane_mean_abs_error"] is None else f"{lanes['lane_mean_abs_error']:.3f}",
                     f"{lanes['wrong_lane_s']:.1f}", str(o["interventions"]), f"{o['autonomy']:.1f}",
                     str(o["laps_completed"])])
    widths = [max(len(x[i]) for x in [headers, *rows]) for i in range(len(headers))]
    lines = ["  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True)),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    return "lane change on demand, unseen tracks:\n" + "\n".join(lines)


def thesis_claim_met(report: dict[str, Any]) -> bool:
    """Every commanded lane change succeeded and the car never left the road."""
    o = report["overall"]
    lanes = o["lanes"]
    return lanes["lane_changes"] > 0 and lanes["lane_changes_ok"] == lanes["lane_changes"] and o["interventions"] == 0
