"""The lanes models under the robustness protocol (``vehicle sim robustness --lanes``).

Each run is ``vehicle demo --lanes --seed N --precision P --draws D``: it trains the two-stream
``lanes`` model and the single-stream ``behavior`` model, drives both with commanded lane changes on
unseen two-lane tracks in its own look and under D hidden randomisation draws per trained theme,
and keeps a summary (:func:`write_lanes_summary`, ``eval/result.json``). The protocol then reports
per model and theme, over every run and draw: the change success rate (mean, worst draw, worst
seed), the time to change, the wrong-lane time, the off-track events, and where each failed change
was commanded (curvature ahead, start lane, whether the expert would have waited; its frames are in
the run's failure gallery).
"""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

#: failed changes listed in robustness.md (all of them are in robustness.json)
LISTED_FAILURES = 20


def lane_draws(models: dict[str, Path], eval_tracks: list[int], laps: int, cfg: Any, draws: int,
               galleries: Path) -> dict[str, dict[str, Any]]:
    """Each model (type -> file) driven with commanded lane changes under ``draws`` hidden draws in
    every theme of SIM_THEME (:func:`vehicle.app.eval_draws.evaluate_draws`), its interventions and
    failed changes in a gallery per theme and draw (``galleries/<type>/<theme>-draw<N>/``, replaced)."""
    from parts.sim.themes import theme_list
    from vehicle.app.eval_draws import evaluate_draws, hidden_draws
    from vehicle.app.failure_moments import GallerySpec

    shutil.rmtree(galleries, ignore_errors=True)  # the demo's own folder: a rerun replaces its galleries
    seeds = hidden_draws(draws, cfg.SIM_RANDOMIZE)
    reports = {}
    for model_type, path in models.items():
        # no worst-|CTE| moments: on two lanes the CTE to the road's centre line says nothing
        spec = GallerySpec(str(galleries / model_type), str(path), worst=0)
        reports[model_type] = evaluate_draws(path, eval_tracks, laps, cfg=cfg, draws=seeds,
                                             themes=theme_list(cfg.SIM_THEME), expert=False,
                                             workers=cfg.SIM_EVAL_WORKERS, gallery=spec)
    return reports


def failed_changes(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The failed commands of an evaluation (or of one over draws), each with its track, theme and draw."""
    return [{"track": t["seed"], "theme": t.get("theme"), "randomize": t.get("randomize"), **c}
            for t in report["tracks"] for c in (t.get("lanes") or {}).get("commands", []) if c["success"] is False]


def lane_figures(overall: dict[str, Any]) -> dict[str, Any]:
    """What the protocol reports of an evaluation's overall: its lane metrics and interventions."""
    lanes = overall["lanes"]
    return {k: lanes.get(k) for k in ("lane_changes", "lane_changes_ok", "lane_change_success_rate",
                                      "mean_time_to_change_s", "max_time_to_change_s", "wrong_lane_s",
                                      "off_track_events")} | {"interventions": overall.get("interventions")}


def write_lanes_summary(result: dict[str, Any], path: Path, total_s: float) -> Path:
    """Write :func:`vehicle.app.demo_lanes.run_lanes_demo`'s result as JSON, atomically (the protocol
    takes a run whose file exists as finished): per model its training metrics, its figures in the
    demo's own look (``plain``) and, per theme, each hidden draw's, and every failed change."""
    from parts.tub.format import atomic_write

    by_draw = result.get("draws") or {}
    models = {}
    for model_type in result["models"]:
        plain = result["reports"][f"{model_type} model"]
        draws = by_draw.get(model_type)
        m = result["metrics"][model_type]
        models[model_type] = {
            "metrics": {k: m.get(k) for k in ("best_val_loss", "best_epoch", "epochs")},
            "plain": lane_figures(plain["overall"]),
            "by_theme": draws["by_theme"] if draws else {},
            "failed_changes": failed_changes(plain) + (failed_changes(draws) if draws else []),
        }
    first = next(iter(by_draw.values()), None)
    summary = {k: result[k] for k in ("seed", "precision", "train_seed", "sim_seed", "eval_tracks", "laps")}
    summary.update(demo="lanes", seconds={k: round(v, 1) for k, v in result["seconds"].items()},
                   total_seconds=round(total_s, 1), draws=first["draws"] if first else [],
                   themes=first["themes"] if first else [], models=models,
                   expert={"plain": lane_figures(result["reports"]["expert"]["overall"])})
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json.dumps(summary, indent=1, default=str) + "\n")
    return path


# -- the protocol's report ---------------------------------------------------------------------------
def _draw_badness(row: dict[str, Any]) -> tuple[float, ...]:
    """Larger is worse: lower success (a draw with no judged change is worst), more off-track events,
    more wrong-lane time, slower changes."""
    rate = row.get("lane_change_success_rate")
    return (-(rate if rate is not None else -1.0), row.get("off_track_events") or 0,
            row.get("wrong_lane_s") or 0.0, row.get("max_time_to_change_s") or 0.0)


