"""Lane extraction: the thesis's warp and S-channel threshold, scaled points, colour masks, the part."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from parts.vision.lanes import (
    THESIS_DESTINATION,
    THESIS_SOURCE,
    LaneExtraction,
    LaneExtractor,
    LaneSettings,
    preview_strip,
)
from vehicle.config import Config


def test_thesis_values_are_the_defaults_and_the_config_matches_them():
    s = LaneSettings()
    assert s.source == ((0.0, 180.0), (112.5, 87.5), (200.0, 87.5), (307.5, 180.0))
    assert s.destination == ((80.0, 180.0), (80.0, 0.25), (230.0, 0.25), (230.0, 180.0))
    assert s.points_size == (320, 180) and s.s_threshold == (65, 255) and s.normalize
    assert LaneSettings.from_config(Config.defaults()) == s


def test_the_warp_maps_the_source_trapezoid_onto_the_destination_rectangle_at_any_size():
    ex = LaneExtractor()
    for in_size, out_size in (((320, 180), (320, 180)), ((160, 120), (160, 120)), ((640, 360), (160, 80))):
        m = ex.matrix(in_size, out_size)
        src = np.float32(THESIS_SOURCE) * [in_size[0] / 320, in_size[1] / 180]
        dst = cv2.perspectiveTransform(src.reshape(-1, 1, 2), m).reshape(-1, 2)
        assert np.allclose(dst, np.float32(THESIS_DESTINATION) * [out_size[0] / 320, out_size[1] / 180], atol=1e-3)
    assert ex.matrix((160, 120), (160, 120)) is ex.matrix((160, 120), (160, 120))  # computed once


def test_s_channel_threshold_is_the_thesiss_cv2_threshold():
    rng = np.random.default_rng(0)
    warped = rng.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    warped[0, 0], warped[0, 1] = 0, 255  # full range: the min-max stretch changes nothing
    ex = LaneExtractor()
    mask = ex.threshold(warped)
    s = cv2.cvtColor(warped, cv2.COLOR_RGB2HLS)[:, :, 2]
    _, thesis = cv2.threshold(s, 65, 255, cv2.THRESH_BINARY)
    assert np.array_equal(mask, thesis)
    # channel order does not matter for S (the thesis converted RGB frames with BGR2HLS)
    s_bgr = cv2.cvtColor(warped, cv2.COLOR_BGR2HLS)[:, :, 2]
    assert np.array_equal(s, s_bgr)


def _road(width: int = 320, height: int = 180) -> np.ndarray:
    """A grey road with a saturated yellow line and a white line, seen from the car."""
    img = np.full((height, width, 3), (90, 90, 95), np.uint8)
    img[: int(height * 0.45)] = (150, 180, 230)  # sky, above the region of interest
    cv2.line(img, (40, height - 1), (140, height // 2), (230, 190, 40), 6)  # yellow, left
    cv2.line(img, (300, height - 1), (185, height // 2), (245, 245, 245), 6)  # white, right
    return img


def test_yellow_lines_pass_the_s_threshold_white_needs_the_colour_mask():
    frame = _road()
    thesis = LaneExtractor().extract(frame)
    white = LaneExtractor(LaneSettings(color_mask="white")).extract(frame)
    assert thesis.dtype == np.uint8 and set(np.unique(thesis)) <= {0, 255}
    left, right = thesis[:, :160], thesis[:, 160:]
    assert left.sum() > 20 * 255 and right.sum() == 0  # S sees the yellow line only
    assert white[:, 160:].sum() > 20 * 255  # the white mask adds the white one
    only_white = LaneExtractor(LaneSettings(color_mask="white", s_threshold=None)).extract(frame)
    assert only_white[:, :160].sum() == 0


def test_bad_settings_say_which_setting_and_how():
    with pytest.raises(ValueError, match="LANE_SOURCE_POINTS"):
        LaneSettings(source=((0, 0), (1, 1)))
    with pytest.raises(ValueError, match="convex"):
        LaneSettings(source=((0, 180), (200, 87.5), (112.5, 87.5), (307.5, 180)))
    with pytest.raises(ValueError, match="LANE_S_THRESHOLD"):
        LaneSettings(s_threshold=(200, 100))
    with pytest.raises(ValueError, match="LANE_COLOR_MASK"):
        LaneSettings(color_mask="green")
    with pytest.raises(ValueError, match="both are off"):
        LaneSettings(s_threshold=None)
    with pytest.raises(ValueError, match="uint8 HxWx3"):
        LaneExtractor().extract(np.zeros((10, 10), np.uint8))
    assert LaneSettings.from_dict(LaneSettings(color_mask="white").to_dict()) == LaneSettings(color_mask="white")
    with pytest.raises(ValueError, match="unknown lane setting"):
        LaneSettings.from_dict({"roi": 1})


def test_part_and_preview_strip():
    part = LaneExtraction(out_size=(80, 60))
    frame = _road(160, 120)
    out = part.run(frame)
    assert out.shape == (60, 80) and out.any()
    assert part.run(None) is None
    strip = preview_strip([frame, _road(320, 180)], LaneExtractor(), scale=2)
    assert strip.shape == (2 * 120 * 2, 3 * 160 * 2, 3)


def test_points_for_another_aspect_ratio_than_the_frames_are_warned_about_once(caplog):
    """The thesis's points are for 16:9 frames; on a 4:3 camera they would be stretched silently."""
    import logging

    extractor = LaneExtractor(LaneSettings())  # LANE_POINTS_SIZE 320x180
    frame = np.zeros((120, 160, 3), np.uint8)
    with caplog.at_level(logging.WARNING):
        extractor.extract(frame)
        extractor.extract(frame)
        extractor.extract(np.zeros((90, 160, 3), np.uint8))  # 16:9: the points' own aspect ratio
        extractor.extract(frame, out_size=(80, 45))  # another output size of the same frames: no new warning
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "320x180" in warnings[0] and "160x120" in warnings[0] and "LANE_POINTS_SIZE" in warnings[0]
    assert "vehicle lanes preview" in warnings[0]
