"""Saliency of a registered model on a few frames of its own datasets (the console's model page).

:func:`saliency_samples` picks ``count`` records spread over the model's datasets, explains the
model's steering and throttle on each (:mod:`parts.pilots.saliency`) and writes the pictures into a
folder, with ``samples.json`` describing them. A folder already made for the same model file (same
size and time) is reused.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

SAMPLES_JSON = "samples.json"


def _stamp(model: Path) -> list[int]:
    st = model.stat()
    return [st.st_size, st.st_mtime_ns]


def _picks(records: list[Any], count: int, frames: int) -> list[int]:
    """Indexes (into ``records``) of ``count`` records spread evenly, each with ``frames - 1`` before it."""
    usable = list(range(frames - 1, len(records)))
    if not usable:
        return []
    return sorted({usable[round(k * (len(usable) - 1) / max(1, count - 1))] for k in range(min(count, len(usable)))})


def saliency_samples(model: str | Path, datasets: list[str | Path], out: str | Path, count: int = 4,
                     method: str = "integrated") -> dict[str, Any]:
    """Write (or reuse) the saliency pictures of ``model`` on ``count`` frames of ``datasets``.

    Returns the samples' description (also in ``out/samples.json``). Raises ValueError (one line)
    when no dataset has frames, or when the model was trained on frames of another size.
    """
    import cv2

    from parts.pilots.saliency import Explainer
    from parts.tub.reader import iter_images, iter_records

    model, out = Path(model), Path(out)
    cached = out / SAMPLES_JSON
    if cached.is_file():
        data = json.loads(cached.read_text())
        if data.get("stamp") == _stamp(model) and data.get("method") == method:
            return data
    explainer = Explainer.from_file(model)
    if explainer.model.views > 1:
        raise ValueError(f"model type {explainer.model.type_name!r} takes {explainer.model.views} camera views; "
                         "its saliency is shown in evaluation galleries")
    tubs = [Path(p) for p in datasets if Path(p).is_dir()]
    records = list(iter_records(tubs, check_images=False)) if tubs else []
    frames_needed = explainer.model.frames
    picks = _picks(records, count, frames_needed)
    if not picks:
        raise ValueError("no frames to explain: the model's datasets are missing or empty")
    wanted = sorted({j for i in picks for j in range(i - frames_needed + 1, i + 1)})
    images = dict(zip(wanted, (img for _, img in iter_images([records[j] for j in wanted], on_error="raise")),
                      strict=True))
    out.mkdir(parents=True, exist_ok=True)
    samples = []
    for n, i in enumerate(picks):
        rec = records[i]
        frames = [images[j] for j in range(i - frames_needed + 1, i + 1)]
        extra = None
        if explainer.model.extra_inputs and isinstance(rec.get(explainer.model.extra_inputs[0]), list):
            extra = rec.get(explainer.model.extra_inputs[0])
        entry: dict[str, Any] = {"tub": Path(rec.tub).name, "index": rec.index,
                                 "recorded": {"angle": rec.angle, "throttle": rec.throttle}}
        cv2.imwrite(str(out / f"s{n}.jpg"), cv2.cvtColor(frames[-1], cv2.COLOR_RGB2BGR))
        entry["image"] = f"s{n}.jpg"
        for output in ("steering", "throttle"):
            sal = explainer.explain(frames, extra, output=output, method=method)
            entry["prediction"] = {"angle": round(sal.prediction[0], 4), "throttle": round(sal.prediction[1], 4)}
            entry[output] = {}
            for stream, picture in explainer.overlays(frames, sal).items():
                name = f"s{n}-{output}-{stream.replace('/', '_')}.jpg"
                cv2.imwrite(str(out / name), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
                entry[output][stream] = name
        samples.append(entry)
    data = {"model": model.name, "stamp": _stamp(model), "method": method, "samples": samples}
    cached.write_text(json.dumps(data, indent=1, default=float) + "\n")
    return data
