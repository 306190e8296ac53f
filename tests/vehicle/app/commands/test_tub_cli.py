"""``vehicle tub info|ls|delete|restore|check|hist|movie`` through the real command line."""

from __future__ import annotations

import json

import pytest

from parts.tub.tools import format_ranges, parse_ranges
from parts.tub.tub import Tub
from vehicle.app.cli import main


def test_info_ls_delete_restore(donkey_tub, capsys):
    path, _ = donkey_tub(8, max_len=3, deleted=(7,), sessions=("26-11-20_0", "26-11-20_1"))
    assert main(["tub", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "records:   7 (1 deleted, next index 8)" in out
    assert "26-11-20_0: 4" in out and "26-11-20_1: 3" in out
    assert "user/angle (float)" in out and "catalogs:  3" in out and "(0.3 s)" in out
    assert main(["tub", "delete", str(path), "1,3:5"]) == 0
    assert "deleted 3 records" in capsys.readouterr().out
    assert main(["tub", "ls", str(path), "--fields", "user/mode"]) == 0
    rows = capsys.readouterr().out.splitlines()[1:]
    assert [int(r.split()[0]) for r in rows] == [0, 2, 5, 6]
    assert main(["tub", "restore", str(path), "3:"]) == 0
    assert Tub(path, read_only=True).deleted_indexes == {1}
    assert main(["tub", "delete", str(path), "5:99"]) == 2
    assert "outside the tub's records 0..7" in capsys.readouterr().err


def test_restore_reports_the_indexes_kept_deleted(tmp_path, capsys):
    with Tub(tmp_path / "t", ["a"], ["int"]) as tub:
        tub.write_record({"a": 0})
        tub.write_record({"a": 4}, index=4)  # 1-3 could not be written
        tub.write_record({"a": 5}, index=6)  # 5 neither
        tub.delete_records([0])
    assert main(["tub", "restore", str(tmp_path / "t"), ":"]) == 0
    out = capsys.readouterr().out
    assert "restored 1 records (7 indexes given); 3 records now" in out
    assert "4 kept deleted: they have no input value (mostly indexes kept for records that could not " \
        "be written): 1:4,5" in out


def test_parse_ranges():
    assert parse_ranges("3, 10:12,18:", 20) == [3, 10, 11, 18, 19]
    for indexes in ([], [4], [1, 2, 3, 7], [0, 2, 3, 9, 10, 11]):
        assert parse_ranges(format_ranges(indexes), 20) == indexes
    assert format_ranges([1, 2, 3, 7]) == "1:4,7"
    assert parse_ranges(":2", 5) == [0, 1]
    with pytest.raises(ValueError, match="bad index range 'x'"):
        parse_ranges("x", 5)


def test_check_reports_then_repairs(donkey_tub, capsys):
    path, _ = donkey_tub(6, max_len=4)
    (path / "images" / "2_cam_image_array_.jpg").write_bytes(b"")
    data = (path / "images" / "4_cam_image_array_.jpg").read_bytes()
    (path / "images" / "4_cam_image_array_.jpg").write_bytes(data[: len(data) // 2])
    cat = path / "catalog_1.catalog"
    cat.write_bytes(cat.read_bytes()[:-20])  # torn last line (record 5)
    assert main(["tub", "check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "record 2: 2_cam_image_array_.jpg: empty (0 bytes)" in out
    assert "record 4: 4_cam_image_array_.jpg: truncated JPEG" in out
    assert "torn last line(s): " in out and "--repair" in out
    assert main(["tub", "check", "--repair", str(path)]) == 0
    assert "repaired" in capsys.readouterr().out
    tub = Tub(path, read_only=True)
    assert tub.deleted_indexes == {2, 4} and tub.current_index == 5
    assert json.loads((path / "manifest.json").read_text().splitlines()[4])["current_index"] == 5
    assert main(["tub", "check", str(path)]) == 0
    assert capsys.readouterr().out.rstrip().endswith("OK")


def test_hist_writes_a_png(donkey_tub, tmp_path, capsys):
    path, _ = donkey_tub(10)
    out = tmp_path / "h.png"
    assert main(["tub", "hist", str(path), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000


def test_movie_writes_an_mp4_with_every_frame(donkey_tub, tmp_path, capsys):
    import cv2

    path, _ = donkey_tub(12, deleted=(3,))
    out = tmp_path / "m.mp4"
    assert main(["tub", "movie", str(path), "--out", str(out), "--start", "1", "--end", "10"]) == 0
    assert "(8 frames)" in capsys.readouterr().out
    cap = cv2.VideoCapture(str(out))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 8
    ok, frame = cap.read()
    assert ok and frame.shape == (240, 320, 3)
    cap.release()


def test_errors_are_user_errors(tmp_path, capsys):
    assert main(["tub", "info", str(tmp_path / "missing")]) == 2
    assert "no such folder" in capsys.readouterr().err
