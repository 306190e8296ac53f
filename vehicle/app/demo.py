"""``vehicle demo``: record → train → evaluate on unseen tracks and an unseen theme, with nothing but a CPU.

    vehicle demo                      # works in ./demo (regenerated each run)
    vehicle demo --out /tmp/mydemo --records 20000 --epochs 12
    vehicle demo --eval-randomize 2   # evaluate under a randomisation draw never trained on

1. The simulator's expert drives the training tracks (with noise injection, so the data shows
   recoveries) and its clean commands are recorded in a tub. The tracks alternate between the
   road and indoor themes and are randomised (light, shadows, colours, camera, sensor, latency,
   distractors, lines worn away in patches: SIM_RANDOMIZE = 1).
2. The default ``linear`` model trains on that tub (the same training code as ``manage.py train``),
   with the hue and blur augmentations on top of the default ones.
3. The model is exported to ONNX when onnx and onnxruntime are installed (the pilot then runs it).
4. The trained pilot and the expert drive tracks the pilot never saw, in each trained theme and in
   the park theme it never saw at all (a path without lines): one table per theme. By default in
   each theme's plain look (what it was randomised around); ``--eval-randomize SEED`` evaluates
   under a randomisation draw it never saw instead.

The demo folder is an ordinary car folder: ``vehicle models --car demo`` lists the model,
``vehicle sim eval --pilot demo/models/demo_linear.pt --theme park --randomize off`` evaluates it again.
"""

from __future__ import annotations

import logging
import shutil
import time
from pathlib import Path
from typing import Any, NamedTuple

logger = logging.getLogger(__name__)

#: settings the demo runs with (tuned so the pilot completes its laps within the time budget);
#: each is a normal setting (docs/config.md)
DEMO_SETTINGS: dict[str, Any] = {
    "ROI_CROP_TOP": 40,  # the top third of the frame is sky: less to learn and 1/3 less compute
    "BATCH_SIZE": 64,
    # the expert (and so the pilot it teaches) drives at 1.5 m/s instead of 2: at 2 m/s one sharp
    # curve per unseen track was too much for a model trained in 2 minutes
    "SIM_EXPERT_SPEED": 1.5,
    # the training tracks alternate between two themes, each randomised (seed 1)
    "SIM_THEME": ["road", "indoor"],
    "SIM_RANDOMIZE": 1,
    # worn lines up to gone in patches: where a line vanishes, the pilot must steer by where the
    # road's surface ends (what the unseen park theme has instead of lines)
    "SIM_RANDOMIZE_RANGES": {"line_wear": (0.0, 1.0)},
    # the default augmentations plus hue (tape of one colour teaches the others) and blur (thin
    # lines count less against the broad edges of the drivable surface)
    "AUGMENTATIONS": ["flip", "shift", "hue", "brightness", "shadow", "blur"],  # applied in this order
    "SHOW_PLOT": True,
}
#: ``vehicle demo --robust``: the batch augmentations added to the demo's (training/batch_augment.py):
#: measured to lift the unseen park theme under hidden randomisation draws, at some training time
#: (docs/pilot.md, "Robustness: what closes the gap")
ROBUST_AUGMENTATIONS = ["light", "colour", "noise", "cutout"]


class Recording(NamedTuple):
    """One more recording of the training tracks by ``vehicle demo --robust``."""

    tub: str  # folder name under the demo's data/
    draw: int  # SIM_RANDOMIZE: the randomisation seed
    seed: int  # SIM_SEED: the per-frame effects and the steering noise
    ranges: dict[str, tuple[float, float]] | None  # SIM_RANDOMIZE_RANGES; None: the demo's
    surfaces: float = 0.0  # SIM_ROAD_SURFACE_SHARE of the recording (never of the evaluation)


