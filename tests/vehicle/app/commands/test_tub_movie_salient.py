"""``vehicle tub movie --model M --salient``: the model's steering and where it looks, filmed."""

from __future__ import annotations

import numpy as np
import pytest
from fixtures.pilots import line_angle, line_frame, write_line_tub

from parts.pilots.saliency import Explainer
from parts.pilots.salient_view import SalientView
from parts.tub.reader import iter_records
from vehicle.app.cli import main


def test_the_view_heats_the_line_and_gives_the_model_steering(line_model, tmp_path):
    tub = write_line_tub(tmp_path / "tub", [10])
    rec = next(iter(iter_records([tub])))
    ex = Explainer.from_file(line_model)
    frame = line_frame(10)
    picture, angle = SalientView(ex, "integrated")(frame, rec)
    assert angle == pytest.approx(ex.predict([frame])[0]) and angle == pytest.approx(line_angle(10), abs=0.25)
    change = np.abs(picture.astype(int) - frame.astype(int)).sum(axis=2)
    assert change[:, 10:14].mean() > 5 * change[:, 30:].mean()  # heat on the line, little elsewhere
    plain, plain_angle = SalientView(ex, None)(frame, rec)
    assert plain is frame and plain_angle == pytest.approx(angle)


def test_movie_with_the_model_and_saliency(line_model, tmp_path, capsys):
    import cv2

    tub = write_line_tub(tmp_path / "tub", [5, 20, 35, 50])
    out = tmp_path / "m.mp4"
    assert main(["tub", "movie", str(tub), "--out", str(out), "--model", str(line_model), "--salient",
                 "--scale", "1"]) == 0
    assert "(4 frames)" in capsys.readouterr().out
    cap = cv2.VideoCapture(str(out))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 4
    ok, first = cap.read()
    cap.release()
    assert ok and first.shape == (64, 64, 3)
    plain = tmp_path / "plain.mp4"
    assert main(["tub", "movie", str(tub), "--out", str(plain), "--scale", "1"]) == 0
    cap = cv2.VideoCapture(str(plain))
    _, plain_first = cap.read()
    cap.release()
    # the films differ by the heat on the line (columns 5..8), not elsewhere (rows 22..40: clear of
    # the text at the top and the steering bars at the bottom)
    diff = np.abs(first.astype(int) - plain_first.astype(int)).sum(axis=2)[22:40]
    assert diff[:, 5:9].mean() > 20 and diff[:, 5:9].mean() > 4 * diff[:, 20:].mean()


def test_bad_input_gets_one_line_and_writes_nothing(line_model, make_model_file, tmp_path, capsys):
    tub = write_line_tub(tmp_path / "tub", [5, 20])
    out = tmp_path / "m.mp4"
    other = make_model_file("linear")  # trained on 120x160 frames
    assert main(["tub", "movie", str(tub), "--out", str(out), "--model", str(other), "--salient"]) == 2
    err = capsys.readouterr().err.strip()
    assert "frame is 64x64x3 but the model was trained on 120x160x3 frames" in err and "\n" not in err
    assert not out.exists()
    assert main(["tub", "movie", str(tub), "--out", str(out), "--salient"]) == 2
    assert "give the model with --model MODEL" in capsys.readouterr().err
    assert main(["tub", "movie", str(tub), "--out", str(out), "--model", str(tmp_path / "nope.pt")]) == 2
    assert "no such model file" in capsys.readouterr().err
    empty = write_line_tub(tmp_path / "empty", [5, 20])
    assert main(["tub", "delete", str(empty), "0:"]) == 0  # every record deleted: nothing to film
    assert main(["tub", "movie", str(empty), "--out", str(out), "--model", str(line_model), "--salient"]) == 2
    assert "no records" in capsys.readouterr().err
    assert not out.exists()
