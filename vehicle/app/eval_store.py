"""Keep an evaluation report in the car's model database, with the picture of the driven trajectories.

``vehicle sim eval --store`` and the trainer console's evaluation job both call
:func:`store_report`; the leaderboard (``vehicle models leaderboard``, the console) ranks what is
stored.
"""

from __future__ import annotations

import logging
import tempfile
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)


def report_picture(report: dict[str, Any], cfg: Any, panel: int = 360) -> bytes:
    """The report's trajectories over the track maps as PNG bytes (one panel per track)."""
    from parts.sim.eval_report import write_png

    with tempfile.TemporaryDirectory() as tmp:
        path = write_png(report, Path(tmp) / "eval.png", cfg, panel=panel)
        return path.read_bytes()


def store_report(cfg: Any, model: str | Path, report: dict[str, Any]) -> Any:
    """Store ``report`` as an evaluation of the registered model ``model`` (a name or its file).

    Returns the stored :class:`training.model_db.Evaluation`. Raises
    :class:`training.model_db.ModelDBError` when the model is not in the car's model database.
    """
    from training.model_db import ModelDB

    db = ModelDB.for_models_dir(cfg.path("MODELS_PATH"))
    entry = db.get(str(model))
    try:
        picture: bytes | None = report_picture(report, cfg)
    except (OSError, ValueError) as exc:  # the numbers matter more than the picture
        logger.warning("no trajectory picture for the evaluation of %s: %s", entry.name, exc)
        picture = None
    return db.add_evaluation(entry.name, report, picture)
