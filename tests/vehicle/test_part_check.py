"""check_part: the part contract checker, on toy parts that break it one way each, and on every
part the cars of the templates assemble (built with the MOCK camera and drivetrain)."""

from __future__ import annotations

import threading

import pytest

from vehicle import Vehicle
from vehicle.config import Config
from vehicle.part import ThreadedPart
from vehicle.part_check import PartCheckError, check_part


class Good:
    INPUTS = ("user/angle", "imu/gyro_z")
    OUTPUTS = ("angle", "imu/ok")
    OPTIONAL_INPUTS = ("imu/gyro_z",)

    def run(self, angle, gyro):
        return angle, gyro is not None


class Servo:
    INPUTS = ("angle",)
    OUTPUTS = ()

    def __init__(self):
        self.neutrals = 0
        self.closed = False

    def run(self, angle):
        return None

    def neutral(self):
        self.neutrals += 1

    def shutdown(self):
        if self.closed:
            raise RuntimeError("bus already closed")
        self.closed = True


class Counter(ThreadedPart):
    OUTPUTS = ("count/n",)
    period = 0.001

    def __init__(self):
        super().__init__()
        self.n = 0

    def poll(self):
        self.n += 1
        return self.n


def test_a_part_that_keeps_the_contract_passes():
    check_part(Good(), inputs=(0.5, None))
    counter = Counter()
    check_part(counter)
    assert not counter.running and counter.error is None


@pytest.mark.parametrize(("part", "problem"), [
    (type("BadKeys", (Good,), {"INPUTS": ("Angle", "user/angle", "user/angle"), "OPTIONAL_INPUTS": ("x/y",)})(),
     "INPUTS ['Angle']: neither standard keys"),
    (type("Twice", (Good,), {"OUTPUTS": ("angle", "angle")})(), "OUTPUTS lists ['angle'] more than once"),
    (type("Stray", (Good,), {"OPTIONAL_INPUTS": ("imu/accel_x",)})(), "OPTIONAL_INPUTS ['imu/accel_x'] are not among"),
    (type("Short", (Good,), {"run": lambda self, a, g: a})(), "run() returned a single float for the 2 OUTPUTS"),
    (type("Loud", (Good,), {"OUTPUTS": ()})(), "run() returned tuple but OUTPUTS declares no key"),
    (type("Str", (Good,), {"INPUTS": "user/angle"})(), "INPUTS must be a tuple of memory keys"),
    (Servo(), "shutdown() a second time raised RuntimeError: bus already closed"),
])
def test_each_broken_rule_is_named(part, problem):
    with pytest.raises(PartCheckError) as info:
        check_part(part, inputs=(0.5, None) if isinstance(part, Good) else None)
    assert problem in str(info.value)


def test_a_run_that_raises_and_an_actuator_whose_neutral_fails_are_named():
    class Broken(Servo):
        def run(self, angle):
            raise ValueError("angle None")

        def neutral(self):
            raise OSError("I2C bus gone")

    with pytest.raises(PartCheckError) as info:
        check_part(Broken())
    message = str(info.value)
    assert "run() raised ValueError: angle None" in message
    assert "neutral() raised OSError: I2C bus gone: every stop path calls it" in message


def test_a_threaded_part_must_answer_at_once_and_end_its_thread():
    release = threading.Event()

    class Slow:
        OUTPUTS = ("slow/value",)

        def update(self):
            release.wait(5)

        def run_threaded(self):
            release.wait(5)
            return 1

        def shutdown(self):
            """Forgets to stop update()."""

    with pytest.raises(PartCheckError) as info:
        check_part(Slow(), threaded=True, timeout=0.2)
    release.set()
    assert "run_threaded() blocked" in str(info.value) and "its thread still runs after shutdown()" in str(info.value)


def _basic_car(cfg: Config, model: str | None) -> Vehicle:
    """The parts templates/basic/manage.py's drive assembles, in its order."""
    from vehicle.app import assembly

    V = Vehicle()
    assembly.add_camera(V, cfg)
    assembly.add_controller(V, cfg)
    assembly.add_camera_watchdog(V, cfg)
    assembly.add_behavior(V, cfg)
    if model:
        assembly.add_pilot(V, cfg, model)
    assembly.add_drive_mode(V, cfg)
    assembly.add_throttle_filter(V, cfg)
    assembly.add_drivetrain(V, cfg)
    assembly.add_recording_rules(V, cfg)
    assembly.add_tub_writer(V, cfg)
    return V


def test_every_part_of_the_basic_car_keeps_the_contract(tmp_path, make_model_file):
    """Each part gets the inputs it had in a real loop of the same car."""
    model = str(make_model_file("linear"))
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CAMERA_TYPE="MOCK", DRIVE_TRAIN_TYPE="MOCK", ESC_ARM_TIME_S=0.0,
                          WEB_CONTROL_PORT=0, TRAIN_BEHAVIORS=True)
    warm = _basic_car(cfg, model)
    warm.start(rate_hz=50, max_loop_count=3, log_summary=False)
    memory = dict(warm.mem.d)
    V = _basic_car(cfg, model)
    names = []
    for entry in V.parts:
        check_part(entry.part, inputs=[memory.get(k) for k in entry.inputs], threaded=entry.threaded)
        names.append(type(entry.part).__name__)
    assert {"Camera", "WebController", "Pilot", "DriveMode", "MockPWMSteeringThrottle", "TubWriter"} <= set(names)


