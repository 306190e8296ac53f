"""Export to ONNX and TorchScript: outputs equal eager PyTorch, and the auto backend prefers an
ONNX export only when it was made from the .pt as it is now."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from parts.pilots import load_pilot
from training.export import export_model
from vehicle.app.cli import main

# every kind of input: plain, extra from memory (behaviour), fed-back history, frame sequence,
# decoded outputs (categorical argmax, derived throttle)
TYPES = [("linear", {}), ("behavior", {}), ("memory", {"mem_length": 2}), ("rnn", {"seq_length": 3}),
         ("categorical", {}), ("pilotnet", {}), ("lanes", {})]


def drive(pilot, frames, extra):
    return [pilot.run(f, *extra) for f in frames]


@pytest.mark.parametrize("model_type, options", TYPES)
def test_exports_match_eager(make_model_file, model_type, options):
    path = make_model_file(model_type, **options)
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (120, 160, 3), dtype=np.uint8) for _ in range(4)]
    eager = load_pilot(path, backend="torch")
    extra = [[0.0, 1.0]] * len(eager.runner.extra_inputs)
    expected = np.array(drive(eager, frames, extra))
    for fmt, backend in (("onnx", "onnx"), ("torchscript", "torchscript")):
        out = export_model(path, fmt)
        assert out.suffix == {"onnx": ".onnx", "torchscript": ".ts"}[fmt] and out.parent == path.parent
        for pilot in (load_pilot(path, backend=backend), load_pilot(out)):  # via the .pt, or the export alone
            assert pilot.runner.backend == backend
            got = np.array(drive(pilot, frames, extra))
            if model_type == "categorical":  # argmax of nearly equal logits: compare bins, not floats
                assert np.abs(got - expected).max() < 0.15
            else:
                np.testing.assert_allclose(got, expected, atol=2e-5)


def test_auto_prefers_a_matching_onnx_export_and_ignores_a_stale_one(make_model_file, frame, caplog):
    path = make_model_file("linear", seed=1)
    assert load_pilot(path).runner.backend == "torch"  # no export yet
    export_model(path, "onnx")
    pilot = load_pilot(path)
    assert pilot.runner.backend == "onnx" and pilot.model_name == "linear.onnx"
    assert list(pilot.run(frame)) == pytest.approx(load_pilot(path, backend="torch").run(frame), abs=2e-5)
    make_model_file("linear", seed=2)  # retrained: same name, other weights; the export is stale now
    with caplog.at_level(logging.WARNING):
        assert load_pilot(path).runner.backend == "torch"
    assert "exported from another version" in caplog.text
    with pytest.raises(ValueError, match="re-export"):
        load_pilot(path, backend="onnx")
    with pytest.raises(ValueError, match="no torchscript export"):
        load_pilot(path, backend="torchscript")


def test_onnx_session_uses_one_thread_by_default(make_model_file):
    path = make_model_file("linear")
    export_model(path, "onnx")
    runner = load_pilot(path, backend="onnx").runner
    assert runner.session.get_session_options().intra_op_num_threads == 1
    assert load_pilot(path, backend="onnx", onnx_threads=2).runner.session.get_session_options() \
        .intra_op_num_threads == 2


def test_cli_export(make_model_file, tmp_path, capsys):
    path = make_model_file("linear")
    (tmp_path / "myconfig.py").write_text("")
    from parts.pilots.modelfile import read_meta
    from training.model_db import register_model

    register_model(path, read_meta(path))
    assert main(["models", "export", "linear", "--format", "torchscript", "--car", str(tmp_path)]) == 0
    assert (path.with_suffix(".ts")).is_file()
    out = tmp_path / "elsewhere" / "x.onnx"
    assert main(["models", "export", str(path), "--format", "onnx", "--out", str(out)]) == 0
    assert out.is_file() and f"wrote {out}" in capsys.readouterr().out
    assert main(["models", "export", "nothing", "--car", str(tmp_path)]) == 2
    assert "not a file" in capsys.readouterr().err


def test_an_onnx_pilot_drives_and_is_evaluated_without_torch(make_model_file, tmp_path):
    """A car (a Pi) driving an ONNX export needs onnxruntime, not torch."""
    import subprocess
    import sys

    path = make_model_file("linear")
    export_model(path, "onnx")
    code = f"""
import sys
sys.modules["torch"] = None  # any import of torch now fails
import numpy as np
from parts.pilots import load_pilot
from vehicle.app.evaluate import evaluate
from vehicle.config import Config
pilot = load_pilot({str(path)!r})
assert pilot.runner.backend == "onnx", pilot.runner.backend
angle, throttle = pilot.run(np.zeros((120, 160, 3), np.uint8))
report = evaluate(pilot, [11], 1, cfg=Config.defaults(SIM_TEXTURE_RES=0.02), max_time=1.0)
print("ok", report["tracks"][0]["frames"])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "ok 20" in out.stdout


def _foreign_torchscript(path, meta=None):
    import torch

    """A TorchScript file this framework did not write (optionally with a bogus pilot metadata)."""
    module = torch.jit.script(torch.nn.Linear(2, 2))
    from training.export import META_KEY

    extra = {} if meta is None else {f"{META_KEY}.txt": meta}
    torch.jit.save(module, str(path), _extra_files=extra)
    return path


@pytest.mark.parametrize("content", ["garbage", "truncated", "foreign", "bad-meta", "incomplete-meta"])
def test_corrupt_or_foreign_torchscript_files_are_clear_errors(make_model_file, tmp_path, content):
    from parts.pilots.modelfile import ModelFileError
    from vehicle.app.assembly.pilot import add_pilot
    from vehicle.config import Config
    from vehicle.errors import UserError
    from vehicle.vehicle import Vehicle

    path = tmp_path / f"{content}.ts"
    if content == "garbage":
        path.write_bytes(b"\x00not torchscript at all" * 10)
    elif content == "truncated":
        good = export_model(make_model_file("linear"), "torchscript")
        path.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    elif content == "foreign":
        _foreign_torchscript(path)
    else:
        _foreign_torchscript(path, "{not json" if content == "bad-meta" else '{"model": {}}')
    with pytest.raises(ModelFileError) as info:
        load_pilot(path)
    msg = str(info.value)
    assert str(path) in msg and "\n" not in msg and "Traceback" not in msg
    with pytest.raises(UserError, match="cannot drive with"):
        add_pilot(Vehicle(), Config.defaults(CAR_PATH=str(tmp_path)), path)
