"""`vehicle camera calibrate` and `vehicle lanes ...` from the command line, and the car using the
result (Undistort in the simulator car's loop)."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from vehicle.app.cli import main

LENS = [-0.25, 0.07, 0.001, -0.0015, 0.0]


@pytest.fixture
def car(tmp_path, monkeypatch):
    """A simulated car with a wide-angle lens on a 320x240 camera, as the current directory."""
    (tmp_path / "myconfig.py").write_text(
        f"SIM_TEXTURE_RES = 0.02\nSIM_CAMERA_W = 320\nSIM_CAMERA_H = 240\nSIM_CAMERA_DISTORTION = {LENS}\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_calibrate_the_simulated_camera_live_then_drive_undistorted(car, capsys):
    assert main(["camera", "calibrate", "--sim", "--views", "12"]) == 0
    out = capsys.readouterr().out
    assert "calibrated from 12 views of 320x240" in out and "CAMERA_UNDISTORT = True" in out
    saved = json.loads((car / "camera_calibration.json").read_text())
    assert saved["rms_px"] < 0.3 and saved["dist_coeffs"][0] == pytest.approx(LENS[0], abs=0.01)
    assert len(list((car / "calibration_views").glob("view_*.png"))) == 12
    assert len(list((car / "calibration_views").glob("corners_*.png"))) == 12
    check = cv2.imread(str(car / "camera_calibration_check.png"))
    assert check.shape == (240, 2 * 320 + 4, 3)

    # the car now undistorts its (simulated) frames: the Undistort part follows the simulator
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import load_config

    cfg = load_config(car_path=car).replace(CAMERA_UNDISTORT=True)
    V = Vehicle()
    sim = assembly.add_simulator(V, cfg)
    names = [type(getattr(e, "part", None)).__name__ for e in V.parts]
    assert names == ["SimCar", "Undistort"]
    V.add(lambda: (0.0, 0.0), outputs=["angle", "throttle"])  # a driver that stands still
    V.start(rate_hz=1000, max_loop_count=2)
    frame = V.mem["cam/image_array"]
    assert frame.shape == (240, 320, 3) and not np.array_equal(frame, sim.render())


def test_calibrate_from_a_folder_and_the_errors(car, capsys, tmp_path):
    from parts.sim.camera import camera_from_config
    from parts.sim.chessboard import random_board_poses, render_board_view
    from vehicle.config import load_config

    camera = camera_from_config(load_config(car_path=car))
    photos = tmp_path / "photos"
    photos.mkdir()
    for i, (r, t) in enumerate(random_board_poses(camera, 10, 7, 10, seed=9)):
        cv2.imwrite(str(photos / f"p{i}.jpg"), cv2.cvtColor(render_board_view(camera, 10, 7, r, t), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert main(["camera", "calibrate", "--images", str(photos), "--out", "cal/cam.json"]) == 0
    out = capsys.readouterr().out
    used = int(re.search(r"calibrated from (\d+) views", out).group(1))
    assert used >= 8 and f"({10 - used} without the whole board" in out  # a board seen too obliquely is named
    assert (car / "cal" / "cam.json").is_file() and len(list((photos / "corners").glob("*.png"))) == used
    # wrong corner count: one line saying what to check
    assert main(["camera", "calibrate", "--images", str(photos), "--board", "9x6"]) == 2
    assert "CAMERA_CALIB_BOARD" in capsys.readouterr().err
    assert main(["camera", "calibrate", "--images", str(photos), "--board", "ten"]) == 2
    assert "COLSxROWS" in capsys.readouterr().err
    assert main(["camera", "calibrate", "--images", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err


def test_undistort_without_a_calibration_says_how_to_make_one(car, capsys):
    (car / "myconfig.py").write_text("CAMERA_UNDISTORT = True\nSIM_TEXTURE_RES = 0.02\n")
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import load_config
    from vehicle.errors import VehicleError

    with pytest.raises(VehicleError, match="vehicle camera calibrate"):  # printed as one line, exit 2
        assembly.add_simulator(Vehicle(), load_config(car_path=car))


def test_lanes_points_and_preview(car, capsys, tmp_path):
    (car / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\nSIM_LANES = 2\n")
    assert main(["lanes", "points", "--sim"]) == 0
    lines = capsys.readouterr().out
    assert "LANE_SOURCE_POINTS = [(" in lines and "LANE_POINTS_SIZE = (160, 120)" in lines
    (car / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\nSIM_LANES = 2\nLANE_COLOR_MASK = 'white'\n" +
                                     "\n".join(ln for ln in lines.splitlines() if ln.startswith("LANE_")) + "\n")
    assert main(["lanes", "preview", "--sim", "--tracks", "1,2", "--frames", "4", "--png", "p.png"]) == 0
    out = capsys.readouterr().out
    assert "wrote p.png: 4 frames of 160x120" in out and "lane pixels per frame" in out
    assert cv2.imread(str(car / "p.png")).shape == (4 * 240, 3 * 320, 3)
    # from a tub recorded with lane changes
    assert main(["sim", "record", "--records", "300", "--tub", "t", "--lane-changes", "2", "--tracks", "1"]) == 0
    assert main(["lanes", "preview", "--tub", "t", "--frames", "3", "--png", "q.png"]) == 0
    assert cv2.imread(str(car / "q.png")).shape == (3 * 240, 3 * 320, 3)
    capsys.readouterr()
    assert main(["lanes", "preview", "--tub", "missing"]) == 2
    assert "no such tub" in capsys.readouterr().err
    (car / "myconfig.py").write_text("LANE_S_THRESHOLD = None\n")
    assert main(["lanes", "preview", "--sim", "--frames", "1"]) == 2
    assert "LANE_COLOR_MASK" in capsys.readouterr().err


def test_live_calibration_from_the_cars_camera_with_the_web_view(tmp_path, monkeypatch, capsys):
    """--live runs the car's own camera part (here a folder of photos replayed as the camera) and
    the web page showing the detected corners."""
    from parts.sim.camera import Camera
    from parts.sim.chessboard import random_board_poses, render_board_view

    camera = Camera(320, 240, distortion=(-0.2, 0.05, 0.0, 0.0, 0.0))
    photos = tmp_path / "photos"
    photos.mkdir()
    for i, (r, t) in enumerate(random_board_poses(camera, 10, 7, 4, seed=11)):
        cv2.imwrite(str(photos / f"{i}.png"), cv2.cvtColor(render_board_view(camera, 10, 7, r, t), cv2.COLOR_RGB2BGR))
    (tmp_path / "myconfig.py").write_text('CAMERA_TYPE = "IMAGE_LIST"\nCAMERA_IMAGE_PATH = "photos"\nIMAGE_W = 320\n'
                                          'IMAGE_H = 240\nWEB_CONTROL_PORT = 0\n')
    monkeypatch.chdir(tmp_path)
    assert main(["camera", "calibrate", "--live", "--views", "3", "--timeout", "60", "--web"]) == 0
    out = capsys.readouterr().out
    assert "calibrated from 3 views of 320x240" in out
    assert len(list((tmp_path / "calibration_views").glob("view_*.png"))) == 3
    assert json.loads((tmp_path / "camera_calibration.json").read_text())["image_size"] == [320, 240]
    # too few views before the timeout: a one-line error
    assert main(["camera", "calibrate", "--live", "--views", "50", "--timeout", "2",
                 "--views-dir", "again"]) == 2
    assert "views were collected" in capsys.readouterr().err