def _mean(values: list[Any], nd: int = 3) -> float | None:
    values = [v for v in values if v is not None]
    return round(float(np.mean(values)), nd) if values else None


def _rate(ok: int, n: int) -> float | None:
    return round(ok / n, 3) if n else None


def model_theme_summary(results: list[dict[str, Any]], model: str, theme: str) -> dict[str, Any]:
    """One model in one theme over every run and hidden draw (see the module docstring)."""
    rows, per_run = [], []
    for r in results:
        draws = r["models"][model]["by_theme"].get(theme, {}).get("per_draw", [])
        mine = [{**d["lanes"], "interventions": d.get("interventions"), "randomize": d["randomize"],
                 "run": r["name"], "seed": r["seed"], "precision": r["precision"]} for d in draws]
        rows += mine
        ok, n = sum(d["lane_changes_ok"] for d in mine), sum(d["lane_changes"] for d in mine)
        per_run.append({"seed": r["seed"], "precision": r["precision"], "run": r["name"], "lane_change_success_rate":
                        _rate(ok, n), "off_track_events": sum(d["off_track_events"] for d in mine)})
    if not rows:
        raise ValueError(f"no run drove the {model} model under hidden draws in the {theme} theme")
    worst = max(rows, key=_draw_badness)
    worst_seed = max(per_run, key=_draw_badness)
    failed = [f for r in results for f in r["models"][model]["failed_changes"]
              if f.get("theme") == theme and f.get("randomize") is not None]
    return {
        "runs": len(per_run), "draws": len(rows),
        "lane_changes": sum(d["lane_changes"] for d in rows),
        "lane_changes_ok": sum(d["lane_changes_ok"] for d in rows),
        "success_rate_mean": _mean([d["lane_change_success_rate"] for d in rows]),
        "worst_draw": {k: worst.get(k) for k in ("run", "seed", "precision", "randomize", "lane_change_success_rate",
                                                 "lane_changes", "lane_changes_ok", "off_track_events",
                                                 "wrong_lane_s")},
        "worst_seed": worst_seed,
        "time_to_change_s": {"mean": _mean([d["mean_time_to_change_s"] for d in rows]),
                             "max": max((d["max_time_to_change_s"] for d in rows
                                         if d["max_time_to_change_s"] is not None), default=None)},
        "wrong_lane_s": {"mean_per_draw": _mean([d["wrong_lane_s"] for d in rows]),
                         "max_per_draw": max(d["wrong_lane_s"] for d in rows)},
        "off_track_events": {"total": sum(d["off_track_events"] for d in rows),
                             "max_per_draw": max(d["off_track_events"] for d in rows)},
        "failed_changes": {"total": len(failed), "expert_would_wait": sum(bool(f.get("expert_would_wait"))
                                                                          for f in failed),
                           "off_road": sum(f.get("failure") == "off_road" for f in failed)},
    }


