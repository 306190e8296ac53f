"""The simulated car's side cameras (SIM_SIDE_CAMERAS_OFFSET): the same camera, moved sideways."""

from __future__ import annotations

import numpy as np
import pytest

from parts.sim.simulator import OUTPUTS, SIDE_OUTPUTS, SimCar
from vehicle.config import Config


def test_side_frames_are_the_centre_camera_moved_left_and_right():
    sim = SimCar([3], world={"res": 0.02}, side_cameras=0.12, realtime=False)
    assert sim.OUTPUTS == OUTPUTS + SIDE_OUTPUTS  # per car, not per class
    assert SimCar([3], world={"res": 0.02}, realtime=False).OUTPUTS == OUTPUTS
    values = dict(zip(sim.OUTPUTS, sim.run(0.0, 0.5), strict=True))
    x, y, heading = sim.car.state.x, sim.car.state.y, sim.car.state.heading
    left, right = values["cam/image_array_left"], values["cam/image_array_right"]
    assert left.shape == right.shape == values["cam/image_array"].shape == (120, 160, 3)
    assert not np.array_equal(left, values["cam/image_array"])
    # a car placed 0.12 m to its left (right) sees with its centre camera what the left (right) camera saw
    for frame, side in ((left, 0.12), (right, -0.12)):
        sim.car.place(x - side * np.sin(heading), y + side * np.cos(heading), heading)
        assert np.array_equal(sim.render(), frame)

    plain = SimCar([3], world={"res": 0.02}, realtime=False)
    assert plain.OUTPUTS == OUTPUTS and len(plain.run(0.0, 0.5)) == len(OUTPUTS)
    with pytest.raises(ValueError, match="side camera offset must be > 0 m"):
        SimCar([3], world={"res": 0.02}, side_cameras=0.0)


def test_the_setting_turns_them_on_and_refuses_undistortion():
    cfg = Config.defaults(SIM_SIDE_CAMERAS_OFFSET=0.1, SIM_TEXTURE_RES=0.02)
    assert SimCar.from_config(cfg, seeds=[3]).side_cameras == 0.1
    with pytest.raises(ValueError, match="SIM_SIDE_CAMERAS_OFFSET with CAMERA_UNDISTORT"):
        cfg.replace(CAMERA_UNDISTORT=True)


def test_a_simulator_car_records_the_side_frames(tmp_path):
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.clock import SimulatedClock

    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_SIDE_CAMERAS_OFFSET=0.1, SIM_TEXTURE_RES=0.02)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(V, cfg, seeds=[3])
    writer = assembly.add_tub_writer(V, cfg)  # manage.py drive's recording: TUB_INPUTS and what the car makes
    try:
        assert [k for k in writer.inputs if k.startswith("cam/image_array")] == [
            "cam/image_array", "cam/image_array_left", "cam/image_array_right"]
        assert writer.tub.manifest.types[writer.tub.manifest.inputs.index("cam/image_array_left")] == "image_array"
    finally:
        writer.shutdown()
