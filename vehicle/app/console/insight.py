"""What the console shows of a pilot's sight: evaluation galleries, saliency samples, tub movies.

Blocking work for :mod:`vehicle.app.console.api` (run in threads), without torch: the saliency of
a model is computed by a worker process (``python -m vehicle.app.console.worker saliency``) and
kept, as the movies and the console's evaluation galleries are, under the car's ``insight/``
folder. Files are served only from inside the folder they belong to.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
from pathlib import Path
from typing import Any

from vehicle.app.console.datasets import DatasetError

#: the car's folder of what the console makes to show (galleries/, saliency/, movies/)
INSIGHT_DIR = "insight"
#: frames of a tub's movie at most (100 s at 20 Hz): a longer tub is filmed from its start
MAX_MOVIE_FRAMES = 2000
#: content types of the files served
CONTENT_TYPES = {".jpg": "image/jpeg", ".html": "text/html; charset=utf-8", ".json": "application/json",
                 ".webm": "video/webm"}

_movie_locks: dict[int, threading.Lock] = {}
_locks_lock = threading.Lock()


def insight_dir(cfg: Any, kind: str) -> Path:
    """``<car>/insight/<kind>``."""
    return Path(cfg.CAR_PATH) / INSIGHT_DIR / kind


def _inside(root: Path, rel: str) -> Path:
    """The file ``rel`` names inside ``root`` (DatasetError 404 otherwise: no ``..``, no link out)."""
    from parts.web.server import static_file

    path = static_file(root, rel)
    if path is None or path.suffix not in CONTENT_TYPES:
        raise DatasetError(f"no file {rel!r} here", status=404)
    return path


# -- evaluation galleries ----------------------------------------------------------------------------
def gallery_folder(db: Any, evaluation_id: int) -> Path:
    """The gallery folder of a stored evaluation (404 when it has none, or it was removed)."""
    ev = db.evaluation(evaluation_id)
    folder = (ev.settings or {}).get("gallery")
    if not folder:
        raise DatasetError(f"evaluation {evaluation_id} has no gallery: evaluate again here, or with `vehicle sim "
                           "eval --gallery DIR --store`", status=404)
    if not (Path(folder) / "gallery.json").is_file():
        raise DatasetError(f"the gallery of evaluation {evaluation_id} is gone ({folder})", status=404)
    return Path(folder)


def gallery_data(db: Any, evaluation_id: int) -> dict[str, Any]:
    """The gallery's JSON, with ``base``: the URL its relative image paths are under."""
    data = json.loads((gallery_folder(db, evaluation_id) / "gallery.json").read_text())
    data["base"] = f"api/evaluations/{evaluation_id}/gallery/"
    return data


def gallery_file(db: Any, evaluation_id: int, rel: str) -> Path:
    """A file of a stored evaluation's gallery (its page, pictures or JSON)."""
    return _inside(gallery_folder(db, evaluation_id), rel)


# -- tub movies --------------------------------------------------------------------------------------
def _stamp(tub: Path) -> str:
    """Changes when records are added or (un)deleted: the newest time of the tub's own files."""
    times = [p.stat().st_mtime_ns for p in tub.iterdir() if p.is_file()]
    return f"{max(times, default=0):x}"


def dataset_movie(cfg: Any, tub: Path, dataset_id: int) -> Path:
    """The WebM movie of a tub (its first :data:`MAX_MOVIE_FRAMES` records), made once per state of
    the tub. DatasetError 404 for a tub without records."""
    from parts.tub.errors import TubError
    from parts.tub.reader import iter_records
    from parts.tub.visualize import write_movie

    with _locks_lock:
        lock = _movie_locks.setdefault(dataset_id, threading.Lock())
    with lock:  # one making per dataset; a second request waits and gets the same file
        folder = insight_dir(cfg, "movies")
        out = folder / f"dataset-{dataset_id}-{_stamp(tub)}.webm"
        if out.is_file():
            return out
        end = None
        for n, rec in enumerate(iter_records([tub], check_images=False)):
            if n == MAX_MOVIE_FRAMES:
                end = rec.index
                break
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob(f"dataset-{dataset_id}-*.webm"):  # an older state of this tub
            old.unlink(missing_ok=True)
        tmp = folder / f".making-{dataset_id}-{os.getpid()}.webm"
        try:
            write_movie(tub, tmp, end=end, fps=20.0, scale=2)
            os.replace(tmp, out)
        except TubError as exc:
            raise DatasetError(f"no movie: {exc}", status=404) from exc
        finally:
            with contextlib.suppress(OSError):
                tmp.unlink()
        return out


# -- saliency samples of a model ----------------------------------------------------------------------
def saliency_folder(cfg: Any, name: str) -> Path:
    """Where the saliency samples of the model ``name`` are kept."""
    return insight_dir(cfg, "saliency") / name


def saliency_file(cfg: Any, name: str, rel: str) -> Path:
    """A picture of the model's saliency samples."""
    return _inside(saliency_folder(cfg, name), rel)
