"""A pilot's failures as a gallery: the frames before each intervention and worst-|CTE| moment.

``vehicle sim eval --pilot M --gallery DIR`` writes, per track, the frames of the seconds before
each moment (:mod:`vehicle.app.failure_moments`) with the pilot's and the expert's steering and the
saliency of the pilot's steering laid over them (:mod:`parts.pilots.saliency`), as

    DIR/index.html      a static page (thumbnails, no script, no server: opens in any browser)
    DIR/gallery.json    the same as data: tracks, moments, frames, image paths relative to DIR
    DIR/track-<seed>/   m<k>-f<i>.jpg (the frame), m<k>-f<i>-<stream>.jpg (its saliency)

With ``--draws``, one such gallery per theme and draw (``DIR/<theme>-draw<N>/``) and an index of them.
"""

from __future__ import annotations

import functools
import html
import json
import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vehicle.app.failure_moments import GallerySpec, Moment

logger = logging.getLogger(__name__)

GALLERY_JSON = "gallery.json"
GALLERY_HTML = "index.html"
#: JPEG quality of the gallery's pictures (small files, faithful enough at 160x120)
JPEG_QUALITY = 90


def check_new_folder(folder: str | Path) -> Path:
    """The gallery's folder, which must not exist yet (a gallery never overwrites anything)."""
    path = Path(folder).expanduser()
    if path.exists():
        raise ValueError(f"gallery folder {path} exists: give a new folder (a gallery never overwrites one)")
    return path


@functools.lru_cache(maxsize=2)
def _explainer(model: str) -> Any:
    """One explainer per model file and process (evaluation workers reuse it across tracks)."""
    from parts.pilots.saliency import Explainer

    return Explainer.from_file(model)


def _frames_for(explainer: Any, steps: Sequence[Any], i: int) -> tuple[list[np.ndarray], list[float] | None]:
    """The model's frames and extra input at step ``i`` of a moment, as the pilot had them."""
    model = explainer.model
    step = steps[i]
    if model.views > 1:
        frames = [step.inputs[key] for key in model.image_inputs]
    else:
        first = max(0, i - model.frames + 1)
        frames = [s.inputs["cam/image_array"] for s in steps[first:i + 1]]
        frames = [frames[0]] * (model.frames - len(frames)) + frames
    extra = None
    if model.command_history:  # the pilot's own previous commands, zeros before the window
        previous = [s.pilot for s in steps[max(0, i - model.command_history):i]]
        previous = [(0.0, 0.0)] * (model.command_history - len(previous)) + previous
        extra = [v for pair in previous for v in pair]
    elif model.extra_inputs:
        value = step.inputs.get(model.extra_inputs[0])
        extra = list(value) if value is not None else None
    return frames, extra


def _jpeg(path: Path, rgb: np.ndarray) -> None:
    import cv2

    if not cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]):
        raise OSError(f"cannot write {path}")


