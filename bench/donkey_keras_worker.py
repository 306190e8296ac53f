"""DonkeyCar 5.3's Keras trainer, one epoch per command: the worker bench/donkey_train.py drives.

Runs in DonkeyCar's own virtual environment (bench/setup_donkey_venv.sh with WITH_TENSORFLOW=1):

    .bench/donkey-venv/bin/python bench/donkey_keras_worker.py TUB CROP_TOP BATCH THREADS

It builds what ``donkey train --type linear`` builds (donkeycar.pipeline.training.train): the tub's
records through ``TubDataset``, DonkeyCar's random 80/20 split, ``BatchSequence`` tf.data pipelines
(its image cache, ``normalize_image``) with the top CROP_TOP rows cut off (DonkeyCar's CROP
transformation masks them instead, keeping 120x160 inputs: cutting matches our input size),
``KerasLinear`` for that input compiled with Adam and MSE, then waits on stdin. Each line
``epoch`` trains one epoch and validates (``model.fit`` with ``initial_epoch``, as Keras continues a
run), keeps the best weights by validation loss (DonkeyCar's
ModelCheckpoint ``save_best_only``), and answers one JSON line: samples, seconds, losses.
``save PATH`` writes the best weights as .npz (layer name/index -> arrays); ``quit`` ends.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import time


def _stub_unused_imports() -> None:
    """donkeycar.pipeline.training imports pandas (for its model database) and albumentations (for
    augmentations): neither runs here (no database, AUGMENTATIONS = []), so where the venv lacks
    them (setup_donkey_venv.sh installs neither) they are stand-ins: an empty Compose."""
    import importlib.util
    import types

    if importlib.util.find_spec("pandas") is None:
        pd = types.ModuleType("pandas")
        pd.DataFrame = type("DataFrame", (), {})  # never instantiated: Keras's isinstance checks say no
        pd.Series = type("Series", (), {})
        sys.modules["pandas"] = pd
    if importlib.util.find_spec("albumentations") is None:
        class Compose(list):
            def __init__(self, transforms):
                super().__init__(transforms)

        names = ("albumentations", "albumentations.core", "albumentations.core.transforms_interface",
                 "albumentations.augmentations")
        mods = {name: types.ModuleType(name) for name in names}
        mods["albumentations"].Compose = Compose
        mods["albumentations"].GaussianBlur = mods["albumentations.augmentations"].RandomBrightnessContrast = None
        mods["albumentations.core.transforms_interface"].BasicTransform = object
        mods["albumentations"].core = mods["albumentations.core"]
        mods["albumentations.core"].transforms_interface = mods["albumentations.core.transforms_interface"]
        mods["albumentations"].augmentations = mods["albumentations.augmentations"]
        sys.modules.update(mods)


def main() -> int:
    tub, crop_top, batch = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    threads = int(sys.argv[4]) if len(sys.argv) > 4 else 0  # 0: TensorFlow's default (every core)
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    _stub_unused_imports()
    with contextlib.redirect_stdout(io.StringIO()):  # donkeycar prints a banner on import
        import numpy as np
        import tensorflow as tf
        from donkeycar.config import Config
        from donkeycar.parts.interpreter import KerasInterpreter
        from donkeycar.parts.keras import KerasLinear
        from donkeycar.pipeline.training import BatchSequence
        from donkeycar.pipeline.types import TubDataset
        from donkeycar.utils import train_test_split

    tf.random.set_seed(42)
    if threads:
        tf.config.threading.set_intra_op_parallelism_threads(threads)
        tf.config.threading.set_inter_op_parallelism_threads(1)

    class TrainClock(tf.keras.callbacks.Callback):
        """When fit's validation starts: the epoch's training seconds without it."""

        def on_epoch_begin(self, epoch, logs=None):
            self.start = time.perf_counter()
            self.train_end = None

        def on_test_begin(self, logs=None):
            self.train_end = time.perf_counter()

    clock = TrainClock()
    cfg = Config()
    cfg.from_object(type("Defaults", (), {
        "IMAGE_H": 120, "IMAGE_W": 160, "IMAGE_DEPTH": 3, "BATCH_SIZE": batch, "TRAIN_TEST_SPLIT": 0.8,
        "LEARNING_RATE": 0.001, "TRANSFORMATIONS": [], "POST_TRANSFORMATIONS": [],
        "AUGMENTATIONS": [], "ROI_CROP_TOP": crop_top, "ROI_CROP_BOTTOM": 0, "ROI_CROP_LEFT": 0,
        "ROI_CROP_RIGHT": 0, "CACHE_IMAGES": True, "SEQUENCE_LENGTH": 3, "DEFAULT_MODEL_TYPE": "linear",
        "TRAIN_FILTER": None}))
    kl = KerasLinear(interpreter=KerasInterpreter(), input_shape=(120 - crop_top, 160, 3))
    kl.compile()
    model = kl.interpreter.model
    dataset = TubDataset(config=cfg, tub_paths=[tub], seq_size=kl.seq_size())
    train_records, val_records = train_test_split(dataset.get_records(), shuffle=True, test_size=0.2)
    class CroppedBatchSequence(BatchSequence):
        """DonkeyCar's pipeline with the sky cut off (a view of the cached frame): its own CROP
        transformation only masks the rows black and trains at the full 120x160."""

        def image_processor(self, img_arr):
            # the bottom rows: TubRecord caches the processed frame and processes it again on the
            # next read, so the cut must be idempotent
            return super().image_processor(img_arr)[-(120 - crop_top):]

    train_pipe = CroppedBatchSequence(kl, cfg, train_records, is_train=True)
    val_pipe = CroppedBatchSequence(kl, cfg, val_records, is_train=False)
    tune = tf.data.experimental.AUTOTUNE
    train_data = train_pipe.create_tf_data().prefetch(tune)
    val_data = val_pipe.create_tf_data().prefetch(tune)
    print(json.dumps({"ready": True, "train_records": len(train_records), "val_records": len(val_records),
                      "tf": tf.__version__, "input": list(kl.input_shape)}), flush=True)
    best, best_weights, epoch = float("inf"), None, 0
    for line in sys.stdin:
        cmd = line.split()
        if not cmd or cmd[0] == "quit":
            break
        if cmd[0] == "epoch":
            start, cpu = time.perf_counter(), time.process_time()
            h = model.fit(train_data, steps_per_epoch=len(train_pipe), epochs=epoch + 1, initial_epoch=epoch,
                          validation_data=val_data, validation_steps=len(val_pipe), verbose=0,
                          callbacks=[clock])
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
            epoch += 1
            val = float(h.history["val_loss"][-1])
            if val < best:
                best, best_weights = val, [w.copy() for w in model.get_weights()]
            print(json.dumps({"epoch": epoch, "seconds": seconds, "cpu_seconds": cpu,
                              "train_seconds": clock.train_end - clock.start,
                              "samples": len(train_pipe) * batch,
                              "train_loss": float(h.history["loss"][-1]), "val_loss": val, "best": val == best}),
                  flush=True)
        elif cmd[0] == "save":
            names = [f"{i:02d}_{w.name}" for i, w in enumerate(model.weights)]
            np.savez(cmd[1], **dict(zip(names, best_weights or model.get_weights(), strict=True)))
            print(json.dumps({"saved": cmd[1]}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
