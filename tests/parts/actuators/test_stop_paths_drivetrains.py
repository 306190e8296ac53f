"""Every drivetrain ends in neutral on every stop path: a part's exception, the end of the loops,
the command watchdog while the loop hangs, and Ctrl-C / SIGTERM / SIGHUP in a real process.

Each drivetrain runs from its settings alone (DRIVE_TRAIN_TYPE and DonkeyCar's default pins),
against a fake of its hardware: gpiozero's MockFactory pins, a fake VESC or Robo HAT MM1 on a pty.
A drive command (angle -1, throttle 0.5) is sent for a few loops; afterwards every output that
changed must take its neutral value after its last driving value (servo centred, ESC stopped,
drive motors braked, a DC steering motor coasting, a VESC braking).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from fixtures.fake_mm1 import FakeMM1
from fixtures.fake_vesc import FakeVESC
from gpiozero.pins.mock import MockFactory, MockPWMPin

from vehicle import Vehicle
from vehicle.app.assembly.drivetrain import add_drivetrain
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import PartError

T = 1 / 4096  # one tick of a servo pulse, as a duty cycle
# per drivetrain with GPIO pins: (settings, {pin: (value while driving, neutral value)}); DonkeyCar's
# default pins by BOARD number, here by the GPIO they are (BOARD 33 = GPIO13, 18 = 24, 16 = 23,
# 35 = 19, 15 = 22, 13 = 27, 22 = 25, 11 = 17)
GPIO_RIGS: dict[str, tuple[dict, dict[str, tuple[float, float]]]] = {
    "PWM_STEERING_THROTTLE": (
        {"PWM_STEERING_THROTTLE": {"PWM_STEERING_PIN": "RPI_GPIO.BOARD.33", "PWM_THROTTLE_PIN": "RPI_GPIO.BCM.18"}},
        {"GPIO13": (460 * T, 375 * T), "GPIO18": (435 * T, 370 * T)}),
    "SERVO_HBRIDGE_2PIN": ({}, {"GPIO13": (460 * T, 375 * T), "GPIO24": (0.5, 1), "GPIO23": (0, 1)}),
    "SERVO_HBRIDGE_3PIN": ({}, {"GPIO13": (460 * T, 375 * T), "GPIO24": (1, 1), "GPIO23": (0, 1),
                                "GPIO19": (0.5, 1)}),
    # angle -1 drives the steering motor's LEFT_DUTY_PIN (BOARD 18); neutral lets it coast
    "DC_STEER_THROTTLE": ({}, {"GPIO24": (1, 0), "GPIO23": (0, 0), "GPIO22": (0.5, 1), "GPIO27": (0, 1)}),
    # arcade mix of (-1, 0.5): left -1/3, right 1
    "DC_TWO_WHEEL": ({}, {"GPIO24": (0, 1), "GPIO23": (1 / 3, 1), "GPIO22": (1, 1), "GPIO27": (0, 1)}),
    "DC_TWO_WHEEL_L298N": ({}, {"GPIO23": (0, 1), "GPIO24": (1, 1), "GPIO25": (1 / 3, 1), "GPIO22": (1, 1),
                                "GPIO27": (0, 1), "GPIO17": (1, 1)}),
}
SERIAL_RIGS = ("VESC", "MM1")
ALL = (*GPIO_RIGS, *SERIAL_RIGS)
BASE = dict(ESC_ARM_TIME_S=0.0, PWM_SHUTDOWN_HOLD_S=0.0)


def _same(a: float, b: float) -> bool:
    return abs(a - b) < 1e-9


def ended_in_neutral(history: dict[str, list], expected: dict[str, tuple], released: float | None = None) -> None:
    """Each output drove, and its last value before the hardware was released is neutral.

    ``released``: the value every output takes when it is let go (GPIO pins: 0), which follows
    neutral on shutdown; a pin already there records no change.
    """
    for name, (drive, neutral) in expected.items():
        values = list(history[name])
        same = (lambda v, w: v == w) if isinstance(drive, tuple) else _same
        if released is not None:
            assert _same(values[-1], released), f"{name} was not released: {values}"
            if not _same(neutral, released):
                values = values[:-1]
        if not same(drive, neutral):
            assert any(same(v, drive) for v in values), f"{name} never drove: {values}"
        assert same(values[-1], neutral), f"{name} did not end in neutral: {values}"


class Rig:
    """One drivetrain from its settings, with a fake of its hardware."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.gpio = self.device = None
        self.settings: dict = {"DRIVE_TRAIN_TYPE": kind, **BASE}
        self.released = 0.0 if kind in GPIO_RIGS else None
        if kind in GPIO_RIGS:
            self.settings.update(GPIO_RIGS[kind][0])
            self.expected = GPIO_RIGS[kind][1]
            self.gpio = MockFactory(pin_class=MockPWMPin)
        elif kind == "VESC":
            self.device = FakeVESC().start()
            self.settings.update(VESC_SERIAL_PORT=self.device.port, VESC_BRAKE_CURRENT=5.0)
            self.expected = {"motor": (("duty", 0.1), ("brake", 5.0)), "servo": (0.0, 0.5)}
        else:
            self.device = FakeMM1().start()
            self.settings.update(MM1_SERIAL_PORT=self.device.port)
            self.expected = {"outputs": ((2000, 1750), (1500, 1500))}

    def wiring(self) -> dict:
        return {"gpio_factory": self.gpio} if self.gpio is not None else {}

    def history(self) -> dict[str, list]:
        if self.gpio is not None:
            return {info.name: [s.state for s in pin.states] for info, pin in self.gpio.pins.items()}
        if self.kind == "VESC":
            servo = [v for n, v in self.device.commands if n == "servo"]
            return {"motor": self.device.motor_commands(), "servo": servo}
        return {"outputs": list(self.device.outputs)}

    def at_neutral(self) -> bool:
        """Whether the hardware shows neutral right now."""
        if self.gpio is not None:
            return all(_same(self.gpio.pins[next(i for i in self.gpio.pins if i.name == n)].state, v)
                       for n, (_, v) in self.expected.items())
        if self.kind == "VESC":
            commands = self.device.motor_commands()
            return bool(commands) and commands[-1] == ("brake", 5.0) and len(commands) > 2
        return self.device.output == (1500, 1500) and len(self.device.outputs) > 2

    def check(self) -> None:
        if self.device is not None:  # the serial bytes travel: wait until the last ones arrived
            self.device.wait_for(lambda: self._done(), timeout=10)
        ended_in_neutral(self.history(), self.expected, self.released)
        if self.kind == "VESC":
            assert self.device.crc_errors == 0

    def _done(self) -> bool:
        try:
            ended_in_neutral(self.history(), self.expected, self.released)
            return True
        except AssertionError:
            return False

    def close(self) -> None:
        if self.gpio is not None:
            self.gpio.close()
        if self.device is not None:
            self.device.stop()


