"""EpisodeMetrics on telemetry streams other than our simulator's: lap counters that restart, resets."""

from __future__ import annotations

import pytest

from parts.sim.metrics import EpisodeMetrics


def feed(m: EpisodeMetrics, rows):
    for lap, progress, off in rows:
        m.run(0.0, 0.1, off, 1.0, (0.0, 0.0), lap, 10.0 if lap else None, progress)


def test_laps_are_counted_as_increments_of_the_simulators_counter():
    m = EpisodeMetrics(0.05, laps=5, max_time=100.0, penalty_s=6.0)
    # lap 0 -> 1, then the simulator restarts its counter (a new scene), then 0 -> 1 again
    feed(m, [(0, 0.5, False), (0, 0.9, False), (1, 0.1, False), (0, 0.0, False), (0, 0.5, False), (1, 0.05, False)])
    r = m.result()
    assert r["laps_completed"] == 2 and r["lap_times_s"] == [10.0, 10.0]


def test_a_reset_jump_is_not_progress():
    m = EpisodeMetrics(0.05, laps=5, max_time=100.0, penalty_s=6.0)
    # 0.1 -> 0.2 driven; off the road; the simulator puts the car at 0.7 (a jump): only driving counts
    feed(m, [(0, 0.1, False), (0, 0.2, False), (0, 0.25, True), (0, 0.7, False), (0, 0.8, False)])
    r = m.result()
    assert r["interventions"] == 1
    assert r["laps_driven"] == pytest.approx(0.25)  # 0.1 + 0.05 + (jump skipped) + 0.1
