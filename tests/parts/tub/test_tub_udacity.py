"""Udacity driving_log.csv import: both file forms, decimal commas, left/right images."""

from __future__ import annotations

import time

import pytest

from parts.tub.reader import load_records
from parts.tub.udacity import _rebuild, import_udacity, read_driving_log, timestamp_from_name
from vehicle.app.cli import main

NAMES = ["2016_12_01_13_30_48_287", "2016_12_01_13_30_48_404", "2016_12_01_13_30_48_520"]


@pytest.fixture
def recording(tmp_path, image, jpeg):
    """A Udacity recording folder with IMG/ holding center/left/right JPEGs of three frames."""
    rec = tmp_path / "rec"
    (rec / "IMG").mkdir(parents=True)
    for i, stamp in enumerate(NAMES):
        for side in ("center", "left", "right"):
            (rec / "IMG" / f"{side}_{stamp}.jpg").write_bytes(jpeg(image(i, 160, 320)))
    return rec


def test_simulator_form_windows_paths_no_header(recording, tmp_path):
    win = "C:\\Users\\me\\Desktop\\data\\IMG\\"
    rows = [f"{win}center_{s}.jpg,{win}left_{s}.jpg,{win}right_{s}.jpg,{a},0.5,0,{v}"
            for s, a, v in zip(NAMES, ("-0.25", "0", "0.1"), ("30.1", "29.5", "0"), strict=True)]
    (recording / "driving_log.csv").write_text("\r\n".join(rows) + "\r\n")
    report = import_udacity(recording, tmp_path / "tub")
    assert report.imported == 3 and report.skipped == []
    recs = load_records(tmp_path / "tub")
    assert [r.angle for r in recs] == [-0.25, 0.0, 0.1]
    assert recs[0]["enc/speed"] == pytest.approx(30.1 * 0.44704)
    assert recs[0]["user/throttle"] == 0.5 and recs[0]["user/brake"] == 0.0
    assert recs[0].image().shape == (160, 320, 3)
    assert recs[2].image("cam/image_array_right").shape == (160, 320, 3)
    # images are copied byte for byte
    assert recs[1].image_path().read_bytes() == (recording / "IMG" / f"center_{NAMES[1]}.jpg").read_bytes()
    expected = int(time.mktime((2016, 12, 1, 13, 30, 48, 0, 0, -1)) * 1000) + 287
    assert recs[0]["_timestamp_ms"] == expected


def test_sample_data_form_header_relative_paths_posix(recording, tmp_path):
    lines = ["center,left,right,steering,throttle,brake,speed"]
    lines += [f"IMG/center_{s}.jpg, IMG/left_{s}.jpg, IMG/right_{s}.jpg, 0.05, 0.9, 0, 22.1" for s in NAMES]
    (recording / "driving_log.csv").write_text("\n".join(lines) + "\n")
    assert main(["tub", "import-udacity", str(recording / "driving_log.csv"), str(tmp_path / "t")]) == 0
    recs = load_records(tmp_path / "t")
    assert len(recs) == 3 and recs[2].throttle == 0.9


def test_absolute_posix_paths_found_after_the_recording_moved(recording, tmp_path):
    rows = [f"/home/old/data/IMG/center_{s}.jpg,,,0.1,0.2,0.0,5.0" for s in NAMES[:2]]
    rows.append("/home/old/data/IMG/center_missing.jpg,,,0.1,0.2,0.0,5.0")
    (recording / "driving_log.csv").write_text("\n".join(rows) + "\n")
    report = import_udacity(recording, tmp_path / "t")
    assert report.imported == 2 and report.skipped == ["line 3: image '/home/old/data/IMG/"
                                                        "center_missing.jpg' not found"]
    recs = load_records(tmp_path / "t")
    assert "cam/image_array_left" not in recs[0].data


def test_decimal_commas(tmp_path, recording):
    s = NAMES[0]
    p = f"IMG/center_{s}.jpg,IMG/left_{s}.jpg,IMG/right_{s}.jpg"
    (recording / "driving_log.csv").write_text(
        f'{p},"-0,25","0,5",0,"12,5"\n'          # quoted
        f"{p},-0,25,0,5,0,12,5\n"                 # unquoted: split in two fields each
        f"{p},0,1,0,0,30,19\n")                   # unquoted, steering and speed with decimals
    rows = read_driving_log(recording / "driving_log.csv")
    assert [(r.steering, r.throttle, r.brake, r.speed) for r in rows] == [
        (-0.25, 0.5, 0.0, 12.5), (-0.25, 0.5, 0.0, 12.5), (0.1, 0.0, 0.0, 30.19)]
    semi = recording / "semi.csv"
    semi.write_text(f"{p.replace(',', ';')};-0,25;0,5;0;12,5\n")
    assert read_driving_log(semi)[0].steering == -0.25


def test_bad_logs_name_the_line(tmp_path):
    bad = tmp_path / "driving_log.csv"
    bad.write_text("a.jpg,b.jpg\n")
    with pytest.raises(ValueError, match="line 1: 2 fields, expected 7"):
        read_driving_log(bad)
    with pytest.raises(ValueError, match="more than one way"):
        _rebuild(["0", "1", "0", "0", "3"], 7)  # 0.1,0,0,3 or 0,1,0,0.3
    with pytest.raises(ValueError, match="no way"):
        _rebuild(["0", "5", "0", "5", "0"], 7)
    assert timestamp_from_name("center.jpg") is None
