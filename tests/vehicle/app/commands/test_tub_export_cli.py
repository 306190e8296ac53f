"""``vehicle tub export-lerobot|import-lerobot|export-udacity`` through the real command line."""

from __future__ import annotations

import csv
import json
import shutil

import pytest

from parts.tub.reader import load_records
from parts.tub.tub import Tub
from vehicle.app.cli import main

pytest.importorskip("pyarrow")
pytest.importorskip("av")


def test_export_and_import_a_donkeycar_tub(donkey_tub, tmp_path, capsys):
    """A tub written as DonkeyCar 4.x does (user/steering), two sessions, one record deleted."""
    path, written = donkey_tub(12, angle_key="user/steering", deleted=(4,),
                               sessions=("26-11-20_0", "26-11-20_1"), image_size=(48, 64))
    ds = tmp_path / "ds"
    assert main(["tub", "export-lerobot", str(path), "--out", str(ds), "--images"]) == 0
    out = capsys.readouterr().out
    assert f"{ds}: 11 frames in 2 episodes, 1 tasks, 20 fps (measured), images" in out
    info = json.loads((ds / "meta/info.json").read_text())
    assert info["features"]["action"]["names"] == ["angle", "throttle"] and "observation.state" not in info["features"]
    assert main(["tub", "import-lerobot", str(ds), "--out", str(tmp_path / "back")]) == 0
    assert f"{tmp_path / 'back'}: imported 11 records of 2 episodes" in capsys.readouterr().out
    back = load_records(tmp_path / "back")
    live = [r for r in written if r["_index"] != 4]
    assert Tub(tmp_path / "back", read_only=True).inputs == ["cam/image_array", "user/steering", "user/throttle",
                                                              "user/mode"]
    for rec, original in zip(back, live, strict=True):
        # the action is float32 in LeRobot: 2**-24 relative rounding
        assert rec.angle == pytest.approx(original["user/steering"], rel=2 ** -24)
        assert rec.throttle == pytest.approx(original["user/throttle"], rel=2 ** -24)
        assert rec["user/mode"] == "user" and rec.timestamp_ms == original["_timestamp_ms"]
        assert rec.image_bytes() == (path / "images" / original["cam/image_array"]).read_bytes()


def test_bad_input_exits_2_with_one_line_and_writes_nothing(donkey_tub, tmp_path, capsys):
    path, _ = donkey_tub(4, image_size=(48, 64))
    odd, _ = donkey_tub(2, name="odd", image_size=(47, 63))
    (tmp_path / "empty").mkdir()
    full = tmp_path / "full"
    full.mkdir()
    (full / "notes.txt").write_text("keep me")
    cases = [
        (["tub", "export-lerobot", str(tmp_path / "empty"), "--out", str(tmp_path / "a")], "holds no tub"),
        (["tub", "export-lerobot", str(path), "--out", str(full)], "exists and is not empty"),
        (["tub", "export-lerobot", str(path), "--out", str(tmp_path / "a"), "--fps", "0"], "fps must be"),
        (["tub", "export-udacity", str(path), "--out", str(full)], "exists and is not empty"),
        (["tub", "import-lerobot", str(path), "--out", str(tmp_path / "b")], "not a LeRobot dataset"),
        (["tub", "export-lerobot", str(path), "--out", str(tmp_path / "a"), "--max-gap", "-1"],
         "--max-gap must be >= 0 seconds (0: never split on a gap), got -1"),
        (["tub", "export-lerobot", str(path), "--out", str(tmp_path / "a"), "--max-episode-s", "3000"],
         "--max-episode-s must be > 0 and <= 2048 s"),
        (["tub", "export-lerobot", str(odd), "--out", str(tmp_path / "a"), "--vcodec", "h264"],
         "h264: 63x47 frames: h264 and hevc need an even width and height; use --vcodec libsvtav1"),
    ]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    old = tmp_path / "old"
    assert main(["tub", "export-lerobot", str(path), "--out", str(old), "--images"]) == 0
    info = json.loads((old / "meta/info.json").read_text())
    info["codebase_version"] = "v2.1"
    (old / "meta/info.json").write_text(json.dumps(info))
    capsys.readouterr()
    assert main(["tub", "import-lerobot", str(old), "--out", str(tmp_path / "b")]) == 2
    assert "codebase version 'v2.1'" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    assert [p.name for p in full.iterdir()] == ["notes.txt"]


def test_export_udacity_for_seed_001_scripts(donkey_tub, tmp_path, capsys):
    """The semicolon style read as the behavioural-cloning script of seed 001 reads it."""
    path, written = donkey_tub(5, image_size=(48, 64))
    out = tmp_path / "data"
    assert main(["tub", "export-udacity", str(path), "--out", str(out), "--style", "semicolon"]) == 0
    assert f"{out}: 5 rows (center camera), skipped 0" in capsys.readouterr().out
    steering, images = [], []
    with open(out / "driving_log.csv") as f:
        header = True
        for row in csv.reader(f, delimiter=";"):
            if header:
                header = False
                continue
            steering.append(float(row[3]))
            images.append((out / "IMG" / row[0].split("/")[-1]).read_bytes())
    assert steering == [r["user/angle"] for r in written]
    assert images == [(path / "images" / r["cam/image_array"]).read_bytes() for r in written]
    for style in ("semicolon", "simulator", "sample"):  # import-udacity reads every style back
        shutil.rmtree(out)
        assert main(["tub", "export-udacity", str(path), "--out", str(out), "--style", style]) == 0
        first = (out / "driving_log.csv").read_text().splitlines()[0]
        assert first.startswith("center") == (style != "simulator")
        assert main(["tub", "import-udacity", str(out), str(tmp_path / style)]) == 0
        back = load_records(tmp_path / style)
        assert [r.angle for r in back] == [r["user/angle"] for r in written]
        assert [r.throttle for r in back] == [r["user/throttle"] for r in written]
        assert [r.timestamp_ms for r in back] == [r["_timestamp_ms"] for r in written]
        assert [r.image_bytes() for r in back] == [(path / "images" / r["cam/image_array"]).read_bytes()
                                                   for r in written]


def test_max_episode_s_splits_long_sessions(donkey_tub, tmp_path, capsys):
    path, _ = donkey_tub(12, image_size=(48, 64))  # 0.6 s at 20 Hz, one session
    ds = tmp_path / "ds"
    assert main(["tub", "export-lerobot", str(path), "--out", str(ds), "--images", "--max-episode-s", "0.25"]) == 0
    assert f"{ds}: 12 frames in 3 episodes" in capsys.readouterr().out  # 5 + 5 + 2 frames