def _r(x: float | None, nd: int = 3) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def render_track(moments: Sequence[Moment], spec: GallerySpec, track: dict[str, Any]) -> dict[str, Any]:
    """Write the pictures of one track's moments under ``spec.folder``; returns its JSON entry.

    ``track`` is the track's result (seed, theme, conditions, randomize)."""
    folder = Path(spec.folder)
    sub = f"track-{track.get('seed')}"
    (folder / sub).mkdir(parents=True, exist_ok=True)
    explainer = _explainer(spec.model)
    entries = []
    for k, moment in enumerate(moments, 1):
        steps = moment.steps
        picks = {round(j * (len(steps) - 1) / max(1, spec.frames - 1)) for j in range(spec.frames)}
        if moment.command_time_s is not None:  # a failed change: its command's frame too
            picks |= {i for i, st in enumerate(steps) if abs(st.time_s - moment.command_time_s) < 1e-6}
        picks = sorted(picks)
        frames = []
        for i in picks:
            step = steps[i]
            model_frames, extra = _frames_for(explainer, steps, i)
            sal = explainer.explain(model_frames, extra, method=spec.method)
            name = f"{sub}/m{k:02d}-f{i:03d}"
            camera = step.inputs["cam/image_array"]
            _jpeg(folder / f"{name}.jpg", camera)
            saliency = {}
            for stream, picture in explainer.overlays(model_frames, sal).items():
                label = stream.replace("/", "_")
                _jpeg(folder / f"{name}-{label}.jpg", picture)
                saliency[stream] = f"{name}-{label}.jpg"
            frames.append({"t": _r(step.time_s - moment.time_s, 2), "time_s": _r(step.time_s, 2),
                           "image": f"{name}.jpg", "saliency": saliency,
                           "pilot": {"angle": _r(step.pilot[0]), "throttle": _r(step.pilot[1])},
                           "expert": {"angle": _r(step.expert)}, "cte": _r(step.cte)})
        entry = {"kind": moment.kind, "number": k, "time_s": _r(moment.time_s, 2), "cte": _r(moment.cte),
                 "pos": moment.pos, "frames": frames}
        if moment.command_time_s is not None:
            entry.update(command_time_s=_r(moment.command_time_s, 2), command=moment.command)
        entries.append(entry)
    return {"seed": track.get("seed"), "theme": track.get("theme"), "randomize": track.get("randomize"),
            "conditions": track.get("conditions"), "interventions": track.get("interventions"),
            "folder": sub, "moments": entries}


def write_gallery(spec: GallerySpec, report: dict[str, Any], tracks: Sequence[dict[str, Any]]) -> Path:
    """``gallery.json`` and ``index.html`` of one evaluation; returns the page."""
    folder = Path(spec.folder)
    folder.mkdir(parents=True, exist_ok=True)
    draw = (report.get("conditions") or {}).get("randomize")
    data = {"pilot": report.get("pilot"), "model": spec.model, "method": spec.method, "window_s": spec.window_s,
            "laps": report.get("laps"), "randomize": draw,
            "themes": (report.get("conditions") or {}).get("themes"), "tracks": list(tracks)}
    (folder / GALLERY_JSON).write_text(json.dumps(data, indent=1, default=str) + "\n")
    page = folder / GALLERY_HTML
    page.write_text(gallery_html(data))
    return page


def write_gallery_index(folder: str | Path, title: str, galleries: Sequence[dict[str, Any]]) -> Path:
    """A page linking several galleries: ``galleries`` = [{"name", "folder", "label", "moments"}]."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / GALLERY_JSON).write_text(json.dumps({"title": title, "galleries": list(galleries)}, indent=1) + "\n")
    rows = "".join(f'<li><a href="{html.escape(g["folder"])}/{GALLERY_HTML}">{html.escape(g["label"])}</a>: '
                   f'{g["moments"]} moment(s)</li>' for g in galleries)
    page = folder / GALLERY_HTML
    page.write_text(_page(title, f"<ul class=index>{rows}</ul>"))
    return page


# -- the page --------------------------------------------------------------------------------------
_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:0;padding:12px;background:#111;color:#eee}
h1{font-size:18px;margin:0 0 4px} h2{font-size:16px;margin:18px 0 6px;border-bottom:1px solid #444}
.note{color:#aaa;margin:0 0 10px} a{color:#8cf}
.moment{background:#1c1c1c;border-radius:6px;padding:8px;margin:8px 0}
.moment h3{font-size:14px;margin:0 0 6px} .kind-intervention h3{color:#f88} .kind-worst_cte h3{color:#fc6}
.kind-failed_change h3{color:#f8c}
.frames{display:flex;flex-wrap:wrap;gap:8px}
figure{margin:0;width:170px} figure img{width:100%;image-rendering:pixelated;display:block;border-radius:3px}
figcaption{font-size:12px;color:#ccc}
.bar{position:relative;height:14px;background:#333;margin:3px 0;border-radius:2px}
.bar span{position:absolute;top:0;height:7px} .bar .pilot{background:#f90} .bar .expert{top:7px;background:#4af}
.bar:after{content:"";position:absolute;left:50%;top:0;bottom:0;border-left:1px solid #888}
.legend span{display:inline-block;width:10px;height:10px;margin:0 4px 0 10px}
@media (max-width:600px){figure{width:calc(50% - 4px)}}
"""


