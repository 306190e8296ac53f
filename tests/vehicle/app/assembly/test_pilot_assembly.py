"""add_pilot: PilotCondition, the model switch and the Pilot wired into a Vehicle."""

from __future__ import annotations

import numpy as np
import pytest

from parts.drive.modes import DriveMode
from parts.pilots.compat import ModelMismatch
from vehicle import Vehicle
from vehicle.app.assembly.pilot import add_pilot, make_pilot
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import PartError, UserError


def vehicle_with_frames(frame, mode):
    V = Vehicle(clock=SimulatedClock())
    V.mem["cam/image_array"] = frame
    V.mem["user/mode"] = mode
    return V


@pytest.mark.parametrize("mode, runs", [("local", True), ("user", False)])
def test_pilot_runs_only_in_pilot_modes(make_model_file, frame, mode, runs):
    path = make_model_file("linear")
    V = vehicle_with_frames(frame, mode)
    pilot = add_pilot(V, Config.defaults(PILOT_BACKEND="torch"), path)
    V.start(rate_hz=20, max_loop_count=3)
    assert V.mem["run_pilot"] is runs
    assert V.mem["pilot/model"] == "linear.pt"
    if runs:
        assert (V.mem["pilot/angle"], V.mem["pilot/throttle"]) == pilot.run(frame)
    else:
        assert V.mem.get(["pilot/angle"]) == [None]


def test_speed_control_wires_the_speed_and_the_limit(make_model_file, frame):
    V = vehicle_with_frames(frame, "local")
    V.add(lambda: 1.5, outputs=["sim/speed"])  # a simulator at 1.5 m/s
    cfg = Config.defaults(PILOT_BACKEND="torch", PILOT_SPEED_CONTROL="limit", PILOT_SPEED_LIMIT=2.0)
    pilot = add_pilot(V, cfg, make_model_file("linear"))
    assert pilot.inputs == ["cam/image_array", "sim/speed"]  # its own target: not the page's limit
    V.start(rate_hz=20, max_loop_count=2)
    assert V.mem["pilot/throttle"] == pytest.approx(0.25)  # 1 - 1.5 / 2.0


def test_hot_switch_in_a_running_vehicle(make_model_file, frame):
    a = make_model_file("linear", name="a", seed=1)
    make_model_file("linear", name="b", seed=2)
    V = vehicle_with_frames(frame, "local")
    pilot = add_pilot(V, Config.defaults(PILOT_BACKEND="torch", CAR_PATH=str(a.parent.parent)), a)
    V.add(DriveMode(), inputs=["user/mode", "user/angle", "user/throttle", "pilot/angle", "pilot/throttle"],
          outputs=["angle", "throttle"])
    V.mem.put(["user/angle", "user/throttle"], [0.0, 0.0])
    V.mem["pilot/model_request"] = "b.pt"  # what the web page's model picker writes (in MODELS_PATH)
    V.start(rate_hz=20, max_loop_count=2)
    assert pilot.wait_loaded(timeout=30)
    after_switch = pilot.run(frame)
    assert pilot.model_name == "b.pt"
    # a model that needs other inputs is refused while wired: the loop's input list is fixed
    pilot.request_model(make_model_file("behavior"))
    assert pilot.wait_loaded(timeout=30)
    assert pilot.model_name == "b.pt" and "restart the car" in pilot.load_error
    assert pilot.run(frame) == after_switch


def test_missing_model_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="no such model file"):
        add_pilot(Vehicle(), Config.defaults(CAR_PATH=str(tmp_path)), "models/nope.pt")


def model_for_frames(tmp_path, shape, name="small", model_type="linear", **options):
    """A model file trained (untrained here) on camera frames of ``shape`` (H, W, 3)."""
    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    pre = Preprocess(image_shape=shape)
    model = create_model(model_type, pre.output_shape(shape), **options)
    return save_model(tmp_path / "models" / f"{name}.pt", model, {"preprocess": pre.to_dict()})


def test_a_model_of_another_frame_size_is_refused_at_load(tmp_path):
    # issue 21: it was accepted and stopped the whole drive process at the first frame in auto mode
    from vehicle.app.assembly.sim import add_simulator

    path = model_for_frames(tmp_path, (90, 120, 3))
    V = Vehicle(clock=SimulatedClock())
    cfg = Config.defaults(PILOT_BACKEND="torch", CAR_PATH=str(tmp_path))
    add_simulator(V, cfg)
    with pytest.raises(UserError, match=r"frame is 120x160x3 but the model was trained on 90x120x3 frames; "
                                         r"set SIM_CAMERA_W/SIM_CAMERA_H to the training size or re-train"):
        add_pilot(V, cfg, path)
    # the simulator's own camera size counts, not IMAGE_W/IMAGE_H
    V = Vehicle(clock=SimulatedClock())
    cfg = cfg.replace(SIM_CAMERA_W=120, SIM_CAMERA_H=90)
    add_simulator(V, cfg)
    assert add_pilot(V, cfg, path).model_name == "small.pt"



