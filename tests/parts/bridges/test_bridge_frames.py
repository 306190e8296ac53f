"""Camera frames over simulator protocols: sizes are checked before anything is decoded."""

from __future__ import annotations

import base64
import io

import numpy as np
import pytest
from PIL import Image

from parts.bridges.frames import MAX_PIXELS, MAX_SIDE, clamp_size, decode_frame, within_limits


def encoded(width: int, height: int, fmt: str = "JPEG", mode: str = "RGB") -> str:
    buf = io.BytesIO()
    Image.new(mode, (width, height), 90).save(buf, fmt)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def test_a_frame_is_rgb_whatever_it_was_encoded_as() -> None:
    rgb = decode_frame(encoded(160, 120))
    assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
    grey = decode_frame(encoded(64, 48, "PNG", "L"))
    assert grey.shape == (48, 64, 3) and (grey[..., 0] == grey[..., 2]).all()


def test_oversized_and_wrong_frames_are_refused_with_a_reason() -> None:
    with pytest.raises(ValueError, match=r"5000x1000, larger than 4096"):
        decode_frame(encoded(5000, 1000, "PNG", "L"))  # a few KB of PNG, 5 Mpx decoded
    with pytest.raises(ValueError, match="PNG, expected JPEG"):
        decode_frame(encoded(32, 32, "PNG"), formats=("JPEG",))
    with pytest.raises(ValueError, match="not base64|not an image"):
        decode_frame("@@@not base64@@@")
    with pytest.raises(ValueError, match="not an image"):
        decode_frame(base64.b64encode(b"hello").decode())
    with pytest.raises(ValueError, match="no image"):
        decode_frame(None)


def test_clamp_size_keeps_the_aspect_ratio_within_the_limits() -> None:
    assert clamp_size(160, 120) == (160, 120)
    for w, h in ((5000, 1000), (1000, 5000), (3000, 3000), (10**12, 10**12), (100000, 8)):
        cw, ch = clamp_size(w, h)
        assert within_limits(cw, ch), (w, h, cw, ch)
        assert cw / ch == pytest.approx(w / h, rel=0.02) or min(cw, ch) == 1
    assert clamp_size(5000, 1000) == (MAX_SIDE, 819)
    assert clamp_size(3000, 3000)[0] ** 2 <= MAX_PIXELS
