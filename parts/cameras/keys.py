"""Memory keys of the camera family: frames and their capture times (DonkeyCar's ``cam/*``).

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    "cam/image_array": KeyInfo("ndarray HxWx3 uint8 RGB", "latest camera frame"),
    "cam/timestamp": KeyInfo("float", "capture time of cam/image_array, seconds (time.time())"),
    "cam/image_array_left": KeyInfo("ndarray HxWx3 uint8 RGB", "frame of a camera left of the centre one (Udacity "
                                                               "recordings, the simulator's SIM_SIDE_CAMERAS_OFFSET; "
                                                               "training: TRAIN_SIDE_CAMERAS)"),
    "cam/image_array_right": KeyInfo("ndarray HxWx3 uint8 RGB", "frame of a camera right of the centre one"),
    "cam/frame_id": KeyInfo("int", "counter of frames delivered by the camera"),
    "cam/ok": KeyInfo("bool", "False when the camera stopped delivering frames"),
}

#: older names -> the standard name. Tubs and settings written with an old name are still read (our
#: docs once named the side cameras ``cam/left_image_array``, which ``vehicle tub import-udacity``
#: never wrote).
ALIASES: dict[str, str] = {
    "cam/left_image_array": "cam/image_array_left",
    "cam/right_image_array": "cam/image_array_right",
}
