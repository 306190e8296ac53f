"""Frame sources: video file, image folder, tub, mock, and the OpenCV/CSI/picamera2 seams."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from parts.cameras.base import CameraError
from parts.cameras.mock import MockSource
from parts.cameras.opencv import (
    CAP_GSTREAMER,
    CAP_PROP_BUFFERSIZE,
    CAP_PROP_FOURCC,
    CAP_PROP_FRAME_HEIGHT,
    CAP_PROP_FRAME_WIDTH,
    CAP_V4L2,
    CSISource,
    OpenCVSource,
    csi_pipeline,
    flip_method_for,
    fourcc_code,
)
from parts.cameras.picam import PiCamera2Source
from parts.cameras.replay import ImageFolderSource, VideoFileSource, list_images


def test_video_file_is_rgb_and_loops(red_blue_video):
    src = VideoFileSource(red_blue_video, loop=True)
    src.open()
    assert src.frame_count == 30
    frames = [src.read() for _ in range(31)]
    assert frames[0].shape == (120, 160, 3) and frames[0].dtype == np.uint8
    r, g, b = frames[0][60, 80]
    assert r > 240 and g < 15 and b < 15  # RGB order, not OpenCV's BGR
    assert frames[20][60, 80, 2] > 240  # blue half
    assert frames[30][60, 80, 0] > 240  # looped back to the first (red) frame
    src.close()


def test_video_file_without_loop_ends(red_blue_video):
    src = VideoFileSource(red_blue_video, loop=False)
    src.open()
    assert sum(src.read() is not None for _ in range(35)) == 30
    assert src.ended and src.read() is None


def test_missing_or_bad_video_file(tmp_path):
    with pytest.raises(CameraError, match="CAMERA_VIDEO_PATH"):
        VideoFileSource(tmp_path / "none.mp4").open()
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video at all")
    with pytest.raises(CameraError, match="cannot decode"):
        VideoFileSource(bad).open()


def test_image_folder_in_natural_order(image_folder):
    src = ImageFolderSource(image_folder, loop=False)
    src.open()
    reds = [int(src.read()[0, 0, 0]) for _ in range(12)]
    assert reds == [n * 10 for n in range(1, 13)]  # img_2 before img_10
    assert src.read() is None


def test_image_folder_loops_and_skips_unreadable(image_folder):
    (image_folder / "img_5.png").write_bytes(b"broken")
    src = ImageFolderSource(image_folder, loop=True)
    src.open()
    reds = [int(src.read()[0, 0, 0]) for _ in range(13)]
    assert 50 not in reds and reds[:4] == [10, 20, 30, 40] and reds[11] == 10


def test_tub_images_are_replayed_in_record_order(tmp_path, image_folder):
    tub = tmp_path / "tub_1"
    (tub / "images").mkdir(parents=True)
    (tub / "manifest.json").write_text(json.dumps({}) + "\n")
    for n in (10, 2, 1):
        src = image_folder / f"img_{n}.png"
        (tub / "images" / f"{n}_cam_image_array_.png").write_bytes(src.read_bytes())
    assert [p.name.split("_")[0] for p in list_images(tub)] == ["1", "2", "10"]


def test_empty_or_missing_folder(tmp_path):
    with pytest.raises(CameraError, match="CAMERA_IMAGE_PATH"):
        ImageFolderSource(tmp_path / "none").open()
    with pytest.raises(CameraError, match="no images"):
        ImageFolderSource(tmp_path).open()


def test_mock_pattern_moves_every_frame():
    src = MockSource(160, 120, step=4)
    src.open()
    a, b = src.read(), src.read()
    assert a.shape == (120, 160, 3)
    assert (a[:, 0] == 255).all() and not (a[:, 4] == 255).all()
    assert (b[:, 4] == 255).all()
    assert not np.array_equal(a, b)


def test_opencv_source_asks_mjpg_then_size_and_one_buffer(fake_capture):
    src = OpenCVSource(2, 160, 120, 30, capture_factory=fake_capture)
    src.open()
    cap = fake_capture.instances[0]
    assert (cap.device, cap.backend) == (2, CAP_V4L2)
    props = [p for p, _ in cap.sets]
    assert props.index(CAP_PROP_FOURCC) < props.index(CAP_PROP_FRAME_WIDTH)
    assert (CAP_PROP_BUFFERSIZE, 1) in cap.sets
    assert (CAP_PROP_FOURCC, fourcc_code("MJPG")) in cap.sets and fourcc_code("MJPG") == 0x47504A4D
    assert (CAP_PROP_FRAME_HEIGHT, 120) in cap.sets
    frame = src.read()
    assert frame.shape == (480, 640, 3) and tuple(frame[0, 0]) == (0, 0, 200)  # BGR -> RGB
    src.close()
    assert cap.released


def test_opencv_source_errors_and_failed_reads(fake_capture, caplog):
    with pytest.raises(CameraError, match="v4l2-ctl --list-devices"):
        OpenCVSource(0, capture_factory=lambda d, b: fake_capture(d, b, opened=False)).open()
    src = OpenCVSource(0, capture_factory=lambda d, b: fake_capture(d, b, frames=[]))
    src.open()
    assert src.read() is None and src.failed_reads == 1
    assert "read failed" in caplog.text


def test_csi_pipeline_string():
    assert csi_pipeline(0, 1280, 720, 60, 160, 120, 2) == (
        "nvarguscamerasrc sensor-id=0 ! video/x-raw(memory:NVMM), width=1280, height=720, "
        "format=NV12, framerate=60/1 ! nvvidconv flip-method=2 ! video/x-raw, width=160, "
        "height=120, format=BGRx ! videoconvert ! video/x-raw, format=BGR ! appsink drop=true max-buffers=1")
    assert [flip_method_for(v, h) for v, h in ((0, 0), (1, 1), (0, 1), (1, 0))] == [0, 2, 4, 6]
    with pytest.raises(ValueError, match="flip_method"):
        csi_pipeline(flip_method=9)


def test_csi_source_opens_the_pipeline_with_gstreamer(fake_capture):
    src = CSISource(160, 120, 60, sensor_id=1, capture_factory=fake_capture)
    src.open()
    cap = fake_capture.instances[0]
    assert cap.backend == CAP_GSTREAMER and "sensor-id=1" in cap.device
    assert cap.sets == []  # nothing set on a GStreamer pipeline: the caps string says it all
    failing = CSISource(capture_factory=lambda d, b: fake_capture(d, b, opened=False))
    with pytest.raises(CameraError, match="built with GStreamer"):
        failing.open()


class FakePicamera2:
    def __init__(self, num):
        self.num, self.calls = num, []

    def create_preview_configuration(self, main, controls, queue):
        self.calls.append(("config", main, controls, queue))
        return {"main": main}

    def configure(self, config):
        self.calls.append(("configure", config))

    def start(self):
        self.calls.append(("start",))

    def capture_array(self, stream):
        return np.full((120, 160, 4), 7, np.uint8)

    def stop(self):
        self.calls.append(("stop",))

    def close(self):
        self.calls.append(("close",))


def test_picamera2_source_asks_bgr888_which_is_rgb_and_drops_alpha():
    made = []
    src = PiCamera2Source(160, 120, 20, picamera2_class=lambda n: made.append(FakePicamera2(n)) or made[-1])
    src.open()
    cam = made[0]
    _, main, controls, queue = cam.calls[0]
    assert main == {"size": (160, 120), "format": "BGR888"} and queue is False
    assert controls == {"FrameDurationLimits": (50000, 50000)}
    assert src.read().shape == (120, 160, 3)
    src.close()
    assert cam.calls[-2:] == [("stop",), ("close",)]


def test_picamera2_missing_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "picamera2", None)
    with pytest.raises(CameraError, match="python3-picamera2"):
        PiCamera2Source().open()