#: wider ranges than the defaults (parts/sim/randomize.py RANGES): darker and brighter, warmer and
#: cooler light, more contrast, colour jitter, sensor noise, shadows, camera tilt and field of
#: view, and clutter; lines worn up to gone in patches as in the demo
ROBUST_WIDE_RANGES: dict[str, tuple[float, float]] = {
    "line_wear": (0.0, 1.0), "light": (0.35, 1.9), "colour_temperature": (2500.0, 10000.0),
    "contrast": (0.6, 1.4), "colour_jitter": (0.0, 0.25), "noise": (0.0, 14.0), "shadows": (0, 10),
    "camera_pitch": (-6.0, 6.0), "camera_fov": (-12.0, 12.0), "distractors": (0, 14)}
#: ``vehicle demo --robust`` drives the training tracks twice more, as many records each time: under
#: another draw of the demo's ranges, and under the wider ranges. Measured (docs/pilot.md, "Robustness:
#: what closes the gap"): with the batch augmentations these 36 000 records held every hidden draw of
#: the trained themes and took the unseen park theme to 97.9 % (worst draw 93.8 %); a third draw of
#: the demo's ranges instead of the wider ones gave 67.8 % in park, the wider ones alone 78.7 %.
ROBUST_RECORDINGS = (Recording("demo_tub_draw11", 11, 11, None),
                     Recording("demo_tub_wide", 1, 0, ROBUST_WIDE_RANGES))
#: ``vehicle demo --seed N`` records with the randomisation and effects seeds of seed 1 plus
#: (N - 1) * SEED_STRIDE: seed 2 records draws 10001 and 10011, far from the hidden evaluation draws
#: (eval_draws.HIDDEN_DRAW_BASE + 1 ..) and DAgger's roll-out draws (dagger.ROLLOUT_DRAW_BASE + round)
SEED_STRIDE = 10_000
#: the largest --seed: its draws stay within SIM_RANDOMIZE's range (below 2**32)
MAX_SEED = 100_000
#: TRAIN_SEED of ``--seed 1`` (the setting's default: the demo as it always trained)
BASE_TRAIN_SEED = 42

class Recipe(NamedTuple):
    """What a demo recipe adds to :data:`DEMO_SETTINGS` (``vehicle demo --recipe NAME``)."""

    augmentations: tuple[str, ...]  # batch augmentations added to AUGMENTATIONS
    recordings: tuple[Recording, ...]  # recordings of the training tracks beside the demo's own
    what: str  # one line for --help
    surfaces: float = 0.0  # SIM_ROAD_SURFACE_SHARE of every recording; evaluations keep the themes as they are
    settings: dict[str, Any] | None = None  # training settings beside DEMO_SETTINGS (docs/config.md)


#: the demo's recipes, measured against each other by ``vehicle sim robustness --recipe``
RECIPES: dict[str, Recipe] = {
    "plain": Recipe((), (), "the demo's settings"),
    "augmented": Recipe(tuple(ROBUST_AUGMENTATIONS), (), "plus the light, colour, noise and cutout batch "
                        "augmentations (no more records; some training time)"),
    "robust": Recipe(tuple(ROBUST_AUGMENTATIONS), ROBUST_RECORDINGS, "plus those augmentations and two more "
                     "recordings of the training tracks (another draw, wider ranges): three times the records"),
    # half the training tracks keep their theme's surface, so the trained themes are still seen as they are
    "materials": Recipe((), (), "the demo's settings, with the road (indoor: the floor) of half the training tracks "
                        "drawn from a generic pool of surfaces: asphalt, concrete, gravel, pavers, packed earth",
                        surfaces=0.5),
    # batch norm after each convolution: training leaves the "predict the mean" plateau in the first
    # epoch (seed 2's plain training stayed on it for every epoch: docs/benchmarks.md, issue 38)
    "normed": Recipe((), (), "the materials recipe with batch norm after each convolution of the model",
                     surfaces=0.5, settings={"MODEL_OPTIONS": {"batch_norm": True}}),
    # group norm normalises each frame by its own statistics: it leaves the plateau as batch norm
    # does, without applying the training frames' statistics to a road under other light
    "grouped": Recipe((), (), "the materials recipe with group norm (per frame) after each convolution of the model",
                      surfaces=0.5, settings={"MODEL_OPTIONS": {"group_norm": True}}),
    # He initialisation keeps the signal's scale through the ReLU layers (torch's default shrinks it):
    # training leaves the plateau without a normalisation layer, so nothing changes at inference
    "initialised": Recipe((), (), "the materials recipe with He initialisation of the model's layers",
                          surfaces=0.5, settings={"MODEL_OPTIONS": {"he_init": True}}),
}

