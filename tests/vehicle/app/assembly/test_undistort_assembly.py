"""add_undistort: a calibration that cannot serve the camera's frames is refused before the loop."""

from __future__ import annotations

import numpy as np
import pytest

from parts.sim.camera import PinholeCamera
from parts.vision.calibration import CameraCalibration
from vehicle import Vehicle
from vehicle.app.assembly.camera import add_camera, add_undistort
from vehicle.app.assembly.sim import add_simulator
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import UserError


def _calibrate_at(car, width, height):
    CameraCalibration((width, height), PinholeCamera(width, height).intrinsics, np.array([-0.2, 0.05, 0.0, 0.0, 0.0]),
                      0.1).save(car / "camera_calibration.json")


def test_another_aspect_ratio_is_a_one_line_error_before_the_first_frame(tmp_path):
    _calibrate_at(tmp_path, 320, 240)  # 4:3
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CAMERA_UNDISTORT=True, CAMERA_TYPE="MOCK", IMAGE_W=160, IMAGE_H=90)
    with pytest.raises(UserError) as err:
        add_camera(Vehicle(), cfg)
    message = str(err.value)
    assert "\n" not in message and "320x240" in message and "160x90" in message
    assert "IMAGE_W" in message and "vehicle camera calibrate" in message
    # the simulator's frames are SIM_CAMERA_W x SIM_CAMERA_H, whatever IMAGE_W/H say
    sim_cfg = cfg.replace(SIM_TEXTURE_RES=0.02, SIM_CAMERA_W=160, SIM_CAMERA_H=90, IMAGE_W=160, IMAGE_H=120)
    with pytest.raises(UserError, match="SIM_CAMERA_W"):
        add_simulator(Vehicle(clock=SimulatedClock()), sim_cfg)
    # the same aspect ratio at another size is scaled: accepted, maps ready before the loop
    part = add_undistort(Vehicle(), cfg.replace(IMAGE_W=160, IMAGE_H=120))
    assert set(part._maps) == {(160, 120)}
