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


def test_record_with_lane_changes_flips_the_behaviour_and_the_expert_follows(cfg, tmp_path):
    from vehicle.errors import UserError

    two = cfg.replace(SIM_LANES=2)
    path = record_expert(two, [1, 2], 800, tmp_path / "lanes", lane_changes=4)
    with Tub(path, read_only=True) as tub:
        records = [r for _, r in tub.records()]
        assert {"behavior/state", "behavior/label", "behavior/one_hot_state_array"} <= set(tub.inputs)
        assert tub.metadata.get("lane_changes") == "4"
    states = [r["behavior/state"] for r in records]
    assert sum(a != b for a, b in zip(states, states[1:], strict=False)) == 4
    assert all(r["behavior/one_hot_state_array"] == [1.0 - s, float(s)] for r, s in zip(records, states, strict=True))
    assert {r["behavior/label"] for r in records} == {"Left_Lane", "Right_Lane"}
    # the car starts in the initial behaviour's lane (left: CTE < 0) and is in the commanded lane
    # four seconds (80 records) after every change
    assert records[0]["sim/cte"] == pytest.approx(-0.2, abs=1e-3)
    changes = [i for i in range(1, len(states)) if states[i] != states[i - 1]]
    for i in changes:
        later = records[min(i + 80, len(records) - 1)]
        assert (later["sim/cte"] < 0) == (later["behavior/label"] == "Left_Lane")
    with pytest.raises(UserError, match="SIM_LANES = 2"):
        record_expert(cfg, [1], 100, tmp_path / "x", lane_changes=2)
    with pytest.raises(UserError, match="do not fit"):
        record_expert(two, [1], 100, tmp_path / "y", lane_changes=5)


def test_record_expert_mixes_themes_and_randomisation(cfg, tmp_path):
    c = cfg.replace(SIM_THEME=["road", "indoor"], SIM_RANDOMIZE=4, SIM_RANDOMIZE_RANGES={"latency": (2, 2)})
    path = record_expert(c, [1, 2], 40, tmp_path / "tub", noise=0.0)
    with Tub(path, read_only=True) as tub:
        assert tub.metadata.get("themes") == "road,indoor" and tub.metadata.get("randomize") == "4"
        records = [r for _, r in tub.records()]
    assert {r["sim/track"] for r in records} == {1, 2}
    # two loops of latency: the car stands still for the first two loops on each track
    speeds = [r["sim/speed"] for r in records if r["sim/track"] == 2]
    assert speeds[:2] == [0.0, 0.0] and speeds[5] > 0


def test_the_stop_report_names_no_internal_part(cfg, tmp_path, caplog):
    # issue 27: the internal `_Backpressure` appeared in the timing report printed at the stop
    import logging
    import re

    with caplog.at_level(logging.INFO, logger="vehicle.vehicle"):
        record_expert(cfg, [1], 5, tmp_path / "tub")
    report = caplog.text[caplog.text.index("vehicle stopped"):]
    names = re.findall(r"^(\S+)\s+\d+\s", report, re.MULTILINE)
    assert "TubWriter" in names and "WaitForTubWriter" in names
    assert not [n for n in names if n.startswith("_")], names


def test_an_expert_recording_records_the_cars_sensors(cfg, tmp_path):
    # docs/sensors.md: a sensor's keys are recorded when it is present, by the expert recording too
    sensed = cfg.replace(HAVE_ODOM=True, HAVE_IMU=True, HAVE_GPS=True, USE_LIDAR=True)
    path = record_expert(sensed, [1], 12, tmp_path / "sensed")
    with Tub(path, read_only=True) as tub:
        inputs = set(tub.inputs)
        records = [r for _, r in tub.records()]
    assert {"enc/speed", "pos/x", "imu/acl_x", "imu/gyr_z", "gps/x", "gps/ok", "lidar/dist_array"} <= inputs
    assert len(records) == 12
    assert records[-1]["enc/distance"] > 0  # the simulated encoder counted the expert's metres
    assert len(records[-1]["lidar/dist_array"]) > 0