# 12000 records on 64 tracks: with half of each, one unseen indoor track in five failed (docs/pilot.md)
DEFAULTS = {"records": 12000, "epochs": 10, "noise": 0.4, "train_tracks": list(range(1, 65)),
            "eval_tracks": [101, 102, 103, 104, 105], "laps": 2, "eval_randomize": None, "unseen_theme": "park"}


#: the --lanes demo's wall time in seconds on a quiet 2-core CPU of each kind: "bf16" where the CPU
#: has native bf16 (AVX512-BF16 or AMX: training runs in bf16), "fp32" where it has not. Measured
#: figures only (docs/vision.md); a kind without one is said to be unmeasured. (The plain demo
#: measures the host instead: vehicle/app/demo_estimate.py.)
EXPECTED_SECONDS: dict[str, dict[str, float]] = {
    "lanes": {"bf16": 240},
}


def expected_time(demo: str, native_bf16: bool, cpu: str) -> str:
    """The demo's start-up line: what it should take on this CPU and what that depends on.

    ``demo`` is "plain" or "lanes"; ``native_bf16`` and ``cpu`` (its name) describe the CPU
    (:func:`training.acceleration.cpu_caps`).
    """
    kind = "bf16" if native_bf16 else "fp32"
    what = f"{cpu}, {'native bf16: trains in bf16' if native_bf16 else 'no native bf16: trains in fp32'}"
    seconds = EXPECTED_SECONDS.get(demo, {}).get(kind)
    if seconds is None:
        return f"expected time: not measured on a CPU of this kind ({what}); each step prints its time"
    return (f"expected time: about {_minutes(seconds)} on a quiet 2-core CPU of this kind ({what}); more on a busy "
            "machine, less with more cores; most of it is training")


def _minutes(seconds: float) -> str:
    """``about 2 minutes`` style wording: whole minutes from 90 s on, else seconds."""
    return f"{seconds:.0f} s" if seconds < 90 else f"{round(seconds / 60)} minutes"


def training_recordings(seed: int = 1, recipe: str = "plain") -> list[Recording]:
    """The recordings of ``vehicle demo --seed seed`` (with ``--recipe robust``: three): seed 1 is the demo
    as it always recorded (draw 1, SIM_SEED 0; --robust also draws 11 and 1 over wider ranges), seed
    N adds (N - 1) * :data:`SEED_STRIDE` to each draw and effects seed. ValueError outside 1..MAX_SEED."""
    if not 1 <= seed <= MAX_SEED:
        raise ValueError(f"--seed {seed}: use 1 .. {MAX_SEED}")
    offset = (seed - 1) * SEED_STRIDE
    base = [Recording("demo_tub", DEMO_SETTINGS["SIM_RANDOMIZE"], 0, None), *RECIPES[recipe].recordings]
    return [r._replace(draw=r.draw + offset, seed=r.seed + offset, surfaces=RECIPES[recipe].surfaces) for r in base]


