"""add_pilot: PilotCondition, the model switch and the Pilot wired into a Vehicle."""

from __future__ import annotations

import pytest

from parts.drive.modes import DriveMode
from vehicle import Vehicle
from vehicle.app.assembly.pilot import add_pilot
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import UserError


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
    assert pilot.inputs == ["cam/image_array", "sim/speed", "user/speed_limit"]
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