@pytest.fixture(params=ALL)
def rig(request):
    r = Rig(request.param)
    yield r
    r.close()


class Driver:
    """Neutral for two loops (arming), then angle -1, throttle 0.5; may fail at a given loop."""

    def __init__(self, fail_at: int | None = None) -> None:
        self.n = 0
        self.fail_at = fail_at

    def run(self) -> tuple[float, float]:
        self.n += 1
        if self.n == self.fail_at:
            raise RuntimeError("pilot crashed")
        return (0.0, 0.0) if self.n <= 2 else (-1.0, 0.5)


def test_part_exception_ends_in_neutral(rig):
    V = Vehicle(clock=SimulatedClock())
    V.add(Driver(fail_at=6), outputs=["angle", "throttle"])
    add_drivetrain(V, Config.defaults(**rig.settings), **rig.wiring())
    with pytest.raises(PartError, match="pilot crashed"):
        V.start(rate_hz=20)
    rig.check()


def test_end_of_loops_ends_in_neutral(rig):
    V = Vehicle(clock=SimulatedClock())
    V.add(Driver(), outputs=["angle", "throttle"])
    add_drivetrain(V, Config.defaults(**rig.settings), **rig.wiring())
    V.start(rate_hz=20, max_loop_count=6)
    rig.check()


def test_watchdog_neutral_while_the_loop_hangs(rig):
    class Stall:
        n = 0

        def run(self):
            self.n += 1
            if self.n == 6:  # hang until the hardware shows neutral (bounded), then give up
                deadline = time.monotonic() + 5.0
                while not rig.at_neutral() and time.monotonic() < deadline:
                    time.sleep(0.01)
                raise RuntimeError("stalled")

    V = Vehicle()  # real time: the watchdog measures real seconds
    V.add(Driver(), outputs=["angle", "throttle"])
    V.add(Stall())
    cfg = Config.defaults(ACTUATOR_WATCHDOG_S=0.1, DRIVE_LOOP_HZ=200, **rig.settings)
    part = add_drivetrain(V, cfg, **rig.wiring())
    with pytest.raises(PartError, match="stalled"):
        V.start(rate_hz=200)
    assert part.watchdog.trips == 1
    rig.check()


SCRIPT = textwrap.dedent("""
    import json, sys
    from vehicle import Vehicle
    from vehicle.app.assembly.drivetrain import add_drivetrain
    from vehicle.app.manage import run
    from vehicle.config import Config

    settings, out = json.loads(sys.argv[1]), sys.argv[2]
    wiring, factory = {}, None
    if settings.pop("_gpio"):
        from gpiozero.pins.mock import MockFactory, MockPWMPin
        factory = MockFactory(pin_class=MockPWMPin)
        wiring["gpio_factory"] = factory

    class Driver:
        n = 0
        def run(self):
            self.n += 1
            if self.n == 10:
                print("driving", flush=True)
            return (0.0, 0.0) if self.n <= 2 else (-1.0, 0.5)

    cfg = Config.defaults(DRIVE_LOOP_HZ=50, **settings)
    V = Vehicle()
    V.add(Driver(), outputs=["angle", "throttle"])
    add_drivetrain(V, cfg, **wiring)
    code = run(V, cfg)
    if factory is not None:
        with open(out, "w") as f:
            json.dump({info.name: [s.state for s in pin.states] for info, pin in factory.pins.items()}, f)
    sys.exit(code)
""")


def _signal_run(rig: Rig, sig: int, tmp_path: Path) -> None:
    out = tmp_path / "pins.json"
    settings = {**rig.settings, "_gpio": rig.gpio is not None}
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, json.dumps(settings), str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "driving", proc.stderr.read() if proc.poll() is not None else ""
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == (130 if sig == signal.SIGINT else 128 + sig), err
    if rig.gpio is not None:
        ended_in_neutral(json.loads(out.read_text()), rig.expected, rig.released)
    else:
        rig.check()


@pytest.mark.parametrize("kind", ALL)
def test_sigterm_ends_in_neutral(kind, tmp_path):
    r = Rig(kind)
    try:
        _signal_run(r, signal.SIGTERM, tmp_path)
    finally:
        r.close()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGINT])
@pytest.mark.parametrize("kind", ALL)
def test_sighup_and_ctrl_c_end_in_neutral(kind, sig, tmp_path):
    r = Rig(kind)
    try:
        _signal_run(r, sig, tmp_path)
    finally:
        r.close()
