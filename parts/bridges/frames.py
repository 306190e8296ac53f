"""Camera frames that travel over a simulator protocol: base64 text in, an RGB array out.

A frame's size is read from its header before anything is decoded, so a frame that claims an
absurd size (a broken fork, a hostile peer: a 30000x30000 JPEG decodes to 2.5 GiB) is refused with
a reason instead of exhausting memory; the same limits bound the camera size a client may ask of
``vehicle sim serve``.
"""

from __future__ import annotations

import base64
import binascii
import io
import math
import warnings
from collections.abc import Sequence
from typing import Final

import numpy as np

#: largest frame side accepted, pixels
MAX_SIDE: Final = 4096
#: largest frame area accepted, pixels (4 Mpx: 2560x1600 fits, 160x120 is 0.5 % of it)
MAX_PIXELS: Final = 4 * 1024 * 1024


def frame_header(data: bytes) -> tuple[str, int, int]:
    """(format, width, height) of encoded image bytes, read from the header only.

    Raises:
        ValueError: the bytes are not an image Pillow recognises.
    """
    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as image:  # lazy: reads the header, decodes nothing
                return str(image.format), int(image.size[0]), int(image.size[1])
    except Image.DecompressionBombError:
        raise ValueError(f"the image is larger than {MAX_SIDE}x{MAX_SIDE} pixels") from None
    except Exception as exc:  # UnidentifiedImageError, a truncated header (OSError, SyntaxError ...)
        raise ValueError(f"not an image ({type(exc).__name__})") from None


def within_limits(width: int, height: int) -> bool:
    """True when a ``width`` x ``height`` frame is within :data:`MAX_SIDE` and :data:`MAX_PIXELS`."""
    return 0 < width <= MAX_SIDE and 0 < height <= MAX_SIDE and width * height <= MAX_PIXELS


def clamp_size(width: int, height: int) -> tuple[int, int]:
    """The largest size within the limits with (about) the aspect ratio of ``width`` x ``height``."""
    w, h = max(1, int(width)), max(1, int(height))
    scale = min(1.0, MAX_SIDE / w, MAX_SIDE / h, math.sqrt(MAX_PIXELS / (w * h)))
    w, h = max(1, min(MAX_SIDE, int(w * scale))), max(1, min(MAX_SIDE, int(h * scale)))
    while w * h > MAX_PIXELS:  # rounding
        w, h = max(1, w - 1), max(1, h - 1)
    return w, h


def decode_frame(encoded: object, formats: Sequence[str] = ("JPEG", "PNG")) -> np.ndarray:
    """A base64 frame -> HxWx3 uint8 RGB (a grey frame gets three equal channels).

    Args:
        encoded: the base64 text of the frame, as the simulator sends it.
        formats: image formats accepted (Pillow's names: "JPEG", "PNG").

    Raises:
        ValueError: what is wrong, in a few words: not base64, not one of ``formats``, larger than
            the limits, or not decodable.
    """
    from parts.tub.codec import decode_image

    if not isinstance(encoded, str) or not encoded:
        raise ValueError("no image")
    try:
        data = base64.b64decode(encoded, validate=False)
    except (binascii.Error, ValueError) as exc:
        raise ValueError(f"the image is not base64 ({exc})") from None
    kind, width, height = frame_header(data)
    if kind not in formats:
        raise ValueError(f"the image is {kind}, expected {' or '.join(formats)}")
    if not within_limits(width, height):
        raise ValueError(f"the image is {width}x{height}, larger than {MAX_SIDE} per side or "
                         f"{MAX_PIXELS // (1024 * 1024)} Mpx")
    try:
        image = decode_image(data)
    except Exception:  # OpenCV raises its own error type on odd channel layouts
        image = None
    if image is None or image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise ValueError(f"the {kind} image does not decode to 8-bit RGB")
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    elif image.shape[2] != 3:
        raise ValueError(f"the {kind} image has {image.shape[2]} channels, expected 3")
    return image
