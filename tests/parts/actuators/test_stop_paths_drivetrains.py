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
from fixtures.drivetrain_rigs import ALL, Rig, ended_in_neutral
from fixtures.driving import ScriptedDriver as Driver

from vehicle import Vehicle
from vehicle.app.assembly.drivetrain import add_drivetrain
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import PartError


@pytest.fixture(params=ALL)
def rig(request):
    r = Rig(request.param)
    yield r
    r.close()


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
    held: dict = {}

    class Stall:
        n = 0

        def run(self):
            self.n += 1
            if self.n == 6:  # hang until the watchdog trips and the hardware shows neutral (bounded)
                trips = held["part"].watchdog.trips
                deadline = time.monotonic() + 5.0
                while not (held["part"].watchdog.trips > trips and rig.at_neutral()) and time.monotonic() < deadline:
                    time.sleep(0.01)
                held["tripped_while_hung"] = held["part"].watchdog.trips > trips
                raise RuntimeError("stalled")

    V = Vehicle()  # real time: the watchdog measures real seconds
    V.add(Driver(), outputs=["angle", "throttle"])
    V.add(Stall())
    cfg = Config.defaults(ACTUATOR_WATCHDOG_S=0.1, DRIVE_LOOP_HZ=200, **rig.settings)
    held["part"] = add_drivetrain(V, cfg, **rig.wiring())
    with pytest.raises(PartError, match="stalled"):
        V.start(rate_hz=200)
    # (a loaded machine may delay a loop past the watchdog before the hang too: that trip is fine)
    assert held["tripped_while_hung"]
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
