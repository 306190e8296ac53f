"""DonkeyCar tub v2 compatibility, both ways, checked against tubs built from the documented format."""

from __future__ import annotations

import json
import logging
import re

import numpy as np
import pytest

from parts.tub.errors import TubError, TubSchemaError
from parts.tub.reader import load_records
from parts.tub.tub import Tub

INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
TYPES = ["image_array", "float", "float", "str"]


def test_reads_donkey_tub_with_several_catalogs_and_deleted_records(donkey_tub):
    path, written = donkey_tub(8, max_len=3, deleted=(1, 2), metadata={"driver": "bob"})
    tub = Tub(path, read_only=True)
    assert tub.inputs == INPUTS and tub.types == TYPES
    assert tub.metadata == {"driver": "bob"}
    assert len(tub) == 6 and tub.current_index == 8
    assert list(tub) == [r for r in written if r["_index"] not in (1, 2)]
    assert tub.problems == []
    recs = load_records(path)
    assert [r.index for r in recs] == [0, 3, 4, 5, 6, 7]
    assert recs[1].data == written[3]
    img = recs[1].image()
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8


def test_reads_user_steering_tubs(donkey_tub):
    path, written = donkey_tub(4, angle_key="user/steering")
    recs = load_records(path)
    assert [r.angle for r in recs] == [w["user/steering"] for w in written]


def test_written_tub_follows_the_documented_format(tmp_path, image):
    path = tmp_path / "tub"
    with Tub(path, INPUTS, TYPES, metadata=["driver:ann"], max_catalog_len=3) as tub:
        for i in range(7):
            assert tub.write_record({"cam/image_array": image(i), "user/angle": i / 10,
                                     "user/throttle": np.float32(0.5), "user/mode": "user",
                                     "not/an/input": 1}, timestamp_ms=1000 + i) == i
        tub.delete_records([2, 5])
    lines = (path / "manifest.json").read_text().split("\n")
    assert len(lines) == 6 and lines[5] == ""  # five newline-terminated JSON lines
    assert json.loads(lines[0]) == INPUTS and json.loads(lines[1]) == TYPES
    assert json.loads(lines[2]) == {"driver": "ann"}
    sessions = json.loads(lines[3])["sessions"]
    assert re.fullmatch(r"\d\d-\d\d-\d\d_0", sessions["last_full_id"])
    assert sessions["all_full_ids"] == [sessions["last_full_id"]] and sessions["last_id"] == 0
    assert json.loads(lines[4]) == {"paths": ["catalog_0.catalog", "catalog_1.catalog", "catalog_2.catalog"],
                                    "current_index": 7, "max_len": 3, "deleted_indexes": [2, 5]}
    for k, n in ((0, 3), (1, 3), (2, 1)):
        text = (path / f"catalog_{k}.catalog").read_text()
        raw = text.splitlines(keepends=True)
        assert len(raw) == n
        meta = json.loads((path / f"catalog_{k}.catalog_manifest").read_text())
        assert meta["line_lengths"] == [len(x) for x in raw]
        assert meta["start_index"] == 3 * k and meta["path"] == f"catalog_{k}.catalog_manifest"
        for line in raw:
            rec = json.loads(line)
            assert line == json.dumps(rec, allow_nan=False, sort_keys=True) + "\n"
    rec = json.loads((path / "catalog_1.catalog").read_text().splitlines()[1])
    assert rec == {"_index": 4, "_session_id": sessions["last_full_id"], "_timestamp_ms": 1004,
                   "cam/image_array": "4_cam_image_array_.jpg", "user/angle": 0.4,
                   "user/mode": "user", "user/throttle": 0.5}
    img = load_records(path)[3].image()
    assert np.abs(img.astype(int) - image(4).astype(int)).mean() < 8  # lossy JPEG, same picture


