"""A camera without hardware: a generated moving pattern (for tests, benches and bench-top cars)."""

from __future__ import annotations

from typing import Any

import numpy as np

from vehicle.config import check_settings


class MockSource:
    """Generates frames: a colour gradient with a bright bar that moves one step per frame.

    Each frame differs from the previous one, so a stalled pipeline is visible, and frame ``n`` is
    reproducible (the bar is at column ``n * step mod width``).
    """

    paced = True

    def __init__(self, width: int = 160, height: int = 120, step: int = 4) -> None:
        check_settings(IMAGE_W=width, IMAGE_H=height)
        self.width, self.height, self.step = width, height, step
        self.name = "mock"
        self.count = 0
        y = np.linspace(0, 255, height, dtype=np.float32)[:, None]
        x = np.linspace(0, 255, width, dtype=np.float32)[None, :]
        self._base = np.stack([np.broadcast_to(x, (height, width)),
                               np.broadcast_to(y, (height, width)),
                               np.full((height, width), 64, np.float32)], axis=2).astype(np.uint8)

    @classmethod
    def from_config(cls, cfg: Any) -> MockSource:
        """CAMERA_TYPE = "MOCK": frames of IMAGE_W x IMAGE_H."""
        return cls(cfg.IMAGE_W, cfg.IMAGE_H)

    def open(self) -> None:
        """Nothing to open."""
        self.count = 0

    def bar_column(self, n: int) -> int:
        """Column of the bar in frame ``n`` (0-based)."""
        return (n * self.step) % self.width

    def read(self) -> np.ndarray:
        """The next frame."""
        frame = self._base.copy()
        col = self.bar_column(self.count)
        frame[:, col:col + 2] = 255
        self.count += 1
        return frame

    def close(self) -> None:
        """Nothing to close."""
