"""JPEG/PNG encoding and decoding (codecs imported on first use, not at import time).

JPEGs go through simplejpeg when it is installed (the ``train`` extra: libjpeg-turbo called
directly, decoding a 160x120 frame in about half OpenCV's time here, and releasing the GIL), else
through OpenCV, which also handles PNGs and the rare JPEG simplejpeg refuses (CMYK). Both decode to
the same pixels (within 1 where OpenCV is built on another libjpeg) and ignore EXIF orientation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

_cv2: Any = None


def cv2() -> Any:
    """The cv2 module, imported once on first use."""
    global _cv2
    if _cv2 is None:
        import cv2 as module

        _cv2 = module
    return _cv2


_simplejpeg: Any = None  # the module; False once known to be missing


def simplejpeg() -> Any | None:
    """The simplejpeg module, or None when it is not installed (OpenCV does the work then)."""
    global _simplejpeg
    if _simplejpeg is None:
        try:
            import simplejpeg as module

            _simplejpeg = module
        except ImportError:
            _simplejpeg = False
    return _simplejpeg or None


def encode_image(array: Any, tp: str, quality: int) -> tuple[bytes, str]:
    """Encode an image value -> (file bytes, extension).

    ``image_array``: HxWx3 RGB (or HxW / HxWx1 gray) uint8 -> JPEG; bytes given are taken as an
    already encoded JPEG and kept as they are. ``gray16_array``: HxW uint16 -> 16-bit PNG.
    """
    if isinstance(array, bytes | bytearray | memoryview):
        return bytes(array), ".png" if tp == "gray16_array" else ".jpg"
    arr = np.asarray(array)
    sj = simplejpeg() if tp != "gray16_array" else None
    if sj is not None and arr.dtype == np.uint8 and arr.ndim in (2, 3):
        color = arr.ndim == 3 and arr.shape[2] == 3
        if color or arr.ndim == 2 or arr.shape[2] == 1:
            # 4:2:0 chroma subsampling: what OpenCV, PIL and so DonkeyCar write at this quality
            return sj.encode_jpeg(np.ascontiguousarray(arr if color else arr.reshape(*arr.shape[:2], 1)),
                                  int(quality), "RGB" if color else "GRAY", "420", fastdct=False), ".jpg"
    cv = cv2()
    if tp == "gray16_array":
        ok, buf = cv.imencode(".png", arr.astype(np.uint16, copy=False))
        ext = ".png"
    else:
        if arr.dtype != np.uint8:
            arr = np.clip(arr, 0, 255).astype(np.uint8)
        if arr.ndim == 3 and arr.shape[2] == 3:
            arr = cv.cvtColor(arr, cv.COLOR_RGB2BGR)  # OpenCV writes BGR
        elif not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 1)):
            raise ValueError(f"image of shape {arr.shape} cannot be stored: expected HxWx3 RGB or HxW gray")
        ok, buf = cv.imencode(".jpg", arr, [cv.IMWRITE_JPEG_QUALITY, int(quality)])
        ext = ".jpg"
    if not ok:
        raise ValueError(f"OpenCV could not encode an image of shape {arr.shape}")
    return buf.tobytes(), ext


_RGB_FLAG: int | None = None


def decode_image(data: bytes | np.ndarray, out: np.ndarray | None = None) -> np.ndarray | None:
    """Decode JPEG/PNG bytes -> HxWx3 uint8 RGB (16-bit PNG -> HxW uint16); None when undecodable.

    ``out``: a C-contiguous uint8 array the JPEG may be decoded into (saves an allocation and a copy
    when filling a batch); the result is a view of it when it was used, a new array otherwise. A
    frame of another size is packed into its first bytes: check the result's shape.

    EXIF orientation is ignored on both paths (as PIL, and so DonkeyCar, do).
    """
    global _RGB_FLAG
    sj = simplejpeg()
    if sj is not None and len(data) > 2 and data[0] == 0xFF and data[1] == 0xD8:
        try:
            if out is not None and out.dtype == np.uint8 and out.flags.c_contiguous and out.flags.writeable:
                try:
                    return sj.decode_jpeg(data, "RGB", buffer=out)
                except ValueError:
                    pass  # out too small for this frame: decode into a new array
            return sj.decode_jpeg(data, "RGB")
        except ValueError:
            pass  # torn, or a JPEG libjpeg-turbo cannot turn into RGB (CMYK): OpenCV decides
    cv = cv2()
    buf = np.frombuffer(data, np.uint8) if not isinstance(data, np.ndarray) else data
    if buf.size == 0:
        return None
    if _RGB_FLAG is None:
        rgb = getattr(cv, "IMREAD_COLOR_RGB", -1)
        _RGB_FLAG = rgb | cv.IMREAD_IGNORE_ORIENTATION if rgb >= 0 else -1
    if buf.size > 8 and bytes(buf[:8]) == b"\x89PNG\r\n\x1a\n":
        img = cv.imdecode(buf, cv.IMREAD_UNCHANGED)
        if img is not None and img.dtype == np.uint8 and img.ndim == 3:
            img = cv.cvtColor(img, cv.COLOR_BGR2RGB)
        return img
    if _RGB_FLAG >= 0:
        return cv.imdecode(buf, _RGB_FLAG)
    img = cv.imdecode(buf, cv.IMREAD_COLOR | cv.IMREAD_IGNORE_ORIENTATION)
    return None if img is None else cv.cvtColor(img, cv.COLOR_BGR2RGB)


def looks_whole_jpeg(data: bytes) -> bool:
    """Cheap check: JPEG start marker and end-of-image marker present (catches torn/0-byte files)."""
    return len(data) > 4 and data[:2] == b"\xff\xd8" and data.rstrip(b"\x00")[-2:] == b"\xff\xd9"


_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def image_problem(data: bytes, name: str, decode: bool = True) -> str | None:
    """Why the bytes of image file ``name`` are not a whole, clean image; None when they are.

    Without ``decode`` only the markers are looked at (empty, not a JPEG/PNG, truncated). With it
    the image is decoded, and a JPEG that decodes only with libjpeg's warnings ("Corrupt JPEG
    data: ...", what a file damaged in its middle gives: the image is partly grey or garbled) is
    reported with the warning. The warnings come from simplejpeg; without it, OpenCV decodes and
    only a JPEG that does not decode at all is found.
    """
    if not data:
        return "empty (0 bytes)"
    if name.endswith(".png"):
        if not data.startswith(_PNG_MAGIC):
            return "not a PNG (no PNG signature)"
        return "does not decode" if decode and decode_image(data) is None else None
    if data[:2] != b"\xff\xd8":
        return "not a JPEG (no JPEG start marker)"
    if not looks_whole_jpeg(data):
        return "truncated JPEG (no end marker)"
    if not decode:
        return None
    sj = simplejpeg()
    if sj is not None:
        try:
            sj.decode_jpeg(data, "RGB", strict=True)
            return None
        except ValueError as exc:
            warning = " ".join(str(exc).split())[:120]
        try:
            sj.decode_jpeg(data, "RGB", strict=False)
        except ValueError:  # fatal for libjpeg-turbo's RGB path: OpenCV decides (CMYK JPEGs)
            return None if decode_image(data) is not None else f"does not decode ({warning})"
        return f"decodes with errors ({warning})"
    return "does not decode" if decode_image(data) is None else None
