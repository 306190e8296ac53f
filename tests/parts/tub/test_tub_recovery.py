"""Opening a tub after a crash at any instant: torn lines, stale or broken manifests, empty tubs."""

from __future__ import annotations

import json

from parts.tub.reader import iter_records, load_records
from parts.tub.tub import Tub


def _cut(path, nbytes):
    data = path.read_bytes()
    path.write_bytes(data[:-nbytes])


def test_torn_last_line_is_ignored_then_cut_and_never_merged(donkey_tub, read_lines, image):
    path, written = donkey_tub(5, max_len=10)
    _cut(path / "catalog_0.catalog", 40)  # power loss in the middle of record 4
    ro = Tub(path, read_only=True)
    assert [r["_index"] for r in ro] == [0, 1, 2, 3]
    assert ro.current_index == 4
    with Tub(path) as tub:
        assert tub.write_record({"cam/image_array": image(1), "user/angle": 0.5}) == 4
    lines = read_lines(path)  # every line parses: the new record is not glued to the torn one
    assert [r["_index"] for r in lines] == [0, 1, 2, 3, 4]
    assert lines[:4] == written[:4] and lines[4]["user/angle"] == 0.5
    meta = json.loads((path / "catalog_0.catalog_manifest").read_text())
    assert meta["line_lengths"] == [len(x) for x in (path / "catalog_0.catalog").read_text()
                                    .splitlines(keepends=True)]


def test_catalog_ahead_of_manifest_gives_no_duplicate_index(donkey_tub, read_lines):
    path, _ = donkey_tub(6, max_len=4)
    lines = (path / "manifest.json").read_text().splitlines()
    cat = json.loads(lines[4])
    cat["current_index"] = 3  # DonkeyCar killed after the catalog write, before the manifest write
    lines[4] = json.dumps(cat)
    (path / "manifest.json").write_text("\n".join(lines) + "\n")
    with Tub(path) as tub:
        assert tub.current_index == 6
        assert any("current_index 3" in p for p in tub.problems)
        tub.write_record({"user/angle": 0.0})
    indexes = [r["_index"] for r in read_lines(path)]
    assert indexes == [0, 1, 2, 3, 4, 5, 6]
    assert json.loads((path / "manifest.json").read_text().splitlines()[4])["current_index"] == 7


def test_manifest_cut_after_line_four_still_opens(donkey_tub):
    path, written = donkey_tub(7, max_len=3, deleted=())
    text = (path / "manifest.json").read_text().splitlines(keepends=True)
    (path / "manifest.json").write_text("".join(text[:4]))  # killed between truncate and write
    tub = Tub(path, read_only=True)
    assert list(tub) == written
    assert tub.max_len == 3 and tub.manifest.paths == [f"catalog_{k}.catalog" for k in range(3)]


def test_unreadable_manifest_is_rebuilt_from_the_catalogs(donkey_tub):
    path, written = donkey_tub(5, max_len=2)
    (path / "manifest.json").write_bytes(b"\x00\x00garbage{")
    tub = Tub(path)
    assert tub.inputs == ["cam/image_array", "user/angle", "user/mode", "user/throttle"]
    assert tub.types == ["image_array", "float", "str", "float"]
    assert tub.current_index == 5 and tub.max_len == 2
    tub.close()
    lines = (path / "manifest.json").read_text().splitlines()
    assert len(lines) == 5 and json.loads(lines[4])["current_index"] == 5
    assert [r.data for r in load_records(path)] == written
    (path / "manifest.json").unlink()
    assert len(Tub(path, read_only=True)) == 5


def test_empty_tubs_open_as_empty(tmp_path, donkey_tub):
    path, _ = donkey_tub(0)  # manifest + empty catalog_0.catalog (DonkeyCar's "cannot mmap" case)
    assert len(Tub(path, read_only=True)) == 0
    assert list(iter_records(path)) == []
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "manifest.json").write_bytes(b"")  # killed right at creation
    assert len(Tub(bare, read_only=True)) == 0
    with Tub(bare, ["a"], ["float"]) as tub:
        tub.write_record({"a": 1.0})
    assert [r["a"] for r in Tub(bare, read_only=True)] == [1.0]


def test_session_of_a_crashed_run_is_not_reused(donkey_tub):
    path, _ = donkey_tub(4, sessions=("26-11-20_0", "26-11-20_3"))
    lines = (path / "manifest.json").read_text().splitlines()
    meta = json.loads(lines[3])
    meta["sessions"] = {"all_full_ids": ["26-11-20_0"], "last_id": 0, "last_full_id": "26-11-20_0"}
    lines[3] = json.dumps(meta)  # session 3 crashed before reaching the manifest
    (path / "manifest.json").write_text("\n".join(lines) + "\n")
    assert Tub(path, read_only=True).session_id.endswith("_4")


def test_merged_donkeycar_line_salvages_the_whole_record(donkey_tub, caplog):
    path, written = donkey_tub(3, max_len=10)
    cat = path / "catalog_0.catalog"
    lines = cat.read_text().splitlines(keepends=True)
    # DonkeyCar after a power loss: record 1 torn, record 2 appended on the same line
    cat.write_text(lines[0] + lines[1][:30] + lines[2])
    errors = []
    recs = list(iter_records(path, errors=errors))
    assert [r.index for r in recs] == [0, 2]
    assert recs[1].data == written[2]


def test_catalog_missing_from_manifest_is_adopted(donkey_tub):
    path, written = donkey_tub(6, max_len=3)
    lines = (path / "manifest.json").read_text().splitlines()
    cat = json.loads(lines[4])
    cat["paths"] = ["catalog_0.catalog"]  # crash right after the rollover to catalog_1
    cat["current_index"] = 3
    lines[4] = json.dumps(cat)
    (path / "manifest.json").write_text("\n".join(lines) + "\n")
    tub = Tub(path, read_only=True)
    assert list(tub) == written and tub.current_index == 6
