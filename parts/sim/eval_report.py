"""Evaluation reports: a printed table, a JSON file and a PNG of the driven trajectories."""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

logger = logging.getLogger(__name__)

#: table columns: (header, report key, format)
_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("autonomy %", "autonomy", "{:.1f}"),
    ("laps", "laps_completed", "{:d}"),
    ("driven %", "completion", "{:.0%}"),  # of the laps asked: a car that stands still has no interventions
    ("interv.", "interventions", "{:d}"),
    ("off/lap", "off_track_per_lap", "{:.2f}"),
    ("mean|cte| m", "mean_abs_cte", "{:.3f}"),
    ("p95|cte| m", "p95_abs_cte", "{:.3f}"),
    ("lap s", "mean_lap_s", "{:.2f}"),
    ("speed m/s", "mean_speed", "{:.2f}"),
    ("steer/s", "steering_smoothness", "{:.2f}"),
)


#: a path follower's column: its true distance to the path it recorded
_PATH = ("path|d| m", "mean_path_distance", "{:.3f}")

#: the theme column of built-in simulator reports
_THEME = ("theme", "theme", "{}")
#: lane table columns (commanded lane changes): (header, key of the "lanes" section, format)
_LANE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("changes", "lane_changes", "{:d}"),
    ("ok", "lane_changes_ok", "{:d}"),
    ("success %", "lane_change_success_rate", "{:.0%}"),
    ("change s", "mean_time_to_change_s", "{:.2f}"),
    ("max s", "max_time_to_change_s", "{:.2f}"),
    ("lane|err| m", "lane_mean_abs_error", "{:.3f}"),
    ("max|err| m", "lane_max_abs_error", "{:.3f}"),
    ("wrong lane s", "wrong_lane_s", "{:.1f}"),
    ("off-track", "off_track_events", "{:d}"),
)


