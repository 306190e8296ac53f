"""Issue 27 items 9, 10, 11: a tub killed while it is created is complete or absent; a catalog is
listed in the manifest before its records are visible; repair converges on a line damaged in its
middle and removes what an older version left at a tub's birth.

Kills are simulated exactly: a forked child counts the file-system calls the tub code makes and
leaves with ``os._exit`` (no ``finally``, no cleanup, like SIGKILL) at the Nth one; the parent then
looks at what is on disk. Every N up to the last call is tried, so every window is hit."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from parts.tub.check import check_tub
from parts.tub.tub import Tub

pytestmark = pytest.mark.skipif(sys.platform == "win32" or not hasattr(os, "fork"), reason="needs fork")

INPUTS, TYPES = ["cam/image_array", "user/angle"], ["image_array", "float"]
_CALLS = ("open", "write", "fsync", "replace", "rename", "mkdir", "unlink", "ftruncate", "rmdir")


def _killed_at(n: int, work) -> bool:
    """Run ``work()`` in a forked child killed at its ``n``-th file-system call; True when the
    child got that far (False: ``work`` finished first)."""
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 3
        try:
            count = [0]
            for name in _CALLS:
                real = getattr(os, name)

                def wrapped(*a, _real=real, **k):
                    count[0] += 1
                    if count[0] == n:
                        os._exit(9)  # killed: nothing below runs, nothing is cleaned up
                    return _real(*a, **k)

                setattr(os, name, wrapped)
            work()
            code = 0
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    assert code in (0, 9), f"the child failed ({code})"
    return code == 9


def _frame(i: int) -> np.ndarray:
    return np.full((12, 16, 3), (i * 9) % 256, np.uint8)


def _listed_and_on_disk(path):
    lines = (path / "manifest.json").read_text().splitlines()
    listed = json.loads(lines[4])["paths"]
    with_records = sorted(p.name for p in path.glob("catalog_*.catalog") if p.stat().st_size)
    return listed, with_records


def test_a_tub_killed_while_it_is_created_is_complete_or_absent(tmp_path, donkeycar_opens):
    from parts.tub.errors import TubError
    from parts.tub.reader import find_tubs

    n, windows, hidden_seen = 0, 0, False
    while True:
        n += 1
        path = tmp_path / f"tub_{n}"
        if not _killed_at(n, lambda p=path: Tub(p, INPUTS, TYPES, max_catalog_len=5).close()):
            break
        windows += 1
        if any(p.name.startswith(".") for p in tmp_path.iterdir()):  # a half-built tub is no tub yet
            hidden_seen = True
            try:
                tubs = find_tubs([tmp_path])
            except TubError:  # none yet
                tubs = []
            assert not [t for t in tubs if t.name.startswith(".")]
        visible = sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))
        if path.name not in visible:
            continue  # absent (a hidden half-built folder is removed by the next creation)
        assert (path / "manifest.json").is_file(), f"call {n}: {sorted(os.listdir(path))}"
        tub = Tub(path, read_only=True)
        assert tub.inputs == INPUTS and tub.problems == [], f"call {n}: {tub.problems}"
        with Tub(path) as w:  # a car records into it as into any tub
            for i in range(3):
                w.write_record({"cam/image_array": _frame(i), "user/angle": 0.1 * i})
        assert donkeycar_opens(path) == [], f"call {n}"
        assert check_tub(path).ok, f"call {n}"
    assert windows > 5 and hidden_seen
    # the next creation removes the hidden folders the killed ones left
    Tub(tmp_path / "last", INPUTS, TYPES).close()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_a_catalog_is_listed_before_its_records_are_visible(tmp_path, donkeycar_opens):
    """Item 11: at a roll-over, DonkeyCar (which reads the catalogs manifest.json lists) must never
    silently read fewer records than the folder holds."""
    base = tmp_path / "base"
    with Tub(base, INPUTS, TYPES, max_catalog_len=3) as tub:
        for i in range(3):
            tub.write_record({"cam/image_array": _frame(i), "user/angle": 0.1})

    def roll_over(p):
        with Tub(p) as t:
            t.write_record({"cam/image_array": _frame(9), "user/angle": 0.9})

    import shutil

    n, windows = 0, 0
    while True:
        n += 1
        path = tmp_path / f"t{n}"
        shutil.copytree(base, path)
        if not _killed_at(n, lambda p=path: roll_over(p)):
            break
        windows += 1
        listed, with_records = _listed_and_on_disk(path)
        assert set(with_records) <= set(listed), f"call {n}: records in {with_records}, manifest lists {listed}"
        problems = donkeycar_opens(path)
        assert problems == [] or all("FileNotFoundError" in p for p in problems), f"call {n}: {problems}"
        report = check_tub(path, repair=True)
        assert check_tub(path).ok, f"call {n}: {report.lines()}"
        assert donkeycar_opens(path) == [], f"call {n}"
        assert len(Tub(path, read_only=True)) in (3, 4)
    assert windows > 5


def test_repair_converges_on_a_line_damaged_in_its_middle(donkey_tub, donkeycar_opens):
    path, _ = donkey_tub(8, max_len=5)
    catalog = path / "catalog_0.catalog"
    lines = catalog.read_bytes().splitlines(keepends=True)
    lines[2] = lines[2][:10] + b"\x00garbage{" + lines[2][25:]
    catalog.write_bytes(b"".join(lines))
    first = check_tub(path)
    assert not first.ok and first.unparsable
    repaired = check_tub(path, repair=True)
    assert repaired.repaired
    again = check_tub(path)
    assert again.ok, again.lines()
    tub = Tub(path, read_only=True)
    assert 2 in tub.deleted_indexes and len(tub) == 7
    assert [i for _, i, _, _, _ in tub.scan()] == list(range(8))
    assert donkeycar_opens(path) == []
    for line in catalog.read_bytes().splitlines():  # DonkeyCar parses every line
        json.loads(line)


STILLBORN = [  # what an older version left when killed while creating a tub
    {},
    {"images": None},
    {"images": None, "catalog_0.catalog": b""},
    {"images": None, "catalog_0.catalog": b"", ".catalog_0.catalog_manifest.tmp": b"{"},
    {"images": None, "catalog_0.catalog": b"",
     "catalog_0.catalog_manifest": b'{"created_at": 1, "line_lengths": [], "path": "catalog_0.catalog_manifest", '
                                   b'"start_index": 0}\n'},
]


@pytest.mark.parametrize("files", STILLBORN, ids=[",".join(f) or "empty" for f in STILLBORN])
def test_repair_removes_a_tub_an_older_version_left_at_its_birth(tmp_path, files, capsys):
    from vehicle.app.cli import main

    data = tmp_path / "data"
    good = data / "tub_good"
    with Tub(good, INPUTS, TYPES) as tub:
        tub.write_record({"cam/image_array": _frame(1), "user/angle": 0.1})
    born = data / "tub_killed"
    born.mkdir()
    for name, content in files.items():
        if content is None:
            (born / name).mkdir()
        else:
            (born / name).write_bytes(content)
    assert main(["tub", "check", str(born)]) == 1
    out = capsys.readouterr().out
    assert "killed while it was created" in out and "--repair" in out
    assert main(["tub", "check", "--repair", str(data if files else born)]) == 0  # an empty folder: named
    out = capsys.readouterr().out
    assert "removed" in out and not born.exists() and good.is_dir()
    assert main(["tub", "check", str(data)]) == 0


def test_check_finds_an_image_damaged_in_its_middle_by_its_crc(tmp_path, donkeycar_opens):
    """Item 12: the writer records each image's CRC-32 in a side file DonkeyCar ignores; check
    finds a 1-byte change in the middle of a JPEG that still decodes cleanly."""
    from parts.tub.writer import TubWriter

    path = tmp_path / "tub"
    writer = TubWriter(path, INPUTS, TYPES, max_catalog_len=4)
    rng = np.random.default_rng(0)
    for i in range(10):
        writer.run(rng.integers(0, 255, (24, 32, 3), dtype=np.uint8), 0.1 * i)
    writer.shutdown()
    assert check_tub(path).ok
    assert donkeycar_opens(path) == []
    images = sorted((path / "images").iterdir())
    victim = images[5]
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x01  # one bit, mid-scan: the JPEG still decodes
    victim.write_bytes(bytes(data))
    report = check_tub(path)
    assert list(report.bad_records.values()) == [f"{victim.name}: changed since it was recorded (its CRC-32 "
                                                 "differs from image_crc32.jsonl)"]
    check_tub(path, repair=True)
    assert check_tub(path).ok and len(Tub(path, read_only=True)) == 9


def test_a_crc_of_a_record_a_crash_lost_is_never_applied(tmp_path):
    """A checksum line whose record never reached the catalog names a session no later record has."""
    path = tmp_path / "tub"
    with Tub(path, INPUTS, TYPES) as tub:
        tub.write_record({"cam/image_array": _frame(1), "user/angle": 0.1})
    with Tub(path) as tub:  # index 1 in a run that lost it to a crash: its checksum line outlived it
        tub.write_record({"cam/image_array": _frame(2), "user/angle": 0.2}, timestamp_ms=1)
    crcs = path / "image_crc32.jsonl"
    stale = crcs.read_text().splitlines()[-1].replace('"_session_id": "', '"_session_id": "lost_')
    with crcs.open("a") as f:  # the last word on index 1: a session no record has
        f.write(stale.replace('"crc32": {"cam/image_array": ', '"crc32": {"cam/image_array": 1') + "\n{torn")
    assert check_tub(path).ok


def test_a_tub_is_built_in_place_where_it_cannot_be_renamed_into_place(tmp_path, monkeypatch):
    """An empty mount point (a USB stick's root) cannot be replaced by a rename: built in place."""
    import errno

    real = os.replace

    def busy(src, dst):
        if str(src).endswith(f".partial-{os.getpid()}"):
            raise OSError(errno.EBUSY, "Device or resource busy")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", busy)
    stick = tmp_path / "stick"
    stick.mkdir()
    with Tub(stick, INPUTS, TYPES) as tub:
        tub.write_record({"cam/image_array": _frame(1), "user/angle": 0.1})
    assert len(Tub(stick, read_only=True)) == 1 and check_tub(stick).ok
    assert [p.name for p in tmp_path.iterdir()] == ["stick"]


def _record_one(path) -> None:
    with Tub(path, INPUTS, TYPES, max_catalog_len=5) as tub:
        tub.write_record({"cam/image_array": _frame(1), "user/angle": 0.5})


def test_a_tub_is_never_visible_with_an_empty_catalog(tmp_path, donkeycar_opens):
    """Hardening item 12: a kill right after a tub's birth, before its first record was committed,
    left a 0-record tub that DonkeyCar 5.3 cannot open (its read-only open mmaps the catalog:
    ``cannot mmap an empty file``). A tub now becomes visible with its first record."""
    n, windows, visible = 0, 0, 0
    while True:
        n += 1
        path = tmp_path / f"tub_{n}"
        if not _killed_at(n, lambda p=path: _record_one(p)):
            break
        windows += 1
        if path.exists():
            visible += 1
            assert donkeycar_opens(path) == [], f"call {n}: {sorted(os.listdir(path))}"
            assert [r["user/angle"] for r in Tub(path, read_only=True)] == [0.5], f"call {n}"
            assert check_tub(path).ok, f"call {n}"
    assert windows > 5 and visible > 0
    _record_one(tmp_path / "last")  # the hidden folders of the killed ones are removed
    assert donkeycar_opens(tmp_path / "last") == []
    assert [p.name for p in tmp_path.iterdir() if not p.name.startswith("tub_")] == ["last"]


def test_a_tub_closed_without_records_leaves_nothing(tmp_path):
    from parts.tub.writer import TubWriter

    Tub(tmp_path / "plain", INPUTS, TYPES).close()
    TubWriter(tmp_path / "writer", INPUTS, TYPES).shutdown()
    assert list(tmp_path.iterdir()) == []


def _donkeycar_empty_tub(path) -> None:
    """What DonkeyCar 5.3 leaves after driving without recording (reference section 2.6, #815)."""
    path.mkdir()
    (path / "images").mkdir()
    (path / "manifest.json").write_text(
        '["cam/image_array", "user/angle"]\n["image_array", "float"]\n{}\n'
        '{"created_at": 1795238373.33, "sessions": {"all_full_ids": [], "last_id": 0, "last_full_id": ""}}\n'
        '{"paths": ["catalog_0.catalog"], "current_index": 0, "max_len": 1000, "deleted_indexes": []}')
    (path / "catalog_0.catalog").write_bytes(b"")
    (path / "catalog_0.catalog_manifest").write_text(
        '{"created_at": 1795238373.33, "line_lengths": [], "path": "catalog_0.catalog_manifest", "start_index": 0}')


def test_check_flags_an_empty_tub_and_repair_moves_it_aside_restorably(tmp_path, capsys, donkeycar_opens):
    from vehicle.app.cli import main

    data = tmp_path / "data"
    data.mkdir()
    empty = data / "tub_empty"
    _donkeycar_empty_tub(empty)
    assert donkeycar_opens(empty) == ["ValueError: cannot mmap an empty file (catalog_0.catalog)"]
    manifest = (empty / "manifest.json").read_bytes()
    report = check_tub(empty)
    assert not report.ok and report.empty
    assert main(["tub", "check", str(empty)]) == 1
    out = capsys.readouterr().out
    assert "no records" in out and "DonkeyCar cannot open it" in out and "--repair" in out
    assert main(["tub", "check", "--repair", str(data)]) == 0
    out = capsys.readouterr().out
    aside = data / ".tub_empty.empty"
    assert not empty.exists() and (aside / "manifest.json").read_bytes() == manifest
    assert f"mv {aside} {empty}" in out
    assert main(["tub", "check", str(data)]) == 2  # no tub left to check: said, not OK
    assert "holds no tub" in capsys.readouterr().err
