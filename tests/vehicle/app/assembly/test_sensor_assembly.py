"""Sensor assembly: a simulator car with every simulated sensor, the odometer's speed holding the
page's speed limit and obstacle stop in the loop; a real car's sensors from its settings against
fake devices; tubs record the sensors' keys."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from parts.drive.obstacle import ObstacleStop
from parts.sensors.encoder import Encoder, EncoderError
from parts.sensors.gps import GPS
from vehicle.app.assembly.drive import add_drive_mode, add_obstacle_stop, add_speed_limit
from vehicle.app.assembly.pilot import speed_key_of
from vehicle.app.assembly.sensors import add_sensors
from vehicle.app.assembly.sim import add_expert, add_simulator
from vehicle.app.assembly.tub import add_tub_writer
from vehicle.clock import SimulatedClock
from vehicle.errors import UserError
from vehicle.vehicle import Vehicle

sys.path.insert(0, str(Path(__file__).parents[3] / "parts" / "sensors"))
from sensor_fakes import ArduinoEncoder, NmeaSource, gga, rmc  # noqa: E402


def test_simulator_car_with_sensors_limits_speed_from_ticks_and_records_them(cfg, tmp_path):
    cfg = cfg.replace(SIM_TRACK_SEEDS=[2], HAVE_ODOM=True, HAVE_IMU=True, HAVE_GPS=True, USE_LIDAR=True,
                      OBSTACLE_STOP=True, LIDAR_BINS=90, SIM_EXPERT_SPEED=2.5, DATA_PATH=str(tmp_path / "data"),
                      AUTO_CREATE_NEW_TUB=False)
    V = Vehicle(clock=SimulatedClock())
    sim = add_simulator(V, cfg)
    assert "enc/speed" not in sim.OUTPUTS  # measured from ticks, not the simulator's truth
    add_expert(V, cfg, sim)
    V.add(lambda: 1.2, outputs=["user/speed_limit"])  # the page's speed limit, m/s
    assert speed_key_of(V, cfg) == "enc/speed"
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    names = [e.name for e in V.parts]
    assert names.index("SimSensors") == 1 and {"Odometer", "BicyclePose", "SpeedLimit", "ObstacleStop"} <= set(names)
    writer = add_tub_writer(V, cfg)
    speeds = []
    V.add(lambda v: speeds.append(v), inputs=["sim/speed"])
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=240)
    assert max(speeds[120:]) < 1.2 * 1.12 and min(speeds[120:]) > 0.8  # held near the limit
    m = V.mem
    assert m["enc/ok"] and m["imu/ok"] and m["gps/ok"] and m["lidar/ok"]
    assert m["enc/distance"] > 3.0 and abs(m["enc/speed"] - m["sim/speed"]) < 0.15
    assert len(m["lidar/dist_array"]) == 90 and m["obstacle/stop"] is False
    assert sim.resets == 0
    assert writer is not None
    manifest = (Path(cfg.DATA_PATH) / "manifest.json").read_text().splitlines()[0]
    for key in ("enc/speed", "pos/x", "imu/gyr_z", "gps/x", "lidar/dist_array"):
        assert key in manifest, key


def test_obstacle_stop_needs_a_lidar(cfg):
    V = Vehicle(clock=SimulatedClock())
    with pytest.raises(UserError, match="OBSTACLE_STOP needs a LiDAR"):
        add_obstacle_stop(V, cfg.replace(OBSTACLE_STOP=True))
    assert add_obstacle_stop(V, cfg) is None
    V.add(lambda: [0.0] * 8, outputs=["lidar/dist_array"])
    assert isinstance(add_obstacle_stop(V, cfg.replace(OBSTACLE_STOP=True)), ObstacleStop)


def test_real_car_sensors_from_settings_against_fake_devices(cfg):
    encoder, receiver = ArduinoEncoder(), NmeaSource()
    try:
        cfg = cfg.replace(HAVE_ODOM=True, ENCODER_TYPE="arduino", ODOM_SERIAL=encoder.path, MM_PER_TICK=10.0,
                          HAVE_GPS=True, GPS_SERIAL=receiver.path, GPS_ORIGIN=(48.0, 11.0))
        V = Vehicle()
        parts = add_sensors(V, cfg)
        assert [type(p).__name__ for p in parts] == ["Encoder", "GPS", "Odometer", "BicyclePose"]
        assert all(e.threaded for e in V.parts if isinstance(e.part, Encoder | GPS))
        encoder.step = 3  # the wheel turns
        receiver.sentences = [gga(48.0, 11.0), rmc(48.0, 11.0, knots=1.0)]
        seen = []
        V.add(lambda *v: seen.append(v), inputs=["enc/distance", "enc/ok", "gps/x", "gps/ok"])
        V.start(rate_hz=50, max_loop_count=150)
    finally:
        encoder.close()
        receiver.close()
    assert any(d is not None and d > 0 and ok for d, ok, _, _ in seen)  # the device's ticks arrived
    assert any(gok and abs(x) < 0.05 for _, _, x, gok in seen)


def test_a_missing_sensor_stops_the_assembly_with_its_reason(cfg):
    cfg = cfg.replace(HAVE_ODOM=True, ENCODER_TYPE="ARDUINO", ODOM_SERIAL="/dev/ttyNOPE7")
    with pytest.raises(EncoderError, match="/dev/ttyNOPE7.*ODOM_SERIAL"):
        add_sensors(Vehicle(), cfg)


def test_a_gps_only_car_measures_its_speed_with_the_gps(cfg):
    from parts.sensors.gps import SpeedFromGPS
    from vehicle.app.assembly.sensors import add_odometry

    V = Vehicle(clock=SimulatedClock())
    V.add(lambda: (2.5, True), outputs=["gps/speed", "gps/ok"])
    (part,) = add_odometry(V, cfg)
    assert isinstance(part, SpeedFromGPS) and speed_key_of(V, cfg) == "enc/speed"
    assert part.run(2.5, True) == 2.5 and part.run(2.5, False) is None  # a lost fix: no speed
