"""Wheel encoders against their fakes: gpiozero's MockFactory pins and DonkeyCar's Arduino encoder
protocol on a pty; the odometer and the pose models on exact arcs."""

from __future__ import annotations

import math
import threading

import pytest
from gpiozero.pins.mock import MockFactory
from sensor_fakes import ArduinoEncoder

from parts.sensors.encoder import Encoder, EncoderError, GpioTicks, SerialTicks, gpio_pin_name
from parts.sensors.odometry import BicyclePose, Odometer, UnicyclePose


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def factory():
    f = MockFactory()
    yield f
    f.reset()


def _quadrature(a, b, cycles: int) -> None:
    """Drive A and B through ``cycles`` full quadrature cycles (A leads B: forward; negative: back)."""
    states = [(0, 1), (0, 0), (1, 0), (1, 1)]  # from the pulled-up rest state (1, 1)
    if cycles < 0:
        states = [(1, 0), (0, 0), (0, 1), (1, 1)]
    for _ in range(abs(cycles)):
        for sa, sb in states:
            a.drive_high() if sa else a.drive_low()
            b.drive_high() if sb else b.drive_low()


def test_pin_names_follow_donkeycar_specifiers() -> None:
    assert gpio_pin_name(13) == "BOARD13"
    assert gpio_pin_name("RPI_GPIO.BCM.17") == "GPIO17"
    assert gpio_pin_name("PIGPIO.BCM.27") == "GPIO27"
    assert gpio_pin_name("RPI_GPIO.BOARD.33") == "BOARD33"
    assert gpio_pin_name("GPIO5") == "GPIO5"
    with pytest.raises(EncoderError, match="header pin number"):
        gpio_pin_name("")


def test_quadrature_counts_both_ways(factory) -> None:
    ticks = GpioTicks("GPIO17", "GPIO18", pin_factory=factory)
    ticks.open()
    a, b = factory.pin(17), factory.pin(18)
    _quadrature(a, b, 7)
    assert ticks.read() == (7,)
    _quadrature(a, b, -3)
    assert ticks.read() == (4,)
    ticks.close()


@pytest.mark.parametrize(("mode", "expected"), [("FORWARD_ONLY", 5 + 3 + 2), ("FORWARD_REVERSE", 5 - 3 - 2),
                                                ("FORWARD_REVERSE_STOP", 5 - 3)])
def test_single_channel_direction_follows_the_throttle(factory, mode, expected) -> None:
    ticks = GpioTicks(13, mode=mode, pin_factory=factory)
    ticks.open()
    pin = factory.pin(27)  # header pin 13 is BCM 27

    def pulses(n: int) -> None:
        for _ in range(n):
            pin.drive_low()
            pin.drive_high()

    ticks.set_throttle(0.4)
    pulses(5)
    ticks.set_throttle(-0.3)
    pulses(3)
    ticks.set_throttle(0.0)  # coasting: the last direction, or nothing counted (STOP)
    pulses(2)
    assert ticks.read() == (expected,)
    ticks.close()


def test_the_throttle_sets_the_direction_at_once_in_the_non_threaded_run(factory) -> None:
    """Pulses after a loop's run(throttle) count with that throttle's sign (as in the threaded
    path), not with the sign of the loop before."""
    part = Encoder(GpioTicks(13, mode="FORWARD_REVERSE", pin_factory=factory), clock=Clock())
    pin = factory.pin(27)  # header pin 13 is BCM 27
    deltas, last = [], 0
    for throttle, pulses in ((-0.5, 30), (-0.5, 10), (0.5, 5), (0.5, 0)):
        ticks = part.run(throttle)[0]
        deltas.append(ticks - last)
        last = ticks
        for _ in range(pulses):
            pin.drive_low()
            pin.drive_high()
    assert deltas[1:] == [-30, -10, 5]
    part.shutdown()


class CountedTicks:
    """A tick source that counts the part thread's reads, so that a test knows when a read began
    after what it did (the thread reads every ``period``: no sleeping for a guessed time)."""

    def __init__(self, source: GpioTicks) -> None:
        self.source, self.channels, self.reads = source, source.channels, 0
        self._done = threading.Condition()

    def open(self) -> None:
        self.source.open()

    def set_throttle(self, throttle: float | None) -> None:
        self.source.set_throttle(throttle)

    def read(self) -> tuple[int, ...] | None:
        value = self.source.read()
        with self._done:
            self.reads += 1
            self._done.notify_all()
        return value

    def close(self) -> None:
        self.source.close()

    def settle(self, timeout: float = 10.0) -> None:
        """Wait for 3 more reads: the 2nd began after this call (it set the direction from the
        loop's throttle stored before, and counted every pulse given before); the 3rd began after the
        2nd's value was published."""
        with self._done:
            target = self.reads + 3
            assert self._done.wait_for(lambda: self.reads >= target, timeout), "the encoder thread stopped reading"


def test_the_throttle_sets_the_direction_in_the_threaded_run(factory) -> None:
    """Item 9 through the threaded path (the car's: Vehicle.add(..., threaded=True)): the same
    direction change as the non-threaded test gives the same deltas, -30, -10, +5."""
    source = CountedTicks(GpioTicks(13, mode="FORWARD_REVERSE", pin_factory=factory))
    part = Encoder(source, clock=Clock(), period=0.002)
    part.start()
    pin = factory.pin(27)  # header pin 13 is BCM 27
    deltas, last = [], 0
    try:
        for throttle, pulses in ((-0.5, 30), (-0.5, 10), (0.5, 5), (0.5, 0)):
            ticks = part.run_threaded(throttle)[0] or 0  # None before the first reading
            deltas.append(ticks - last)
            last = ticks
            source.settle()  # the thread took this loop's throttle
            for _ in range(pulses):
                pin.drive_low()
                pin.drive_high()
            source.settle()  # and counted the pulses
    finally:
        part.shutdown()
    assert deltas[1:] == [-30, -10, 5]
    assert part.error is None