def _page(title: str, body: str) -> str:
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8>"
            f'<meta name=viewport content="width=device-width,initial-scale=1"><title>{html.escape(title)}</title>'
            f"<style>{_CSS}</style></head><body>{body}</body></html>\n")


def _bar(value: float | None, cls: str) -> str:
    """A steering bar from the centre: left is negative (CSS percentages of the bar's width)."""
    if value is None:
        return ""
    v = max(-1.0, min(1.0, value))
    left, width = (50 + 50 * v, -50 * v) if v < 0 else (50, 50 * v)
    return f'<span class={cls} style="left:{left:.1f}%;width:{width:.1f}%"></span>'


def _figure(frame: dict[str, Any]) -> str:
    p, e = frame["pilot"]["angle"], frame["expert"]["angle"]
    pics = "".join(f'<img src="{html.escape(src)}" alt="saliency ({html.escape(stream)})" loading=lazy>'
                   for stream, src in frame["saliency"].items())
    fmt = lambda v: "-" if v is None else f"{v:+.2f}"  # noqa: E731 - a local formatter
    return (f'<figure><img src="{html.escape(frame["image"])}" alt="frame at {frame["t"]} s" loading=lazy>{pics}'
            f"<div class=bar>{_bar(p, 'pilot')}{_bar(e, 'expert')}</div>"
            f"<figcaption>{frame['t']:+.2f} s · pilot {fmt(p)} · expert {fmt(e)} · cte {fmt(frame['cte'])}"
            f"</figcaption></figure>")


def _draw(value: Any) -> str:
    """A randomisation draw as the page names it (None: the track's own look)."""
    return "none" if value is None else html.escape(str(value))


def gallery_html(data: dict[str, Any]) -> str:
    """The static page of a gallery's JSON (no script: every browser opens it from the disk)."""
    title = f"Failures of {data.get('pilot')}"
    parts = [f"<h1>{html.escape(title)}</h1>",
             f"<p class=note>{len(data['tracks'])} track(s), saliency: {html.escape(str(data['method']))} "
             f"(where the pilot looked for its steering), {data['window_s']:g} s before each moment; "
             f"randomisation draw {_draw(data.get('randomize'))}. "
             f"<span class=legend><span style='background:#f90'></span>pilot"
             f"<span style='background:#4af'></span>expert steering</span></p>"]
    for track in data["tracks"]:
        parts.append(f"<h2 id=track-{track['seed']}>Track {track['seed']} · theme {html.escape(str(track['theme']))}"
                     f" · draw {_draw(track.get('randomize', data.get('randomize')))} · "
                     f"{track.get('interventions')} intervention(s)</h2>")
        if not track["moments"]:
            parts.append("<p class=note>nothing to show: no intervention and no worst-|CTE| moment kept</p>")
        for m in track["moments"]:
            parts.append(f"<section class='moment kind-{m['kind']}'><h3>{html.escape(moment_title(m))}</h3>"
                         "<div class=frames>" + "".join(_figure(f) for f in m["frames"]) + "</div></section>")
    return _page(title, "".join(parts))


def moment_title(m: dict[str, Any]) -> str:
    """A moment's heading; a failed lane change says where it was commanded and why it failed."""
    if m["kind"] == "intervention":
        return f"Intervention {m['number']} at {m['time_s']} s (cte {m['cte']} m)"
    if m["kind"] != "failed_change":
        return f"Worst |CTE| {m['number']} at {m['time_s']} s (cte {m['cte']} m)"
    from parts.sim.lane_metrics import describe_command

    c = m.get("command")
    what = describe_command(c) if c else f"at {m['command_time_s']} s"
    return f"Failed lane change {m['number']}, commanded {what} (frames up to {m['time_s']} s)"
