"""Saliency maps (parts.pilots.saliency): they show what the model uses, for every model type."""

from __future__ import annotations

import numpy as np
import pytest
from fixtures.pilots import line_angle, line_frame

from parts.pilots.models import model_type_names
from parts.pilots.saliency import METHODS, Explainer, heat_overlay

COLUMNS = (5, 20, 30, 50, 40, 12)
ROWS = (30, 50, 8, 40, 20, 12)


def _column_peak(sal: np.ndarray) -> int:
    return int(sal.mean(axis=0).argmax())


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("output", ["steering", "throttle"])
def test_the_map_of_a_line_peaks_on_the_line(line_model, method, output):
    ex = Explainer.from_file(line_model)
    offsets = []
    for col in COLUMNS[:4]:
        sal = ex.explain([line_frame(col)], output=output, method=method)
        assert set(sal.maps) == {"camera"} and sal.maps["camera"].shape == (64, 64)
        assert sal.prediction[0] == pytest.approx(line_angle(col), abs=0.25)  # the model learned the task
        offsets.append(abs(_column_peak(sal.maps["camera"]) - (col + 1.5)))
    assert np.median(offsets) <= 3.0, offsets  # the line is 4 px wide: its centre is col + 1.5


@pytest.mark.parametrize("method", ["integrated", "occlusion"])
def test_the_map_depends_on_the_model_not_on_the_picture(line_model, method):
    """Both lines are equally bright: a map of the picture (edges, intensity) scores them alike. The
    trained model steers by the vertical line only; an untrained one of the same type does not."""
    import torch

    from parts.pilots.models import create_model

    trained = Explainer.from_file(line_model)
    torch.manual_seed(1)
    untrained = Explainer(create_model("linear", (3, 64, 64), dropout=0.0), trained.preprocess)

    def ratio(ex: Explainer) -> float:
        ratios = []
        for col, row in zip(COLUMNS, ROWS, strict=True):
            m = ex.explain([line_frame(col, row)], method=method).maps["camera"]
            vertical = np.delete(m[:, col:col + 4], range(row, row + 4), axis=0).mean()
            horizontal = np.delete(m[row:row + 4, :], range(col, col + 4), axis=1).mean()
            ratios.append(vertical / horizontal)
        return float(np.median(ratios))

    r_trained, r_untrained = ratio(trained), ratio(untrained)
    assert r_trained > 1.7, r_trained
    assert r_trained > 1.4 * r_untrained, (r_trained, r_untrained)


@pytest.mark.parametrize("model_type", model_type_names())
def test_every_model_type_gets_a_map_per_stream(make_model_file, model_type):
    path = make_model_file(model_type)
    ex = Explainer.from_file(path)
    frames = [np.random.default_rng(i).integers(0, 256, (120, 160, 3), dtype=np.uint8)
              for i in range(ex.frames_needed)]
    sal = ex.explain(frames, method="smoothgrad", samples=2)
    want = {"lanes": {"camera", "lanes"}, "lanes_basic": {"camera", "lanes"},
            "three_camera": {"cam/image_array_left", "cam/image_array", "cam/image_array_right"}}
    assert set(sal.maps) == want.get(model_type, {"camera"}) == set(ex.streams())
    c, h, w = ex.model.input_shape
    for m in sal.maps.values():
        assert m.shape == (h, w) and m.dtype == np.float32
        assert 0.0 <= m.min() and m.max() == pytest.approx(1.0)  # normalised, and not blank
    pictures = ex.overlays(frames, sal)
    assert set(pictures) == set(sal.maps)
    camera, seen = (pictures["cam/image_array"], frames[1]) if ex.model.views > 1 else (pictures["camera"], frames[-1])
    assert camera.shape == (120, 160, 3) and camera.dtype == np.uint8
    # the crop (40 rows of sky) is not what the model saw: nothing drawn there, and heat below it
    assert np.array_equal(camera[:40], seen[:40]) and not np.array_equal(camera[40:], seen[40:])


def test_wrong_inputs_are_refused_in_one_line(make_model_file, line_model):
    ex = Explainer.from_file(make_model_file("linear"))
    with pytest.raises(ValueError, match="frame is 64x64x3 but the model was trained on 120x160x3"):
        ex.explain([line_frame(3)])
    with pytest.raises(ValueError, match="takes 1 frame"):
        ex.explain([])
    with pytest.raises(ValueError, match="output must be one of"):
        Explainer.from_file(line_model).explain([line_frame(3)], output="brake")
    with pytest.raises(ValueError, match="method must be one of"):
        Explainer.from_file(line_model).explain([line_frame(3)], method="gradcam")


def test_heat_overlay_leaves_cold_pixels_alone():
    frame = np.full((10, 20, 3), 100, np.uint8)
    sal = np.zeros((10, 20), np.float32)
    sal[:, 15:] = 1.0
    out = heat_overlay(frame, sal)
    assert np.array_equal(out[:, :15], frame[:, :15])
    assert not np.array_equal(out[:, 15:], frame[:, 15:])
