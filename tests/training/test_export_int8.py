"""int8 ONNX exports: static (calibrated on tub frames) and dynamic quantisation, the onnx-int8
backend, and the CLI."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from parts.pilots import load_pilot
from training.export import export_model
from training.trainer import train
from vehicle.app.cli import main
from vehicle.config import Config

pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def trained(tmp_path_factory, tiny_tub):
    """A linear model trained for 6 epochs on the tiny tub (its bar-position steering is learnt)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        folder = tmp_path_factory.mktemp("int8")
        cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=6, AUGMENTATIONS=[], TRAIN_SEED=0, CAR_PATH=str(folder),
                              SHOW_PLOT=False)
        path = folder / "models" / "pilot.pt"
        train(cfg, [tiny_tub], path, register=False)
        return path
    finally:
        torch.set_num_threads(before)


def _frames(tub, n=40):
    from parts.tub.reader import load_records

    records = list(load_records([str(tub)]))
    return [records[i].image("cam/image_array") for i in np.linspace(0, len(records) - 1, n).astype(int)]


def _steering(pilot, frames):
    return np.array([pilot.run(f)[0] for f in frames])


@pytest.mark.parametrize("method", ["static", "dynamic"])
def test_int8_export_steers_like_the_float_export(trained, tiny_tub, tmp_path, method):
    model = shutil.copy(trained, tmp_path / "pilot.pt")
    export_model(model, "onnx")
    out = export_model(model, "onnx-int8", int8=method, calibration=[tiny_tub] if method == "static" else None)
    assert out.name == "pilot.int8.onnx"
    int8 = load_pilot(model, backend="onnx-int8")
    assert int8.runner.backend == "onnx-int8" and int8.model_name == "pilot.int8.onnx"
    record = int8.runner.quantization
    assert record["method"] == method
    assert record["calibration_frames"] == (120 if method == "static" else 0)  # every record of the tub
    frames = _frames(tiny_tub)
    fp32 = _steering(load_pilot(model, backend="onnx"), frames)
    q = _steering(int8, frames)
    assert np.std(fp32) > 0.2  # the model steers (trained), so the comparison means something
    assert np.abs(q - fp32).mean() < 0.05
    assert load_pilot(out).runner.backend == "onnx-int8"  # the export alone knows what it is
    assert load_pilot(model).runner.backend == "onnx"  # auto never picks int8


def test_static_int8_calibrates_on_the_training_tubs_by_default(trained):
    out = export_model(trained, "onnx-int8")
    assert load_pilot(out).runner.quantization["calibration_tubs"] != []


def test_static_int8_without_calibration_data_says_what_to_do(make_model_file):
    path = make_model_file("linear")  # its metadata names data/tub_1, which does not exist
    with pytest.raises(ValueError, match="--calibration TUB"):
        export_model(path, "onnx-int8")
    assert not path.with_suffix(".int8.onnx").exists()
    with pytest.raises(ValueError, match="unknown int8 method 'fp8'"):
        export_model(path, "onnx-int8", int8="fp8")


def test_onnx_int8_backend_refuses_missing_stale_or_float_exports(make_model_file):
    path = make_model_file("linear", seed=1)
    with pytest.raises(ValueError, match="no onnx-int8 export"):
        load_pilot(path, backend="onnx-int8")
    float_onnx = export_model(path, "onnx")
    with pytest.raises(ValueError, match="float ONNX export, not an int8 one"):
        load_pilot(float_onnx, backend="onnx-int8")
    export_model(path, "onnx-int8", int8="dynamic")
    make_model_file("linear", seed=2)  # retrained since
    with pytest.raises(ValueError, match="re-export"):
        load_pilot(path, backend="onnx-int8")
    export_model(path, "onnx-int8", int8="dynamic")
    export_model(path, "onnx-int8", path.with_suffix(".onnx"), int8="dynamic")  # int8 where the float one goes
    with pytest.raises(ValueError, match="not an onnx export"):
        load_pilot(path, backend="onnx")


def test_cli_exports_int8_and_removes_it_with_the_model(trained, tiny_tub, tmp_path, capsys):
    car = tmp_path / "car"
    (car / "models").mkdir(parents=True)
    (car / "myconfig.py").write_text("")
    model = shutil.copy(trained, car / "models" / "pilot.pt")
    from parts.pilots.modelfile import read_meta
    from training.model_db import register_model

    register_model(model, read_meta(model))
    assert main(["models", "export", "pilot", "--format", "onnx-int8", "--calibration", str(tiny_tub),
                 "--calibration-frames", "20", "--car", str(car)]) == 0
    out = car / "models" / "pilot.int8.onnx"
    assert f"wrote {out}" in capsys.readouterr().out
    assert load_pilot(out).runner.quantization["calibration_frames"] == 20
    assert main(["models", "export", "pilot", "--format", "onnx-int8", "--calibration-frames", "0",
                 "--car", str(car)]) == 2
    assert "--calibration-frames must be >= 1" in capsys.readouterr().err
    assert main(["models", "rm", "pilot", "--delete-files", "--car", str(car)]) == 0
    assert not out.exists()