def demo_settings(recipe: str = "plain", seed: int = 1, precision: str = "auto") -> dict[str, Any]:
    """The settings ``vehicle demo --recipe recipe --seed seed --precision precision`` trains with and
    writes to its myconfig.py: :data:`DEMO_SETTINGS` with the recipe's augmentations and settings, the
    seed's randomisation draw and TRAIN_SEED, the precision (each only where it differs from the
    setting's default, so that --seed 1 writes the myconfig.py the demo always wrote)."""
    settings = {**DEMO_SETTINGS, "SIM_RANDOMIZE": training_recordings(seed, recipe)[0].draw}
    if train_seed(seed) != BASE_TRAIN_SEED:
        settings["TRAIN_SEED"] = train_seed(seed)
    if precision != "auto":
        settings["TRAIN_PRECISION"] = precision
    settings["AUGMENTATIONS"] = [*settings["AUGMENTATIONS"], *RECIPES[recipe].augmentations]
    settings.update(RECIPES[recipe].settings or {})
    return settings


def train_seed(seed: int = 1) -> int:
    """TRAIN_SEED of ``vehicle demo --seed seed``: 42 for seed 1, then 43, 44, ..."""
    return BASE_TRAIN_SEED + seed - 1


def say(text: str) -> None:
    print(text, flush=True)  # noqa: T201 - the command's own output


def run_demo(out: Path, *, records: int, epochs: int, noise: float, train_tracks: list[int],
             eval_tracks: list[int], laps: int, model_type: str = "linear",
             eval_randomize: int | None = DEFAULTS["eval_randomize"],
             unseen_theme: str = DEFAULTS["unseen_theme"], recipe: str = "plain", draws: int = 0, seed: int = 1,
             precision: str = "auto") -> dict[str, Any]:
    """Run the four steps in ``out``; returns ``{"reports": {theme: {"pilot": report, "expert":
    report}}, "trained_themes": [...], "unseen_theme": name, "model": path, "seconds": {step: s},
    "cpu_seconds": {step: s}, "metrics": {...}}`` (wall time, and CPU time of this process and its
    finished workers: on a shared machine the two differ). ``recipe`` names one of :data:`RECIPES`: its
    batch augmentations are added, and as many records again recorded for each of its recordings.
    With ``draws`` > 0 the pilot is also driven under that many hidden randomisation draws per theme
    (``vehicle sim eval --draws``) and the result holds ``"draws"``: that report, whose ``by_theme``
    gives the mean and the worst draw. ``seed`` picks the recordings' draws and effects seeds and
    TRAIN_SEED (:func:`training_recordings`, :func:`train_seed`; 1: the demo as it always ran),
    ``precision`` TRAIN_PRECISION. Raises ValueError on bad arguments."""
    from vehicle.config import Config

    trained, recordings = _check_demo(records, epochs, laps, train_tracks, eval_tracks, unseen_theme, recipe,
                                      seed, eval_randomize, draws)
    out = out.resolve()
    settings = demo_settings(recipe, seed, precision)
    cfg = Config.defaults(CAR_PATH=str(out), **settings)
    write_myconfig(out, settings, "vehicle demo")
    # the demo records afresh each run; it never touches other folders
    tubs = [out / "data" / r.tub for r in recordings]
    for tub in tubs:
        if tub.exists():
            shutil.rmtree(tub)
    model_path = out / "models" / f"demo_{model_type}.pt"
    seconds: dict[str, float] = {}
    cpu: dict[str, float] = {}

    t, c = time.perf_counter(), cpu_seconds()
    _record(cfg, tubs, recordings, train_tracks, records, noise, trained)
    seconds["record"] = time.perf_counter() - t
    cpu["record"] = cpu_seconds() - c
    say(f"      recorded in {seconds['record']:.0f} s")

    t, c = time.perf_counter(), cpu_seconds()
    say(f"[2/4] training a {model_type} model for up to {epochs} epochs ...")
    metrics = train_or_stop(cfg, tubs, model_path, model_type_name=model_type, epochs=epochs,
                            comment="vehicle demo")
    seconds["train"] = time.perf_counter() - t
    cpu["train"] = cpu_seconds() - c
    say(f"      best val_loss {metrics['best_val_loss']:.5f} at epoch {metrics['best_epoch']} of "
         f"{metrics['epochs']} ({seconds['train']:.0f} s)")

    t, c = time.perf_counter(), cpu_seconds()
    export_onnx(model_path)
    seconds["export"] = time.perf_counter() - t
    cpu["export"] = cpu_seconds() - c

    t, c = time.perf_counter(), cpu_seconds()
    reports, by_draw = _evaluate_demo(cfg, out, model_path, eval_tracks, laps, trained, unseen_theme,
                                      eval_randomize, draws)
    seconds["evaluate"] = time.perf_counter() - t
    cpu["evaluate"] = cpu_seconds() - c
    say(f"      evaluated in {seconds['evaluate']:.0f} s")
    _say_reports(reports, trained, by_draw)
    return {"reports": reports, "trained_themes": trained, "unseen_theme": unseen_theme, "model": model_path,
            "seconds": seconds, "cpu_seconds": cpu, "metrics": metrics, "seed": seed, "precision": precision,
            "recipe": recipe, "eval_tracks": list(eval_tracks), "laps": laps,
            "recordings": [{"tub": r.tub, "draw": r.draw, "seed": r.seed, "surfaces": r.surfaces} for r in recordings],
            "train_seed": train_seed(seed), **({"draws": by_draw} if by_draw is not None else {})}


