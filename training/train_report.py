"""Training reports written next to the model: the loss-curve PNG and the metrics JSON."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any


def sidecar(model_path: str | os.PathLike[str], suffix: str) -> Path:
    """``models/NAME.pt`` -> ``models/NAME<suffix>`` (e.g. ``.loss.png``, ``.metrics.json``)."""
    p = Path(model_path)
    return p.with_name(p.stem + suffix)


def write_metrics(path: str | os.PathLike[str], metrics: dict[str, Any]) -> Path:
    """Write ``metrics`` as JSON (NaN/inf become null so any JSON reader accepts it)."""

    def clean(v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        return v

    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(clean(metrics), indent=2) + "\n")
    os.replace(tmp, path)
    return path


def plot_losses(path: str | os.PathLike[str], train_loss: list[float], val_loss: list[float],
                title: str = "", best_epoch: int = 0) -> Path:
    """Loss per epoch as a PNG (matplotlib with the Agg backend: no display needed)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # a bare Figure needs no pyplot state

    fig = Figure(figsize=(6, 4), dpi=100)
    ax = fig.add_subplot(1, 1, 1)
    epochs = list(range(1, len(train_loss) + 1))
    ax.plot(epochs, train_loss, marker="o", label="train")
    if any(math.isfinite(v) for v in val_loss):
        ax.plot(epochs, val_loss, marker="o", label="validation")
    if best_epoch:
        ax.axvline(best_epoch, color="grey", linestyle="--", label=f"best (epoch {best_epoch})")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # epochs are whole numbers
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


def train_summary(metrics: dict[str, Any], model_path: Path) -> str:
    """What a training run left, in one line: the file, its best epoch among the planned ones,
    where a stop came, and the model the user had that was kept."""
    best = metrics.get("best_val_loss")
    loss = f"{best:.5f}" if isinstance(best, float) else "n/a"
    saved = Path(metrics.get("model_file") or model_path)
    planned = metrics.get("epochs_planned") or metrics["epochs"]
    stopped = ""
    if metrics.get("cancelled"):
        stopped = f"stopped by Ctrl-C in epoch {metrics.get('stopped_in_epoch') or metrics['epochs']} of {planned}: "
    kept = metrics.get("kept_model")
    kept_text = f"; kept your {kept} (a stopped run does not replace it)" if kept else ""
    return (f"{stopped}saved {saved} (best epoch {metrics['best_epoch']}, {metrics['epochs']} of {planned} epochs "
            f"run, val_loss {loss}){kept_text}; metrics: {sidecar(saved, '.metrics.json')}")