def test_appending_to_a_donkey_tub_continues_indexes_and_sessions(donkey_tub, read_lines, image):
    path, written = donkey_tub(5, max_len=3, sessions=("26-11-20_0", "26-11-20_1"))
    with Tub(path) as tub:  # no inputs: adopt the stored schema
        assert tub.session_id.endswith("_2")
        assert tub.write_record({"cam/image_array": image(9), "user/angle": 0.1, "user/throttle": 0.2,
                                 "user/mode": "user"}) == 5
    lines = read_lines(path)
    assert lines[:5] == written
    assert [r["_index"] for r in lines] == [0, 1, 2, 3, 4, 5]
    assert lines[5]["_session_id"].endswith("_2")
    m = (path / "manifest.json").read_text().splitlines()
    assert json.loads(m[3])["sessions"]["all_full_ids"][-1] == lines[5]["_session_id"]
    assert json.loads(m[4])["current_index"] == 6


def test_reopen_gives_a_new_session_and_metadata_merges(tmp_path):
    path = tmp_path / "t"
    ids = []
    for i in range(3):
        with Tub(path, ["a"], ["float"], metadata={"run": str(i)}) as tub:
            tub.write_record({"a": 1.0})
            ids.append(tub.session_id)
    assert [s.rsplit("_", 1)[1] for s in ids] == ["0", "1", "2"]
    assert Tub(path, read_only=True).metadata == {"run": "2"}


def test_schema_errors_say_what_to_do(tmp_path):
    with pytest.raises(TubSchemaError, match="give inputs and types"):
        Tub(tmp_path / "new")
    assert not (tmp_path / "new").exists()  # no empty folder left behind
    with pytest.raises(TubSchemaError, match="same length"):
        Tub(tmp_path / "x", ["a", "b"], ["float"])
    with pytest.raises(TubSchemaError, match="unknown type 'double'; use one of \\['float', 'int'"):
        Tub(tmp_path / "x", ["a"], ["double"])
    with Tub(tmp_path / "t", ["a"], ["float"]) as tub:
        tub.write_record({"a": 1.0})
    with pytest.raises(TubSchemaError, match="Record into a new tub"):
        Tub(tmp_path / "t", ["b"], ["float"])
    with Tub(tmp_path / "t") as tub, pytest.raises(TubSchemaError, match="NaN"):
        tub.write_record({"a": float("nan")})
    with pytest.raises(TubSchemaError, match="key:value"):
        Tub(tmp_path / "m", ["a"], ["float"], metadata=["novalue"])


def test_value_types_are_stored_as_donkeycar_does(tmp_path):
    inputs = ["f", "i", "s", "b", "n", "l"]
    types = ["float", "int", "str", "boolean", "nparray", "list"]
    with Tub(tmp_path / "t", inputs, types) as tub:
        tub.write_record({"f": np.float64(1.5), "i": np.int64(3), "s": "x", "b": np.bool_(True),
                          "n": np.arange(3), "l": (1, 2), "extra": 5})
        tub.write_record({"f": None, "i": 4})  # None values are left out, like DonkeyCar
    recs = list(Tub(tmp_path / "t", read_only=True))
    assert {k: v for k, v in recs[0].items() if not k.startswith("_")} == \
        {"f": 1.5, "i": 3, "s": "x", "b": True, "n": [0, 1, 2], "l": [1, 2]}
    assert "f" not in recs[1] and recs[1]["i"] == 4


def test_soft_delete_restore_and_delete_last_n(tmp_path):
    with Tub(tmp_path / "t", ["a"], ["int"], max_catalog_len=4) as tub:
        for i in range(10):
            tub.write_record({"a": i})
        tub.delete_records(range(2, 4))
        assert tub.delete_last_n_records(3) == [7, 8, 9]
        assert len(tub) == 5
        tub.restore_records([3, 8])
        with pytest.raises(ValueError, match="outside 0..9"):
            tub.delete_records([10])
    tub = Tub(tmp_path / "t", read_only=True)
    assert [r["a"] for r in tub] == [0, 1, 3, 4, 5, 6, 8]
    assert tub.deleted_indexes == {2, 7, 9}
    assert (tmp_path / "t" / "catalog_2.catalog").read_text().count("\n") == 2  # nothing removed


