"""Step-response tuning: the fit recovers a known first-order plant, and the gains it suggests hold
a set speed in the simulator from encoder ticks."""

from __future__ import annotations

import numpy as np
import pytest
from fixtures.driving import hold_speed_from_ticks

from parts.drive.speed_tuning import StepTest, TuningError, fit_step, simc_gains
from parts.sensors.odometry import Odometer
from parts.sim.sensors import SimSensors
from parts.sim.simulator import SimCar


def test_fit_recovers_a_first_order_plant_with_dead_time() -> None:
    t = np.arange(0, 8, 0.05)
    k, tau, theta, u = 4.0, 0.8, 0.15, 0.5
    v = np.where(t > theta, k * u * (1 - np.exp(-(t - theta) / tau)), 0.0)
    model = fit_step(t, v, u)
    assert model.gain == pytest.approx(k, rel=0.02)
    assert model.tau == pytest.approx(tau, rel=0.05)
    assert model.dead_time == pytest.approx(theta, abs=0.03)
    gains = simc_gains(model)
    assert gains.tau_c == pytest.approx(model.dead_time)  # theta > tau / 10 here
    assert gains.kp == pytest.approx(model.tau / (model.gain * 2 * model.dead_time), rel=1e-9)
    assert gains.ki == pytest.approx(gains.kp / model.tau, rel=1e-9)  # Ti = min(tau, 8 theta) = tau


def test_fit_refuses_what_it_cannot_use() -> None:
    with pytest.raises(TuningError, match="did not move"):
        fit_step(np.arange(20) * 0.1, np.zeros(20), 0.3)
    with pytest.raises(TuningError, match="still rising"):
        fit_step(np.arange(20) * 0.1, np.arange(20) * 0.1, 0.3)


def test_tuned_gains_hold_a_speed_in_the_simulator() -> None:
    mm = 0.005
    sim = SimCar([3], render=False, realtime=False, measured_speed=False, reset_off_track=False)
    sensors, odo = SimSensors(sim, m_per_tick=mm), Odometer(mm, smoothing=2)
    test = StepTest(0.3, dt=sim.dt, duration=6.0, distance=20.0)
    angle = throttle = 0.0
    while True:
        sim.run(angle, throttle)
        ticks, stamp, _ = sensors.run()
        distance, speed = odo.run(ticks, stamp)
        angle, throttle, done = test.run(speed, distance)
        if done:
            break
    model, gains = test.result()
    # the simulated plant: dv/dt = 4 u - 0.8 v - 0.3 -> K = (4 * 0.3 - 0.3) / 0.8 / 0.3, tau = 1 / 0.8
    assert model.final_speed == pytest.approx((1.2 - 0.3) / 0.8, rel=0.05)
    assert model.tau == pytest.approx(1.25, rel=0.2)
    # closed loop with the suggested gains, on the road, from encoder ticks alone
    sim = SimCar([3], render=False, realtime=False, measured_speed=False)
    true = hold_speed_from_ticks(sim, mm, kp=gains.kp, ki=gains.ki, target=1.2, expert_speed=3.0, steps=300,
                                 settle=150)
    assert np.mean(true) == pytest.approx(1.2, abs=0.08)
    assert np.std(true) < 0.1


def test_a_step_cut_short_is_extrapolated() -> None:
    t = np.arange(0, 2.0, 0.05)  # 1.6 time constants: still rising at the end
    v = 3.0 * 0.4 * (1 - np.exp(-t / 1.25))
    model = fit_step(t, v, 0.4)
    assert model.final_speed == pytest.approx(1.2, rel=0.03)
    assert model.tau == pytest.approx(1.25, rel=0.1)
