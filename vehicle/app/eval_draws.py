"""Evaluation over hidden randomisation draws: how robust a pilot is, as a number.

One draw is one randomisation seed (SIM_RANDOMIZE): light, shadows, colours, camera, sensor,
latency and distractors of every track (:mod:`parts.sim.randomize`). A pilot that drives well in
the draw it was trained on may still fail in another; ``vehicle sim eval --draws N`` therefore
drives the same unseen tracks in each theme under N draws the pilot never saw and reports, per
theme, the **mean** over the draws and the **worst draw** (the one with the lowest score, autonomy
times the share of the asked laps driven, so a draw where the car stood still is the worst; ties:
more interventions, then fewer laps, then larger mean |CTE|), beside the expert's speed on the same
tracks and draws (the pilot's speed as a share of it).

The hidden draws are the seeds ``HIDDEN_DRAW_BASE + 1 .. HIDDEN_DRAW_BASE + N``, far from the
small seeds recordings use (the demo trains with draw 1; DAgger roll-outs use
:data:`vehicle.app.dagger.ROLLOUT_DRAW_BASE` + round), so the same N always means the same draws
and a report is reproducible.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

#: hidden draws are the randomisation seeds HIDDEN_DRAW_BASE + 1, + 2, ...
HIDDEN_DRAW_BASE = 1000
#: per-draw figures summarised over the draws: (key of a report's "overall", worse when larger)
SUMMARY_KEYS: dict[str, bool] = {"autonomy": False, "interventions": True, "laps_completed": False,
                                 "mean_abs_cte": True, "mean_speed": False, "off_track_per_lap": True,
                                 # the share of the asked laps driven and autonomy times it (rank_key):
                                 # a car that stood still has 100 % autonomy and completion 0
                                 "completion": False, "score": False}


def hidden_draws(n: int, training_draw: int | None = None) -> list[int]:
    """The ``n`` hidden randomisation seeds; ValueError when ``n`` < 1 or the training draw is one."""
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ValueError(f"draws must be an int >= 1, got {n!r}")
    draws = [HIDDEN_DRAW_BASE + k for k in range(1, n + 1)]
    if training_draw in draws:
        raise ValueError(f"randomisation seed {training_draw} (SIM_RANDOMIZE) is one of the hidden draws "
                         f"{draws[0]}..{draws[-1]}: train with a seed below {HIDDEN_DRAW_BASE}")
    return draws


def worst_index(overalls: Sequence[dict[str, Any]]) -> int:
    """Index of the worst draw: lowest score (autonomy times the share of the laps driven, see
    :func:`parts.sim.metrics.rank_key`), then most interventions, then fewest laps, then largest
    mean |CTE|."""
    from parts.sim.metrics import rank_key

    def badness(o: dict[str, Any]) -> tuple[float, ...]:
        score, *rest = rank_key(o)
        return (score, o.get("interventions") or 0, *rest)

    return max(range(len(overalls)), key=lambda i: badness(overalls[i]))


def summarise(overalls: Sequence[dict[str, Any]], draws: Sequence[int],
              expert: Sequence[dict[str, Any]] | None = None) -> dict[str, Any]:
    """Mean over the draws and the worst draw of the :data:`SUMMARY_KEYS` of each draw's overall,
    with the expert's mean speed and the pilot's share of it (percent) when ``expert`` is given."""
    if not overalls or len(overalls) != len(draws):
        raise ValueError("summarise needs one overall result per draw")

    def mean(key: str, rows: Sequence[dict[str, Any]]) -> float | None:
        values = [r[key] for r in rows if r.get(key) is not None]
        return round(float(np.mean(values)), 4) if values else None

    w = worst_index(overalls)
    out: dict[str, Any] = {
        "draws": list(draws),
        "mean": {k: mean(k, overalls) for k in SUMMARY_KEYS},
        "worst": {"randomize": draws[w], **{k: overalls[w].get(k) for k in SUMMARY_KEYS}},
        # with commanded lane changes, each draw's lane metrics too (parts/sim/lane_metrics.py)
        "per_draw": [{"randomize": d, **{k: o.get(k) for k in SUMMARY_KEYS}, **({"lanes": o["lanes"]} if "lanes" in o
                                                                                else {})}
                     for d, o in zip(draws, overalls, strict=True)],
    }
    if expert is not None:
        speed = mean("mean_speed", expert)
        out["expert_speed"] = speed
        pilot = out["mean"]["mean_speed"]
        out["speed_vs_expert_pct"] = round(100.0 * pilot / speed, 1) if speed and pilot is not None else None
        out["expert_autonomy"] = mean("autonomy", expert)
    return out


def evaluate_draws(pilot: Any, seeds: Sequence[int], laps: int, *, cfg: Any, draws: Sequence[int],
                   themes: Sequence[str], expert: bool = True, workers: int = 1,
                   max_time: float | None = None, gallery: Any = None) -> dict[str, Any]:
    """Evaluate ``pilot`` on tracks ``seeds`` in each of ``themes`` under each randomisation seed of
    ``draws`` (:func:`vehicle.app.evaluate.evaluate` for every pair), and the expert too when
    ``expert``.

    Returns a report shaped like ``evaluate``'s (so ``--json`` and ``--store`` keep it as they keep
    one): ``tracks`` holds every episode (each with its ``theme`` and ``randomize``), ``overall``
    pools them all, and ``by_theme`` maps each theme to :func:`summarise`'s dict. With ``gallery``
    (a :class:`vehicle.app.failure_moments.GallerySpec`), one failure gallery per theme and draw in
    ``<folder>/<theme>-draw<N>/`` and a page linking them (the report's ``gallery``).
    """
    from parts.sim.metrics import overall
    from vehicle.app.evaluate import evaluate

    draws, themes = list(draws), list(themes)
    if not draws or not themes:
        raise ValueError("evaluate_draws needs at least one draw and one theme")
    if gallery is not None:
        from vehicle.app.gallery import check_new_folder

        check_new_folder(gallery.folder)
    galleries: list[dict[str, Any]] = []
    tracks: list[dict[str, Any]] = []
    by_theme: dict[str, Any] = {}
    name = None
    settings: dict[str, Any] = {}
    for theme in themes:
        pilot_overalls, expert_overalls = [], []
        for draw in draws:
            c = cfg.replace(SIM_THEME=theme, SIM_RANDOMIZE=draw)
            sub = gallery_name(theme, draw)
            report = evaluate(pilot, seeds, laps, cfg=c, workers=workers, max_time=max_time,
                              gallery=gallery.sub(sub) if gallery is not None else None)
            name, settings = report["pilot"], report["settings"]
            if gallery is not None:
                galleries.append({"name": sub, "folder": sub, "theme": theme, "randomize": draw,
                                  "label": f"theme {theme}, draw {draw}: {report['overall']['interventions']} "
                                           f"intervention(s)", "moments": _moments(report["gallery"])})
            for t in report["tracks"]:
                t["randomize"] = draw
            tracks += report["tracks"]
            pilot_overalls.append(report["overall"])
            if expert:
                expert_overalls.append(evaluate("expert", seeds, laps, cfg=c, workers=workers,
                                                max_time=max_time)["overall"])
            o = report["overall"]
            logger.info("draws: %s in %s under draw %d: autonomy %.1f %%, %d interventions", name, theme, draw,
                        o["autonomy"], o["interventions"])
        by_theme[theme] = summarise(pilot_overalls, draws, expert_overalls if expert else None)
    penalty = settings.get("penalty_s", cfg.SIM_INTERVENTION_PENALTY)
    extra: dict[str, Any] = {}
    lanes: dict[str, Any] = {}
    if tracks and all("lanes" in t for t in tracks):  # commanded lane changes: pooled like evaluate's
        from parts.sim.lane_metrics import overall_lane_metrics

        lanes["lanes"] = overall_lane_metrics([t["lanes"] for t in tracks])
    if gallery is not None:
        from vehicle.app.gallery import write_gallery_index

        settings = {**settings, "gallery": str(Path(gallery.folder).expanduser().resolve())}
        extra["gallery"] = str(write_gallery_index(gallery.folder, f"Failures of {name} under hidden draws",
                                                   galleries))
    return {**extra,
        "pilot": name, "simulator": "builtin", "laps": laps, "seeds": list(seeds), "draws": draws,
        "themes": themes,
        "conditions": {"themes": themes, "randomize": draws, "distractors": "randomised", "lanes": cfg.SIM_LANES,
                       "ranges": {k: list(v) for k, v in cfg.SIM_RANDOMIZE_RANGES.items()}},
        "settings": {**settings, "draws": draws, "themes": themes},
        "tracks": tracks,
        # pooled over every episode (the p95 |CTE| needs the frames, which are not kept: None)
        "overall": {**overall(tracks, penalty, np.empty(0)), "by_theme": by_theme, **lanes},
        "by_theme": by_theme,
    }


def gallery_name(theme: str, draw: int) -> str:
    """The sub-folder of the gallery of ``theme`` under hidden draw ``draw``."""
    return f"{theme}-draw{draw}"


def _moments(page: str) -> int:
    """Moments in the gallery whose page is ``page``."""
    import json

    data = json.loads((Path(page).parent / "gallery.json").read_text())
    return sum(len(t["moments"]) for t in data["tracks"])


def cell(value: Any, fmt: str) -> str:
    """``value`` formatted with ``fmt``, or "-" when it is unknown (None)."""
    return "-" if value is None else fmt.format(value)


def driven_pct(completion: float | None) -> float | None:
    """The share of the asked laps driven (``completion``, 0..1) in percent; None stays None."""
    return None if completion is None else 100.0 * completion


#: how the worst draw is picked (:func:`worst_index`), for the tables' footers
WORST_DRAW = "worst = the draw with the lowest score (autonomy x share of the laps driven)"


def format_draws_table(report: dict[str, Any]) -> str:
    """One row per theme: mean over the draws and the worst draw of the score, the share of the laps
    driven, autonomy, interventions, laps, mean |CTE| and speed, and the expert's speed (the pilot's
    as a share of it). The score comes first: autonomy alone reads 100 % for a car that stood still."""
    headers = ["theme", "score mean", "worst (draw)", "driven % mean", "worst", "autonomy % mean", "worst",
               "interv. mean", "worst", "laps mean", "worst", "|cte| m mean", "worst", "speed m/s mean", "worst",
               "expert m/s", "% of expert"]
    rows = []
    for theme, s in report["by_theme"].items():
        m, w = s["mean"], s["worst"]
        rows.append([theme, cell(m.get("score"), "{:.1f}"), f"{cell(w.get('score'), '{:.1f}')} ({w['randomize']})",
                     cell(driven_pct(m.get("completion")), "{:.0f}"), cell(driven_pct(w.get("completion")), "{:.0f}"),
                     cell(m["autonomy"], "{:.1f}"), cell(w["autonomy"], "{:.1f}"),
                     cell(m["interventions"], "{:.1f}"), cell(w["interventions"], "{:d}"),
                     cell(m["laps_completed"], "{:.1f}"), cell(w["laps_completed"], "{:d}"),
                     cell(m["mean_abs_cte"], "{:.3f}"), cell(w["mean_abs_cte"], "{:.3f}"),
                     cell(m["mean_speed"], "{:.2f}"), cell(w["mean_speed"], "{:.2f}"),
                     cell(s.get("expert_speed"), "{:.2f}"), cell(s.get("speed_vs_expert_pct"), "{:.0f}")])
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers))]
    lines = ["  ".join(h.rjust(wd) for h, wd in zip(headers, widths, strict=True)),
             "  ".join("-" * wd for wd in widths)]
    lines += ["  ".join(c.rjust(wd) for c, wd in zip(r, widths, strict=True)) for r in rows]
    draws = report["draws"]
    lines.append(f"pilot {report['pilot']}: tracks {','.join(map(str, report['seeds']))}, {report['laps']} lap(s) "
                 f"each, under {len(draws)} hidden randomisation draw(s) ({', '.join(map(str, draws))}) per theme; "
                 + WORST_DRAW)
    return "\n".join(lines)

