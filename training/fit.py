"""The training loop: Adam, early stopping on the validation loss, best-model callback, progress bar,
progress events for a live view (the trainer console) and a clean stop on request.

It runs the device plan of :mod:`training.acceleration` (autocast precision, gradient scaler,
channels_last batches, non-blocking copies, torch.compile) and measures per epoch how long the loop
waited for its next batch (``History.data_seconds``): the data path's cost to training.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import islice
from typing import Any

import torch
from torch import nn
from torch.utils.data import DataLoader

from parts.pilots.models import PilotModel
from parts.pilots.preprocess import Preprocess
from training.acceleration import TrainPlan, autocast, grad_scaler, to_layout
from training.distributed import DistInfo, all_sum
from training.prefetch import Prefetcher
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

_SINGLE = DistInfo()  # one process, rank 0
#: training steps between two reads of the loss on a GPU (each read waits for the GPU to finish)
SYNC_STEPS = 25


class TrainingDiverged(VehicleError, RuntimeError):
    """The loss became NaN or infinite."""


#: receives progress events (plain dicts, see :func:`fit`)
EventSink = Callable[[dict[str, Any]], None]


@dataclass
class FitSettings:
    """Optimiser and stopping settings (LEARNING_RATE, MAX_EPOCHS, EARLY_STOP_PATIENCE, MIN_DELTA)."""

    epochs: int = 100
    learning_rate: float = 1e-3
    weight_decay: float = 0.0
    patience: int | None = 5  # None: never stop early
    min_delta: float = 0.0005
    progress: bool | None = None  # None: a bar only when stderr is a terminal
    prefetch: int = 2  # batches read ahead in a background thread (0 = read in the training loop)
    # batches per epoch (None: the whole training set once); more than one pass goes round the
    # training set again, each pass in a new order with new augmentation draws (Keras's
    # fit(generator, steps_per_epoch=...), which the source documents use)
    steps_per_epoch: int | None = None
    val_steps: int | None = None  # validation batches per epoch (None: the whole validation set)
    lr_schedule: str = "constant"  # TRAIN_LR_SCHEDULE: "constant" or "one_cycle" (:func:`make_scheduler`)
    warmup: float = 0.2  # TRAIN_WARMUP: share of the run's steps the one-cycle schedule warms up over


@dataclass
class Patience:
    """Keras' two rules, as DonkeyCar's training uses them: the best model is the one with the lowest
    loss so far (any drop counts), while early stopping waits for a drop of more than ``min_delta``
    below the loss it last reset on; ``waited`` counts epochs since that reset."""

    min_delta: float
    best: float = math.inf  # lowest loss so far: the model kept
    reference: float = math.inf  # loss of the last drop by more than min_delta
    waited: int = 0

    def update(self, loss: float) -> bool:
        """Record one epoch's loss; True when it is the best so far (the model to keep)."""
        if loss < self.reference - self.min_delta:
            self.reference, self.waited = loss, 0
        else:
            self.waited += 1
        if loss < self.best:
            self.best = loss
            return True
        return False


@dataclass
class History:
    """Per-epoch figures; ``best_epoch`` is 1-based (0 = none yet)."""

    train_loss: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    samples_per_s: list[float] = field(default_factory=list)
    samples: list[int] = field(default_factory=list)  # training samples per epoch, all processes
    data_seconds: list[float] = field(default_factory=list)  # of each epoch's seconds, waiting for batches
    best_epoch: int = 0
    best_loss: float = math.inf
    stopped_early: bool = False
    cancelled: bool = False  # stopped on request (should_stop); the partial epoch is not counted
    stopped_in_epoch: int = 0  # the epoch a stop request ended (0: not stopped)

    def as_dict(self) -> dict[str, Any]:
        return {"train_loss": self.train_loss, "val_loss": self.val_loss, "epoch_seconds": self.seconds,
                "train_samples_per_s": self.samples_per_s, "epoch_samples": self.samples,
                "epoch_data_seconds": self.data_seconds,
                "best_epoch": self.best_epoch,
                "best_loss": self.best_loss if math.isfinite(self.best_loss) else None,
                "epochs": len(self.train_loss), "stopped_early": self.stopped_early,
                "cancelled": self.cancelled, "stopped_in_epoch": self.stopped_in_epoch}