def test_every_drivetrain_and_hardware_free_camera_row_keeps_the_contract():
    from fixtures.drivetrain_rigs import ALL, Rig

    from parts.actuators.fake_pca9685 import FakeI2C
    from parts.actuators.registry import DRIVETRAINS
    from parts.cameras.base import Camera
    from parts.cameras.registry import CAMERAS

    for name in DRIVETRAINS:
        if name in ALL:  # GPIO and serial drivetrains: each with a fake of its hardware
            rig = Rig(name)
            try:
                part = DRIVETRAINS.from_config(Config.defaults(**rig.settings), **rig.wiring())
                part.open()
                check_part(part, inputs=(0.2, 0.0))
            finally:
                rig.close()
            if name != "PWM_STEERING_THROTTLE":  # its default pins are PCA9685 channels: that too
                continue
        i2c = FakeI2C()
        i2c.add_board(1, 0x40)
        part = DRIVETRAINS.from_config(Config.defaults(DRIVE_TRAIN_TYPE=name, ESC_ARM_TIME_S=0.0),
                                       bus_factory=i2c.smbus)
        part.open()
        check_part(part, inputs=(0.2, 0.0))
    cfg = Config.defaults(CAMERA_TYPE="MOCK")
    check_part(Camera(CAMERAS.from_config(cfg), cfg.IMAGE_W, cfg.IMAGE_H), threaded=True)


def _simulator_car(cfg: Config, model: str | None) -> Vehicle:
    """The parts templates/simulator/manage.py's drive assembles with the built-in simulator."""
    from vehicle.app import assembly

    V = Vehicle(clock=assembly.sim_clock(cfg))
    assembly.add_simulator(V, cfg, seeds=[1])
    assembly.add_controller(V, cfg)
    assembly.add_camera_watchdog(V, cfg)
    assembly.add_behavior(V, cfg)
    if model:
        assembly.add_pilot(V, cfg, model)
    assembly.add_drive_mode(V, cfg)
    assembly.add_tub_writer(V, cfg)
    assembly.add_simulator_commands(V)
    return V


def test_every_part_of_the_simulator_car_keeps_the_contract(tmp_path, make_model_file):
    model = str(make_model_file("linear"))
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_REALTIME=False, WEB_CONTROL_PORT=0)
    warm = _simulator_car(cfg, model)
    warm.start(rate_hz=20, max_loop_count=3, log_summary=False)
    memory = dict(warm.mem.d)
    V = _simulator_car(cfg, model)
    for entry in V.parts:
        check_part(entry.part, inputs=[memory.get(k) for k in entry.inputs], threaded=entry.threaded)
    assert "SimCar" in {type(e.part).__name__ for e in V.parts}


def test_the_evaluation_episode_parts_keep_the_contract():
    from parts.sim.episode import ResetOnOffTrack, StopIfNoSimulator

    check_part(ResetOnOffTrack(), inputs=(True,))
    stopped = []
    waiter = StopIfNoSimulator(0.0, lambda: stopped.append(True))
    check_part(waiter, inputs=(False,))
    assert waiter.gave_up and stopped == [True]


def test_every_sensor_row_keeps_the_contract(monkeypatch):
    """Every row of every sensor table, built from its settings against a fake of its device."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "parts" / "sensors"))
    import smbus2
    from sensor_fakes import ArduinoEncoder, FakeSMBus, MPU6050Model, NmeaSource, RPLidarDevice, gga

    from parts.sensors.registry import sensor_tables

    encoder, gps, lidar = ArduinoEncoder(), NmeaSource(), RPLidarDevice(lambda a: 1.0)
    gps.sentences = [gga(48.1, 11.5, hdop=1.0)]
    monkeypatch.setattr(smbus2, "SMBus", lambda bus: FakeSMBus({0x68: MPU6050Model(0x68),
                                                                0x69: MPU6050Model(0x71)}))
    devices = {"ENCODER_TYPE": {"ODOM_SERIAL": encoder.path, "GPIO_MOCK": True},
               "IMU_SENSOR": {"IMU_ADDRESS": 0x68}, "GPS_TYPE": {"GPS_SERIAL": gps.path},
               "LIDAR_TYPE": {"LIDAR_SERIAL": lidar.path}}
    checked = []
    try:
        for table in sensor_tables():
            for name in table:
                settings = {table.setting: name, **devices[table.setting]}
                if name == "mpu9250":
                    settings["IMU_ADDRESS"] = 0x69
                part = table.from_config(Config.defaults(**settings))
                check_part(part, inputs=(0.0,) * len(getattr(part, "INPUTS", ())), threaded=True)
                checked.append(name)
    finally:
        for device in (encoder, gps, lidar):
            device.close()
    assert checked == ["GPIO", "ARDUINO", "arduino", "mpu6050", "mpu9250", "NMEA", "RP"]


def test_recorded_keys_must_be_outputs_with_a_tub_type():
    class Recorder(Good):
        RECORDED = {"angle": "float", "imu/gyro_z": "float"}

    with pytest.raises(PartCheckError, match=r"RECORDED \['imu/gyro_z'\] are not among its OUTPUTS"):
        check_part(Recorder(), inputs=(0.1, None))

    class Untyped(Good):
        RECORDED = {"angle": None}

    with pytest.raises(PartCheckError, match="RECORDED must map output keys to tub types"):
        check_part(Untyped(), inputs=(0.1, None))
