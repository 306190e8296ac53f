from __future__ import annotations

import pytest

from vehicle.clock import RateKeeper, SimulatedClock


def test_deadlines_are_absolute_and_exact():
    clock = SimulatedClock(start=100.0)
    rk = RateKeeper(50, clock)  # 20 ms
    wakes = []
    for _ in range(1000):
        clock.advance(0.007)  # every loop does 7 ms of work
        assert rk.wait()
        wakes.append(clock.now())
    # no drift after 1000 loops: the k-th wake is exactly at start + k * period
    assert wakes[-1] == pytest.approx(100.0 + 1000 * 0.02, abs=1e-9)
    assert wakes[0] == pytest.approx(100.02, abs=1e-12)
    assert rk.overruns == 0


def test_overrun_skips_to_next_slot_without_burst():
    clock = SimulatedClock()
    rk = RateKeeper(10, clock)  # 100 ms slots
    clock.advance(0.05)
    rk.wait()
    assert clock.now() == pytest.approx(0.1)
    clock.advance(0.25)  # overrun: now 0.35, slots 0.2 and 0.3 are gone
    assert rk.wait() is False
    assert clock.now() == pytest.approx(0.4)  # next grid slot, not 0.2 then 0.3 back to back
    assert rk.overruns == 1 and rk.skipped_slots == 2
    clock.advance(0.01)
    assert rk.wait() is True
    assert clock.now() == pytest.approx(0.5)


def test_rate_must_be_positive():
    with pytest.raises(ValueError, match="rate_hz must be > 0"):
        RateKeeper(0, SimulatedClock())