def _check_demo(records: int, epochs: int, laps: int, train_tracks: list[int], eval_tracks: list[int],
                unseen_theme: str, recipe: str, seed: int, eval_randomize: int | None,
                draws: int) -> tuple[list[str], list[Recording]]:
    """(the trained themes, the recordings) of a demo's arguments; ValueError for bad ones."""
    from parts.sim.themes import theme_list

    if set(train_tracks) & set(eval_tracks):
        raise ValueError(f"evaluation tracks {sorted(set(train_tracks) & set(eval_tracks))} are also training "
                         "tracks: evaluate on tracks the pilot never saw")
    if records < 100 or epochs < 1 or laps < 1:
        raise ValueError(f"need records >= 100, epochs >= 1 and laps >= 1 (got {records}, {epochs}, {laps})")
    trained = theme_list(DEMO_SETTINGS["SIM_THEME"])
    theme_list(unseen_theme)  # a known theme
    if unseen_theme in trained:
        raise ValueError(f"the unseen theme {unseen_theme!r} is a training theme: pick another")
    if recipe not in RECIPES:
        raise ValueError(f"recipe {recipe!r}: choose one of {', '.join(RECIPES)}")
    recordings = training_recordings(seed, recipe)
    if eval_randomize in {r.draw for r in recordings}:
        raise ValueError(f"randomisation seed {eval_randomize} is a training draw: evaluate with another")
    if draws:
        from vehicle.app.eval_draws import hidden_draws

        for r in recordings:  # raises when a training draw is one of the hidden ones
            hidden_draws(draws, r.draw)
    return trained, recordings


def _record(cfg: Any, tubs: list[Path], recordings: list[Recording], train_tracks: list[int], records: int,
            noise: float, trained: list[str]) -> None:
    """Step 1: the expert drives the training tracks once per recording of the recipe."""
    from vehicle.app.record import record_expert

    for tub, r in zip(tubs, recordings, strict=True):
        ranges = cfg.SIM_RANDOMIZE_RANGES if r.ranges is None else r.ranges
        wider = "" if r.ranges is None else " over wider ranges"
        if r.surfaces:
            wider += f", {r.surfaces:.0%} of the tracks on a surface from the generic pool"
        say(f"[1/4] the expert drives training tracks {train_tracks} (themes {', '.join(trained)}, randomised "
            f"with seed {r.draw}{wider}): recording {records} records (steering noise {noise}) ...")
        # the recording's settings only: cfg, which the evaluation uses, keeps the themes' own surfaces
        record_expert(cfg.replace(SIM_RANDOMIZE=r.draw, SIM_SEED=r.seed, SIM_RANDOMIZE_RANGES=ranges,
                                  SIM_ROAD_SURFACE_SHARE=r.surfaces), train_tracks, records, tub, noise=noise)