def _set_epoch(loader: DataLoader, epoch: int) -> None:
    for obj in (loader.sampler, getattr(loader, "batch_sampler", None), loader.dataset):
        if obj is not None and hasattr(obj, "set_epoch"):
            obj.set_epoch(epoch)


def plain_plan(device: torch.device) -> TrainPlan:
    """fp32, default layout, eager: what :func:`fit` runs when given no plan."""
    cuda = device.type == "cuda"
    return TrainPlan(device.type, pin_memory=cuda, non_blocking=cuda)


def _passes(loader: DataLoader, epoch: int, epochs: int):
    """The loader's batches, pass after pass: pass k of epoch e draws as epoch ``e + k * epochs``,
    so no two passes of a run share an order or augmentation draws."""
    k = 0
    while True:
        if k:
            _set_epoch(loader, epoch + k * epochs)
        yield from loader
        k += 1


def _batches(loader: Any, device: torch.device, pre: Preprocess, needs_extra: bool,
             plan: TrainPlan, augment: Callable[[torch.Tensor], torch.Tensor] | None = None):
    # uint8 images travel to the device (4x fewer bytes than floats), are augmented and laid out
    # there, then become floats in one pass that keeps the layout
    nb = plan.non_blocking
    for x, extra, y in loader:
        x = x.to(device, non_blocking=nb)
        if augment is not None:
            x = augment(x)
        x = pre.normalize_batch(to_layout(x, plan))
        e = extra.to(device, non_blocking=nb) if needs_extra else None
        yield x, e, y.to(device, non_blocking=nb)


def evaluate(model: PilotModel, loader: DataLoader, pre: Preprocess, device: torch.device,
             info: DistInfo = _SINGLE, plan: TrainPlan | None = None, max_batches: int | None = None) -> float:
    """Mean loss of ``model`` over ``loader`` (summed over every process when distributed), over its
    first ``max_batches`` batches when given, in the plan's precision (default fp32)."""
    plan = plan or plain_plan(device)
    model.eval()
    loss_sum = torch.zeros((), dtype=torch.float64, device=device)  # read once: no GPU wait per batch
    count = 0
    with torch.no_grad():
        for x, e, y in islice(_batches(loader, device, pre, model.extra_size > 0, plan), max_batches):
            with autocast(plan):
                out = model(x, e)
            loss_sum += model.loss(out.float(), y) * len(y)
            count += len(y)
    total, count = all_sum([float(loss_sum), float(count)], info, device)
    return total / count if count else math.nan


def _check_finite(loss_sum: float, epoch: int, settings: FitSettings) -> None:
    if not math.isfinite(loss_sum):
        raise TrainingDiverged(f"the training loss became {loss_sum} in epoch {epoch}; lower "
                               f"LEARNING_RATE (now {settings.learning_rate}) or check the labels")


def make_optimizer(model: nn.Module, settings: FitSettings, device: torch.device) -> torch.optim.Optimizer:
    """Adam with LEARNING_RATE and TRAIN_WEIGHT_DECAY; the fused kernel (one pass over all the
    parameters instead of a dozen small operations per tensor) on CPUs and GPUs."""
    fused = device.type in ("cpu", "cuda")
    return torch.optim.Adam(model.parameters(), lr=settings.learning_rate, weight_decay=settings.weight_decay,
                            fused=fused or None)


