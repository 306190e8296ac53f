from __future__ import annotations

import pytest

from vehicle.app.assembly.drive import add_drive_mode
from vehicle.app.assembly.sim import add_expert, add_expert_noise, add_simulator
from vehicle.clock import SimulatedClock
from vehicle.vehicle import Vehicle


def test_simulator_car_loop_with_expert_drive_mode_and_noise(cfg):
    cfg = cfg.replace(SIM_EXPERT_NOISE=0.4, SIM_TRACK_SEEDS=[2])
    V = Vehicle(clock=SimulatedClock())
    sim = add_simulator(V, cfg)
    expert = add_expert(V, cfg, sim)
    add_drive_mode(V, cfg)
    noise = add_expert_noise(V, cfg)
    assert noise is not None and expert.sim is sim
    executed = []
    V.add(lambda a, ua: executed.append((a, ua)), inputs=["angle", "user/angle"])
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=400)
    assert V.mem["sim/lap"] == 1 and V.mem["sim/lap_time"] > 5.0
    assert V.mem["recording"] is True and V.mem["user/mode"] == "user"
    assert sim.time == pytest.approx(400 / cfg.DRIVE_LOOP_HZ)
    assert any(abs(a - ua) > 0.1 for a, ua in executed)  # executed = label + noise
    assert sim.resets == 0


def test_no_noise_part_when_noise_is_off(cfg):
    assert add_expert_noise(Vehicle(clock=SimulatedClock()), cfg.replace(SIM_EXPERT_NOISE=0.0)) is None
