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
    ("interv.", "interventions", "{:d}"),
    ("off/lap", "off_track_per_lap", "{:.2f}"),
    ("mean|cte| m", "mean_abs_cte", "{:.3f}"),
    ("p95|cte| m", "p95_abs_cte", "{:.3f}"),
    ("lap s", "mean_lap_s", "{:.2f}"),
    ("speed m/s", "mean_speed", "{:.2f}"),
    ("steer/s", "steering_smoothness", "{:.2f}"),
)


def format_table(report: dict[str, Any]) -> str:
    """The report as a fixed-width text table: one row per track, then the overall row."""
    headers = ["track", *(c[0] for c in _COLUMNS)]
    rows = []
    for name, res in [(str(t["seed"]), t) for t in report["tracks"]] + [("all", report["overall"])]:
        row = [name]
        for _, key, fmt in _COLUMNS:
            v = res.get(key)
            row.append("-" if v is None else fmt.format(v))
        rows.append(row)
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers))]
    lines = ["  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
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
    return "\n".join(lines)


def write_json(report: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Write the report as indented JSON (parents created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=1) + "\n")
    return path


def track_image(seed: int, cfg: Any, size: int = 480, trajectory: Any = None,
                events: Any = None, title: str | None = None) -> np.ndarray:
    """A square RGB map of a track (its texture), with a driven trajectory and off-track marks."""
    from parts.sim.simulator import load_world, world_params

    track, texture = load_world(seed, **world_params(cfg))
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
        title = (f"track {t['seed']}: {t['autonomy']:.1f} % autonomy, {t['laps_completed']} laps, "
                 f"{t['interventions']} off")
        panels.append(track_image(t["seed"], cfg, panel, t.get("trajectory"), t.get("off_track_at"), title))
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