def _evaluate_demo(cfg: Any, out: Path, model_path: Path, eval_tracks: list[int], laps: int, trained: list[str],
                   unseen_theme: str, eval_randomize: int | None,
                   draws: int) -> tuple[dict[str, dict[str, Any]], dict[str, Any] | None]:
    """Step 4: the pilot and the expert on the unseen tracks in every theme (and, with ``draws``,
    the pilot under hidden draws, with failure galleries); (reports by theme, the draws report)."""
    from parts.sim.eval_report import write_json
    from vehicle.app.evaluate import evaluate

    how = ("in each theme's plain look" if eval_randomize is None
           else f"randomised with seed {eval_randomize} (a draw never trained on)")
    say(f"[4/4] driving {laps} laps on each of the unseen tracks {eval_tracks}, {how}, in the trained themes "
        f"{', '.join(trained)} and in the {unseen_theme} theme it never saw ...")
    reports: dict[str, dict[str, Any]] = {}
    for theme in [*trained, unseen_theme]:
        c_theme = cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=eval_randomize)
        reports[theme] = {
            "pilot": evaluate(model_path, eval_tracks, laps, cfg=c_theme, workers=cfg.SIM_EVAL_WORKERS),
            "expert": evaluate("expert", eval_tracks, laps, cfg=c_theme, workers=cfg.SIM_EVAL_WORKERS)}
        for who, report in reports[theme].items():
            write_json(report, out / "eval" / f"{who}_{theme}.json")
    if not draws:
        return reports, None
    from vehicle.app.eval_draws import evaluate_draws, hidden_draws
    from vehicle.app.failure_moments import GallerySpec

    say(f"      and under {draws} hidden randomisation draw(s) per theme (mean and worst draw) ...")
    galleries = out / "eval" / "gallery"  # the demo's own folder: a rerun replaces its galleries
    shutil.rmtree(galleries, ignore_errors=True)
    by_draw = evaluate_draws(model_path, eval_tracks, laps, cfg=cfg, draws=hidden_draws(draws, cfg.SIM_RANDOMIZE),
                             themes=[*trained, unseen_theme], workers=cfg.SIM_EVAL_WORKERS,
                             gallery=GallerySpec(str(galleries), str(model_path)))
    write_json(by_draw, out / "eval" / "pilot_draws.json")
    return reports, by_draw


def _say_reports(reports: dict[str, dict[str, Any]], trained: list[str], by_draw: dict[str, Any] | None) -> None:
    """The evaluation's tables: per theme the pilot's, the expert's line, then the draws'."""
    from parts.sim.eval_report import describe, format_table

    for theme, pair in reports.items():
        seen = "a trained theme" if theme in trained else "a theme the pilot never saw"
        say(f"\ntrained pilot on unseen tracks, theme {theme} ({seen}):")
        say(format_table(pair["pilot"]))
        e = pair["expert"]["overall"]
        say(f"the expert on the same tracks, for comparison: autonomy {e['autonomy']:.1f} %, "
            f"{e['laps_completed']} laps, {e['interventions']} interventions, mean |cte| {e['mean_abs_cte']:.3f} m "
            f"({describe(pair['expert'])[len('conditions: '):]})")
    if by_draw is not None:
        from vehicle.app.eval_draws import format_draws_table

        say("\ntrained pilot on unseen tracks under hidden randomisation draws (robustness):")
        say(format_draws_table(by_draw))

