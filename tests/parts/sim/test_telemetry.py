from __future__ import annotations

import pytest

from parts.sim.kinematics import CarState
from parts.sim.telemetry import LapTracker
from parts.sim.track import make_track


def at(track, s, offset=0.0, speed=1.0) -> CarState:
    x, y, h = track.pose_at(s, offset)
    return CarState(x, y, h, speed)


def test_laps_lap_times_and_progress():
    track = make_track(8)
    lt = LapTracker(track, off_track_cte=0.4)
    lt.restart(0.0)
    t, frames = 0.0, []
    for i in range(int(2.5 * track.length / 0.1)):
        t += 0.05
        frames.append(lt.update(at(track, 0.1 * (i + 1)), t))
    assert lt.laps == 2
    assert [f.lap_completed for f in frames].count(True) == 2
    step_time = track.length / 0.1 * 0.05
    assert lt.lap_times == pytest.approx([step_time, step_time], abs=0.11)  # +- 2 steps
    assert frames[-1].progress == pytest.approx(0.5, abs=0.01)
    assert frames[-1].lap_time == lt.lap_times[-1]


def test_wiggling_over_the_start_line_or_reversing_counts_no_lap():
    track = make_track(8)
    lt = LapTracker(track, off_track_cte=0.4)
    for i in range(200):  # back and forth across s = 0
        lt.update(at(track, (0.3 if i % 2 else -0.3)), i * 0.05)
    assert lt.laps == 0
    # a full lap backwards is not a lap either
    for i in range(int(track.length / 0.1) + 10):
        lt.update(at(track, -0.1 * i, speed=-1.0), 10 + i * 0.05)
    assert lt.laps == 0
    assert lt.distance < -track.length * 0.9


def test_off_track_events_are_rising_edges_and_cte_signed():
    track = make_track(8)
    lt = LapTracker(track, off_track_cte=0.4)
    offsets = [0.0, -0.2, -0.5, -0.6, -0.3, 0.45, 0.5, 0.0]  # left = positive offset, cte negative
    frames = [lt.update(at(track, 1.0 + 0.05 * i, off), i * 0.05) for i, off in enumerate(offsets)]
    assert [f.off_track for f in frames] == [False, False, True, True, False, True, True, False]
    assert [f.off_track_event for f in frames] == [False, False, True, False, False, True, False, False]
    assert lt.off_track_events == 2
    assert frames[2].cte == pytest.approx(0.5, abs=1e-3)  # offset -0.5 (right) -> cte +0.5
    assert frames[1].heading_error == pytest.approx(0.0, abs=0.05)
    with pytest.raises(ValueError, match="off-track"):
        LapTracker(track, off_track_cte=0.0)