def make_scheduler(optimizer: torch.optim.Optimizer, settings: FitSettings,
                   steps: int) -> torch.optim.lr_scheduler.LRScheduler | None:
    """The learning-rate schedule over a run of ``steps`` optimiser steps, stepped after each one:
    None for "constant"; for "one_cycle", torch's OneCycleLR peaking at the learning rate after
    ``warmup`` of the steps (from a 25th of it), then a cosine down to ~0 at the last step. Adam's
    betas stay as they are (no momentum cycling)."""
    if settings.lr_schedule == "constant":
        return None
    if settings.lr_schedule != "one_cycle":
        raise ValueError(f"TRAIN_LR_SCHEDULE = {settings.lr_schedule!r}: use 'constant' or 'one_cycle'")
    return torch.optim.lr_scheduler.OneCycleLR(optimizer, max_lr=settings.learning_rate, total_steps=max(steps, 2),
                                               pct_start=settings.warmup, anneal_strategy="cos",
                                               cycle_momentum=False)


def fit(model: nn.Module, train_loader: DataLoader, val_loader: DataLoader | None, pre: Preprocess,
        device: torch.device, settings: FitSettings, info: DistInfo = _SINGLE,
        on_best: Callable[[int, History], None] | None = None,
        optimizer: torch.optim.Optimizer | None = None, plan: TrainPlan | None = None,
        on_event: EventSink | None = None, should_stop: Callable[[], bool] | None = None,
        augment: Any = None) -> History:
    """Train ``model`` (a PilotModel, or DDP around one) and return the history.

    ``plan`` (:func:`training.acceleration.plan_for`; default fp32 eager) sets the precision,
    the batches' layout and compilation; a channels_last plan expects the model already laid out
    by :func:`training.acceleration.apply_layout`.

    Each epoch trains on ``train_loader`` (its first ``steps_per_epoch`` batches when set) then
    measures ``val_loader`` (the training loss stands in when there is no validation data).
    ``on_best(epoch, history)`` runs on every process whenever the monitored loss is the lowest so
    far; training stops after ``patience`` epochs without a drop of more than ``min_delta``
    (:class:`Patience`).

    ``on_event`` (main process) gets ``{"event": "batch", "epoch", "epochs", "batch", "batches",
    "loss", "samples", "samples_per_s"}`` after every step (on a GPU every ``SYNC_STEPS`` steps:
    reading the loss waits for the GPU) and ``{"event": "epoch", "epoch", "epochs", "train_loss",
    "val_loss", "seconds", "samples_per_s", "best", "best_epoch"}`` after every epoch.
    ``settings.lr_schedule`` sets the learning rate step by step over the whole run
    (:func:`make_scheduler`).
    ``should_stop()`` is asked after every step (single process only): when it says yes, training
    ends at once, the unfinished epoch is dropped and ``history.cancelled`` is set; the best model
    so far has already been handed to ``on_best``.

    ``augment`` (:class:`training.batch_augment.BatchAugmenter`, training batches only) changes
    each uint8 training batch on the device before it becomes floats; its ``set_epoch`` is called
    at the start of every epoch.
    """
    if should_stop is not None and info.enabled:
        logger.warning("fit: should_stop is ignored when training on several processes")
        should_stop = None
    run = _Run.start(model, train_loader, pre, device, settings, info, optimizer, plan, on_event, should_stop,
                     augment)
    history = History()
    patience = Patience(settings.min_delta)
    for epoch in range(1, settings.epochs + 1):
        done = _train_epoch(run, train_loader, epoch)
        if done.cancelled:
            history.cancelled, history.stopped_in_epoch = True, epoch
            if info.is_main:
                logger.info("training cancelled in epoch %d/%d (batch %d of %d); the best model so far "
                            "is kept (epoch %d)", epoch, settings.epochs, done.steps, run.n_batches,
                            history.best_epoch)
            break
        if _end_epoch(run, done, epoch, history, patience, val_loader, on_best):
            break
    return history


