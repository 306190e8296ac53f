"""The camera family's table: CAMERA_TYPE -> frame source (each built by its ``from_config(cfg)``).

A new camera type is a module here with a frame source class (``open``, ``read``, ``close`` and a
``from_config`` classmethod, see :class:`parts.cameras.base.FrameSource`) and one row below.
"""

from __future__ import annotations

from vehicle.registry import Registry

CAMERAS = Registry("CAMERA_TYPE", {
    "PICAM": "parts.cameras.picam:PiCamera2Source",
    "CVCAM": "parts.cameras.opencv:OpenCVSource",
    "WEBCAM": "parts.cameras.opencv:OpenCVSource",
    "CSIC": "parts.cameras.opencv:CSISource",
    "VIDEO": "parts.cameras.replay:VideoFileSource",
    "IMAGE_LIST": "parts.cameras.replay:ImageFolderSource",
    "MOCK": "parts.cameras.mock:MockSource",
})