def _table(rows_in: list[tuple[str, dict[str, Any]]], columns: tuple[tuple[str, str, str], ...],
           first: str = "track") -> list[str]:
    headers = [first, *(c[0] for c in columns)]
    rows = []
    for name, res in rows_in:
        row = [name]
        for _, key, fmt in columns:
            v = res.get(key)
            row.append("-" if v is None else fmt.format(v))
        rows.append(row)
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers))]
    lines = ["  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return lines


def describe(report: dict[str, Any]) -> str:
    """One line naming the conditions of a built-in simulator evaluation: themes and randomisation."""
    cond = report.get("conditions")
    if not cond:
        return "conditions: not recorded"
    themes = ", ".join(dict.fromkeys(cond["themes"]))
    if cond["randomize"] is None:
        rand = "not randomised"
        if cond.get("distractors"):
            rand += f", {cond['distractors']} distractors per track"
    else:
        rand = f"randomised with seed {cond['randomize']}"
        if cond.get("ranges"):
            rand += " (ranges " + ", ".join(f"{k} {v[0]:g}..{v[1]:g}" for k, v in cond["ranges"].items()) + ")"
    lanes = " two-lane," if cond.get("lanes") == 2 else ""
    return f"conditions: theme {themes},{lanes} {rand}"


def format_table(report: dict[str, Any]) -> str:
    """The report as a fixed-width text table: the conditions (built-in simulator), one row per
    track, then the overall row; with commanded lane changes, a second table of the lane metrics."""
    tracks = [(str(t["seed"]), t) for t in report["tracks"]] + [("all", report["overall"])]
    themed = bool(report.get("conditions"))
    columns = (*_COLUMNS, _PATH) if report["overall"].get("mean_path_distance") is not None else _COLUMNS
    lines = ([describe(report)] if themed else []) + _table(tracks, (_THEME, *columns) if themed else columns)
    o = report["overall"]
    simulator = report.get("simulator", "builtin")
    success = "-" if o.get("success_rate") is None else f"{o['success_rate'] * 100:.0f} %"
    clock = "simulated" if simulator == "builtin" or report.get("settings", {}).get("synchronous") else "driven"
    lines.append(f"pilot {report['pilot']}: {report['laps']} lap(s) per track, success rate "
                 f"{success}, {o['elapsed_s']:.1f} s {clock}" + ("" if simulator == "builtin" else f" ({simulator})"))
    missing = o.get("unavailable") or {}
    if missing:
        headers = {key: header for header, key, _ in _COLUMNS}
        parts = []
        for what in missing.values():
            shown = [headers[m] for m in what["metrics"] if m in headers]
            parts.append(what["signal"] + (f" ({', '.join(shown)})" if shown else ""))
        lines.append(f"not available: the {simulator} simulator reports no " + "; no ".join(parts)
                     + ": '-' above means unknown, not zero")
    if "lanes" in o:
        lines.append("")
        lines += _table([(name, res["lanes"]) for name, res in tracks], _LANE_COLUMNS)
        lanes = o["lanes"]
        rate = lanes["lane_change_success_rate"]
        lines.append(f"commanded lane changes: {lanes['lane_changes_ok']} of {lanes['lane_changes']} done "
                     f"({'-' if rate is None else f'{rate:.0%}'}), lane error and wrong-lane time measured between "
                     f"changes, {o['interventions']} off-track")
        lines += failed_change_lines(report["tracks"])
    return "\n".join(lines)


def failed_change_lines(tracks: list[dict[str, Any]]) -> list[str]:
    """One line per failed commanded lane change: where it was given and why it failed."""
    from parts.sim.lane_metrics import describe_command

    lines = [f"  track {t['seed']}: change {describe_command(c)}" for t in tracks
             for c in (t.get("lanes") or {}).get("commands", []) if c["success"] is False]
    return ["failed lane changes:", *lines] if lines else []


def format_comparison(reports: list[dict[str, Any]]) -> str:
    """Several drivers on the same tracks (learned pilots, path followers), one overall row each."""
    rows = [(str(r["pilot"]), r["overall"]) for r in reports]
    lines = _table(rows, (*_COLUMNS, _PATH), first="driver")
    seeds = ",".join(str(s) for s in reports[0]["seeds"]) if reports else ""
    lines.append(f"tracks {seeds}, {reports[0]['laps'] if reports else 0} lap(s) each; path|d|: a path follower's "
                 "true distance to its recorded path")
    return "\n".join(lines)


def write_json(report: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Write the report as indented JSON (parents created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=1) + "\n")
    return path


def track_image(seed: int, cfg: Any, size: int = 480, trajectory: Any = None,
                events: Any = None, title: str | None = None, commands: Any = None,
                theme: str | None = None) -> np.ndarray:
    """A square RGB map of a track (its texture in ``theme``, default the first of SIM_THEME), with
    a driven trajectory, off-track marks and, for lane changes, where each change was commanded (a
    triangle and L/R; green if it was done, red if not, grey if the episode ended first)."""
    from parts.sim.themes import theme_list
    from parts.sim.world import load_world, world_params

    world = load_world(seed, theme=theme or theme_list(cfg.SIM_THEME)[0], **world_params(cfg))
    track, texture = world.track, world.texture
    img = texture.image
    h, w = img.shape[:2]
    scale = size / max(h, w)
    small = cv2.resize(img, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    canvas = np.empty((size, size, 3), np.uint8)
    canvas[:] = img.reshape(-1, 3)[:: max(1, h * w // 4096)].mean(axis=0)  # the texture's mean colour
    oy, ox = (size - small.shape[0]) // 2, (size - small.shape[1]) // 2
    canvas[oy:oy + small.shape[0], ox:ox + small.shape[1]] = small

    def to_px(xy: Any) -> np.ndarray:
        pts = texture.to_pixels(np.asarray(xy, float)) * scale + np.array([ox, oy])
        return np.round(pts * 16).astype(np.int32)

    x, y, hd = track.pose_at(0.0)
    start = to_px([[x - 0.4 * math.sin(hd), y + 0.4 * math.cos(hd)], [x + 0.4 * math.sin(hd), y - 0.4 * math.cos(hd)]])
    cv2.line(canvas, tuple(start[0]), tuple(start[1]), (255, 255, 255), 3, cv2.LINE_AA, 4)
    if trajectory is not None and len(trajectory) > 1:
        cv2.polylines(canvas, [to_px(trajectory).reshape(-1, 1, 2)], False, (0, 200, 255), 2, cv2.LINE_AA, 4)
    for p in events if events is not None else []:
        c = to_px([p])[0]
        cv2.circle(canvas, (int(c[0]), int(c[1])), 6 * 16, (255, 40, 40), 2, cv2.LINE_AA, 4)
    for cmd in commands if commands is not None else []:
        if cmd.get("pos") is None or None in cmd["pos"]:
            continue
        u, v = (to_px([cmd["pos"]])[0] / 16).astype(int)
        colour = {True: (40, 220, 40), False: (255, 40, 40)}.get(cmd.get("success"), (200, 200, 200))
        tri = np.array([[u, v - 7], [u - 6, v + 5], [u + 6, v + 5]], np.int32)
        cv2.fillPoly(canvas, [tri], colour, cv2.LINE_AA)
        cv2.polylines(canvas, [tri], True, (0, 0, 0), 1, cv2.LINE_AA)
        letter = (cmd.get("lane") or "?")[:1].upper()
        cv2.putText(canvas, letter, (u + 7, v + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(canvas, letter, (u + 7, v + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    label = title if title is not None else f"track {seed}"
    cv2.rectangle(canvas, (0, 0), (size, 24), (0, 0, 0), -1)
    cv2.putText(canvas, label, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return canvas


def write_png(report: dict[str, Any], path: str | os.PathLike[str], cfg: Any = None, panel: int = 480) -> Path:
    """Write a PNG with one panel per track: the map, the driven path, where it left the road."""
    if cfg is None:
        from vehicle.config import Config

        cfg = Config.defaults()
    panels = []
    for t in report["tracks"]:
        title = (f"track {t['seed']} ({t.get('theme', 'road')}): {t['autonomy']:.1f} % autonomy, "
                 f"{t['laps_completed']} laps, {t['interventions']} off")
        lanes = t.get("lanes")
        if lanes is not None:
            title += f", lane changes {lanes['lane_changes_ok']}/{lanes['lane_changes']}"
        panels.append(track_image(t["seed"], cfg, panel, t.get("trajectory"), t.get("off_track_at"), title,
                                  lanes["commands"] if lanes is not None else None, theme=t.get("theme")))
    return write_panels(panels, path)


def write_panels(panels: list[np.ndarray], path: str | os.PathLike[str], cols: int = 3) -> Path:
    """Tile RGB panels of equal size into a grid and write it as PNG; returns the path."""
    if not panels:
        raise ValueError("nothing to draw: the report has no tracks")
    cols = min(cols, len(panels))
    rows = math.ceil(len(panels) / cols)
    ph, pw = panels[0].shape[:2]
    grid = np.zeros((rows * ph, cols * pw, 3), np.uint8)
    for i, p in enumerate(panels):
        r, c = divmod(i, cols)
        grid[r * ph:(r + 1) * ph, c * pw:(c + 1) * pw] = p
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(grid, cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {path}: use a .png file name in a writable folder")
    return path
