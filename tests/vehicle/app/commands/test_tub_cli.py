"""``vehicle tub info|ls|delete|restore|check|hist|movie`` through the real command line."""

from __future__ import annotations

import json

import numpy as np
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


# -- issue 21: what check finds and repair fixes --------------------------------------------------
def _corrupt_middle(path):
    """Zero 64 bytes in the middle of a JPEG (a zeroed block, what a power cut can leave in a file
    being written): its start and end markers stay intact, it still decodes, with errors."""
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    data[mid:mid + 64] = bytes(64)
    path.write_bytes(bytes(data))


def test_check_decodes_every_image_and_finds_a_corrupt_middle(donkey_tub, capsys):
    path, _ = donkey_tub(6, max_len=3)
    _corrupt_middle(path / "images" / "4_cam_image_array_.jpg")
    (path / "images" / "2_cam_image_array_.jpg").write_bytes(bytes(range(256)) * 8)  # not a JPEG
    assert main(["tub", "check", str(path), "--quick"]) == 1  # without decoding: only the stranger
    out = capsys.readouterr().out
    assert "record 2: 2_cam_image_array_.jpg: not a JPEG" in out and "record 4" not in out
    assert main(["tub", "check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "record 4: 4_cam_image_array_.jpg: decodes with errors (Corrupt JPEG data" in out, out
    assert "truncated" not in out
    assert main(["tub", "repair", str(path)]) == 0
    assert Tub(path, read_only=True).deleted_indexes == {2, 4}
    assert main(["tub", "check", str(path)]) == 0


def test_a_missing_catalog_manifest_is_reported_and_rebuilt(donkey_tub, capsys, donkeycar_opens):
    path, _ = donkey_tub(8, max_len=3)
    expected = (path / "catalog_1.catalog_manifest").read_text()
    (path / "catalog_1.catalog_manifest").unlink()
    (path / "catalog_0.catalog_manifest").write_text('{"created_at": 1, "line_lengths": [5], '
                                                      '"path": "catalog_0.catalog_manifest", "start_index": 0}\n')
    assert donkeycar_opens(path)
    assert main(["tub", "check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "catalog_1.catalog_manifest is missing" in out
    assert "catalog_0.catalog_manifest: line lengths do not match catalog_0.catalog" in out
    assert main(["tub", "check", "--repair", str(path)]) == 0
    assert donkeycar_opens(path) == []
    rebuilt = json.loads((path / "catalog_1.catalog_manifest").read_text())
    assert rebuilt["line_lengths"] == json.loads(expected)["line_lengths"] and rebuilt["start_index"] == 3
    assert main(["tub", "check", str(path)]) == 0


def test_an_empty_trailing_catalog_is_dropped(donkey_tub, capsys, donkeycar_opens):
    # what a kill right after a rollover left behind (0-byte catalog_3.catalog, start_index 9)
    path, _ = donkey_tub(9, max_len=3)
    (path / "catalog_3.catalog").write_bytes(b"")
    (path / "catalog_3.catalog_manifest").write_text(
        '{"created_at": 1, "line_lengths": [], "path": "catalog_3.catalog_manifest", "start_index": 9}\n')
    lines = (path / "manifest.json").read_text().splitlines()
    cat = json.loads(lines[4])
    cat["paths"].append("catalog_3.catalog")
    lines[4] = json.dumps(cat)
    (path / "manifest.json").write_text("\n".join(lines) + "\n")
    assert donkeycar_opens(path) == ["ValueError: cannot mmap an empty file (catalog_3.catalog)"]
    assert len(Tub(path, read_only=True)) == 9  # ours reads it
    assert main(["tub", "check", str(path)]) == 1
    assert "catalog_3.catalog is empty" in capsys.readouterr().out
    assert main(["tub", "check", "--repair", str(path)]) == 0
    assert donkeycar_opens(path) == [] and not (path / "catalog_3.catalog").exists()
    with Tub(path) as tub:  # the next record starts the catalog again, with its line
        tub.write_record({"cam/image_array": np.zeros((120, 160, 3), np.uint8), "user/angle": 0.0,
                          "user/throttle": 0.0, "user/mode": "user"})
    assert (path / "catalog_3.catalog").stat().st_size > 0 and donkeycar_opens(path) == []
    assert main(["tub", "check", str(path)]) == 0


def test_repair_of_a_half_truncated_manifest_converges_and_rebuilds_from_the_records(donkey_tub, capsys):
    path, records = donkey_tub(8, max_len=3, sessions=("26-11-20_0", "26-11-21_1"))
    text = (path / "manifest.json").read_bytes()
    (path / "manifest.json").write_bytes(text[: len(text) // 2])
    assert main(["tub", "check", str(path)]) == 1
    capsys.readouterr()
    assert main(["tub", "check", "--repair", str(path)]) == 0
    capsys.readouterr()
    assert main(["tub", "check", str(path)]) == 0, capsys.readouterr().out  # converged
    line4 = json.loads((path / "manifest.json").read_text().splitlines()[3])
    assert line4["created_at"] == records[0]["_timestamp_ms"] / 1000  # not the repair time
    assert line4["sessions"] == {"all_full_ids": ["26-11-20_0", "26-11-21_1"], "last_id": 1,
                                 "last_full_id": "26-11-21_1"}


def test_info_mentions_a_torn_last_line(donkey_tub, capsys):
    path, _ = donkey_tub(4, max_len=3)
    with open(path / "catalog_1.catalog", "ab") as f:
        f.write(b'{"_index": 4, "cam/ima')
    assert main(["tub", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "torn last line: 22 bytes at the end of catalog_1.catalog" in out
    assert "vehicle tub repair" in out


def test_a_misspelt_field_is_named_with_the_closest_one(donkey_tub, tmp_path, capsys):
    # acceptance: `tub ls --fields user/angel` printed a column of None, `tub hist` an empty plot
    path, _ = donkey_tub(5)
    assert main(["tub", "ls", str(path), "--fields", "user/angel"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "no field 'user/angel' (did you mean user/angle?)" in err
    out = str(tmp_path / "h.png")
    assert main(["tub", "hist", str(path), "--fields", "user/angle,user/trottle", "--out", out]) == 2
    assert "no field 'user/trottle' (did you mean user/throttle?)" in capsys.readouterr().err
    assert not (tmp_path / "h.png").exists()
    assert main(["tub", "ls", str(path), "--fields", "_session_id,user/angle"]) == 0


@pytest.mark.parametrize("verb", ["delete", "restore"])
def test_editing_a_tub_that_does_not_exist_leaves_no_folder(tmp_path, capsys, verb):
    # acceptance: `tub restore nope 1` created an empty folder nope/ and said "is a new tub: give inputs and types"
    assert main(["tub", verb, str(tmp_path / "nope"), "1"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'nope'}: no such tub folder"
    assert not (tmp_path / "nope").exists()


def test_movie_fps_and_hist_bins_below_one_are_named(donkey_tub, tmp_path, capsys):
    # acceptance: --fps 0 said "OpenCV cannot write ...: use a .mp4 file name", --bins 0 gave numpy's
    # "`bins` must be positive, when an integer"
    path, _ = donkey_tub(5)
    assert main(["tub", "movie", str(path), "--fps", "0", "--out", str(tmp_path / "m.mp4")]) == 2
    assert "fps must be > 0 frames per second, got 0.0" in capsys.readouterr().err
    assert main(["tub", "hist", str(path), "--bins", "0", "--out", str(tmp_path / "h.png")]) == 2
    assert "bins must be a whole number >= 1, got 0" in capsys.readouterr().err


def test_check_names_types_it_does_not_know(donkey_tub, capsys):
    """Hardening item 17: a manifest whose line 2 has an unknown image type was reported OK while
    none of the images were checked."""
    path, _ = donkey_tub(4)
    manifest = path / "manifest.json"
    lines = manifest.read_text().split("\n")
    lines[1] = json.dumps(["image_array_v9" if t == "image_array" else t for t in json.loads(lines[1])])
    manifest.write_text("\n".join(lines))
    assert main(["tub", "check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "cam/image_array: unknown type 'image_array_v9'" in out and "not checked" in out
    assert "OK" not in out
    assert main(["tub", "check", "--repair", str(path)]) == 1  # nothing repair can decide: still said
    assert "unknown type 'image_array_v9'" in capsys.readouterr().out
