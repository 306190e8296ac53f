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
    run, = (car / "calibration_views").iterdir()  # one folder per run
    assert len(list(run.glob("view_*.png"))) == 12
    assert len(list(run.glob("corners_*.png"))) == 12
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
    # the detected corners are drawn into the car folder; the photo folder is left as it was
    assert (car / "cal" / "cam.json").is_file() and len(list((car / "calibration_corners").glob("*.png"))) == used
    assert sorted(p.name for p in photos.iterdir()) == [f"p{i}.jpg" for i in range(10)]
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
    from parts.sim.camera import PinholeCamera
    from parts.sim.chessboard import random_board_poses, render_board_view

    camera = PinholeCamera(320, 240, distortion=(-0.2, 0.05, 0.0, 0.0, 0.0))
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
    assert len(list((tmp_path / "calibration_views").glob("*/view_*.png"))) == 3
    assert json.loads((tmp_path / "camera_calibration.json").read_text())["image_size"] == [320, 240]
    # too few views before the timeout: a one-line error (views are kept at least 1 s apart, so
    # 1.5 s holds at most two, under MIN_VIEWS; 2 s could hold a third at its very end)
    assert main(["camera", "calibrate", "--live", "--views", "50", "--timeout", "1.5",
                 "--views-dir", "again"]) == 2
    assert "views were collected" in capsys.readouterr().err


def _photos(folder, width=320, height=240, n=10, seed=9):
    from parts.sim.camera import PinholeCamera
    from parts.sim.chessboard import random_board_poses, render_board_view

    camera = PinholeCamera(width, height, distortion=LENS)
    folder.mkdir(exist_ok=True)
    for i, (r, t) in enumerate(random_board_poses(camera, 10, 7, n, seed=seed)):
        cv2.imwrite(str(folder / f"p{i}.png"), cv2.cvtColor(render_board_view(camera, 10, 7, r, t), cv2.COLOR_RGB2BGR))
    return folder


def test_a_folder_that_cannot_be_written_is_a_one_line_error(car, capsys, tmp_path):
    photos = _photos(tmp_path / "photos")
    (car / "calibration_corners").write_text("in the way")
    assert main(["camera", "calibrate", "--images", str(photos)]) == 2
    err = capsys.readouterr().err
    assert "calibration_corners" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    (car / "calibration_corners").unlink()
    (car / "blocker").write_text("a file, not a folder")
    assert main(["camera", "calibrate", "--images", str(photos), "--out", "blocker/cam.json"]) == 2
    err = capsys.readouterr().err
    assert "blocker" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_photos_of_another_size_warn_and_of_another_aspect_are_refused(car, capsys, tmp_path):
    # the car's camera: 160x120 (IMAGE_W x IMAGE_H); photos at 320x240 are scaled (a note)
    assert main(["camera", "calibrate", "--images", str(_photos(tmp_path / "big"))]) == 0
    out = capsys.readouterr().out
    assert "the images are 320x240, the car's camera delivers 160x120 (IMAGE_W x IMAGE_H)" in out
    # 16:9 photos cannot serve 4:3 frames: refused, nothing saved
    (car / "camera_calibration.json").unlink()
    assert main(["camera", "calibrate", "--images", str(_photos(tmp_path / "wide", 320, 180, seed=4))]) == 2
    err = capsys.readouterr().err
    assert "another aspect ratio" in err and "car's camera" in err
    assert not (car / "camera_calibration.json").exists()


def test_duplicates_and_unreadable_photos_are_named_and_left_out(car, capsys, tmp_path):
    import shutil

    photos = _photos(tmp_path / "photos")
    shutil.copy(photos / "p0.png", photos / "p0_copy.png")
    (photos / "IMG_1234.heic").write_bytes(b"\x00\x00\x00\x18ftypheic")
    assert main(["camera", "calibrate", "--images", str(photos)]) == 0
    out = capsys.readouterr().out
    assert "near-duplicates of an earlier view: p0_copy.png" in out
    assert "unreadable: IMG_1234.heic" in out and "JPEG" in out


def test_each_live_run_calibrates_its_own_views(car, capsys):
    assert main(["camera", "calibrate", "--sim", "--views", "5"]) == 0
    assert main(["camera", "calibrate", "--sim", "--views", "4", "--views-dir", "mine"]) == 0
    assert main(["camera", "calibrate", "--sim", "--views", "3", "--views-dir", "mine"]) == 0
    out = capsys.readouterr().out
    assert "calibrated from 3 views" in out.splitlines()[-1] or "calibrated from 3 views" in out.split("collecting")[-1]
    assert len(list((car / "mine").glob("view_*.png"))) == 7  # kept, numbered on
    assert json.loads((car / "camera_calibration.json").read_text())["views"] == [
        "view_005.png", "view_006.png", "view_007.png"]


def test_a_wrong_board_size_is_named_while_collecting(tmp_path, monkeypatch, capsys, caplog):
    """The car's camera sees a 10x7 board, the command looks for 8x5: it says so while it runs, and
    the final error says what to count."""
    import logging

    import vehicle.app.commands.camera as camera_command

    _photos(tmp_path / "photos", n=3, seed=11)
    (tmp_path / "myconfig.py").write_text('CAMERA_TYPE = "IMAGE_LIST"\nCAMERA_IMAGE_PATH = "photos"\nIMAGE_W = 320\n'
                                          'IMAGE_H = 240\n')
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(camera_command, "NOT_FOUND_EVERY_S", 0.5)  # 10 s on a car
    with caplog.at_level(logging.WARNING):
        assert main(["camera", "calibrate", "--live", "--views", "3", "--board", "8x5", "--timeout", "1.6"]) == 2
    err = capsys.readouterr().err
    assert "board not found for 0 s" not in caplog.text and "board not found for 1 s" in caplog.text
    assert "inner corners" in caplog.text
    assert "no chessboard was seen" in err and "8x5 inner corners" in err and "--board / CAMERA_CALIB_BOARD" in err


