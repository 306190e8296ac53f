"""Train a pilot from tubs: ``manage.py train`` and ``vehicle train`` both end up in :func:`train`.

Data (:mod:`training.dataset`) -> model (:mod:`parts.pilots.models`) -> loop
(:mod:`training.fit`) -> model file (:mod:`parts.pilots.modelfile`) with the loss curve
``NAME.loss.png`` and ``NAME.metrics.json`` next to it, and an entry in the car's model database.
Runs on the GPU when there is one and on several GPUs/machines under torchrun.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import DataLoader, DistributedSampler

from parts.pilots.compat import camera_meta
from parts.pilots.modelfile import load_model, save_model
from parts.pilots.models import PilotModel, create_model, model_type, model_type_names
from parts.pilots.preprocess import Preprocess, preprocess_from_config
from training.acceleration import TrainPlan, apply_layout, plan_for
from training.augment import Augmenter, AugmentSettings
from training.balance import balance_by_steering
from training.batch_augment import BatchAugmenter
from training.dataset import (
    IMAGE_KEY,
    DriveData,
    PilotDataset,
    behavior_labels,
    behavior_mirror,
    build_samples,
    read_drive_data,
)
from training.distributed import DistInfo, init_distributed, shutdown_distributed
from training.fit import EventSink, FitSettings, fit
from training.framecache import FrameCache
from training.hyperparams import check_config
from training.progress_log import ProgressLog
from training.recipes import Recipe
from training.split import split_train_val
from training.train_report import plot_losses, sidecar, write_metrics
from training.views import require_views
from vehicle.config import check_settings

__all__ = ["default_model_path", "prepare_data", "train"]

logger = logging.getLogger(__name__)


def default_model_path(models_dir: Path) -> Path:
    """``models/pilot_YY-MM-DD_N.pt`` with the first free N (DonkeyCar's naming)."""
    day = datetime.now().strftime("%y-%m-%d")
    n = 1
    while (models_dir / f"pilot_{day}_{n}.pt").exists():
        n += 1
    return models_dir / f"pilot_{day}_{n}.pt"


def interrupted_path(model_path: Path) -> Path:
    """Where a run that would replace ``model_path`` keeps its best model until it finishes, and
    where a stopped one leaves it (``pilot.pt`` -> ``pilot.interrupted.pt``)."""
    return model_path.with_name(f"{model_path.stem}.interrupted{model_path.suffix}")


def dataset_model_path(models_dir: Path, tub: str | os.PathLike[str]) -> Path:
    """``models/[dataset]_[N].pt`` with the first free N from 1 (Track Driver AI's naming), the
    dataset being the folder name of ``tub``."""
    name = Path(tub).resolve().name or "data"
    n = 1
    while (models_dir / f"{name}_{n}.pt").exists():
        n += 1
    return models_dir / f"{name}_{n}.pt"


def _recipe_side_cameras(cfg: Any, recipe: Recipe, data: DriveData) -> Any:
    """A recipe's side cameras where the tubs have them: the documents drove Udacity's simulator,
    which records three cameras; a tub of one camera trains on the centre frames alone."""
    side = dict(cfg.TRAIN_SIDE_CAMERAS)
    present = {k: v for k, v in side.items() if data.records[0].data.get(k) is not None}
    if present != side:
        logger.warning("recipe %s adds the side cameras %s where a tub has them; these tubs hold only %s",
                       recipe.name, ", ".join(sorted(side)), ", ".join([IMAGE_KEY, *sorted(present)]))
        cfg = cfg.replace(TRAIN_SIDE_CAMERAS=present)
    return cfg


def model_options(cfg: Any, type_name: str, data: DriveData) -> dict[str, Any]:
    """Options of ``type_name`` that follow the car's config or the data."""
    cls = model_type(type_name)
    unknown = sorted(set(cfg.MODEL_OPTIONS) - set(cls.defaults))
    if unknown:
        raise ValueError(f"MODEL_OPTIONS names {unknown}, which model type {type_name!r} does not take; "
                         f"it takes {sorted(cls.defaults)}")
    opts: dict[str, Any] = dict(cfg.MODEL_OPTIONS)
    if "seq_length" in cls.defaults:
        opts["seq_length"] = cfg.SEQUENCE_LENGTH
    if "mem_length" in cls.defaults:
        opts["mem_length"] = cfg.SEQUENCE_LENGTH
    if "throttle_range" in cls.defaults:
        opts["throttle_range"] = float(cfg.MODEL_CATEGORICAL_MAX_THROTTLE_RANGE)
    if "num_behaviors" in cls.defaults:
        key = cls.extra_inputs[0]
        value = data.records[0].data.get(key)
        if value is None:
            raise ValueError(f"the records have no {key!r}: record with behaviours (BEHAVIOR_LIST) to train "
                             "a behavior model")
        names, _ = behavior_labels(data, cfg.BEHAVIOR_LIST)
        opts["num_behaviors"] = len(names) if names is not None else len(value)
    return opts


@dataclass
class PreparedData:
    """What :func:`prepare_data` builds: datasets, their preprocessing, and figures for the metadata."""

    data: DriveData
    train: PilotDataset
    val: PilotDataset | None
    preprocess: Preprocess
    image_shape: tuple[int, int, int]
    info: dict[str, Any]
    batch_augment: BatchAugmenter | None = None  # the batch-tensor augmentations (training only)


def prepare_data(cfg: Any, data: DriveData, model: PilotModel, preprocess: Preprocess,
                 augmentations: Sequence[str] | None = None, progress: bool = False,
                 behavior_order: Sequence[str] | None = None) -> PreparedData:
    """Split, balance, expand side cameras, cache frames and wrap everything as datasets.

    A behaviour model's one-hot input follows ``behavior_order`` (default BEHAVIOR_LIST; a
    transferred model's own order), each record placed by its behaviour's name
    (:func:`training.dataset.behavior_labels`).
    """
    train_pos, val_pos = split_train_val(data.segments, cfg.TRAIN_TEST_SPLIT, cfg.TRAIN_SPLIT_BY,
                                         cfg.TRAIN_SPLIT_BLOCK, cfg.TRAIN_SEED)
    n_split = len(train_pos)
    if cfg.TRAIN_BALANCE:
        train_pos = balance_by_steering(data.angles, train_pos, cfg.TRAIN_BALANCE_BINS,
                                        cfg.TRAIN_BALANCE_MAX_PER_BIN, cfg.TRAIN_SEED)
        logger.info("balanced by steering: %d of %d training records kept", len(train_pos), n_split)
    side = dict(cfg.TRAIN_SIDE_CAMERAS)
    if model.views > 1:  # the views are one sample (three_camera), not a sample each with an offset
        if side:
            logger.info("TRAIN_SIDE_CAMERAS left out: model type %s takes %s together", model.type_name,
                        ", ".join(model.image_inputs))
        side = {}
    _check_side_cameras(data, side)
    keys = list(model.image_inputs) if model.views > 1 else [IMAGE_KEY, *side]
    offsets = [0.0, *(float(v) for v in side.values())]
    depth = max(model.frames - 1, model.command_history)
    train_s = build_samples(data, train_pos, n_keys=1 + len(side), depth=depth)
    val_s = build_samples(data, val_pos, n_keys=1, depth=depth)  # validate on what the car sees: centre
    cache = FrameCache(data.records, keys, enabled=cfg.TRAIN_CACHE_IMAGES, max_mb=cfg.TRAIN_CACHE_MAX_MB)
    bad = cache.fill(np.union1d(train_s.positions(), val_s.positions()), progress=progress)
    if bad.size:
        train_s = train_s.subset(~np.isin(train_s.chain, bad).any(axis=1))
        val_s = val_s.subset(~np.isin(val_s.chain, bad).any(axis=1))
    if len(train_s) == 0:
        why = (f"sequence models need {depth} consecutive records before each sample" if depth
               else "the frames of every record could not be read: see the warnings above")
        raise ValueError(f"no training samples left from {len(data)} records ({why}); record more data")
    names = cfg.AUGMENTATIONS if augmentations is None else list(augmentations)
    order = cfg.BEHAVIOR_LIST if behavior_order is None else behavior_order
    mirror, behaviors, extra_values = _behavior_inputs(data, model, names, order)
    if mirror is None and behaviors is not None and "flip" in names:
        names = [n for n in names if n != "flip"]
    if cfg.TRAIN_FLIP_COPY:
        if mirror is None and behaviors is not None:
            logger.warning("TRAIN_FLIP_COPY left out: the behaviours have no left/right mirror, so a "
                           "mirrored frame has no correct behaviour")
        else:
            train_s, val_s = train_s.with_mirrored_copies(), val_s.with_mirrored_copies()
    aug_settings = AugmentSettings.from_config(cfg, names)
    augmenter = Augmenter(aug_settings) if aug_settings.names else None
    batch_augment = BatchAugmenter(aug_settings, cfg.TRAIN_SEED)
    if batch_augment and (preprocess.color != "rgb" or preprocess.lanes is not None):
        logger.warning("augmentations %s left out: they work on RGB frames and this model takes %s%s input",
                       ", ".join(batch_augment.names), preprocess.color, " + lanes" if preprocess.lanes else "")
        batch_augment = None
    common = {"frames": model.frames, "command_history": model.command_history,
              "extra_key": model.extra_inputs[0] if model.extra_inputs else None,
              "extra_size": model.extra_size, "extra_mirror": mirror, "extra_values": extra_values,
              "views": model.views}
    train_ds = PilotDataset(data, train_s, cache, preprocess, key_offsets=offsets, augmenter=augmenter,
                            seed=cfg.TRAIN_SEED, **common)
    val_ds = PilotDataset(data, val_s, cache, preprocess, **common) if len(val_s) else None
    info = {"records": len(data), "train_records": int(len(train_pos)), "val_records": int(len(val_pos)),
            "train_samples": len(train_s), "val_samples": len(val_s), "camera_keys": keys,
            "side_camera_offsets": side, "frames_cached": cache.cached, "cache_mb": round(cache.nbytes / 1e6, 1),
            "augmentations": aug_settings.to_dict(), "behaviors": behaviors}
    return PreparedData(data, train_ds, val_ds, preprocess, tuple(cache.get(int(train_s.chain[0, 0])).shape),
                        info, batch_augment or None)


def _check_side_cameras(data: DriveData, side: dict[str, float]) -> None:
    """ValueError naming a TRAIN_SIDE_CAMERAS key that records lack, and the image keys they hold.

    A record without the image would otherwise be skipped with a warning per record that asks
    for ``tub check --repair``, though the tub is fine and the setting is wrong.
    """
    for key in side:
        lacking = sum(not rec.has_image(key) for rec in data.records)
        if lacking:
            held = sorted({k for rec in data.records[:1000] for k, v in rec.data.items()
                           if k.startswith("cam/") and isinstance(v, str) and v.endswith((".jpg", ".png"))})
            raise ValueError(f"TRAIN_SIDE_CAMERAS names {key!r} but {lacking} of {len(data)} records have no "
                             f"image under it; the tubs' images are {', '.join(held) or 'none'}: name those "
                             "in TRAIN_SIDE_CAMERAS, or set it to {} to train on the centre camera only")


def _behavior_inputs(data: DriveData, model: PilotModel, augmentations: Sequence[str], order: Sequence[str]
                     ) -> tuple[np.ndarray | None, list[str] | None, np.ndarray | None]:
    """For a behaviour model: (permutation of the one-hot for flipped frames, behaviour names, the
    one-hot of every record in the order of the names).

    The one-hot is rebuilt from each record's behaviour name, so tubs recorded with different
    BEHAVIOR_LIST orders train one meaning per input (see :func:`behavior_labels`). A flipped
    frame of the left lane shows the right lane, so its behaviour is swapped; when the records do
    not name the behaviours or a name has no mirror, flipping would teach wrong labels and is left
    out (with a warning). (None, None, None) for models without a behaviour input.

    Raises:
        ValueError: the behaviours cannot be placed (see :func:`behavior_labels`), or the model
            takes another number of behaviours than the records name.
    """
    if "behavior/one_hot_state_array" not in model.extra_inputs:
        return None, None, None
    names, index = behavior_labels(data, order)
    values = None
    if names is not None and index is not None:
        if len(names) != model.extra_size:
            raise ValueError(f"the model takes {model.extra_size} behaviours but the records are placed on "
                             f"{len(names)} ({names}): train a new model, or set BEHAVIOR_LIST to the model's")
        values = np.zeros((len(index), len(names)), np.float32)
        values[np.arange(len(index)), index] = 1.0
    mirror = behavior_mirror(names) if names is not None else None
    if mirror is None and "flip" in augmentations:
        why = (f"behaviours {names} have no left/right mirror" if names is not None
               else "the records do not name every behaviour (behavior/state, behavior/label)")
        logger.warning("flip augmentation left out: %s, so a flipped frame has no correct behaviour", why)
    return mirror, names if names is not None else [], values


def _loaders(prep: PreparedData, batch_size: int, workers: int, dist_info: DistInfo, plan: TrainPlan,
             seed: int) -> tuple[DataLoader, DataLoader | None]:
    # Workers are not persistent: each epoch forks them afresh with the dataset's current epoch (the
    # augmentation draws depend on it) and the frame cache shared copy-on-write.
    common: dict[str, Any] = {"batch_size": batch_size, "num_workers": workers,
                              "pin_memory": plan.pin_memory}
    if dist_info.enabled:
        train_sampler = DistributedSampler(prep.train, num_replicas=dist_info.world_size, rank=dist_info.rank,
                                           shuffle=True, seed=seed)
        train = DataLoader(prep.train, sampler=train_sampler, drop_last=False, **common)
        val = None
        if prep.val is not None:
            val_sampler = DistributedSampler(prep.val, num_replicas=dist_info.world_size, rank=dist_info.rank,
                                             shuffle=False)
            val = DataLoader(prep.val, sampler=val_sampler, **common)
        return train, val
    gen = torch.Generator()
    gen.manual_seed(seed)
    train = DataLoader(prep.train, shuffle=True, generator=gen, **common)
    val = DataLoader(prep.val, shuffle=False, **common) if prep.val is not None else None
    return train, val


def train(cfg: Any, tubs: Sequence[str | os.PathLike[str]], model_path: str | os.PathLike[str], *,
          model_type_name: str | None = None, transfer: str | os.PathLike[str] | None = None,
          epochs: int | None = None, batch_size: int | None = None, learning_rate: float | None = None,
          device: str | None = None, workers: int | None = None, augmentations: Sequence[str] | None = None,
          comment: str | None = None, register: bool = True, progress: bool | None = None,
          precision: str | None = None, on_event: EventSink | None = None,
          should_stop: Callable[[], bool] | None = None, recipe: Recipe | None = None) -> dict[str, Any]:
    """Train a model on ``tubs`` and write it to ``model_path``; returns the metrics.

    ``recipe``: the document recipe whose settings ``cfg`` holds (checked against the frames,
    named in the model's metadata).

    Arguments left None take the car's settings (MAX_EPOCHS, BATCH_SIZE, LEARNING_RATE,
    TRAIN_DEVICE, TRAIN_NUM_WORKERS, AUGMENTATIONS, DEFAULT_MODEL_TYPE, TRAIN_PRECISION). The car's
    settings are checked by :func:`training.hyperparams.check_config`, the rules the CLI and the
    console use.

    Raises:
        ValueError: bad settings or no usable data (the message says what to change).
        parts.pilots.modelfile.ModelFileError: ``transfer`` is not a usable model file.
    """
    started = time.time()
    epochs = cfg.MAX_EPOCHS if epochs is None else epochs
    batch_size = cfg.BATCH_SIZE if batch_size is None else batch_size
    learning_rate = cfg.LEARNING_RATE if learning_rate is None else learning_rate
    workers = cfg.TRAIN_NUM_WORKERS if workers is None else workers
    check_settings(MAX_EPOCHS=epochs, BATCH_SIZE=batch_size, LEARNING_RATE=learning_rate)  # the settings' bounds
    check_config(cfg, model_type_names())

    def phase(name: str) -> None:
        if on_event is not None:
            on_event({"event": "phase", "phase": name})
    model_path = Path(model_path)
    if model_path.suffix != ".pt":
        raise ValueError(f"model file {model_path} must end in .pt (e.g. models/mypilot.pt)")
    dist_info, dev = init_distributed(device or cfg.TRAIN_DEVICE)
    clean = False
    try:
        torch.manual_seed(cfg.TRAIN_SEED)
        phase("reading")
        model, preprocess, type_name, data, old_meta, cfg = _build_model(cfg, tubs, transfer, model_type_name, recipe)
        speed_scale = cfg.TRAIN_SPEED_SCALE if cfg.TRAIN_THROTTLE_LABEL == "speed" else None
        phase("preparing")
        # a transferred behaviour model keeps the order of its one-hot inputs
        order = (old_meta.get("training") or {}).get("behaviors") if old_meta is not None else None
        prep = prepare_data(cfg, data, model, preprocess, augmentations,
                            progress=dist_info.is_main and (progress if progress is not None else _tty()),
                            behavior_order=order or None)
        model.to(dev)
        plan = plan_for(dev, precision or cfg.TRAIN_PRECISION, cfg.TRAIN_COMPILE,
                        spatial_model=model.frames == 1 and model.views == 1)  # 4-D batches only
        apply_layout(model, plan)
        n_params = sum(p.numel() for p in model.parameters())
        if dist_info.is_main:
            _log_start(model, type_name, n_params, dev, prep.info, plan, cfg.PRINT_MODEL_SUMMARY)
        train_model: torch.nn.Module = model
        if dist_info.enabled:
            ids = [dev.index] if dev.type == "cuda" else None
            train_model = torch.nn.parallel.DistributedDataParallel(model, device_ids=ids)
        train_loader, val_loader = _loaders(prep, batch_size, workers, dist_info, plan, cfg.TRAIN_SEED)
        training = {"epochs": epochs, "batch_size": batch_size, "learning_rate": learning_rate,
                    **_training_record(cfg, speed_scale, recipe), "device": str(dev), **plan.to_dict(),
                    "world_size": dist_info.world_size, "parameters": n_params,
                    **{k: v for k, v in prep.info.items() if k not in ("records",)}}
        # the frames it learns from: undistorted (CAMERA_UNDISTORT) or not; the car must match
        base_meta = {"type": type_name, "preprocess": preprocess.to_dict(), "training": training,
                     "camera": camera_meta(cfg), "datasets": data.tubs, "transfer": str(transfer) if transfer else None,
                     "comment": comment, "created": datetime.now(UTC).isoformat(timespec="seconds")}

        # A model the user already has is replaced only by a finished run: until then the best so
        # far goes beside it, and a stopped run leaves it there (kept_model below).
        had_model = model_path.exists()
        best_path = interrupted_path(model_path) if had_model else model_path
        if dist_info.is_main:
            best_path.unlink(missing_ok=True)  # an older interrupted run's: never taken for this one's

        def save_best(epoch: int, history: Any) -> None:
            if dist_info.is_main:
                save_model(best_path, model, {**base_meta, "metrics": _metrics(history, prep, started)})

        settings = _fit_settings(cfg, epochs, learning_rate, progress)
        if on_event is not None and dist_info.is_main:
            on_event({"event": "start", "type": type_name, "parameters": n_params, "device": str(dev),
                      "records": len(data), "train_samples": prep.info["train_samples"],
                      "val_samples": prep.info["val_samples"], "epochs": epochs, "batch_size": batch_size,
                      "batches": cfg.TRAIN_STEPS_PER_EPOCH or len(train_loader), "model": str(model_path)})
            phase("training")
        sink = on_event
        if dist_info.is_main and not (progress if progress is not None else _tty()):
            sink = ProgressLog(on_event)  # no progress bar: a log line at a steady interval instead
        history = fit(train_model, train_loader, val_loader, preprocess, dev, settings, dist_info, save_best,
                      plan=plan, on_event=sink, should_stop=should_stop, augment=prep.batch_augment)
        # every rank got through the last collective: from here each leaves through the barrier,
        # rank 0 even when its own file writing below fails, so no peer waits for it in vain
        clean = True
        metrics = _metrics(history, prep, started)
        metrics["epochs_planned"] = epochs
        final = _keep_or_replace(model_path, best_path, had_model, history.cancelled, dist_info.is_main)
        metrics["model_file"] = str(final)
        metrics["kept_model"] = str(model_path) if final != model_path else None
        if dist_info.is_main:
            _finish(final, base_meta, metrics, history, type_name, cfg.SHOW_PLOT, register, comment)
        return metrics
    finally:
        shutdown_distributed(clean=clean)


def _build_model(cfg: Any, tubs: Sequence[str | os.PathLike[str]], transfer: str | os.PathLike[str] | None,
                 model_type_name: str | None, recipe: Recipe | None) -> tuple[Any, Preprocess, str, Any,
                                                                            dict[str, Any] | None, Any]:
    """Read the tubs and make the model to train: a new one of the asked type, or the ``transfer``
    model (its type and preprocessing kept). Returns (model, preprocess, type name, data, the
    transferred model's metadata or None, cfg with the recipe's side-camera settings)."""
    old_meta: dict[str, Any] | None = None
    if transfer is not None:
        model, old_meta = load_model(transfer)
        old_type = old_meta["model"]["type"]
        if model_type_name is not None and model_type_name != old_type:
            raise ValueError(f"--transfer {transfer} is a {old_type!r} model but --type {model_type_name} "
                             "was asked; leave out --type or transfer from a model of that type")
        model_type_name = old_type
    type_name = model_type_name or cfg.DEFAULT_MODEL_TYPE
    model_type(type_name)  # unknown types fail before reading any data
    speed_scale = cfg.TRAIN_SPEED_SCALE if cfg.TRAIN_THROTTLE_LABEL == "speed" else None
    data = read_drive_data(tubs, modes=cfg.TRAIN_MODES, record_filter=cfg.TRAIN_FILTER, speed_scale=speed_scale)
    if len(model_type(type_name).image_inputs) > 1:  # three_camera: every record needs every view
        require_views(type_name, model_type(type_name).image_inputs, data.records)
    image_shape = tuple(int(v) for v in data.records[0].image(IMAGE_KEY).shape)
    if recipe is not None:
        recipe.check_frames(image_shape)
        cfg = _recipe_side_cameras(cfg, recipe, data)
    if old_meta is not None:
        preprocess = Preprocess.from_dict(old_meta["preprocess"])
        if preprocess.image_shape is not None and preprocess.image_shape != image_shape:
            raise ValueError(f"--transfer model was trained on {preprocess.image_shape} frames, these tubs "
                             f"hold {image_shape} frames")
    else:
        preprocess = preprocess_from_config(cfg, type_name, image_shape)
        model = create_model(type_name, preprocess.output_shape(image_shape), **model_options(cfg, type_name, data))
    return model, preprocess, type_name, data, old_meta, cfg


def _training_record(cfg: Any, speed_scale: float | None, recipe: Recipe | None) -> dict[str, Any]:
    """The settings a training ran with, as its model file records them (beside epochs, batch
    size, learning rate, device, plan and data counts)."""
    return {"weight_decay": cfg.TRAIN_WEIGHT_DECAY,
            "early_stop_patience": cfg.EARLY_STOP_PATIENCE if cfg.USE_EARLY_STOP else None,
            "min_delta": cfg.MIN_DELTA, "train_test_split": cfg.TRAIN_TEST_SPLIT, "split_by": cfg.TRAIN_SPLIT_BY,
            "flip_copy": cfg.TRAIN_FLIP_COPY,
            # the throttle output is a target speed of speed_scale m/s per unit (the Pilot drives to it)
            **({"throttle_label": "speed", "speed_scale": speed_scale} if speed_scale else {}),
            "split_block": cfg.TRAIN_SPLIT_BLOCK, "seed": cfg.TRAIN_SEED, "modes": list(cfg.TRAIN_MODES),
            "filter": getattr(cfg.TRAIN_FILTER, "__name__", None) if cfg.TRAIN_FILTER else None,
            "balance": {"bins": cfg.TRAIN_BALANCE_BINS, "max_per_bin": cfg.TRAIN_BALANCE_MAX_PER_BIN}
            if cfg.TRAIN_BALANCE else None,
            "steps_per_epoch": cfg.TRAIN_STEPS_PER_EPOCH, "val_steps": cfg.TRAIN_VAL_STEPS,
            "lr_schedule": cfg.TRAIN_LR_SCHEDULE,
            "warmup": cfg.TRAIN_WARMUP if cfg.TRAIN_LR_SCHEDULE != "constant" else None,
            "recipe": recipe.name if recipe is not None else None, "model_options": dict(cfg.MODEL_OPTIONS)}


def _keep_or_replace(model_path: Path, best_path: Path, had_model: bool, cancelled: bool, is_main: bool) -> Path:
    """Where the run's model is: a finished run's best replaces the user's model; a stopped one
    stays beside it (the user's model is never lost to an unfinished run)."""
    if had_model and not cancelled and best_path.exists():
        if is_main:
            os.replace(best_path, model_path)
        return model_path
    return best_path


def _log_start(model: Any, type_name: str, n_params: int, dev: torch.device, info: dict[str, Any], plan: TrainPlan,
               summary: bool) -> None:
    """The training's first log lines: model, data, device and plan (PRINT_MODEL_SUMMARY: the layers)."""
    logger.info("training %s model (%d parameters) on %s: %d training / %d validation samples",
                type_name, n_params, dev, info["train_samples"], info["val_samples"])
    logger.info("training plan on %s: %s", _device_name(dev), plan.describe())
    if summary:
        logger.info("%s", model)


def _fit_settings(cfg: Any, epochs: int, learning_rate: float, progress: bool | None) -> FitSettings:
    """The optimiser and stopping settings of the car's configuration."""
    return FitSettings(epochs=epochs, learning_rate=learning_rate, weight_decay=cfg.TRAIN_WEIGHT_DECAY,
                       patience=cfg.EARLY_STOP_PATIENCE if cfg.USE_EARLY_STOP else None,
                       min_delta=cfg.MIN_DELTA, progress=progress, steps_per_epoch=cfg.TRAIN_STEPS_PER_EPOCH,
                       val_steps=cfg.TRAIN_VAL_STEPS, lr_schedule=cfg.TRAIN_LR_SCHEDULE, warmup=cfg.TRAIN_WARMUP)


def _device_name(dev: torch.device) -> str:
    if dev.type == "cuda":
        return f"{dev} ({torch.cuda.get_device_name(dev)})"
    return str(dev)


def _tty() -> bool:
    import sys

    return sys.stderr.isatty()


def _metrics(history: Any, prep: PreparedData, started: float) -> dict[str, Any]:
    h = history.as_dict()
    best = h["best_epoch"]
    return {**h, "best_val_loss": h["val_loss"][best - 1] if best else None,
            "best_train_loss": h["train_loss"][best - 1] if best else None,
            "train_samples": prep.info["train_samples"], "val_samples": prep.info["val_samples"],
            "wall_seconds": round(time.time() - started, 2)}


def _finish(model_path: Path, base_meta: dict[str, Any], metrics: dict[str, Any], history: Any, type_name: str,
            show_plot: bool, register: bool, comment: str | None) -> None:
    """Final metadata into the best model file, the metrics JSON, the loss plot and the model database."""
    if not model_path.exists():
        if metrics.get("cancelled"):
            raise ValueError("training was cancelled before its first epoch ended: no model was saved")
        raise ValueError("training produced no model (no epoch had a finite loss)")
    model, meta = load_model(model_path)
    meta = {**{k: v for k, v in meta.items() if k != "model"}, "metrics": metrics}
    save_model(model_path, model, meta)
    write_metrics(sidecar(model_path, ".metrics.json"), {"model": str(model_path), "type": type_name, **metrics})
    if show_plot:
        try:
            plot_losses(sidecar(model_path, ".loss.png"), history.train_loss, history.val_loss,
                        f"{model_path.name} ({type_name})", history.best_epoch)
        except ImportError:
            logger.warning("matplotlib is not installed: no loss plot (pip install matplotlib)")
    if register:
        try:
            from training.model_db import register_model

            register_model(model_path, meta, comment=comment)
        except Exception as exc:  # the model is written; a db problem must not lose it
            logger.warning("model saved but not registered: %s", exc)
    best = metrics.get("best_val_loss")
    logger.info("saved %s (best epoch %d, val_loss %s)", model_path, metrics["best_epoch"],
                f"{best:.5f}" if isinstance(best, float) and math.isfinite(best) else "n/a")
