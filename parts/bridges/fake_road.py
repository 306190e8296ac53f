"""The camera picture of the fake simulators: sky, grass and a road seen from the car.

Not a renderer (the built-in simulator has one): just enough that the picture changes with the
car's lateral offset and heading, so a pilot's output depends on where the fake car is.
"""

from __future__ import annotations

import math

import numpy as np


def road_view(width: int, height: int, offset: float, heading: float) -> np.ndarray:
    """A ``height`` x ``width`` RGB picture of a straight road.

    Args:
        offset: the car's lateral offset from the road centre, in road half-widths (positive =
            right of the centre: the road moves left in the picture).
        heading: the car's heading relative to the road, radians (positive = turned right).
    """
    import cv2

    img = np.empty((height, width, 3), np.uint8)
    horizon = int(height * 0.375)
    img[:horizon] = (135, 180, 225)
    img[horizon:] = (70, 120, 60)
    half = width * 0.47  # road half-width at the bottom row, pixels
    vanish_x = width / 2 - math.tan(heading) * width * 0.7
    bottom_x = width / 2 - offset * half
    road = np.array([[vanish_x - width * 0.0125, horizon], [vanish_x + width * 0.0125, horizon],
                     [bottom_x + half, height], [bottom_x - half, height]])
    cv2.fillPoly(img, [road.round().astype(np.int32)], (105, 105, 105))
    line = np.array([[vanish_x, horizon], [bottom_x, height]]).round().astype(np.int32)
    cv2.line(img, (int(line[0][0]), int(line[0][1])), (int(line[1][0]), int(line[1][1])), (230, 230, 90),
             max(1, width // 100))
    return img