def test_durability_window_commits_by_count_and_age(tmp_path):
    cat = tmp_path / "t" / "catalog_0.catalog"
    tub = Tub(tmp_path / "t", ["a"], ["int"], fsync_records=3, fsync_ms=60_000)
    tub.write_record({"a": 0})
    tub.write_record({"a": 1})
    # still inside the window: not written yet (and a new tub appears with its first commit)
    assert (tub._dir / "catalog_0.catalog").read_text() == "" and not cat.exists()
    tub.write_record({"a": 2})
    assert cat.read_text().count("\n") == 3
    tub.write_record({"a": 3})
    tub.close()
    assert cat.read_text().count("\n") == 4
    aged = Tub(tmp_path / "u", ["a"], ["int"], fsync_records=100, fsync_ms=0)
    aged.write_record({"a": 0})  # the age limit alone commits
    assert (tmp_path / "u" / "catalog_0.catalog").read_text().count("\n") == 1
    aged.close()


def test_indexes_given_ahead_keep_the_skipped_ones_as_deleted_records(tmp_path):
    tub = Tub(tmp_path / "t", ["cam/image_array", "a"], ["image_array", "int"], max_catalog_len=3)
    assert tub.write_record({"a": 0}) == 0
    # records 1-6 got indexes but could not be written (their images failed): kept as deleted
    # records without values, so that every index stays its position (DonkeyCar relies on it)
    assert tub.write_record({"a": 7}, index=7) == 7
    with pytest.raises(ValueError, match="record index 5 is taken; the next one is 8"):
        tub.write_record({"a": 5}, index=5)
    record = {"cam/image_array": np.zeros((8, 8, 3), np.uint8), "a": 8}
    tub.write_images(8, record)
    with pytest.raises(ValueError, match="belongs to record 8, not 9"):
        tub.write_record(dict(record), index=9)
    assert tub.write_record(record, index=8) == 8
    tub.close()
    t = tmp_path / "t"
    lines = [json.loads(ln) for i in range(3) for ln in (t / f"catalog_{i}.catalog").read_text().splitlines()]
    assert [rec["_index"] for rec in lines] == list(range(9))
    assert [rec.get("a") for rec in lines] == [0, None, None, None, None, None, None, 7, 8]
    reopened = Tub(t, read_only=True)
    assert reopened.deleted_indexes == {1, 2, 3, 4, 5, 6} and len(reopened) == 3
    assert reopened.problems == []
    assert [(r.index, r["a"]) for r in load_records(t, check_images=False)] == [(0, 0), (7, 7), (8, 8)]
    assert lines[8]["cam/image_array"] == "8_cam_image_array_.jpg"


def test_restore_keeps_the_indexes_of_records_that_could_not_be_written_deleted(tmp_path, caplog, monkeypatch):
    caplog.set_level(logging.DEBUG)
    with Tub(tmp_path / "t", ["a", "b"], ["int", "int"]) as tub:
        tub.write_record({"a": 0})
        tub.write_record({"a": 3}, index=3)  # 1 and 2 kept as deleted records without values
        tub.write_record({"b": 4})
        tub.delete_records([0, 4])
        assert tub.restore_records(range(5)) == [1, 2]
        assert tub.deleted_indexes == {1, 2} and len(tub) == 3
        monkeypatch.setattr(tub, "scan", lambda: pytest.fail("catalogs read to restore nothing"))
        assert tub.restore_records([3]) == []  # not deleted: nothing to restore
        monkeypatch.undo()
    assert "2 records kept deleted: they have no input value" in caplog.text
    assert [r.get("a", r.get("b")) for r in Tub(tmp_path / "t", read_only=True)] == [0, 3, 4]


