"""Media for camera tests, generated with OpenCV into tmp_path."""

from __future__ import annotations

import cv2
import numpy as np
import pytest


@pytest.fixture
def red_blue_video(tmp_path):
    """A 30-frame 160x120 MJPG AVI at 20 fps: frames 0-14 pure red, 15-29 pure blue (RGB terms)."""
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 20, (160, 120))
    assert writer.isOpened()
    for i in range(30):
        bgr = np.zeros((120, 160, 3), np.uint8)
        bgr[:, :, 2 if i < 15 else 0] = 255
        writer.write(bgr)
    writer.release()
    return path


@pytest.fixture
def image_folder(tmp_path):
    """PNG frames img_1 .. img_12 whose red channel is the frame number x 10 (order check)."""
    folder = tmp_path / "frames"
    folder.mkdir()
    for n in range(1, 13):
        rgb = np.zeros((60, 80, 3), np.uint8)
        rgb[:, :, 0] = n * 10
        cv2.imwrite(str(folder / f"img_{n}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    (folder / "notes.txt").write_text("not an image")
    return folder


class FakeCapture:
    """Same methods as cv2.VideoCapture; records set() calls, serves BGR frames."""

    instances: list[FakeCapture] = []

    def __init__(self, device, backend=None, opened=True, frames=None, accept=(3, 4, 5, 6, 38)):
        self.device, self.backend = device, backend
        self.opened = opened
        self.sets: list[tuple[int, float]] = []
        self.props: dict[int, float] = {}
        self.accept = accept
        self.frames = list(frames) if frames is not None else None
        self.released = False
        FakeCapture.instances.append(self)

    def isOpened(self):  # noqa: N802 - cv2's name
        return self.opened

    def set(self, prop, value):
        self.sets.append((prop, value))
        if prop in self.accept:
            self.props[prop] = value
            return True
        return False

    def get(self, prop):
        return self.props.get(prop, 0.0)

    def read(self):
        if self.frames is None:
            bgr = np.zeros((480, 640, 3), np.uint8)
            bgr[:, :, 0] = 200  # blue in BGR
            return True, bgr
        if not self.frames:
            return False, None
        return True, self.frames.pop(0)

    def release(self):
        self.released = True


@pytest.fixture
def fake_capture():
    FakeCapture.instances = []
    return FakeCapture
