from __future__ import annotations

import pytest

from parts.tub.tub import Tub
from vehicle.app.record import record_expert


def test_record_expert_writes_clean_labels_on_every_track(cfg, tmp_path):
    path = record_expert(cfg, [1, 2], 120, tmp_path / "tub", noise=0.5)
    assert path == (tmp_path / "tub").absolute()
    with Tub(path, read_only=True) as tub:
        records = [r for _, r in tub.records()]
        assert tub.inputs[:4] == ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
        assert tub.metadata.get("source") == "sim expert" and tub.metadata.get("tracks") == "1,2"
    assert len(records) == 120
    assert {r["sim/track"] for r in records} == {1, 2}  # spread over both tracks
    assert [r["sim/track"] for r in records].count(1) == 60
    assert all(r["user/mode"] == "user" and -1 <= r["user/angle"] <= 1 for r in records)
    stamps = [r["_timestamp_ms"] for r in records]
    assert all(b - a == 50 for a, b in zip(stamps, stamps[1:], strict=False))  # simulated 20 Hz
    assert max(r["sim/speed"] for r in records) > 1.0


def test_record_expert_is_deterministic_and_checks_arguments(cfg, tmp_path):
    a = record_expert(cfg, [3], 30, tmp_path / "a")
    b = record_expert(cfg, [3], 30, tmp_path / "b")
    with Tub(a, read_only=True) as ta, Tub(b, read_only=True) as tb:
        angles_a = [r["user/angle"] for _, r in ta.records()]
        angles_b = [r["user/angle"] for _, r in tb.records()]
    assert angles_a == angles_b and len(angles_a) == 30
    with pytest.raises(ValueError, match="n_records"):
        record_expert(cfg, [3], 0, tmp_path / "c")


def test_record_expert_into_a_new_tub_of_the_car(cfg, tmp_path):
    car_cfg = cfg.replace(CAR_PATH=str(tmp_path))
    first = record_expert(car_cfg, None, 10)
    second = record_expert(car_cfg, None, 10)
    assert first.parent == second.parent == tmp_path / "data" and first != second
    with Tub(second, read_only=True) as tub:
        assert len(tub) == 10