def test_restore_tells_records_without_values_by_their_keys_not_the_schema(donkey_tub):
    path, _ = donkey_tub(3, deleted=(1,))
    lines = (path / "manifest.json").read_text().splitlines()
    lines[0] = json.dumps(["cam/image", "angle", "throttle", "mode"])  # names the records do not use
    (path / "manifest.json").write_text("\n".join(lines) + "\n")
    with Tub(path) as tub:
        assert tub.restore_records([1]) == []
        assert tub.deleted_indexes == set() and len(tub) == 3


def test_skipped_indexes_are_deleted_in_the_manifest_before_their_lines_are_written(tmp_path):
    tub = Tub(tmp_path / "t", ["a"], ["int"], fsync_records=20, fsync_ms=60_000)
    tub.write_record({"a": 0})
    tub.write_record({"a": 3}, index=3)
    # a crash now: manifest.json already deletes 1-2, the catalog holds record 0 only
    manifest = json.loads((tmp_path / "t" / "manifest.json").read_text().splitlines()[4])
    assert manifest["current_index"] == 1 and manifest["deleted_indexes"] == [1, 2]
    crashed = Tub(tmp_path / "t", read_only=True)
    assert crashed.current_index == 1 and crashed.deleted_indexes == set() and len(crashed) == 1
    tub.close()
    done = Tub(tmp_path / "t", read_only=True)
    assert done.current_index == 4 and done.deleted_indexes == {1, 2} and len(done) == 2


def test_building_folder_is_all_or_nothing(tmp_path):
    from parts.tub.format import building_folder

    out = tmp_path / "new"
    with pytest.raises(KeyboardInterrupt), building_folder(out) as tmp:
        (tmp / "half.txt").write_text("half")
        raise KeyboardInterrupt
    assert not out.exists() and list(tmp_path.iterdir()) == []
    out.mkdir()  # an empty folder is replaced
    with building_folder(out) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".new.partial")
        (tmp / "done.txt").write_text("done")
    assert [p.name for p in out.iterdir()] == ["done.txt"] and list(tmp_path.iterdir()) == [out]
    with pytest.raises(TubError, match="exists and is not empty"), building_folder(out):
        pass
    assert (out / "done.txt").read_text() == "done"


def test_folders_left_by_killed_exports_are_removed_on_the_next_run(tmp_path):
    """Issue 27 item 13: a SIGKILLed export or import leaves .NAME.partial-PID; the next run removes
    it (its process is gone) and leaves a running one's alone."""
    import os
    import signal
    import subprocess
    import sys

    from parts.tub.format import building_folder

    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    child.send_signal(signal.SIGKILL)
    child.wait()
    dead = tmp_path / f".lerobot_out.partial-{child.pid}"
    (dead / "data").mkdir(parents=True)
    (dead / "data" / "chunk.parquet").write_bytes(b"half")
    live = tmp_path / f".other.partial-{os.getppid()}"  # a run still going (our parent is alive)
    live.mkdir()
    keep = tmp_path / ".hidden.partial-notapid"
    keep.mkdir()
    with building_folder(tmp_path / "next") as tmp:
        (tmp / "x").write_text("x")
    assert not dead.exists() and live.is_dir() and keep.is_dir() and (tmp_path / "next" / "x").is_file()


def test_the_value_types_are_declared_once_and_documented():
    """parts/tub/format.py declares the tub value types; TUB_TYPES and docs/data-format.md follow."""
    from pathlib import Path

    from parts.tub.format import ALL_TYPES, IMAGE_TYPES, LIST_TYPES, SCALAR_TYPES
    from vehicle.config import constraints

    assert ALL_TYPES == SCALAR_TYPES + LIST_TYPES + IMAGE_TYPES and len(set(ALL_TYPES)) == 9
    assert [c.names() for c in constraints("TUB_TYPES")] == [list(ALL_TYPES)]
    doc = (Path(__file__).resolve().parents[3] / "docs" / "data-format.md").read_text()
    table = doc[doc.index("| Type | Stored as |"):].split("\n\n")[0]
    documented = [t for row in table.splitlines()[2:] for t in re.findall(r"`(\w+)`", row.split("|")[1])]
    assert documented == list(ALL_TYPES)
