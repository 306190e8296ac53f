"""The three-camera model (seed 000's "3 Cameras" extension): architecture, the pilot part feeding
it the left, centre and right frames (PyTorch and ONNX), and its refusal where a car lacks them."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from parts.pilots.models import create_model, model_type
from parts.pilots.pilot import Pilot
from vehicle import Vehicle
from vehicle.app import assembly
from vehicle.app.assembly.pilot import add_pilot
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import WiringError

VIEWS = ["cam/image_array_left", "cam/image_array", "cam/image_array_right"]


def conv(cin: int, cout: int, k: int) -> int:
    return cin * cout * k * k + cout


def dense(n_in: int, n_out: int) -> int:
    return n_in * n_out + n_out


def test_parameter_count_follows_the_layer_list_and_outputs_steering_and_throttle():
    model = create_model("three_camera", (3, 66, 200))
    # DAVE-2's trunk, shared by the three views: 66x200 -> 31x98 -> 14x47 -> 5x22 -> 3x20 -> 1x18
    trunk = conv(3, 24, 5) + conv(24, 36, 5) + conv(36, 48, 5) + conv(48, 64, 3) + conv(64, 64, 3)
    per_view = 64 * 1 * 18
    head = dense(3 * per_view, 100) + dense(100, 50) + dense(50, 10) + dense(10, 2)
    assert sum(p.numel() for p in model.trunk.parameters()) == trunk == 131_348
    assert sum(p.numel() for p in model.parameters()) == trunk + head == 482_630
    out = model(torch.zeros(4, 3, 3, 66, 200))
    assert out.shape == (4, 2)  # steering, throttle
    assert model.describe()["image_inputs"] == VIEWS
    assert isinstance(model.head[1], torch.nn.ELU)  # Track Driver AI's DAVE-2 activation by default
    with pytest.raises(ValueError, match=r"takes \(N, 3, C, H, W\)"):
        model(torch.zeros(4, 3, 66, 200))  # one frame is not three views
    assert model_type("pilotnet").image_inputs == ("cam/image_array",)  # every other type: the centre frame


def views_of(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three different frames: the frame, and it shifted 8 pixels left and right."""
    return np.roll(frame, 8, axis=1), frame, np.roll(frame, -8, axis=1)


def test_the_pilot_feeds_all_three_frames_with_torch_and_onnx(make_model_file, frame, torch_one_thread):
    from training.export import export_model

    path = make_model_file("three_camera", seed=3)
    left, centre, right = views_of(frame)
    pilot = Pilot(path, backend="torch")
    assert pilot.inputs == VIEWS  # the vehicle wires it left, centre, right
    angle, throttle = pilot.run(left, centre, right)
    runner = pilot.runner
    x = torch.from_numpy(np.stack([runner.preprocess(v) for v in (left, centre, right)])[None])
    with torch.inference_mode():
        expected = runner.model(x)[0].clamp(-1, 1).tolist()
    assert [angle, throttle] == pytest.approx(expected, abs=1e-6)
    assert pilot.run(right, centre, left) != pytest.approx((angle, throttle), abs=1e-4)  # the order matters
    assert pilot.run(None, centre, right) == (0.0, 0.0)  # a view not there yet: stand still
    with pytest.raises(TypeError, match="takes 3 inputs"):
        pilot.run(centre)
    pilot.shutdown()

    for fmt, suffix in (("onnx", ".onnx"), ("torchscript", ".ts")):  # exports take (1, 3, C, H, W)
        export_model(path, fmt)
        exported = Pilot(path.with_suffix(suffix))
        assert exported.runner.backend == fmt and exported.inputs == VIEWS
        assert exported.run(left, centre, right) == pytest.approx((angle, throttle), abs=1e-4)
        exported.shutdown()


def test_refused_in_a_car_without_side_cameras(make_model_file, tmp_path):
    path = make_model_file("three_camera")
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CAMERA_TYPE="MOCK", SIM_TEXTURE_RES=0.02)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_camera(V, cfg)
    with pytest.raises(WiringError) as err:
        add_pilot(V, cfg, path)
    message = str(err.value)
    assert "\n" not in message and "no cam/image_array_left and no cam/image_array_right" in message
    assert "this car has one camera" in message and not V.find(Pilot)

    # the built-in simulator without side cameras: the message names the setting
    sim_car = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(sim_car, cfg.replace(SIM_CAMERA_W=160, SIM_CAMERA_H=120), seeds=[3])
    with pytest.raises(WiringError, match="set SIM_SIDE_CAMERAS_OFFSET"):
        add_pilot(sim_car, cfg, path)


def test_the_udacity_simulator_sends_only_the_centre_frame_so_driving_and_evaluation_refuse(make_model_file,
                                                                                             tmp_path):
    from vehicle.app.evaluate import evaluate

    path = make_model_file("three_camera", frames=(160, 320))
    cfg = Config.defaults(CAR_PATH=str(tmp_path))
    V = Vehicle()
    assembly.add_simulator(V, cfg, sim_type="udacity")  # `vehicle udacity drive`'s car (not started)
    with pytest.raises(WiringError, match="Udacity simulator sends only the centre frame while driving"):
        add_pilot(V, cfg, path)
    with pytest.raises(WiringError, match="Udacity simulator sends only the centre frame while driving"):
        evaluate(path, cfg=cfg, sim="udacity")  # refused before waiting for the simulator
    with pytest.raises(WiringError, match="set SIM_SIDE_CAMERAS_OFFSET"):
        evaluate(path, [3], cfg=cfg.replace(SIM_CAMERA_W=320, SIM_CAMERA_H=160))
