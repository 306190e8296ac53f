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


def test_a_car_that_stands_still_scores_nothing_whatever_its_autonomy():
    from parts.sim.metrics import overall, rank_key

    still = EpisodeMetrics(0.05, laps=2, max_time=100.0, penalty_s=6.0)
    feed(still, [(0, 0.0, False)] * 40)  # never moves: no intervention, DAVE-2 autonomy 100 %
    driver = EpisodeMetrics(0.05, laps=2, max_time=100.0, penalty_s=6.0)
    # 1.5 laps in 15 s, off the road once
    feed(driver, [(i // 100, (i % 100) / 100, i == 120) for i in range(150)] + [(1, 0.5, False)] * 150)
    s, d = still.result(), driver.result()
    assert s["autonomy"] == 100.0 and s["completion"] == 0.0 and s["score"] == 0.0
    assert d["autonomy"] < 100.0 and 0 < d["completion"] == pytest.approx(d["laps_driven"] / 2, abs=1e-3)
    assert d["score"] > 0 and d["score"] == pytest.approx(d["autonomy"] * d["completion"], abs=0.01)
    assert sorted([s, d], key=rank_key) == [d, s]  # the car that drove ranks first
    both = overall([s, d], 6.0, __import__("numpy").empty(0))
    assert both["completion"] == pytest.approx(d["completion"] / 2, abs=1e-3)
    assert both["score"] == pytest.approx(both["autonomy"] * both["completion"], abs=0.05)
