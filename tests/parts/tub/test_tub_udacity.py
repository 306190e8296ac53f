"""Udacity driving_log.csv import (both file forms, decimal commas, left/right images) and export."""

from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

import pytest

from parts.tub.reader import load_records
from parts.tub.tub import Tub
from parts.tub.udacity import COLUMNS, _rebuild, export_udacity, import_udacity, read_driving_log, timestamp_from_name
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


def test_importing_into_a_tub_that_holds_records_is_refused(recording, tmp_path, capsys):
    # acceptance: a second import-udacity into the same tub appended every row again (the
    # simulator appends to driving_log.csv, so re-importing an updated recording doubled the data)
    lines = [f"IMG/center_{s}.jpg,,,0.05,0.9,0,22.1" for s in NAMES]
    (recording / "driving_log.csv").write_text("\n".join(lines) + "\n")
    assert main(["tub", "import-udacity", str(recording), str(tmp_path / "t")]) == 0
    assert main(["tub", "import-udacity", str(recording), str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: {tmp_path / 't'} exists and is not empty; give a new folder (nothing was written)"
    assert len(load_records(tmp_path / "t")) == 3
    (tmp_path / "empty").mkdir()
    assert import_udacity(recording, tmp_path / "empty").imported == 3  # an empty folder is fine


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


# -- export ------------------------------------------------------------------------------------------

T0 = 1_700_000_000_000
SIDE_KEYS = {"center": "cam/image_array", "left": "cam/image_array_left", "right": "cam/image_array_right"}
MPH_PER_MS = 2.2369362920544023  # 1 m/s in miles per hour (3600 / 1609.344)


def read_log(out: Path) -> list[list[str]]:
    with open(out / "driving_log.csv", newline="") as f:
        return list(csv.reader(f, skipinitialspace=True))


def test_export_writes_speed_in_mph_brake_and_the_side_cameras(tmp_path, image):
    keys = [*SIDE_KEYS.values(), "user/angle", "user/throttle", "user/brake", "enc/speed"]
    with Tub(tmp_path / "t", keys, ["image_array"] * 3 + ["float"] * 4, fsync=False) as tub:
        for i in range(4):
            tub.write_record({"cam/image_array": image(i, 48, 64), "cam/image_array_left": image(10 + i, 48, 64),
                              "cam/image_array_right": image(20 + i, 48, 64), "user/angle": 0.1 * i - 0.2,
                              "user/throttle": 0.5 - 0.1 * i, "user/brake": 0.25 * i, "enc/speed": 2.0 + i},
                             timestamp_ms=T0 + 50 * i)
    report = export_udacity(tmp_path / "t", tmp_path / "out", style="sample")
    assert report.rows == 4 and report.cameras == ["center", "left", "right"] and not report.skipped
    rows = read_log(tmp_path / "out")
    assert rows[0] == list(COLUMNS)
    for rec, row in zip(load_records(tmp_path / "t"), rows[1:], strict=True):
        stamp = time.strftime("%Y_%m_%d_%H_%M_%S", time.localtime(rec.timestamp_ms // 1000)) \
            + f"_{rec.timestamp_ms % 1000:03d}"
        for side, path in zip(SIDE_KEYS, row[:3], strict=True):
            assert path == f"IMG/{side}_{stamp}.jpg"
            assert (tmp_path / "out" / path).read_bytes() == rec.image_bytes(SIDE_KEYS[side])
        steering, throttle, brake, speed = map(float, row[3:])
        assert (steering, throttle, brake) == (rec.angle, rec.throttle, rec["user/brake"])
        assert speed == pytest.approx(rec["enc/speed"] * MPH_PER_MS, rel=1e-12)  # m/s -> mph
    back = load_records(import_udacity(tmp_path / "out", tmp_path / "back").tub)
    assert [r["enc/speed"] for r in back] == pytest.approx([2.0, 3.0, 4.0, 5.0], rel=1e-12)
    assert [r["user/brake"] for r in back] == [0.0, 0.25, 0.5, 0.75]


def put_nan(tub: Path, index: int, key: str) -> None:
    """Make a record's value NaN in its catalog, as DonkeyCar's json.dumps writes it."""
    for catalog in tub.glob("catalog_*.catalog"):
        lines = catalog.read_text().splitlines(keepends=True)
        for i, line in enumerate(lines):
            rec = json.loads(line)
            if rec["_index"] == index:
                rec[key] = math.nan
                lines[i] = json.dumps(rec, sort_keys=True) + "\n"
        catalog.write_text("".join(lines))
        manifest = catalog.with_name(catalog.stem + ".catalog_manifest")
        meta = json.loads(manifest.read_text())
        meta["line_lengths"] = [len(ln) for ln in lines]
        manifest.write_text(json.dumps(meta))


def test_export_skips_records_without_a_centre_image_or_with_nan_and_says_so(tmp_path, image, capsys):
    keys = ["cam/image_array", "cam/image_array_left", "user/angle", "user/throttle"]
    path = tmp_path / "t"
    with Tub(path, keys, ["image_array", "image_array", "float", "float"], fsync=False) as tub:
        def write(i: int, ts: int, center: bool = True, left: bool = True) -> None:
            rec = {"user/angle": 0.1 * i, "user/throttle": 0.5}
            if center:
                rec["cam/image_array"] = image(i, 48, 64)
            if left:
                rec["cam/image_array_left"] = image(10 + i, 48, 64)
            tub.write_record(rec, timestamp_ms=ts)
        write(0, T0)
        write(1, T0 + 50, center=False)         # a left image only: skipped
        write(2, T0 + 50)                       # the same millisecond: its own names
        write(3, T0 + 100)                      # NaN steering: skipped
        write(4, T0 + 150, center=False, left=False)  # no image at all: skipped
        write(5, T0 + 200)
        write(6, T0 + 200)                      # the same millisecond again: moved on by 1 ms
    put_nan(path, 3, "user/angle")
    out = tmp_path / "out"
    assert main(["tub", "export-udacity", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"{out}: 4 rows (center, left cameras), skipped 3: 2 without a cam/image_array image, " \
           "1 with a non-finite number" in printed
    rows = read_log(out)
    assert [float(r[3]) for r in rows] == pytest.approx([0.0, 0.2, 0.5, 0.6])
    assert "nan" not in (out / "driving_log.csv").read_text().lower()
    names = [Path(p).name for r in rows for p in r[:2]]
    assert names[-2:] == [n.replace("_200.jpg", "_201.jpg") for n in names[-4:-2]]
    assert len(set(names)) == 8 and sorted(p.name for p in (out / "IMG").iterdir()) == sorted(names)
    for rec, row in zip([r for r in load_records(path) if r.index in (0, 2, 5, 6)], rows, strict=True):
        assert row[2] == ""  # the tub has no right camera
        for key, p in zip(("cam/image_array", "cam/image_array_left"), row[:2], strict=True):
            assert Path(p).read_bytes() == rec.image_bytes(key), (rec.index, key)


def test_export_reads_side_cameras_written_under_their_old_names(tmp_path, image):
    # issue 27: docs once named the side cameras cam/left_image_array, cam/right_image_array
    keys = ["cam/image_array", "cam/left_image_array", "cam/right_image_array", "user/angle", "user/throttle"]
    with Tub(tmp_path / "t", keys, ["image_array"] * 3 + ["float"] * 2, fsync=False) as tub:
        for i in range(2):
            tub.write_record({"cam/image_array": image(i, 48, 64), "cam/left_image_array": image(10 + i, 48, 64),
                              "cam/right_image_array": image(20 + i, 48, 64), "user/angle": 0.1,
                              "user/throttle": 0.5}, timestamp_ms=T0 + 50 * i)
    report = export_udacity(tmp_path / "t", tmp_path / "out", style="sample")
    assert report.rows == 2 and report.cameras == ["center", "left", "right"] and not report.skipped
    for rec, row in zip(load_records(tmp_path / "t"), read_log(tmp_path / "out")[1:], strict=True):
        assert (tmp_path / "out" / row[1]).read_bytes() == rec.image_bytes("cam/left_image_array")
        assert (tmp_path / "out" / row[2]).read_bytes() == rec.image_bytes("cam/image_array_right")