def write_summary(result: dict[str, Any], path: Path, total_s: float) -> Path:
    """Write ``run_demo``'s result as JSON, atomically (``vehicle sim robustness`` takes a run whose
    file exists as finished): everything but the per-track reports, of which each theme keeps the
    pilot's and the expert's ``overall``, and of the draws report its ``by_theme``."""
    import json

    from parts.tub.format import atomic_write

    summary = {k: v for k, v in result.items() if k not in ("reports", "draws", "model")}
    summary.update(model=str(result["model"]), total_seconds=round(total_s, 1),
                   overall={theme: {who: r["overall"] for who, r in pair.items()}
                            for theme, pair in result["reports"].items()})
    if "draws" in result:
        summary["by_theme"] = result["draws"]["by_theme"]
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json.dumps(summary, indent=1, default=str) + "\n")
    return path


def train_or_stop(cfg: Any, tubs: list[Path], model_path: Path, *, ends: str = "the demo ends here",
                  **options: Any) -> dict[str, Any]:
    """``training.trainer.train`` as ``manage.py train`` runs it: the first Ctrl-C ends the
    training after the current step and keeps the best model so far with its metrics, loss plot
    and database entry; the caller then says what it kept and what ``ends`` (KeyboardInterrupt:
    exit 130)."""
    from training.trainer import train
    from vehicle.app.interrupt import ctrl_c_stops_training

    with ctrl_c_stops_training() as interrupted:
        try:
            metrics = train(cfg, tubs, model_path, should_stop=interrupted.is_set if interrupted else None,
                            **options)
        except ValueError as exc:
            if interrupted is not None and interrupted.is_set() and "cancelled" in str(exc):
                say("stopped by Ctrl-C before the first epoch ended: no model was saved")
                raise KeyboardInterrupt from None
            raise
    if metrics.get("cancelled"):
        from training.train_report import train_summary

        say(f"{train_summary(metrics, model_path)}, with its loss plot and database entry; {ends}")
        raise KeyboardInterrupt
    return metrics


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its children that have ended."""
    import resource

    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def torch_threads(requested: int | None) -> tuple[int, str]:
    """Torch threads for the demo's training and why: ``requested`` when given; otherwise every
    core, or one when the machine is already busy (load average at least the cores less one).

    On a busy machine a multi-threaded step waits at every parallel operation for a thread that
    another process has descheduled: measured on 2 cores next to other jobs, 2 threads trained at
    0.25x the speed of one (docs/benchmarks.md, "training"); one thread is then the robust choice.
    """
    import os

    cores = os.cpu_count() or 1
    if requested is not None:
        return requested, "--threads"
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    if cores > 1 and load >= cores - 1:
        return 1, f"the machine is busy (load average {load:.1f} on {cores} cores)"
    return cores, f"one per core (load average {load:.1f})"


def write_myconfig(out: Path, settings: dict[str, Any], source: str) -> None:
    """Make ``out`` a car folder with the demo's settings (kept if it already has a myconfig.py),
    so ``vehicle models --car``, ``vehicle sim eval`` and ``manage.py`` there use them too."""
    path = out / "myconfig.py"
    if path.exists():
        return
    out.mkdir(parents=True, exist_ok=True)
    lines = [f'"""Settings of the `{source}` car (written by the demo)."""', ""]
    lines += [f"{name} = {value!r}" for name, value in settings.items()]
    path.write_text("\n".join(lines) + "\n")


def export_onnx(model_path: Path) -> Path | None:
    """Export to ONNX next to the model when onnx and onnxruntime are installed (the pilot then
    runs the export); says what it did. Returns the export, or None."""
    from parts.pilots.backends import onnxruntime_available

    try:
        import onnx  # noqa: F401
        have_onnx = onnxruntime_available()
    except ImportError:
        have_onnx = False
    if not have_onnx:
        say("[3/4] onnx/onnxruntime not installed: the pilot runs in PyTorch")
        return None
    from training.export import export_model

    path = export_model(model_path, "onnx")
    say(f"[3/4] exporting to ONNX: {path}")
    return path
