"""Path files: a CSV a person reads, a round trip that keeps every point, one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from parts.path.pathfile import Path, PathFileError, load_path, save_path


def test_round_trip_keeps_points_and_speeds(tmp_path):
    xy = np.array([[0.0, 0.0], [0.2, 0.01], [0.4, -0.03], [0.61, 0.1]])
    path = Path(xy, [0.0, 0.8, 1.25, 1.5])
    target = save_path(path, tmp_path / "sub" / "p.csv")
    text = target.read_text().splitlines()
    assert text[0] == "x,y,speed"
    assert text[2] == "0.2000,0.0100,0.800"
    back = load_path(target)
    np.testing.assert_allclose(back.xy, xy, atol=1e-4)
    np.testing.assert_allclose(back.speed, [0.0, 0.8, 1.25, 1.5], atol=1e-3)
    assert back.length == pytest.approx(path.length, abs=1e-3)


def test_donkeycar_file_without_header_and_comments_loads(tmp_path):
    f = tmp_path / "donkey_path.csv"
    f.write_text("# recorded in the yard\n1.0, 2.0, 0.5\n1.5,2.0,0.5\n\n2.0,2.0\n")
    path = load_path(f)
    np.testing.assert_allclose(path.xy, [[1, 2], [1.5, 2], [2, 2]])
    np.testing.assert_allclose(path.speed, [0.5, 0.5, 0.0])


@pytest.mark.parametrize("text, expected", [
    ("x,y,speed\n0,0,1\n0.2,abc,1\n", r"p\.csv, line 3: not a number in '0.2,abc,1'"),
    ("x,y,speed\n0,0,1,7\n", r"p\.csv, line 2: expected x,y,speed \(2 or 3 numbers\), got 4 values"),
    ("x,y,speed\n0,nan,1\n", r"p\.csv, line 2: '0,nan,1' is not finite"),
    ("x,y,speed\n", r"p\.csv: no points"),
])
def test_bad_file_is_a_one_line_error_naming_file_and_line(tmp_path, text, expected):
    f = tmp_path / "p.csv"
    f.write_text(text)
    with pytest.raises(PathFileError, match=expected) as info:
        load_path(f)
    assert "\n" not in str(info.value)


def test_missing_file_says_to_record_first(tmp_path):
    with pytest.raises(PathFileError, match=r"nope\.csv: cannot read it .*record and save a path first"):
        load_path(tmp_path / "nope.csv")


def test_a_path_is_immutable_and_closed_when_its_end_meets_its_start():
    lap = Path([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0.1]], [1] * 5)
    with pytest.raises(ValueError):
        lap.xy[0, 0] = 5.0
    assert lap.is_closed(0.2) and not lap.is_closed(0.05)
    with pytest.raises(ValueError, match="one speed per point"):
        Path([[0, 0], [1, 0]], [1.0])


def test_transformed_sees_the_path_from_a_pose():
    path = Path([[1.0, 1.0], [1.0, 2.0]], [0, 0])
    seen = path.transformed(1.0, 1.0, np.pi / 2)  # standing at (1, 1) facing +y
    np.testing.assert_allclose(seen.xy, [[0, 0], [1, 0]], atol=1e-6)


def test_a_huge_field_a_far_point_and_too_many_points_are_refused_in_one_line(tmp_path, monkeypatch):
    """Hardening item 13: a field over csv's 128 KiB limit raised csv.Error (a traceback at start,
    a stopped car when loaded while driving); 1e308 passed (float32: inf); 2 M points blocked."""
    from parts.path import pathfile

    big = tmp_path / "big.csv"
    big.write_text("x,y,speed\n0,0,1\n1," + "9" * 140_000 + ",1\n")
    with pytest.raises(pathfile.PathFileError, match=r"big.csv, line 3: not a CSV line \(field larger"):
        pathfile.load_path(big)
    far = tmp_path / "far.csv"
    far.write_text("x,y,speed\n0,0,1\n1e308,0,1\n")
    with pytest.raises(pathfile.PathFileError, match=r"far.csv, line 3: '1e308,0,1' is out of range"):
        pathfile.load_path(far)
    monkeypatch.setattr(pathfile, "MAX_POINTS", 3)
    many = tmp_path / "many.csv"
    many.write_text("x,y,speed\n" + "".join(f"{i},0,1\n" for i in range(4)))
    with pytest.raises(pathfile.PathFileError, match=r"many.csv, line 5: more than 3 points"):
        pathfile.load_path(many)
    monkeypatch.setattr(pathfile, "MAX_BYTES", 20)
    with pytest.raises(pathfile.PathFileError, match=r"larger than a path file may be"):
        pathfile.load_path(many)
