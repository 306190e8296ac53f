"""Every way a drive ends leaves neutral as the last pulse on the (simulated) PCA9685."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest
from fixtures.driving import ScriptedDriver

from parts.actuators.fake_pca9685 import OFF, FakeI2C, read_trace_file
from vehicle import Vehicle
from vehicle.app.assembly.drivetrain import add_drivetrain
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import PartError

STEERING_CH, THROTTLE_CH = 1, 0  # the defaults of STEERING_CHANNEL / THROTTLE_CHANNEL


def Driver(fail_at: int | None = None) -> ScriptedDriver:  # noqa: N802 - reads as the part it makes
    """Neutral for two loops (so the ESC arms), then full left at full throttle."""
    return ScriptedDriver(fail_at, drive=(-1.0, 1.0))


def _vehicle(cfg: Config, driver: Driver):
    i2c = FakeI2C()
    board = i2c.add_board(1, 0x40)
    V = Vehicle(clock=SimulatedClock())
    V.add(driver, outputs=["angle", "throttle"])
    add_drivetrain(V, cfg, bus_factory=i2c.smbus)
    return V, board


CFG = dict(ESC_ARM_TIME_S=0.0, PWM_SHUTDOWN_HOLD_S=0.0)


def test_part_exception_ends_in_neutral():
    V, board = _vehicle(Config.defaults(**CFG), Driver(fail_at=6))
    with pytest.raises(PartError, match="pilot crashed"):
        V.start(rate_hz=20)
    assert board.pulses(THROTTLE_CH) == [OFF, 370, 500, 370]
    assert board.pulses(STEERING_CH) == [OFF, 375, 460, 375]


def test_max_loops_ends_in_neutral():
    V, board = _vehicle(Config.defaults(**CFG), Driver())
    V.start(rate_hz=20, max_loop_count=5)
    assert board.pulses(THROTTLE_CH) == [OFF, 370, 500, 370]


def test_mock_drivetrain_from_config_alone():
    cfg = Config.defaults(DRIVE_TRAIN_TYPE="MOCK", **CFG)
    V = Vehicle(clock=SimulatedClock())
    V.add(Driver(), outputs=["angle", "throttle"])
    part = add_drivetrain(V, cfg)
    V.start(rate_hz=20, max_loop_count=4)
    assert part.last_ticks == (460, 500)
    assert part.frequency == pytest.approx(59.838, abs=1e-3)


def test_watchdog_neutral_when_the_loop_stalls():
    """A part that hangs the loop: the watchdog thread sets neutral although run() is not called."""
    i2c = FakeI2C()
    board = i2c.add_board(1, 0x40)

    class Stall:
        n = 0

        def run(self):
            self.n += 1
            if self.n == 5:  # hang until the board shows neutral (bounded), then give up
                deadline = time.monotonic() + 5.0
                while board.output(THROTTLE_CH) != 370 and time.monotonic() < deadline:
                    time.sleep(0.01)
                raise RuntimeError("stalled")

    V = Vehicle()  # real time: the watchdog measures real seconds
    V.add(Driver(), outputs=["angle", "throttle"])
    V.add(Stall())
    # the car loops at 200 Hz: a watchdog of 0.1 s is twenty loops (a busy test machine can delay
    # a loop by 50 ms, which tripped a tighter one before the stall)
    add_drivetrain(V, Config.defaults(ACTUATOR_WATCHDOG_S=0.1, DRIVE_LOOP_HZ=200, **CFG), bus_factory=i2c.smbus)
    with pytest.raises(PartError, match="stalled"):
        V.start(rate_hz=200)
    throttle = board.pulses(THROTTLE_CH)
    assert throttle[:3] == [OFF, 370, 500] and throttle[-1] == 370
    assert V.parts[-1].part.watchdog.trips == 1


SCRIPT = textwrap.dedent("""
    import sys
    from vehicle import Vehicle
    from vehicle.app.assembly.drivetrain import add_drivetrain
    from vehicle.app.manage import run
    from vehicle.config import Config

    class Driver:
        n = 0
        def run(self):
            self.n += 1
            if self.n == 10:
                print("driving", flush=True)
            return (0.0, 0.0) if self.n <= 2 else (0.5, 0.5)

    cfg = Config.defaults(DRIVE_TRAIN_TYPE="MOCK", PCA9685_MOCK_TRACE=sys.argv[1], ESC_ARM_TIME_S=0.0,
                          DRIVE_LOOP_HZ=50)
    V = Vehicle()
    V.add(Driver(), outputs=["angle", "throttle"])
    add_drivetrain(V, cfg)
    sys.exit(run(V, cfg))
""")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_signal_ends_in_neutral(tmp_path, sig):
    trace = tmp_path / "trace.txt"
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(trace)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "driving"
        assert read_trace_file(trace)[THROTTLE_CH][-1] == 435  # really driving before the signal
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, err
    pulses = read_trace_file(trace)
    assert pulses[THROTTLE_CH] == [370, 435, 370]
    assert pulses[STEERING_CH] == [375, 332, 375]