def test_lanes_points_and_preview_are_for_the_frames_the_pilot_sees(car, capsys, tmp_path):
    """A car with a wide-angle lens and CAMERA_UNDISTORT feeds its pilot undistorted frames: the
    points are computed and the preview drawn on those."""
    from parts.sim.camera import PinholeCamera, lane_region_points
    from parts.vision.calibration import CameraCalibration
    from parts.vision.undistort import Undistort

    lens = PinholeCamera(320, 240, distortion=LENS)
    cal = CameraCalibration((320, 240), lens.intrinsics, np.array(LENS), 0.1)
    cal.save(car / "camera_calibration.json")
    base = (car / "myconfig.py").read_text()
    (car / "myconfig.py").write_text(base + "CAMERA_UNDISTORT = True\n")
    assert main(["lanes", "points", "--sim"]) == 0
    out = capsys.readouterr().out
    assert "undistorted with" in out and "CAMERA_UNDISTORT" in out
    expected = lane_region_points(lens, intrinsics=Undistort(cal).output_camera_matrix(320, 240))
    assert f"LANE_SOURCE_POINTS = {[tuple(p) for p in expected['LANE_SOURCE_POINTS']]!r}" in out
    # the preview's raw column is the undistorted frame
    assert main(["lanes", "preview", "--sim", "--tracks", "3", "--frames", "1", "--scale", "1",
                 "--png", "u.png"]) == 0
    assert "undistorting the frames as the car does" in capsys.readouterr().out
    (car / "myconfig.py").write_text(base)
    assert main(["lanes", "preview", "--sim", "--tracks", "3", "--frames", "1", "--scale", "1",
                 "--png", "d.png"]) == 0
    out = capsys.readouterr().out
    assert "undistorting" not in out
    undistorted, distorted = cv2.imread(str(car / "u.png")), cv2.imread(str(car / "d.png"))
    expected_raw = cv2.cvtColor(Undistort(cal).undistort(cv2.cvtColor(distorted[:, :320], cv2.COLOR_BGR2RGB)),
                                cv2.COLOR_RGB2BGR)
    # compare below the label band and away from the outlined region (drawn on both)
    body = (slice(30, 240), slice(0, 320))
    # the undistorted frame, not the lens's: several times closer to the one than to the other (a
    # ratio, since how far the two lie apart depends on what the theme draws: 5 on the road theme)
    near, far = (np.abs(undistorted[body].astype(int) - other[body].astype(int)).mean()
                 for other in (expected_raw, distorted))
    assert near < 2 and far > 3 * near
    # without undistortion the lens's points are only near bird's-eye: said so
    assert main(["lanes", "points", "--sim"]) == 0
    assert "only near bird's-eye" in capsys.readouterr().out
    # a calibration of another aspect ratio: one line naming the settings
    CameraCalibration((320, 180), lens.intrinsics, np.array(LENS), 0.1).save(car / "camera_calibration.json")
    (car / "myconfig.py").write_text(base + "CAMERA_UNDISTORT = True\n")
    assert main(["lanes", "points", "--sim"]) == 2
    err = capsys.readouterr().err
    assert "aspect ratio" in err and "SIM_CAMERA_W" in err and len(err.strip().splitlines()) == 1


def test_bad_arguments_of_lanes_and_camera_are_one_line_errors(car, capsys, tmp_path):
    (car / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\n")
    cases = [
        (["lanes", "preview", "--sim", "--frames", "1", "--png", "strip.txt"], "strip.txt"),  # no such image format
        (["lanes", "preview", "--images", str(tmp_path / "none")], "no such folder"),
        (["lanes", "points", "--sim", "--near", "5"], "near 5 m"),
        (["camera", "calibrate", "--live", "--timeout", "0"], "--timeout"),
    ]
    for argv, expected in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert expected in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, (argv, err)
    assert not (car / "strip.txt").exists()
    err_images = main(["lanes", "preview", "--images", str(tmp_path / "none")])
    assert err_images == 2 and "chessboard" not in capsys.readouterr().err


def test_calibrate_sim_in_a_default_car_says_which_setting_makes_it_work(tmp_path, monkeypatch, capsys):
    # acceptance: in a new simulator car (160x120 camera) `vehicle camera calibrate --sim` ended with
    # "cannot place a 10x7 board fully in a 160x120 view (SIM_CAMERA_* settings)": no fix named
    (tmp_path / "myconfig.py").write_text("")
    monkeypatch.chdir(tmp_path)
    assert main(["camera", "calibrate", "--sim", "--views", "3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: simulated calibration: ")
    assert "SIM_CAMERA_W = 320, SIM_CAMERA_H = 240" in err[0] and "--board 7x5" in err[0]
    # and the board the message proposes is found at 160x120
    (tmp_path / "myconfig.py").write_text("CAMERA_CALIB_BOARD = (7, 5)\n")
    assert main(["camera", "calibrate", "--sim", "--views", "3"]) == 0
    assert "calibrated from 3 views of 160x120" in capsys.readouterr().out
