"""Reading many tubs for training: deleted skipped, bad records reported with tub, index and file."""

from __future__ import annotations

import numpy as np
import pytest

from parts.tub.errors import CorruptRecord, TubError
from parts.tub.reader import find_tubs, iter_images, iter_records, load_records


def test_folder_of_tubs_in_order_skipping_deleted(donkey_tub, tmp_path):
    donkey_tub(4, name="data/tub_1", deleted=(0,))
    donkey_tub(3, name="data/tub_2")
    (tmp_path / "data" / "notes").mkdir()  # not a tub: ignored
    recs = load_records(tmp_path / "data")
    assert [(r.tub.name, r.index) for r in recs] == [("tub_1", 1), ("tub_1", 2), ("tub_1", 3),
                                                     ("tub_2", 0), ("tub_2", 1), ("tub_2", 2)]
    assert len(load_records([tmp_path / "data/tub_2", tmp_path / "data/tub_1"], include_deleted=True)) == 7


def test_bad_records_are_reported_and_skipped_or_raised(donkey_tub, caplog):
    path, _ = donkey_tub(6, max_len=10)
    (path / "images" / "1_cam_image_array_.jpg").write_bytes(b"")     # 0-byte JPEG
    (path / "images" / "2_cam_image_array_.jpg").unlink()              # missing
    cat = path / "catalog_0.catalog"
    lines = cat.read_text().splitlines(keepends=True)
    lines[3] = "{not json}\n"
    cat.write_text("".join(lines))
    errors: list[CorruptRecord] = []
    recs = load_records(path, errors=errors)
    assert [r.index for r in recs] == [0, 4, 5]
    assert [(e.index, e.file.name, e.reason) for e in errors] == [
        (1, "1_cam_image_array_.jpg", "image file is empty (0 bytes)"),
        (2, "2_cam_image_array_.jpg", "image file is missing"),
        (3, "catalog_0.catalog", "unparsable catalog line")]
    assert all(e.tub == path for e in errors)
    assert "record 1" in caplog.text and str(path) in caplog.text
    with pytest.raises(CorruptRecord, match=r"record 1: .*1_cam_image_array_\.jpg: image file is empty"):
        load_records(path, on_error="raise")


def test_undecodable_image_raises_from_image_and_is_skipped_by_iter_images(donkey_tub):
    path, _ = donkey_tub(4)
    (path / "images" / "2_cam_image_array_.jpg").write_bytes(b"\xff\xd8 not a jpeg")
    recs = load_records(path)
    with pytest.raises(CorruptRecord) as info:
        recs[2].image()
    assert info.value.index == 2 and info.value.file.name == "2_cam_image_array_.jpg"
    pairs = list(iter_images(recs, workers=2))
    assert [r.index for r, _ in pairs] == [0, 1, 3]
    assert all(img.shape == (120, 160, 3) and img.dtype == np.uint8 for _, img in pairs)
    with pytest.raises(CorruptRecord):
        list(iter_images(recs, on_error="raise"))


def test_streaming_without_stat_still_reports_missing_and_empty_images(donkey_tub, caplog):
    n = 150
    path, _ = donkey_tub(n, max_len=60)  # three catalogs, several decoding tasks
    (path / "images" / "1_cam_image_array_.jpg").write_bytes(b"")
    (path / "images" / "33_cam_image_array_.jpg").unlink()
    pulled = 0

    def counted():
        nonlocal pulled
        for rec in iter_records(path, check_images=False):
            pulled += 1
            yield rec

    stream = iter_images(counted(), workers=2, prefetch=32)
    first = next(stream)
    assert first[0].index == 0 and pulled < n  # frames come out while the catalogs are still read
    pairs = [first, *stream]
    assert pulled == n
    assert [r.index for r, _ in pairs] == [i for i in range(n) if i not in (1, 33)]
    assert "record 1" in caplog.text and "image file is empty (0 bytes)" in caplog.text
    assert "record 33" in caplog.text and "33_cam_image_array_.jpg: cannot read image" in caplog.text
    with pytest.raises(CorruptRecord, match="record 1: "):
        list(iter_images(iter_records(path, check_images=False), on_error="raise"))


def test_stopping_early_drops_the_queued_decoding(donkey_tub, monkeypatch):
    from parts.tub import reader

    path, _ = donkey_tub(200, max_len=1000)
    decoded = 0
    image = reader.TubRecord.image

    def counting(self, *args, **kwargs):
        nonlocal decoded
        decoded += 1
        return image(self, *args, **kwargs)

    monkeypatch.setattr(reader.TubRecord, "image", counting)
    stream = iter_images(load_records(path), workers=1, prefetch=192)  # 6 tasks of 32 queued
    assert next(stream)[0].index == 0
    stream.close()  # what a `break` out of the loop does
    # the tasks not started yet were cancelled: without that all 6 would be decoded for nothing
    assert 32 <= decoded < 192


def test_images_decode_to_rgb(tmp_path):
    from parts.tub.tub import Tub

    img = np.zeros((24, 32, 3), np.uint8)
    img[..., 0] = 250  # pure red
    with Tub(tmp_path / "t", ["cam/image_array"], ["image_array"]) as tub:
        tub.write_record({"cam/image_array": img})
    out = load_records(tmp_path / "t")[0].image()
    assert out[..., 0].mean() > 240 and out[..., 2].mean() < 10


def test_find_tubs_errors_name_the_path(tmp_path):
    with pytest.raises(TubError, match="no such folder"):
        find_tubs(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(TubError, match="holds no tub"):
        find_tubs(tmp_path / "empty")
    with pytest.raises(ValueError, match="on_error"):
        list(iter_records(tmp_path, on_error="ignore"))
