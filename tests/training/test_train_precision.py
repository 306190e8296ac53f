"""bf16 training costs no quality: on the same data and seeds, its validation loss is within a tolerance of fp32's."""

from __future__ import annotations

import pytest
import torch
from fixtures.pilots import write_tub
from torch.utils.data import DataLoader

from parts.pilots.modelfile import load_model
from parts.pilots.preprocess import Preprocess
from training.acceleration import cpu_caps
from training.dataset import read_drive_data
from training.fit import evaluate
from training.trainer import prepare_data, train
from vehicle.config import Config

#: bf16's validation loss, averaged over SEEDS, may exceed fp32's by at most this factor. For scale:
#: on this data fp32 runs that differ only in the seed spread over 3x (0.0063-0.0203 over 10
#: seeds), and so does one seed trained in bf16 against fp32 (the low-precision arithmetic sends
#: training down another path), which is why the comparison is of means, over six seeds: on an AMD
#: EPYC with AVX512-BF16 the means of seeds 0-2 were 1.28x apart where seeds 0-9 gave 1.06x
#: (fp32 dense head; 1.24x with the head in bf16, which parts.pilots.models.base.Float32Head
#: now prevents).
TOLERANCE = 1.25
SEEDS = (0, 1, 2, 3, 4, 5)
#: whether this CPU does bf16 in hardware: elsewhere bf16 is emulated (minutes for the comparison
#: below, and never chosen by training), so there the tests check that fp32 was chosen instead
NATIVE_BF16 = cpu_caps().native_bf16


@pytest.fixture(scope="module")
def bar_tub(tmp_path_factory):
    """400 records of a bar whose column gives the steering (2 sessions)."""
    return write_tub(tmp_path_factory.mktemp("precision") / "tub", n=200, sessions=2)


def _val_loss_fp32(cfg: Config, tub, path) -> float:
    """The saved model's validation loss computed in fp32 (the same split as training)."""
    model, meta = load_model(path)
    pre = Preprocess.from_dict(meta["preprocess"])
    prep = prepare_data(cfg, read_drive_data([tub]), model, pre)
    return evaluate(model, DataLoader(prep.val, batch_size=64), pre, torch.device("cpu"))


@pytest.mark.skipif(not NATIVE_BF16, reason="this CPU has no native bf16 (AVX512-BF16/AMX): training chooses fp32 "
                                             "here (test_auto_precision_is_what_this_cpu_does_natively)")
def test_bf16_validation_loss_is_within_tolerance_of_fp32(bar_tub, tmp_path, torch_one_thread):
    losses: dict[str, list[float]] = {"fp32": [], "bf16": []}
    for seed in SEEDS:
        for precision in ("fp32", "bf16"):
            cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=8, USE_EARLY_STOP=False, TRAIN_SEED=seed,
                                  CAR_PATH=str(tmp_path), SHOW_PLOT=False)
            path = tmp_path / f"{precision}.pt"
            metrics = train(cfg, [bar_tub], path, precision=precision, register=False)
            model, meta = load_model(path)
            assert meta["training"]["precision"] == precision
            assert all(p.dtype == torch.float32 for p in model.parameters())  # fp32 master weights
            loss = _val_loss_fp32(cfg, bar_tub, path)
            assert metrics["best_val_loss"] == pytest.approx(loss, rel=0.02)  # bf16 validation: close
            losses[precision].append(loss)
    # both learnt the bar: predicting the mean would cost ~0.26 (angle = sin, variance 0.5)
    assert max(losses["fp32"] + losses["bf16"]) < 0.05
    mean = {k: sum(v) / len(v) for k, v in losses.items()}
    assert mean["bf16"] <= TOLERANCE * mean["fp32"], losses


def test_training_logs_its_plan_and_how_long_it_waited_for_data(tiny_tub, tmp_path, torch_one_thread, caplog):
    cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=2, CAR_PATH=str(tmp_path), SHOW_PLOT=False, TRAIN_PRECISION="fp32")
    with caplog.at_level("INFO", logger="training"):
        metrics = train(cfg, [tiny_tub], tmp_path / "m.pt", register=False)
    assert "training plan on cpu: fp32, channels_last, eager (CPU " in caplog.text
    assert "TRAIN_PRECISION = 'fp32'" in caplog.text
    assert "% waiting for data" in caplog.text
    waits, seconds = metrics["epoch_data_seconds"], metrics["epoch_seconds"]
    assert len(waits) == 2 and all(0.0 < w < s for w, s in zip(waits, seconds, strict=True))


def test_auto_precision_is_what_this_cpu_does_natively(tiny_tub, tmp_path, torch_one_thread):
    """TRAIN_PRECISION 'auto' trains in bf16 only where the CPU has it natively, else in fp32."""
    cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=1, CAR_PATH=str(tmp_path), SHOW_PLOT=False)
    assert cfg.TRAIN_PRECISION == "auto"
    train(cfg, [tiny_tub], tmp_path / "m.pt", register=False)
    _, meta = load_model(tmp_path / "m.pt")
    assert meta["training"]["precision"] == ("bf16" if NATIVE_BF16 else "fp32")


def test_the_dense_head_runs_in_float32_under_autocast():
    from parts.pilots.models.base import dense_head

    torch.manual_seed(0)
    head = dense_head(8, (4,), 2, 0.0)
    x = torch.randn(3, 8).bfloat16()  # what a bf16 convolution hands on
    with torch.autocast("cpu", dtype=torch.bfloat16):
        y = head(x)
    assert y.dtype == torch.float32
    assert torch.equal(y, head(x.float()))  # exactly the float32 computation