def aggregate_lanes(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Per model: its figures in the demo's own look over the runs, and :func:`model_theme_summary`
    per theme; per run and model one row; every failed change. ValueError without a finished run."""
    if not results:
        raise ValueError("no finished run to aggregate")
    models = list(results[0]["models"])
    themes = list(dict.fromkeys(t for r in results for t in r["themes"]))
    report: dict[str, Any] = {"models": {}, "themes": themes, "runs": [], "failed_changes": []}
    for m in models:
        plain = [r["models"][m]["plain"] for r in results]
        report["models"][m] = {
            "plain": {"lane_changes": sum(p["lane_changes"] for p in plain),
                      "lane_changes_ok": sum(p["lane_changes_ok"] for p in plain),
                      "off_track_events": sum(p["off_track_events"] for p in plain),
                      # the thesis's claim in one run: every change done, never off the road
                      "runs_meeting_claim": sum(p["lane_changes"] > 0 and p["lane_changes_ok"] == p["lane_changes"]
                                                and p["off_track_events"] == 0 for p in plain)},
            "themes": {t: model_theme_summary(results, m, t) for t in themes}}
        for r in results:
            report["runs"].append({"name": r["name"], "seed": r["seed"], "precision": r["precision"], "model": m,
                                   "best_val_loss": r["models"][m]["metrics"].get("best_val_loss"),
                                   "plain": r["models"][m]["plain"], "seconds": r.get("seconds", {}),
                                   "total_seconds": r.get("total_seconds")})
            report["failed_changes"] += [{"run": r["name"], "model": m, **f} for f in r["models"][m]["failed_changes"]]
    return report


def link_lane_galleries(report: dict[str, Any], out: Path) -> None:
    """Give each model and theme's worst draw the path (relative to ``out``) of its failure gallery
    (``runs/<run>/eval/gallery/<model>/<theme>-draw<N>/index.html``), where it exists."""
    from vehicle.app.eval_draws import gallery_name

    for m, s in report["models"].items():
        for theme, t in s["themes"].items():
            w = t["worst_draw"]
            page = Path("runs", str(w["run"]), "eval", "gallery", m, gallery_name(theme, w["randomize"]), "index.html")
            w["gallery"] = page.as_posix() if (out / page).is_file() else None


def _f(value: Any, fmt: str = "{:.1f}") -> str:
    return "-" if value is None else fmt.format(value)


def _pct(rate: float | None) -> str:
    return "-" if rate is None else f"{100 * rate:.0f}"


def lanes_tables(report: dict[str, Any]) -> list[str]:
    """robustness.md's tables: per model and theme under the hidden draws, per model in the demo's
    own look, the failed changes, the galleries and per run (the columns are explained in docs/vision.md)."""
    lines = ["| model | theme | runs x draws | changes ok | success % mean | worst draw: success %, off-track "
             "(seed, precision, draw) | worst seed: success % | time to change s mean / max | wrong lane s per draw "
             "mean / max | off-track events total / worst draw | failed: expert would wait / off road |",
             "|---" * 11 + "|"]
    for m, s in report["models"].items():
        for theme, t in s["themes"].items():
            w, ws, f = t["worst_draw"], t["worst_seed"], t["failed_changes"]
            lines.append(
                f"| {m} | {theme} | {t['runs']} x {t['draws'] // max(1, t['runs'])} | "
                f"{t['lane_changes_ok']}/{t['lane_changes']} | {_pct(t['success_rate_mean'])} | "
                f"{_pct(w['lane_change_success_rate'])}, {w['off_track_events']} (s{w['seed']}, {w['precision']}, "
                f"{w['randomize']}) | {_pct(ws['lane_change_success_rate'])} (s{ws['seed']}, {ws['precision']}) | "
                f"{_f(t['time_to_change_s']['mean'], '{:.2f}')} / {_f(t['time_to_change_s']['max'], '{:.2f}')} | "
                f"{_f(t['wrong_lane_s']['mean_per_draw'])} / {_f(t['wrong_lane_s']['max_per_draw'])} | "
                f"{t['off_track_events']['total']} / {t['off_track_events']['max_per_draw']} | "
                f"{f['expert_would_wait']} of {f['total']} / {f['off_road']} of {f['total']} |")
    lines += ["", "In the demo's own look (no randomisation), as `vehicle demo --lanes` reports it:", "",
              "| model | changes ok | off-track events | runs meeting the claim (every change, never off the road) |",
              "|---|---|---|---|"]
    runs = len({r["name"] for r in report["runs"]})
    for m, s in report["models"].items():
        p = s["plain"]
        lines.append(f"| {m} | {p['lane_changes_ok']}/{p['lane_changes']} | {p['off_track_events']} | "
                     f"{p['runs_meeting_claim']} of {runs} |")
    return [*lines, "", *failure_lines(report), *lane_gallery_lines(report), *lane_run_table(report)]


def failure_lines(report: dict[str, Any]) -> list[str]:
    """The failed changes, where each was commanded (the first :data:`LISTED_FAILURES`)."""
    from parts.sim.lane_metrics import describe_command

    failed = report["failed_changes"]
    if not failed:
        return ["No commanded change failed.", ""]
    lines = ["Failed changes (draw none: the demo's own look):", ""]
    for f in failed[:LISTED_FAILURES]:
        draw = "none" if f["randomize"] is None else f["randomize"]
        lines.append(f"- {f['run']} {f['model']}, {f['theme']} draw {draw}, track {f['track']}: {describe_command(f)}")
    if len(failed) > LISTED_FAILURES:
        lines.append(f"- and {len(failed) - LISTED_FAILURES} more (robustness.json)")
    return [*lines, ""]


def lane_gallery_lines(report: dict[str, Any]) -> list[str]:
    """Markdown links to the worst draws' failure galleries."""
    links = [f"- {m}, {theme}: [{t['worst_draw']['run']}, draw {t['worst_draw']['randomize']}]"
             f"({t['worst_draw']['gallery']})" for m, s in report["models"].items()
             for theme, t in s["themes"].items() if t["worst_draw"].get("gallery")]
    return ["Failure galleries of the worst draws (the frames of each failed change and intervention):", "",
            *links, ""] if links else []


def lane_run_table(report: dict[str, Any]) -> list[str]:
    """One row per run and model: best validation loss, the demo's own look, the step times."""
    lines = ["| run | seed | precision | model | best val loss | own look: changes ok, off-track | "
             "record s | train s | evaluate s |", "|---" * 9 + "|"]
    for r in report["runs"]:
        sec, p, train = r["seconds"], r["plain"], f"train {r['model']}"
        lines.append(f"| {r['name']} | {r['seed']} | {r['precision']} | {r['model']} | "
                     f"{_f(r['best_val_loss'], '{:.5f}')} | {p['lane_changes_ok']}/{p['lane_changes']}, "
                     f"{p['off_track_events']} | {_f(sec.get('record'), '{:.0f}')} | "
                     f"{_f(sec.get(train), '{:.0f}')} | {_f(sec.get('evaluate'), '{:.0f}')} |")
    return [*lines, ""]