def test_a_model_of_another_frame_size_says_what_sizes_the_frames_at_the_first_frame(make_model_file):
    # frames of a part that does not say their size (the Donkey simulator's, a camera part of the
    # user's): the pilot learns it from the first frame and refuses there, with the setting to change
    path = make_model_file("linear")  # 120x160 frames
    V = vehicle_with_frames(np.zeros((90, 120, 3), np.uint8), "local")
    add_pilot(V, Config.defaults(PILOT_BACKEND="torch"), path)
    with pytest.raises(PartError) as info:
        V.start(rate_hz=20, max_loop_count=2)
    assert isinstance(info.value.cause, ModelMismatch)
    assert str(info.value.cause) == ("frame is 90x120x3 but the model was trained on 120x160x3 frames; "
                                     "set IMAGE_W/IMAGE_H to the training size or re-train")

def test_a_model_with_another_number_of_behaviours_is_refused_at_load(make_model_file, frame):
    path = make_model_file("behavior", num_behaviors=2)
    V = vehicle_with_frames(frame, "local")
    V.mem["behavior/one_hot_state_array"] = [1.0, 0.0, 0.0]
    cfg = Config.defaults(PILOT_BACKEND="torch", TRAIN_BEHAVIORS=True, BEHAVIOR_LIST=["a", "b", "c"])
    with pytest.raises(UserError, match=r"behavior/one_hot_state_array .*3 values.*trained with 2"):
        add_pilot(V, cfg, path)


def test_a_switch_to_a_model_of_another_frame_size_keeps_the_running_pilot(make_model_file, frame, tmp_path):
    a = make_model_file("linear", name="a", seed=1)
    small = model_for_frames(a.parent.parent, (90, 120, 3))
    V = vehicle_with_frames(frame, "local")
    pilot = add_pilot(V, Config.defaults(PILOT_BACKEND="torch", CAR_PATH=str(a.parent.parent)), a)
    V.mem["pilot/model_request"] = small.name  # picked on the web page while the pilot drives
    V.start(rate_hz=20, max_loop_count=2)
    assert pilot.wait_loaded(timeout=30)
    assert pilot.model_name == "a.pt"
    assert "frame is 120x160x3 but the model was trained on 90x120x3 frames" in pilot.load_error
    V.start(rate_hz=20, max_loop_count=3)  # the car goes on driving with the running pilot
    assert V.mem["pilot/model"] == "a.pt" and V.mem["pilot/angle"] is not None


def _behaviour_model(make_model_file, name, behaviors, camera=None):
    """A behaviour model file whose metadata says the behaviour order it was trained with (and how
    its frames were undistorted, ``camera``)."""
    from parts.pilots.modelfile import load_model, save_model

    path = make_model_file("behavior", name=name)
    model, meta = load_model(path)
    meta = {k: v for k, v in meta.items() if k != "model"}
    meta["training"] = {"behaviors": list(behaviors)}
    if camera is not None:
        meta["camera"] = camera
    return save_model(path, model, meta)


def test_a_reordered_behavior_list_is_refused(make_model_file, frame):
    path = _behaviour_model(make_model_file, "lanes_lr", ["Left_Lane", "Right_Lane"])
    cfg = Config.defaults(PILOT_BACKEND="torch", TRAIN_BEHAVIORS=True, BEHAVIOR_LIST=["Right_Lane", "Left_Lane"])
    with pytest.raises(UserError) as err:
        make_pilot(cfg, path)
    message = str(err.value)
    assert "\n" not in message
    assert "trained with ['Left_Lane', 'Right_Lane'], BEHAVIOR_LIST is ['Right_Lane', 'Left_Lane']" in message
    assert "TRAIN_BEHAVIORS" not in message
    with pytest.raises(UserError, match="set TRAIN_BEHAVIORS = True"):
        make_pilot(cfg.replace(TRAIN_BEHAVIORS=False), path)
    # the same order drives; a car without the behaviour part is told to add it
    assert make_pilot(cfg.replace(BEHAVIOR_LIST=["Left_Lane", "Right_Lane"]), path).model_name == "lanes_lr.pt"
    V = vehicle_with_frames(frame, "local")
    with pytest.raises(UserError, match="set TRAIN_BEHAVIORS = True"):
        add_pilot(V, cfg.replace(BEHAVIOR_LIST=["Left_Lane", "Right_Lane"], TRAIN_BEHAVIORS=False), path)