def test_serial_encoder_protocol_and_staleness() -> None:
    device = ArduinoEncoder(channels=2)
    clock = Clock()
    try:
        part = Encoder(SerialTicks(device.path, channels=2), max_age=0.2, clock=clock)
        assert part.OUTPUTS == ("enc/left/ticks", "enc/right/ticks", "enc/timestamp", "enc/ok")
        device.ticks = [55, 55]
        assert part.run(None) == (0, 0, 0.0, True)  # opening reset the counts ("r"), then "p"
        assert device.received.startswith(b"r\n")
        device.ticks, device.millis = [120, -7], 5000
        clock.t = 1.0
        assert part.run(None) == (120, -7, 1.0, True)
        assert device.received.count(b"p\n") == 2
        device.silent = True  # the microcontroller stops answering
        part.source.timeout = 0.05
        part.source._serial.timeout = 0.05
        clock.t = 1.1
        assert part.run(None) == (120, -7, 1.0, True)  # within max_age: the last reading
        clock.t = 1.3
        assert part.run(None) == (None, None, None, False)
        device.silent = False
        device.ticks = [130, -7]
        assert part.run(None) == (130, -7, 1.3, True)
    finally:
        part.shutdown()
        device.close()


def test_serial_encoder_ignores_garbage() -> None:
    source = SerialTicks("unused", channels=1)
    assert source.parse(b"42,1000\r\n") == (42,)
    assert source.parse(b"-5,10;7,10\n") == (-5,)
    assert source.parse(b"\x00garbage\n") is None
    assert source.parse(b"42\n") is None


def test_missing_serial_port_says_what_to_check() -> None:
    with pytest.raises(EncoderError, match="ODOM_SERIAL"):
        SerialTicks("/dev/ttyNOPE").open()


def test_odometer_distance_and_smoothed_speed() -> None:
    odo = Odometer(0.01, smoothing=3)  # 1 cm per tick
    assert odo.run(0, 0.0) == (0.0, 0.0)
    assert odo.run(10, 0.1) == pytest.approx((0.1, 1.0))
    assert odo.run(30, 0.2) == pytest.approx((0.3, 1.5))
    assert odo.run(60, 0.3) == pytest.approx((0.6, 2.0))  # over 3 readings: 0.6 m / 0.3 s
    assert odo.run(80, 0.4) == pytest.approx((0.8, 7 * 0.1 / 0.3))
    assert odo.run(None, None) == (None, None)  # stale encoder: no speed, history restarts
    assert odo.run(90, 1.0) == pytest.approx((0.9, 0.0))


def test_bicycle_pose_follows_a_circle() -> None:
    wheel_base, max_angle = 0.26, math.radians(25)
    pose = BicyclePose(wheel_base, max_angle)
    radius = wheel_base / math.tan(max_angle * 0.5)  # angle -0.5: half left
    pose.run(0.0, 0.0, -0.5)
    circumference = 2 * math.pi * radius
    n = 100
    for i in range(1, n + 1):
        out = pose.run(circumference * i / n, i * 0.05, -0.5)
        x, y, heading = out[:3]
        phi = 2 * math.pi * i / n
        assert x == pytest.approx(radius * math.sin(phi), abs=1e-9)
        assert y == pytest.approx(radius * (1 - math.cos(phi)), abs=1e-9)
    assert heading == pytest.approx(0.0, abs=1e-9)
    assert out[5] == pytest.approx(2 * math.pi / n / 0.05)  # vel/angle, rad/s
    assert pose.run(None, None, 0.0) == (None,) * 6


def test_unicycle_pose_turns_on_the_spot_and_drives_straight() -> None:
    pose = UnicyclePose(0.2)
    pose.run(0.0, 0.0, 0.0)
    quarter = math.pi / 2 * 0.1  # each wheel's arc for a quarter turn about the axle's middle
    x, y, heading = pose.run(-quarter, quarter, 0.1)[:3]
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert heading == pytest.approx(math.pi / 2)
    x, y, heading, vx, vy, _ = pose.run(-quarter + 1.0, quarter + 1.0, 0.6)
    assert (x, y) == pytest.approx((0.0, 1.0), abs=1e-12)
    assert (vx, vy) == pytest.approx((0.0, 2.0), abs=1e-9)


def test_a_stale_encoder_takes_the_speed_away_from_the_speed_limit() -> None:
    from parts.drive.speed import SpeedLimit

    class Ticks:  # a tick source that stops answering after a while
        channels = 1

        def __init__(self) -> None:
            self.count, self.alive = 0, True

        def open(self) -> None: ...
        def close(self) -> None: ...

        def read(self):
            if not self.alive:
                return None
            self.count += 10
            return (self.count,)

    clock = Clock()
    source = Ticks()
    encoder, odo = Encoder(source, max_age=0.2, clock=clock), Odometer(0.01)
    limit = SpeedLimit(dt=0.05)
    throttles = []
    for step in range(20):
        clock.t = step * 0.05
        source.alive = step < 10
        ticks, stamp, ok = encoder.run(0.5)
        speed = odo.run(ticks, stamp)[1]
        throttles.append(limit.run(0.5, speed, 10.0))
    assert throttles[5] == 0.5  # 2 m/s, far under a 10 m/s limit: the throttle asked for
    assert throttles[12] == 0.5  # silent for 0.15 s < max_age: the last reading still counts
    assert throttles[-1] == 0.0 and ok is False  # stale: no speed, the limit cannot be held, throttle 0
    encoder.shutdown()
