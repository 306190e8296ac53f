from __future__ import annotations

import numpy as np
import pytest

from parts.sim.expert import Expert, NoiseInjector, speed_profile
from parts.sim.simulator import SimCar
from parts.sim.track import make_track
from vehicle.app.evaluate import evaluate


def test_expert_drives_every_track_without_intervention(cfg):
    report = evaluate("expert", [11, 12, 13, 14], laps=1, cfg=cfg)
    for t in report["tracks"]:
        assert t["autonomy"] == 100.0 and t["interventions"] == 0
        assert t["laps_completed"] == 1 and t["success"]
        assert t["mean_abs_cte"] < 0.05
    assert report["overall"]["autonomy"] == 100.0
    assert report["overall"]["success_rate"] == 1.0


def test_expert_keeps_its_lane_on_two_lane_tracks(cfg):
    cfg2 = cfg.replace(SIM_LANES=2, SIM_ROAD_WIDTH=1.2)
    sim = SimCar.from_config(cfg2, seeds=[6])
    assert sim.track.project((sim.car.state.x, sim.car.state.y)).cte == pytest.approx(0.3, abs=1e-3)  # starts in lane
    expert = Expert.from_config(cfg2, sim)
    ctes = []
    for _ in range(300):
        ctes.append(sim.step(*expert.command()).cte)
    assert np.mean(ctes[50:]) == pytest.approx(0.3, abs=0.05)  # right lane: 0.3 m right of centre


def test_speed_profile_slows_for_curves():
    track = make_track(9)
    v = speed_profile(track, v_max=3.0, lat_accel=2.0, decel=3.0)
    tight = int(np.argmax(np.abs(track.curvature)))
    # curvature is averaged over ±0.3 m, so the corner speed is close to sqrt(a * r_min)
    assert v[tight] < 3.0 and v[tight] == pytest.approx(np.sqrt(2.0 * track.min_radius), rel=0.1)
    assert v.max() == pytest.approx(3.0)
    # braking limit: speed never drops faster than decel allows between samples
    ds = track.length / track.n
    assert np.all(v[:-1] ** 2 - v[1:] ** 2 <= 2 * 3.0 * ds + 1e-9)
    with pytest.raises(ValueError):
        speed_profile(track, 0.0, 1.0, 1.0)


def test_noise_injection_perturbs_the_command_not_the_label(cfg):
    noise = NoiseInjector(0.5, every=1.0, duration=0.5, dt=0.05, seed=3)
    offsets = [noise.offset() for _ in range(400)]
    assert noise.pulses > 5
    assert max(map(abs, offsets)) <= 0.5 and max(map(abs, offsets)) > 0.25
    assert sum(1 for o in offsets if o == 0.0) > 100  # quiet between pulses
    # the part clips and passes throttle unchanged
    n2 = NoiseInjector(0.5, every=0.05, duration=1.0, dt=0.05, seed=1)
    outs = [n2.run(0.95, 0.3) for _ in range(20)]
    assert all(-1.0 <= a <= 1.0 and t == 0.3 for a, t in outs)
    assert any(a != 0.95 for a, _ in outs)
    # same seed, same perturbations
    again = NoiseInjector(0.5, every=1.0, duration=0.5, dt=0.05, seed=3)
    assert [again.offset() for _ in range(400)] == offsets


def test_expert_recovers_from_injected_noise(cfg):
    sim = SimCar.from_config(cfg, seeds=[12], reset_to="nearest")
    expert = Expert.from_config(cfg, sim)
    noise = NoiseInjector(0.6, every=1.5, duration=0.8, dt=sim.dt, seed=7)
    labels, executed, ctes = [], [], []
    while sim.tracker.laps < 1:
        a, t = expert.command()
        na, nt = noise.run(a, t)
        labels.append(a)
        executed.append(na)
        ctes.append(abs(sim.step(na, nt).cte))
    assert sim.tracker.off_track_events == 0
    assert max(ctes) > 0.1  # the noise pushed the car off-centre ...
    assert np.max(np.abs(np.array(executed) - labels)) > 0.2  # ... labels stayed clean
