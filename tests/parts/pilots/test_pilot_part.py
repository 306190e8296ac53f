"""The Pilot part: same preprocessing as training, clamped and NaN-proof outputs, declared inputs,
internal state of memory and sequence models, speed control and the hot model switch."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
import torch

from parts.drive.speed import SpeedControl
from parts.pilots import load_pilot
from parts.pilots.modelfile import load_model
from parts.pilots.pilot import ModelSwitch, Pilot
from parts.pilots.preprocess import Preprocess


def bare(path, frame, extra=None, frames=1):
    """What the model predicts for ``frame`` without the part: the reference."""
    model, meta = load_model(path)
    x = Preprocess.from_dict(meta["preprocess"])(frame)
    x = x.expand(frames, *x.shape)[None] if frames > 1 else x[None]
    with torch.no_grad():
        e = None if extra is None else torch.tensor([extra], dtype=torch.float32)
        return model.controls(model(x, e))[0].tolist()


def test_pilot_matches_the_model_on_the_training_preprocessing(make_model_file, frame):
    path = make_model_file("linear")
    pilot = load_pilot(path, backend="torch")
    assert pilot.inputs == ["cam/image_array"]
    assert pilot.model_name == "linear.pt" and pilot.runner.backend == "torch"
    angle, throttle = pilot.run(frame)
    assert isinstance(angle, float) and isinstance(throttle, float)
    assert [angle, throttle] == pytest.approx(bare(path, frame), abs=1e-6)
    assert not pilot.runner.model.training  # eval mode: dropout off, so repeated runs agree
    assert pilot.run(frame) == (angle, throttle)


def test_outputs_are_clamped(make_model_file, frame):
    path = make_model_file("linear")
    model, meta = load_model(path)
    last = model.head[-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.copy_(torch.tensor([5.0, -3.0]))
    from parts.pilots.modelfile import save_model

    save_model(path, model, meta)
    assert load_pilot(path, backend="torch").run(frame) == (1.0, -1.0)


def test_infinite_and_nan_predictions_give_zero_and_a_rate_limited_warning(make_model_file, frame, caplog):
    path = make_model_file("linear")
    model, meta = load_model(path)
    with torch.no_grad():  # finite weights whose sum overflows float32: the model outputs inf
        model.head[-1].weight.fill_(3e38)
        model.head[-1].bias.fill_(3e38)
    from parts.pilots.modelfile import save_model

    save_model(path, model, meta)
    pilot = load_pilot(path, backend="torch")
    assert not all(math.isfinite(v) for v in bare(path, frame))
    with caplog.at_level("WARNING"):
        assert pilot.run(frame) == (0.0, 0.0)
        pilot.runner.predict = lambda images, extra: (math.nan, 0.5)
        assert pilot.run(frame) == (0.0, 0.0)
    assert pilot.nonfinite_count == 2
    assert sum("non-finite command" in r.message for r in caplog.records) == 1


def test_no_frame_yet_means_stand_still(make_model_file):
    assert load_pilot(make_model_file("linear"), backend="torch").run(None) == (0.0, 0.0)
    # also with speed control, which would give full throttle at standstill
    pilot = load_pilot(make_model_file("linear"), backend="torch",
                       speed_control=SpeedControl("limit", default_limit=2.0))
    assert pilot.run(None, 0.0) == (0.0, 0.0)


def test_wrong_number_of_inputs_is_a_clear_error(make_model_file, frame):
    pilot = load_pilot(make_model_file("behavior"), backend="torch")
    with pytest.raises(TypeError, match=r"takes 2 inputs \['cam/image_array', 'behavior/one_hot_state_array'\]"):
        pilot.run(frame)
    with pytest.raises(ValueError, match="trained with 2"):
        pilot.run(frame, [0.0, 1.0, 0.0])


def test_behavior_model_reads_the_one_hot_state(make_model_file, frame):
    path = make_model_file("behavior")
    pilot = load_pilot(path, backend="torch")
    assert pilot.inputs == ["cam/image_array", "behavior/one_hot_state_array"]
    left, right = pilot.run(frame, [1.0, 0.0]), pilot.run(frame, [0.0, 1.0])
    assert list(left) == pytest.approx(bare(path, frame, [1.0, 0.0]), abs=1e-6)
    assert list(right) == pytest.approx(bare(path, frame, [0.0, 1.0]), abs=1e-6)
    assert left != right
    # no behaviour state yet: zeros (and a warning), never a crash of the loop
    assert list(pilot.run(frame, None)) == pytest.approx(bare(path, frame, [0.0, 0.0]), abs=1e-6)


def test_memory_model_feeds_back_its_previous_commands(make_model_file, frame):
    path = make_model_file("memory", mem_length=2)
    pilot = load_pilot(path, backend="torch")
    assert pilot.inputs == ["cam/image_array"]  # the history is kept inside the part
    first = pilot.run(frame)
    assert list(first) == pytest.approx(bare(path, frame, [0.0, 0.0, 0.0, 0.0]), abs=1e-6)
    second = pilot.run(frame)
    assert list(second) == pytest.approx(bare(path, frame, [0.0, 0.0, *first]), abs=1e-6)
    third = pilot.run(frame)
    assert list(third) == pytest.approx(bare(path, frame, [*first, *second]), abs=1e-6)


def test_sequence_model_buffers_the_last_frames(make_model_file, frame):
    path = make_model_file("rnn", seq_length=3)
    pilot = load_pilot(path, backend="torch")
    # first call: the one frame repeated 3 times
    assert list(pilot.run(frame)) == pytest.approx(bare(path, frame, frames=3), abs=1e-6)
    other = np.zeros_like(frame)
    pilot.run(other)
    pilot.run(other)
    assert list(pilot.run(other)) == pytest.approx(bare(path, other, frames=3), abs=1e-6)


def test_speed_control_replaces_the_throttle_with_its_own_target(make_model_file, frame):
    path = make_model_file("linear")
    pilot = load_pilot(path, backend="torch", speed_control=SpeedControl("limit", default_limit=2.0),
                       speed_key="sim/speed")
    assert pilot.inputs == ["cam/image_array", "sim/speed"]  # not the page's limit: that one caps
    angle, throttle = pilot.run(frame, 1.0)
    assert throttle == pytest.approx(0.5)  # 1 - 1.0 / 2.0
    assert angle == pytest.approx(bare(path, frame)[0], abs=1e-6)
    off = load_pilot(path, backend="torch", speed_control=SpeedControl("limit"), speed_key="sim/speed")
    assert off.run(frame, 1.0)[1] == pytest.approx(bare(path, frame)[1], abs=1e-6)  # no target set


def test_hot_switch_loads_in_the_background_and_swaps(make_model_file, frame, tmp_path):
    a = make_model_file("linear", name="a", seed=1)
    b = make_model_file("linear", name="b", seed=2)
    pilot = Pilot(a, backend="torch", models_dir=a.parent)
    switch = ModelSwitch(pilot)
    assert switch.run(None) == ("a.pt", None)
    assert switch.run("b.pt")[0] in ("a.pt", "b.pt")  # relative to models_dir; never waits for the load
    assert pilot.wait_loaded(timeout=30)
    assert switch.run("b.pt") == ("b.pt", None)
    assert pilot.resolve("models/b.pt") == b  # a car-relative path from another working directory
    assert list(pilot.run(frame)) == pytest.approx(bare(b, frame), abs=1e-6)
    # a file that does not load keeps the current model driving
    (tmp_path / "broken.pt").write_bytes(b"not a model")
    switch.run(str(tmp_path / "broken.pt"))
    assert pilot.wait_loaded(timeout=30)
    assert pilot.model_name == "b.pt" and "broken.pt" in pilot.load_error
    assert list(pilot.run(frame)) == pytest.approx(bare(b, frame), abs=1e-6)
    name, error = switch.run(str(tmp_path / "broken.pt"))  # the same request: not loaded again
    assert name == "b.pt" and "broken.pt" in error  # pilot/load_error: the page shows why
    # the file fixed and asked for again once the picker let go of the request: it loads
    (tmp_path / "broken.pt").write_bytes(a.read_bytes())
    switch.run(None)
    switch.run(str(tmp_path / "broken.pt"))
    assert pilot.wait_loaded(timeout=30)
    assert switch.run(None) == ("broken.pt", None)


def test_a_switch_to_another_type_changes_the_declared_inputs(make_model_file, frame):
    pilot = load_pilot(make_model_file("linear"), backend="torch")
    pilot.request_model(make_model_file("behavior"))
    assert pilot.wait_loaded(timeout=30)
    assert pilot.inputs == ["cam/image_array", "behavior/one_hot_state_array"]


def test_missing_model_file_is_a_clear_error(tmp_path):
    from parts.pilots.modelfile import ModelFileError

    with pytest.raises(ModelFileError, match="no such model file"):
        load_pilot(tmp_path / "nope.pt")
    with pytest.raises(ValueError, match="unknown pilot backend"):
        load_pilot(tmp_path / "nope.pt", backend="tflite")


def test_importing_the_package_does_not_import_torch():
    code = "import sys, parts.pilots; assert 'torch' not in sys.modules and callable(parts.pilots.load_pilot)"
    subprocess.run([sys.executable, "-c", code], check=True)
