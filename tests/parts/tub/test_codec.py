"""JPEG codec: simplejpeg when installed, OpenCV otherwise, the same pixels either way."""

from __future__ import annotations

import numpy as np
import pytest

from parts.tub import codec as imaging
from parts.tub.codec import decode_image, encode_image


@pytest.fixture
def frame() -> np.ndarray:
    y, x = np.mgrid[0:120, 0:160]
    return np.stack([x * 255 // 160, y * 255 // 120, (x + y) % 256], -1).astype(np.uint8)


@pytest.fixture(params=["simplejpeg", "opencv"])
def codec(request, monkeypatch):
    if request.param == "simplejpeg":
        pytest.importorskip("simplejpeg")
    else:
        monkeypatch.setattr(imaging, "_simplejpeg", False)
    return request.param


def test_round_trip_is_close_and_rgb(frame, codec):
    data, ext = encode_image(frame, "image_array", 90)
    assert ext == ".jpg" and data[:2] == b"\xff\xd8"
    img = decode_image(data)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    # channel order kept: red rises left to right, green top to bottom
    assert img[60, 150, 0] > img[60, 10, 0] + 150 and img[110, 80, 1] > img[10, 80, 1] + 150
    assert np.abs(img.astype(int) - frame).mean() < 3


def test_both_codecs_decode_to_the_same_pixels(frame, monkeypatch):
    pytest.importorskip("simplejpeg")
    data, _ = encode_image(frame, "image_array", 75)
    fast = decode_image(data)
    monkeypatch.setattr(imaging, "_simplejpeg", False)
    # identical with this OpenCV wheel; within 1 where OpenCV is built on another libjpeg
    assert np.abs(fast.astype(int) - decode_image(data)).max() <= 1


def test_exif_orientation_is_ignored_by_both_codecs(frame, codec):
    import io

    from PIL import Image

    exif = Image.Exif()
    exif[0x0112] = 6  # "rotate 90° clockwise to display": OpenCV would apply it by default
    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, "JPEG", quality=90, exif=exif)
    img = decode_image(buf.getvalue())
    assert img.shape == (120, 160, 3)  # as stored, like PIL (DonkeyCar) reads it


def test_decode_into_out_uses_it_when_the_frame_fits(frame, codec):
    data, _ = encode_image(frame, "image_array", 75)
    batch = np.zeros((3, 120, 160, 3), np.uint8)
    img = decode_image(data, out=batch[1])
    assert np.array_equal(img, decode_image(data))
    if codec == "simplejpeg":
        assert np.shares_memory(img, batch[1]) and batch[1].any() and not batch[0].any()
    small = np.zeros((10, 10, 3), np.uint8)  # too small: a new array, out untouched
    img = decode_image(data, out=small)
    assert img.shape == (120, 160, 3) and not small.any()


def test_gray_frames_and_broken_data(frame, codec):
    data, _ = encode_image(frame[..., 0], "image_array", 90)
    img = decode_image(data)
    assert img.shape == (120, 160, 3) and np.array_equal(img[..., 0], img[..., 2])
    whole, _ = encode_image(frame, "image_array", 75)
    assert decode_image(whole[: len(whole) // 2]) is None  # torn file
    assert decode_image(b"\xff\xd8not a jpeg") is None
    assert decode_image(b"") is None
