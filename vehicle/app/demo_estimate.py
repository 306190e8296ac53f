"""What ``vehicle demo`` should take on this host, from a measurement of the host, not its CPU kind.

At start the demo measures (about 2 s) how fast this machine, as loaded now, runs the training
step at the demo's input and precision (:func:`training.calibrate.measure_step_rate`) and how fast
the expert records (a 100-record recording), then multiplies them by the work the demo plans
(:class:`DemoWork`): the sample-steps of its training, the records, the evaluated laps.
:func:`estimate_seconds` and :func:`expectation_line` are pure (tested with injected rates).
"""

from __future__ import annotations

import logging
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

#: the training loop's samples/s over the bare step's (augmentations, batches from the frame
#: cache, validation's forward passes): measured for the demo, docs/benchmarks.md "demo's estimate"
TRAIN_LOOP_SHARE = 0.85
#: one evaluated lap (pilot or expert, demo speed 1.5 m/s, the demo's evaluation workers) costs as
#: much as recording this many records: measured, docs/benchmarks.md "demo's estimate"
RECORDS_PER_EVAL_LAP = 125.0
#: a validation sample (forward only) costs about this share of a training sample-step
VAL_COST = 1 / 3
#: records of the recording measured at start
CALIBRATION_RECORDS = 100


@dataclass(frozen=True)
class HostRates:
    """What this host did when measured: training samples/s of the bare step and records/s."""

    train_samples_per_s: float
    records_per_s: float


@dataclass(frozen=True)
class DemoWork:
    """What a demo run will do: records to record, training sample-steps and validation samples
    (over the whole run), laps to evaluate (pilot and expert, every theme)."""

    records: int
    sample_steps: int
    val_samples: int
    eval_laps: int


def plan_work(records: int, epochs: int, train_share: float, eval_tracks: int, laps: int, themes: int,
              steps_per_epoch: int | None = None, batch_size: int = 64) -> DemoWork:
    """The demo's work for its settings: ``train_share`` (TRAIN_TEST_SPLIT) of the records train,
    ``epochs`` times (or ``steps_per_epoch`` batches per epoch), the rest validates every epoch."""
    train = max(1, round(records * train_share))
    per_epoch = train if steps_per_epoch is None else steps_per_epoch * batch_size
    return DemoWork(records=records, sample_steps=per_epoch * epochs, val_samples=(records - train) * epochs,
                    eval_laps=eval_tracks * laps * themes * 2)


def estimate_seconds(work: DemoWork, rates: HostRates) -> dict[str, float]:
    """Seconds of each step (record, train, evaluate) and their total at the measured rates."""
    if rates.train_samples_per_s <= 0 or rates.records_per_s <= 0:
        raise ValueError(f"rates must be positive, got {rates}")
    train_rate = rates.train_samples_per_s * TRAIN_LOOP_SHARE
    out = {"record": work.records / rates.records_per_s,
           "train": (work.sample_steps + VAL_COST * work.val_samples) / train_rate,
           "evaluate": work.eval_laps * RECORDS_PER_EVAL_LAP / rates.records_per_s}
    out["total"] = sum(out.values())
    return out


def expectation_line(estimate: dict[str, float], rates: HostRates, cpu: str, precision: str,
                     threads: int) -> str:
    """The demo's start-up line: the total expected on this host now, its parts and what they rest on."""
    parts = ", ".join(f"{k} ~{_seconds(v)}" for k, v in estimate.items() if k != "total")
    return (f"expected time on this machine as loaded now: about {_seconds(estimate['total'])} ({parts}), from "
            f"a measured {rates.train_samples_per_s:.0f} training samples/s ({precision}, {threads} torch "
            f"thread{'s' if threads != 1 else ''}) and {rates.records_per_s:.0f} records/s on {cpu}; "
            "other work on the machine can make it longer")


def _seconds(s: float) -> str:
    """``85 s`` below 100 s, then ``about 3 min`` style (half minutes up to 10 minutes)."""
    if not math.isfinite(s):
        return "?"
    if s < 100:
        return f"{s:.0f} s"
    minutes = s / 60
    return f"{round(minutes * 2) / 2:g} min" if minutes < 10 else f"{round(minutes):.0f} min"


def measure_host(cfg: Any, model_type: str, input_shape: tuple[int, int, int], batch_size: int,
                 seconds: float = 1.0) -> HostRates:
    """Measure this host (about ``seconds`` + 1 s): the bare training step and a 100-record recording
    by the expert on two training tracks (after a 10-record warm-up that builds the tracks)."""
    from training.calibrate import measure_step_rate
    from vehicle.app.record import record_expert

    train = measure_step_rate(model_type, input_shape, batch_size, precision=cfg.TRAIN_PRECISION, seconds=seconds,
                              options=cfg.MODEL_OPTIONS)
    with tempfile.TemporaryDirectory() as tmp:
        record_expert(cfg, [1, 2], 10, Path(tmp) / "warm", noise=0.0)
        start = time.perf_counter()
        record_expert(cfg, [1, 2], CALIBRATION_RECORDS, Path(tmp) / "calibration", noise=0.0)
        records = CALIBRATION_RECORDS / (time.perf_counter() - start)
    return HostRates(train_samples_per_s=train, records_per_s=records)


def demo_expectation(records: int, epochs: int, eval_tracks: int, laps: int, threads: int,
                     rates: HostRates | None = None, precision: str = "auto", recipe: str = "plain") -> str:
    """The plain demo's start-up line for its arguments: this host measured now (or ``rates``) at
    the training precision the demo will use (``precision``: its --precision, TRAIN_PRECISION),
    with the model options of its ``recipe``."""
    import torch

    from parts.pilots.preprocess import preprocess_from_config
    from training.acceleration import cpu_caps, plan_for
    from vehicle.app.demo import DEMO_SETTINGS, RECIPES
    from vehicle.config import Config

    cfg = Config.defaults(**{**DEMO_SETTINGS, **(RECIPES[recipe].settings or {}), "TRAIN_PRECISION": precision})
    frame = (cfg.IMAGE_H, cfg.IMAGE_W, cfg.IMAGE_DEPTH)
    shape = preprocess_from_config(cfg, cfg.DEFAULT_MODEL_TYPE, frame).output_shape(frame)
    if rates is None:
        rates = measure_host(cfg, cfg.DEFAULT_MODEL_TYPE, shape, cfg.BATCH_SIZE)
    work = plan_work(records, epochs, cfg.TRAIN_TEST_SPLIT, eval_tracks, laps, themes=3,
                     steps_per_epoch=cfg.TRAIN_STEPS_PER_EPOCH, batch_size=cfg.BATCH_SIZE)
    precision = plan_for(torch.device("cpu"), cfg.TRAIN_PRECISION).precision
    return expectation_line(estimate_seconds(work, rates), rates, cpu_caps().name, precision, threads)