def test_a_refused_hot_switch_keeps_the_running_pilot(make_model_file, frame):
    a = _behaviour_model(make_model_file, "a", ["Left_Lane", "Right_Lane"])
    b = _behaviour_model(make_model_file, "b", ["Right_Lane", "Left_Lane"])
    cfg = Config.defaults(PILOT_BACKEND="torch", TRAIN_BEHAVIORS=True, CAR_PATH=str(a.parent.parent))
    pilot = make_pilot(cfg, a)
    before = pilot.run(frame, [1.0, 0.0])
    assert pilot.request_model(b)
    assert pilot.wait_loaded(timeout=30)
    assert pilot.model_name == "a.pt" and "BEHAVIOR_LIST is ['Left_Lane', 'Right_Lane']" in pilot.load_error
    assert pilot.run(frame, [1.0, 0.0]) == before


def test_undistortion_must_match_the_frames_the_model_was_trained_on(make_model_file, tmp_path, caplog):
    import logging

    import numpy as np

    from parts.sim.camera import PinholeCamera
    from parts.vision.calibration import CameraCalibration

    car = tmp_path / "car"
    CameraCalibration((320, 240), PinholeCamera(320, 240).intrinsics, np.zeros(5), 0.1).save(
        car / "camera_calibration.json")
    cfg = Config.defaults(PILOT_BACKEND="torch", CAR_PATH=str(car), TRAIN_BEHAVIORS=True)
    undistorted = _behaviour_model(make_model_file, "u", ["Left_Lane", "Right_Lane"],
                                   camera={"undistort": True, "calibration_size": [320, 240]})
    with pytest.raises(UserError, match="trained on undistorted frames.*CAMERA_UNDISTORT = True"):
        make_pilot(cfg, undistorted)
    assert make_pilot(cfg.replace(CAMERA_UNDISTORT=True), undistorted).model_name == "u.pt"
    raw = _behaviour_model(make_model_file, "r", ["Left_Lane", "Right_Lane"],
                           camera={"undistort": False, "calibration_size": None})
    with pytest.raises(UserError, match="CAMERA_UNDISTORT = False"):
        make_pilot(cfg.replace(CAMERA_UNDISTORT=True), raw)
    # a calibration made at another size: a warning (the undistorted view may differ a little)
    other = _behaviour_model(make_model_file, "o", ["Left_Lane", "Right_Lane"],
                             camera={"undistort": True, "calibration_size": [640, 480]})
    with caplog.at_level(logging.WARNING):
        make_pilot(cfg.replace(CAMERA_UNDISTORT=True), other)
    assert "640x480" in caplog.text and "320x240" in caplog.text


def test_a_registered_model_swapped_for_another_is_refused(make_model_file, frame, capsys):
    """Item 14: a valid model file put under a registered model's name (its CRC-32s all pass) is
    refused in one line by the car, a hot switch and ``vehicle sim eval``; the untouched file drives."""
    import os

    from training.model_db import register_model
    from vehicle.app.cli import main
    from vehicle.errors import VehicleError

    a = make_model_file("linear", name="a", seed=1)
    b = make_model_file("linear", name="b", seed=2)
    other = make_model_file("linear", name="other", seed=3)
    car = a.parent.parent
    (car / "myconfig.py").write_text("PILOT_BACKEND = 'torch'\n")
    for path in (a, b):
        register_model(path, {"type": "linear"})  # into models/models.sqlite3, as training does
    cfg = Config.defaults(PILOT_BACKEND="torch", CAR_PATH=str(car))
    pilot = make_pilot(cfg, a)  # untouched: drives
    before = pilot.run(frame)
    os.replace(other, b)  # another intact model file under b's name
    assert pilot.request_model("b.pt")
    assert pilot.wait_loaded(timeout=30)
    assert pilot.model_name == "a.pt" and "changed since it was registered as model 'b'" in pilot.load_error
    assert pilot.run(frame) == before
    with pytest.raises(VehicleError) as err:
        make_pilot(cfg, b)
    message = str(err.value)
    assert "\n" not in message and f"{b.resolve()}: changed since it was registered as model 'b'" in message
    assert "vehicle models rehash b" in message
    assert main(["sim", "eval", "--car", str(car), "--pilot", str(b), "--tracks", "101", "--laps", "1",
                 "--no-store"]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and "changed since it was registered as model 'b'" in err_lines[0]