@dataclass
class _Run:
    """What the steps of one :func:`fit` share: the model and its (compiled) forward, the optimiser,
    scaler and schedule, the plan, and where progress goes."""

    model: nn.Module
    core: PilotModel
    forward: Callable[..., torch.Tensor]
    optimizer: torch.optim.Optimizer
    scaler: Any
    scheduler: Any
    plan: TrainPlan
    pre: Preprocess
    device: torch.device
    settings: FitSettings
    info: DistInfo
    emit: EventSink | None  # the main process's event sink
    show: bool  # a progress bar on the terminal
    n_batches: int  # training batches per epoch
    augment: Any
    should_stop: Callable[[], bool] | None
    compile_pending: bool  # the first step compiles (logged once)

    @classmethod
    def start(cls, model: nn.Module, train_loader: DataLoader, pre: Preprocess, device: torch.device,
              settings: FitSettings, info: DistInfo, optimizer: torch.optim.Optimizer | None,
              plan: TrainPlan | None, on_event: EventSink | None, should_stop: Callable[[], bool] | None,
              augment: Any) -> _Run:
        core: PilotModel = model.module if isinstance(model, nn.parallel.DistributedDataParallel) else model
        plan = plan or plain_plan(device)
        optimizer = optimizer or make_optimizer(model, settings, device)
        show = settings.progress if settings.progress is not None else sys.stderr.isatty()
        n_batches = len(train_loader) if settings.steps_per_epoch is None else settings.steps_per_epoch
        return cls(model, core, torch.compile(model) if plan.compile else model, optimizer, grad_scaler(plan),
                   make_scheduler(optimizer, settings, settings.epochs * n_batches), plan, pre, device, settings,
                   info, on_event if info.is_main else None, bool(show and info.is_main), n_batches, augment,
                   should_stop, plan.compile)


@dataclass
class _Epoch:
    """One epoch's training pass: the loss summed over its samples, its steps and times (s)."""

    total: float
    count: int
    steps: int
    seconds: float
    data_wait: float  # of which spent waiting for batches
    cancelled: bool  # should_stop said yes during it


def _train_epoch(run: _Run, train_loader: DataLoader, epoch: int) -> _Epoch:
    """Train one pass over ``train_loader`` (its first ``n_batches``), with a progress bar and the
    batch events."""
    settings = run.settings
    _set_epoch(train_loader, epoch)
    if run.augment is not None:
        run.augment.set_epoch(epoch)
    run.model.train()
    start = time.perf_counter()
    bar = None
    if run.show:
        from tqdm import tqdm

        bar = tqdm(total=run.n_batches, desc=f"epoch {epoch}/{settings.epochs}", unit="batch", leave=False,
                   dynamic_ncols=True)
    batches = islice(_batches(_passes(train_loader, epoch, settings.epochs), run.device, run.pre,
                              run.core.extra_size > 0, run.plan, run.augment), run.n_batches)
    source = Prefetcher(batches, settings.prefetch) if settings.prefetch > 0 else None
    data_wait, count, step, cancelled = 0.0, 0, 0, False
    clock = time.perf_counter
    # the loss sum stays on the device; reading it waits for the device, so a GPU is read only
    # every SYNC_STEPS steps (a CPU every step: free there)
    loss_sum = torch.zeros((), dtype=torch.float64, device=run.device)
    sync_every = 1 if run.device.type == "cpu" else SYNC_STEPS
    try:
        it = iter(source if source is not None else batches)
        while True:
            t = clock()
            try:
                x, e, y = next(it)
            except StopIteration:
                data_wait += clock() - t
                break
            t_step = clock()
            data_wait += t_step - t
            loss = _step(run, x, e, y)
            loss_sum += loss.detach() * len(y)
            count += len(y)
            step += 1
            if step % sync_every == 0 or bar is not None:
                _report_batch(run, bar, float(loss_sum), count, step, epoch, clock() - start)
            if run.compile_pending:
                run.compile_pending = False
                if run.info.is_main:
                    logger.info("torch.compile: the first training step took %.1f s (compiling)", clock() - t_step)
            if run.should_stop is not None and run.should_stop():
                cancelled = True
                break
        total = float(loss_sum)
        _check_finite(total, epoch, settings)
    finally:
        if source is not None:
            source.close()
        if bar is not None:
            bar.close()
    return _Epoch(total, count, step, time.perf_counter() - start, data_wait, cancelled)


