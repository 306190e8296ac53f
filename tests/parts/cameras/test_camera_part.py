"""The threaded Camera part: latest frame, timestamps, resize/flip, stall detection, assembly."""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest

from parts.cameras.base import Camera, fit_frame
from parts.cameras.mock import MockSource


class StallingSource:
    """Delivers ``n`` frames, then nothing (a camera that stops); optionally raises instead."""

    paced = False
    name = "stalling"

    def __init__(self, n: int, fail: bool = False) -> None:
        self.n, self.fail, self.closed = n, fail, False

    def open(self):
        pass

    def read(self):
        if self.n > 0:
            self.n -= 1
            return np.zeros((120, 160, 3), np.uint8)
        if self.fail:
            raise OSError(5, "VIDIOC_DQBUF: Input/output error")
        time.sleep(0.01)
        return None

    def close(self):
        self.closed = True


def test_fit_frame_resizes_and_flips():
    img = np.zeros((120, 160, 3), np.uint8)
    img[0, :, 0] = 255  # top row red
    img[:, 0, 1] = 255  # left column green
    out = fit_frame(img, 80, 60, vflip=True, hflip=True)
    assert out.shape == (60, 80, 3) and out.flags["C_CONTIGUOUS"]
    assert out[-1, 40, 0] > 100 and out[0, 40, 0] == 0  # red row now at the bottom
    assert out[30, -1, 1] > 100 and out[30, 0, 1] == 0  # green column now at the right
    grey = fit_frame(np.full((60, 80), 9, np.uint8), 80, 60)
    assert grey.shape == (60, 80, 3)


def test_non_threaded_run_gives_fresh_timestamped_frames():
    cam = Camera(MockSource(160, 120), 80, 60, fps=20, timeout_s=1.0)
    before = time.time()
    img1, ts1, ok1 = cam.run()
    img2, ts2, ok2 = cam.run()
    assert ok1 and ok2 and img1.shape == (60, 80, 3)
    assert before <= ts1 <= ts2 <= time.time()
    assert not np.array_equal(img1, img2)
    assert cam.frame().seq == 2
    cam.shutdown()


def test_threaded_camera_reports_a_stall(caplog):
    src = StallingSource(3)
    cam = Camera(src, 160, 120, fps=50, timeout_s=0.2)
    assert cam.run_threaded() == (None, None, False)  # before the first frame
    cam.start()
    try:
        deadline = time.monotonic() + 3
        while cam.frame() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        img, ts, ok = cam.run_threaded()
        assert ok and img.shape == (120, 160, 3) and isinstance(ts, float)
        with caplog.at_level(logging.ERROR):
            deadline = time.monotonic() + 3
            while cam.run_threaded()[2] and time.monotonic() < deadline:
                time.sleep(0.02)
        img, ts, ok = cam.run_threaded()
        assert ok is False and img is not None  # last frame kept, but flagged stale
        assert "stopped delivering frames" in caplog.text
    finally:
        cam.shutdown()
    assert src.closed


def test_failing_source_means_not_ok(caplog):
    cam = Camera(StallingSource(1, fail=True), 160, 120, fps=50, timeout_s=5.0)
    cam.start()
    try:
        deadline = time.monotonic() + 3
        while cam.error is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert cam.run_threaded()[2] is False  # thread died: not ok even within the timeout
    finally:
        cam.shutdown()


def test_bad_arguments():
    with pytest.raises(ValueError, match="CAMERA_TIMEOUT_S"):
        Camera(MockSource(), timeout_s=0)
    with pytest.raises(ValueError, match="IMAGE_W"):
        Camera(MockSource(), width=0)


def test_add_camera_per_type(tmp_path, red_blue_video, image_folder):
    from vehicle import Vehicle
    from vehicle.app.assembly.camera import add_camera, make_frame_source
    from vehicle.config import Config, ConfigError

    V = Vehicle()
    cam = add_camera(V, Config.defaults(CAMERA_TYPE="MOCK", IMAGE_W=80, IMAGE_H=60))
    assert cam.run_threaded()[2] is False and cam.width == 80  # cam/ok False until the first frame
    assert V.parts[0].outputs == ("cam/image_array", "cam/timestamp", "cam/ok") and V.parts[0].threaded
    cfg = Config.defaults(CAMERA_TYPE="VIDEO", CAR_PATH=str(tmp_path), CAMERA_VIDEO_PATH="clip.avi")
    assert make_frame_source(cfg).path == red_blue_video
    assert type(make_frame_source(Config.defaults(CAMERA_TYPE="IMAGE_LIST",
                                                  CAMERA_IMAGE_PATH=str(image_folder)))).__name__ == "ImageFolderSource"
    assert type(make_frame_source(Config.defaults(CAMERA_TYPE="WEBCAM"))).__name__ == "OpenCVSource"
    assert "flip-method=2" in make_frame_source(Config.defaults(CAMERA_TYPE="CSIC", CAMERA_VFLIP=True,
                                                                CAMERA_HFLIP=True)).pipeline
    assert type(make_frame_source(Config.defaults(CAMERA_TYPE="PICAM"))).__name__ == "PiCamera2Source"
    with pytest.raises(ConfigError, match='CAMERA_TYPE = "VIDEO" needs CAMERA_VIDEO_PATH'):
        make_frame_source(Config.defaults(CAMERA_TYPE="VIDEO"))
    with pytest.raises(ConfigError, match="CAMERA_IMAGE_PATH"):
        make_frame_source(Config.defaults(CAMERA_TYPE="IMAGE_LIST"))
