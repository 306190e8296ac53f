from __future__ import annotations

import math

import numpy as np
import pytest

from parts.sim.simulator import OUTPUTS, SimCar


def test_run_outputs_match_the_declared_keys(cfg):
    sim = SimCar.from_config(cfg, seeds=[3])
    out = dict(zip(OUTPUTS, sim.run(0.0, 0.5), strict=True))
    assert out["cam/image_array"].shape == (cfg.IMAGE_H, cfg.IMAGE_W, 3)
    assert out["sim/speed"] > 0 and out["enc/speed"] == out["sim/speed"]
    assert out["sim/track"] == 3 and out["sim/lap"] == 0 and out["sim/lap_time"] is None
    assert out["sim/off_track"] is False
    assert abs(out["sim/cte"]) < 1e-6 and 0.0 <= out["sim/progress"] < 0.01
    # simulated time: timestamps advance by exactly dt whatever the wall clock does
    t1 = sim.run(0.0, 0.5)[1]
    assert t1 - out["cam/timestamp"] == pytest.approx(1.0 / cfg.DRIVE_LOOP_HZ)
    # None commands (first loop before any controller) are zero
    assert sim.run(None, None)[0].shape == (cfg.IMAGE_H, cfg.IMAGE_W, 3)


def test_same_commands_same_frames(cfg):
    def run() -> list[np.ndarray]:
        sim = SimCar.from_config(cfg, seeds=[4])
        return [sim.run(math.sin(i / 7) * 0.3, 0.4)[0] for i in range(60)]

    a, b = run(), run()
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], a[-1])  # the view changed as the car moved


def test_leaving_the_road_resets_to_start(cfg):
    sim = SimCar.from_config(cfg, seeds=[5])
    frames = [sim.step(1.0, 0.6) for _ in range(80)]  # full right: off the road quickly
    events = [f for f in frames if f.off_track_event]
    assert events and abs(events[0].cte) > cfg.SIM_OFF_TRACK_CTE
    assert sim.resets == len(events)
    assert sim.car.state.speed >= 0
    # after the reset the car stood at the start line (progress restarted from 0)
    first = frames.index(events[0])
    assert frames[first + 1].progress < 0.05


def test_reset_nearest_and_no_reset(cfg):
    sim = SimCar.from_config(cfg, seeds=[5], reset_to="nearest")
    for _ in range(200):
        f = sim.step(0.0, 0.3)
        if f.off_track_event:
            break
    assert f.off_track_event
    s_off = f.s
    sim.step(0.0, 0.0)
    assert sim.frame.s == pytest.approx(s_off, abs=0.3)  # re-centred where it left
    assert abs(sim.frame.cte) < 0.05
    free = SimCar.from_config(cfg, seeds=[5], reset_off_track=False)
    frames = [free.step(1.0, 0.6) for _ in range(80)]
    assert free.resets == 0 and sum(f.off_track for f in frames) > 5  # circles on the verge


def test_reset_on_request_and_track_switching(cfg):
    sim = SimCar.from_config(cfg, seeds=[1, 2], switch_every=10)
    for _ in range(9):
        sim.run(0.0, 0.5)
    assert sim.seed == 1 and sim.car.state.speed > 0
    sim.run(0.0, 0.5)
    assert sim.seed == 2 and sim.car.state.speed == 0.0
    sim.run(0.0, 0.5)
    sim.run(0.0, 0.5, True)  # reset input (rising edge; holding it resets once)
    sim.run(0.0, 0.5, True)
    assert sim.car.state.speed < 0.4 and sim.resets == 1


def test_bad_commands_and_arguments(cfg):
    sim = SimCar.from_config(cfg, seeds=[1])
    with pytest.raises(ValueError, match="non-finite"):
        sim.run(float("nan"), 0.0)
    with pytest.raises(ValueError, match="seeds"):
        SimCar([])
    with pytest.raises(ValueError, match="reset_to"):
        SimCar([1], reset_to="home")