def _step(run: _Run, x: torch.Tensor, e: torch.Tensor | None, y: torch.Tensor) -> torch.Tensor:
    """One optimiser step on a batch; its loss."""
    with autocast(run.plan):
        out = run.forward(x, e)
    loss = run.core.loss(out.float(), y)
    run.optimizer.zero_grad(set_to_none=True)
    if run.scaler is not None:
        run.scaler.scale(loss).backward()
        run.scaler.step(run.optimizer)
        run.scaler.update()
    else:
        loss.backward()
        run.optimizer.step()
    if run.scheduler is not None:
        run.scheduler.step()
    return loss


def _report_batch(run: _Run, bar: Any, total: float, count: int, step: int, epoch: int, elapsed: float) -> None:
    """The running loss, checked finite, on the bar and as a batch event."""
    _check_finite(total, epoch, run.settings)
    if bar is not None:
        bar.update(1)
        bar.set_postfix(loss=f"{total / count:.4f}")
    if run.emit is not None:
        run.emit({"event": "batch", "epoch": epoch, "epochs": run.settings.epochs, "batch": step,
                  "batches": run.n_batches, "loss": total / count, "samples": count,
                  "samples_per_s": count / elapsed if elapsed > 0 else 0.0})


def _end_epoch(run: _Run, done: _Epoch, epoch: int, history: History, patience: Patience,
               val_loader: DataLoader | None, on_best: Callable[[int, History], None] | None) -> bool:
    """Validate, record the epoch in ``history``, hand a new best to ``on_best``, emit the epoch
    event; whether training ends here (cancelled after the epoch, or no improvement for
    ``patience`` epochs)."""
    settings, info = run.settings, run.info
    seconds = done.seconds
    total, count = all_sum([done.total, float(done.count)], info, run.device)
    train_loss = total / max(count, 1.0)
    val_loss = evaluate(run.core, val_loader, run.pre, run.device, info, run.plan, settings.val_steps) \
        if val_loader is not None else math.nan
    history.train_loss.append(train_loss)
    history.val_loss.append(val_loss)
    history.seconds.append(seconds)
    history.samples_per_s.append(count / seconds if seconds > 0 else 0.0)
    history.samples.append(int(count))
    history.data_seconds.append(done.data_wait)
    monitored = val_loss if math.isfinite(val_loss) else train_loss
    improved = patience.update(monitored)
    if info.is_main:
        logger.info("epoch %d/%d: loss %.5f, val_loss %.5f, %.0f samples/s, %.0f %% waiting for data%s",
                    epoch, settings.epochs, train_loss, val_loss, history.samples_per_s[-1],
                    100.0 * done.data_wait / seconds if seconds > 0 else 0.0, " (best)" if improved else "")
    if improved:
        history.best_loss, history.best_epoch = monitored, epoch
        if on_best is not None:
            on_best(epoch, history)
    if run.emit is not None:
        run.emit({"event": "epoch", "epoch": epoch, "epochs": settings.epochs, "train_loss": train_loss,
                  "val_loss": val_loss if math.isfinite(val_loss) else None, "seconds": seconds,
                  "samples_per_s": history.samples_per_s[-1], "best": improved, "best_epoch": history.best_epoch})
    if run.should_stop is not None and run.should_stop():
        history.cancelled, history.stopped_in_epoch = True, epoch
        if info.is_main:
            logger.info("training cancelled after epoch %d/%d; the best model so far is kept (epoch %d)",
                        epoch, settings.epochs, history.best_epoch)
        return True
    if settings.patience is not None and patience.waited >= settings.patience:
        history.stopped_early = True
        if info.is_main:
            logger.info("early stop: no improvement of val_loss by more than %g for %d epochs",
                        settings.min_delta, patience.waited)
        return True
    return False
