"""The simulated car's sensors end to end: odometry from simulated encoder ticks against the true
path, the speed limit holding a speed from ticks alone, GPS/IMU noise models, LiDAR and obstacle
stop before a simulated wall in every drive mode."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fixtures.driving import hold_speed_from_ticks

from parts.drive.modes import DriveMode
from parts.drive.obstacle import ObstacleStop
from parts.sensors.odometry import BicyclePose, Odometer
from parts.sim.expert import Expert
from parts.sim.kinematics import CarParams
from parts.sim.sensors import SimSensors, ray_distances
from parts.sim.simulator import SimCar

MM_PER_TICK = 5.0


def _sim(**kw) -> SimCar:
    return SimCar([3], render=False, realtime=False, measured_speed=False, **kw)


def test_odometry_matches_ground_truth_over_a_lap() -> None:
    sim = _sim()
    sensors = SimSensors(sim, m_per_tick=MM_PER_TICK / 1000)
    params = CarParams()
    odo, pose = Odometer(MM_PER_TICK / 1000, smoothing=2), BicyclePose(params.wheelbase, params.max_steer)
    expert = Expert(sim, speed=2.0)
    true_length, heading0, turned, pos0 = 0.0, sim.car.state.heading, 0.0, (sim.car.state.x, sim.car.state.y)
    pose.reset(*pos0, heading0)
    angle = 0.0
    while sim.tracker.laps < 1:
        angle, throttle, _, _ = expert.run()
        before = sim.car.state.x, sim.car.state.y, sim.car.state.heading
        sim.run(angle, throttle)
        st = sim.car.state
        true_length += math.hypot(st.x - before[0], st.y - before[1])
        turned += (st.heading - before[2] + math.pi) % (2 * math.pi) - math.pi
        ticks, stamp, ok = sensors.run()
        distance, speed = odo.run(ticks, stamp)
        x, y, heading = pose.run(distance, stamp, angle)[:3]
        assert sim.resets == 0
    assert abs(turned) == pytest.approx(2 * math.pi, abs=0.3)  # one lap turns the car once around
    assert distance == pytest.approx(true_length, rel=0.02)
    assert speed == pytest.approx(sim.car.state.speed, abs=0.15)
    heading_error = math.degrees((heading - st.heading + math.pi) % (2 * math.pi) - math.pi)
    assert abs(heading_error) < 5.0
    assert math.hypot(x - st.x, y - st.y) < 0.05 * true_length


def test_speed_limit_holds_a_speed_from_encoder_ticks_alone() -> None:
    sim = _sim()
    assert "enc/speed" not in sim.OUTPUTS and "sim/speed" in sim.OUTPUTS
    true_speeds = hold_speed_from_ticks(sim, MM_PER_TICK / 1000, kp=0.3, ki=0.6, target=1.5, expert_speed=3.5,
                                        steps=400, settle=200)
    assert np.mean(true_speeds) == pytest.approx(1.5, abs=0.1)
    assert max(true_speeds) < 1.5 * 1.15
    assert sim.resets == 0


def test_imu_and_gps_noise_models_are_seeded_and_sized() -> None:
    def drive(seed: int) -> tuple[np.ndarray, np.ndarray, list]:
        sim = _sim()
        sensors = SimSensors(sim, encoder=False, imu=True, gps=True, gps_noise=0.5, gps_hz=5, seed=seed)
        expert = Expert(sim, speed=1.5)
        gyro, gps_err, fixes = [], [], []
        origin = None
        angle = throttle = 0.0
        for _ in range(600):
            prev_heading = sim.car.state.heading
            sim.run(angle, throttle)
            out = dict(zip(sensors.OUTPUTS, sensors.run(), strict=True))
            angle, throttle = expert.run()[:2]
            true_rate = ((sim.car.state.heading - prev_heading + math.pi) % (2 * math.pi) - math.pi) / sim.dt
            gyro.append(out["imu/gyr_z"] - true_rate)
            if origin is None:
                origin = (sim.car.state.x - out["gps/x"], sim.car.state.y - out["gps/y"])
            gps_err.append(math.hypot(out["gps/x"] + origin[0] - sim.car.state.x,
                                      out["gps/y"] + origin[1] - sim.car.state.y))
            fixes.append((out["gps/latitude"], out["gps/longitude"]))
            assert out["imu/ok"] and out["gps/ok"]
            assert out["imu/acl_z"] == pytest.approx(9.81, abs=0.3)
        return np.array(gyro), np.array(gps_err), fixes

    gyro, err, fixes = drive(1)
    assert np.std(gyro) == pytest.approx(0.005, rel=0.3)  # white gyro noise of the given size
    assert 0.05 < np.median(err) < 2.0  # the GPS wanders around the truth, relative to its first fix
    assert len(set(fixes)) == pytest.approx(600 * 0.05 * 5, abs=2)  # 5 fixes per second of 30 s
    assert drive(1)[2] == fixes and drive(2)[2] != fixes  # seeded


def test_ray_distances_against_a_box_and_a_circle() -> None:
    box = np.array([[0, 0, 10, 0], [10, 0, 10, 10], [10, 10, 0, 10], [0, 10, 0, 0]], dtype=float)
    circles = np.array([[5.0, 8.0, 1.0]])
    d = ray_distances((5.0, 5.0), np.array([0.0, math.pi / 2, math.pi, -math.pi / 2]), box, circles, 12.0)
    assert d.tolist() == pytest.approx([5.0, 2.0, 5.0, 5.0])
    assert ray_distances((5.0, 5.0), np.array([0.0]), box, circles, 4.0)[0] == math.inf


@pytest.mark.parametrize("mode", ["user", "local_angle", "local"])
def test_obstacle_stop_brakes_before_a_wall_in_every_mode(mode: str) -> None:
    sim = _sim(reset_off_track=False)  # the road bends: straight ahead leaves it, the wall is what counts
    st = sim.car.state
    h = st.heading  # a wall 3 m straight ahead of the start, square to the car
    x, y = st.x + 3.0 * math.cos(h), st.y + 3.0 * math.sin(h)
    nx, ny = -math.sin(h), math.cos(h)
    wall = ((x - nx, y - ny), (x + nx, y + ny))
    sensors = SimSensors(sim, m_per_tick=MM_PER_TICK / 1000, lidar=True, lidar_bins=180, obstacles=[wall])
    odo = Odometer(MM_PER_TICK / 1000)
    drive_mode, stop = DriveMode(), ObstacleStop(0.6, half_angle_deg=20, brake=1.0)
    angle = throttle = 0.0
    stopped_at = None
    for _ in range(120):
        sim.run(angle, throttle)
        ticks, stamp, _, dist, lidar_ok = sensors.run()
        speed = odo.run(ticks, stamp)[1]
        # user and pilot both steer straight at full throttle: whichever drives, the car runs at the wall
        angle, throttle = drive_mode.run(mode, 0.0, 1.0, 0.0, 1.0, False)
        throttle, stopping, ahead = stop.run(throttle, dist, lidar_ok, speed)
        if stopping and sim.car.state.speed == 0.0 and stopped_at is None:
            stopped_at = sim.car.state.x, sim.car.state.y
    st = sim.car.state
    nose = (st.x + 0.3 * math.cos(st.heading), st.y + 0.3 * math.sin(st.heading))  # the car's front
    gap = (x - nose[0]) * math.cos(h) + (y - nose[1]) * math.sin(h)
    assert stopped_at is not None and st.speed == 0.0
    assert 0.05 < gap < 0.8  # stopped in front of the wall, not through it, not far away
    assert ahead == pytest.approx(gap + 0.3 - 0.15, abs=0.05)  # the LiDAR sits 0.15 m ahead of the rear axle
