"""The calibrate tool: session logic, myconfig editing, and real sessions through a pseudo-terminal."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import select
import signal
import subprocess
import sys
import termios
import textwrap
import time
from pathlib import Path

import pytest

from parts.actuators.config_writer import update_myconfig
from parts.actuators.fake_pca9685 import OFF, read_trace_file
from parts.actuators.pwm_calibration import CalibrationSession, LineReader

REPO = Path(__file__).resolve().parents[3]


# -- session logic (in process) ------------------------------------------------------------------
def _session(driver, lines, channel=0, neutral=370):
    script = iter(lines)
    out: list[str] = []

    def read(prompt):
        item = next(script)
        if isinstance(item, BaseException):
            raise item
        return item
    session = CalibrationSession(driver, channel, neutral, read=read, write=out.append, sleep=lambda s: None)
    return session, out


def test_session_records_roles_and_ends_neutral(driver, board):
    session, out = _session(driver, ["400", "+", "+25", "fwd", "-", "stop", "200", "rev", "q"])
    found = session.run()
    assert found == {"THROTTLE_FORWARD_PWM": 435, "THROTTLE_STOPPED_PWM": 425, "THROTTLE_REVERSE_PWM": 200}
    # the recorded "stopped" value becomes the neutral written on exit
    assert board.pulses(0) == [OFF, 370, 400, 410, 435, 425, 200, 425]


def test_out_of_range_and_unknown_input_send_nothing(driver, board):
    session, out = _session(driver, ["5000", "50", "abc", "-300", "q"])
    session.run()
    assert board.pulses(0) == [OFF, 370]
    assert sum("out of range: enter 123-612 ticks" in line for line in out) == 3
    assert any("'abc' is not a command" in line for line in out)


@pytest.mark.parametrize("ending", [EOFError(), KeyboardInterrupt(), RuntimeError("boom"), SystemExit(143)])
def test_every_way_out_ends_neutral(driver, board, ending):
    session, _ = _session(driver, ["450", ending], channel=1, neutral=375)
    if isinstance(ending, EOFError):
        session.run()
    else:
        with pytest.raises(type(ending)):
            session.run()
    assert board.pulses(1) == [OFF, 375, 450, 375]


def test_line_reader_splits_lines_and_ends_with_eof():
    r, w = os.pipe()
    os.write(w, b"400\n+\nq")
    os.close(w)
    prompts: list[str] = []
    read = LineReader(r, out=prompts.append, poll_s=0.01)
    try:
        assert [read("> "), read("> "), read("> ")] == ["400", "+", "q"]
        with pytest.raises(EOFError):
            read("> ")
    finally:
        os.close(r)
    assert prompts == ["> "] * 4


def test_neutral_outside_the_safe_range_is_refused(driver):
    with pytest.raises(ValueError, match="outside the safe range 123-612"):
        CalibrationSession(driver, 0, 5)


# -- myconfig editing ----------------------------------------------------------------------------
MYCONFIG = textwrap.dedent("""\
    # my car — settings
    import os

    STEERING_LEFT_PWM = 460  # measured in June
    STEERING_RIGHT_PWM: int = (
        290
    )
    # THROTTLE_FORWARD_PWM = 500
    CAMERA_TYPE = "MOCK"
""")


def test_update_myconfig_replaces_uncomments_and_appends(tmp_path):
    path = tmp_path / "myconfig.py"
    path.write_text(MYCONFIG)
    report = update_myconfig(path, {"STEERING_LEFT_PWM": 455, "STEERING_RIGHT_PWM": 300,
                                    "THROTTLE_FORWARD_PWM": 410, "THROTTLE_STOPPED_PWM": 372,
                                    "PCA9685_I2C_ADDR": 0x41})
    text = path.read_text()
    assert text.startswith("# my car — settings\nimport os\n\n"
                           "STEERING_LEFT_PWM = 455  # measured in June\n"
                           "STEERING_RIGHT_PWM = 300\n"
                           "THROTTLE_FORWARD_PWM = 410\n"
                           'CAMERA_TYPE = "MOCK"\n')
    assert text.endswith("THROTTLE_STOPPED_PWM = 372\nPCA9685_I2C_ADDR = 0x41\n")
    assert "# Written by vehicle calibrate on" in text
    assert [r.split("  (")[1] for r in report] == ["replaced line 4)", "replaced line 5)",
                                                   "uncommented line 8)", "added)", "added)"]
    namespace: dict = {}
    exec(text, namespace)
    assert namespace["STEERING_RIGHT_PWM"] == 300 and namespace["PCA9685_I2C_ADDR"] == 0x41


def test_update_myconfig_refuses_broken_files_and_names(tmp_path):
    path = tmp_path / "myconfig.py"
    path.write_text("X = (\n")
    with pytest.raises(ValueError, match="line 1: not valid Python"):
        update_myconfig(path, {"STEERING_LEFT_PWM": 1})
    assert path.read_text() == "X = (\n"
    path.write_text("")
    with pytest.raises(ValueError, match="not a setting name"):
        update_myconfig(path, {"lower": 1})


# -- real sessions through a pseudo-terminal -------------------------------------------------------
# The real CLI main() with only this command registered: skips other rooms' start-up imports.
LAUNCHER = ("import sys, vehicle.app.cli as cli; cli.COMMAND_MODULES = ('vehicle.app.commands.calibrate',); "
            "sys.exit(cli.main(sys.argv[1:]))")


def _take_terminal() -> None:
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)  # the pty becomes the controlling terminal: Ctrl-C works


class Terminal:
    """A child process on a pseudo-terminal, driven like a user at a keyboard."""

    def __init__(self, args: list[str], cwd: Path, real_entry: bool = False) -> None:
        master, slave = pty.openpty()
        cmd = [sys.executable, "-m", "vehicle"] if real_entry else [sys.executable, "-c", LAUNCHER]
        env = dict(os.environ, PYTHONPATH=str(REPO), TERM="dumb")
        self.proc = subprocess.Popen([*cmd, "calibrate", *args], stdin=slave, stdout=slave, stderr=slave,
                                     cwd=cwd, env=env, start_new_session=True,
                                     preexec_fn=_take_terminal)  # noqa: PLW1509 - no threads here
        os.close(slave)
        self.master = master
        self.output = ""

    def expect(self, text: str, timeout: float = 30.0) -> str:
        deadline = time.monotonic() + timeout
        while text not in self.output:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"{text!r} not seen; output so far:\n{self.output}")
            ready, _, _ = select.select([self.master], [], [], left)
            if ready:
                try:
                    chunk = os.read(self.master, 4096)
                except OSError:  # EIO: the child closed the terminal
                    chunk = b""
                if not chunk:
                    raise AssertionError(f"{text!r} not seen before exit; output:\n{self.output}")
                self.output += chunk.decode(errors="replace")
        return self.output

    def send(self, keys: str) -> None:
        os.write(self.master, keys.encode())

    def wait(self, timeout: float = 30.0) -> int:
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:  # drain, so the child never blocks on a full terminal
                ready, _, _ = select.select([self.master], [], [], 0.2)
                if ready:
                    try:
                        chunk = os.read(self.master, 4096)
                    except OSError:
                        break
                    if not chunk:
                        break
                    self.output += chunk.decode(errors="replace")
                elif self.proc.poll() is not None:
                    break
            return self.proc.wait(max(0.1, deadline - time.monotonic()))
        finally:
            os.close(self.master)
            if self.proc.poll() is None:
                self.proc.kill()


@pytest.fixture
def car(tmp_path) -> Path:
    (tmp_path / "myconfig.py").write_text(
        '# my car\nPCA9685_MOCK_TRACE = "trace.txt"\n# STEERING_LEFT_PWM = 460\nDRIVE_LOOP_HZ = 20\n')
    return tmp_path


def test_pty_session_finds_steering_and_saves_on_prompt(car):
    term = Terminal(["--channel", "1", "--mock", "--car", str(car)], cwd=car, real_entry=True)
    term.expect("ch 1 [375] > ")
    steps = [("420\n", "ch 1 [420] > "), ("+\n", "ch 1 [430] > "), ("left\n", "STEERING_LEFT_PWM = 430"),
             ("9999\n", "out of range"), ("300\n", "ch 1 [300] > "), ("right\n", "STEERING_RIGHT_PWM = 300")]
    for keys, answer in steps:
        term.send(keys)
        term.expect(answer)
    term.send("q\n")
    term.expect("[y/N] ")
    term.send("y\n")
    assert term.wait() == 0, term.output
    assert "saved to" in term.output
    text = (car / "myconfig.py").read_text()
    assert text.startswith("# my car\nPCA9685_MOCK_TRACE = \"trace.txt\"\nSTEERING_LEFT_PWM = 430\n"
                           "DRIVE_LOOP_HZ = 20\n")
    assert text.rstrip().endswith("STEERING_RIGHT_PWM = 300")
    assert read_trace_file(car / "trace.txt")[1] == [375, 420, 430, 300, 375]


def test_pty_ctrl_c_leaves_neutral_and_saves_nothing(car):
    term = Terminal(["--channel", "0", "--mock", "--car", str(car)], cwd=car)
    term.expect("ch 0 [370] > ")
    term.send("420\n")
    term.expect("ch 0 [420] > ")
    term.send("forward\n")
    term.expect("THROTTLE_FORWARD_PWM = 420")
    term.send("\x03")  # Ctrl-C
    assert term.wait() == 130, term.output
    assert "back at neutral (370)" in term.output and "not saved" in term.output
    assert read_trace_file(car / "trace.txt")[0] == [370, 420, 370]
    assert "THROTTLE_FORWARD_PWM = 420" not in (car / "myconfig.py").read_text()


def test_pty_end_of_input_with_save(car):
    term = Terminal(["--channel", "0", "--mock", "--car", str(car), "--save"], cwd=car)
    term.expect("ch 0 [370] > ")
    term.send("360\n")
    term.expect("ch 0 [360] > ")
    term.send("stopped\n")
    term.expect("THROTTLE_STOPPED_PWM = 360")
    term.send("400\n")
    term.expect("ch 0 [400] > ")
    term.send("\x04")  # Ctrl-D at the start of a line: end of input
    assert term.wait() == 0, term.output
    assert read_trace_file(car / "trace.txt")[0] == [370, 360, 400, 360]  # ends at the recorded neutral
    assert "THROTTLE_STOPPED_PWM = 360" in (car / "myconfig.py").read_text()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_pty_signal_leaves_neutral(car, sig):
    term = Terminal(["--channel", "1", "--mock", "--car", str(car)], cwd=car)
    term.expect("ch 1 [375] > ")
    term.send("440\n")
    term.expect("ch 1 [440] > ")
    term.proc.send_signal(sig)
    assert term.wait() == 128 + sig, term.output
    assert read_trace_file(car / "trace.txt")[1] == [375, 440, 375]


def test_cli_errors_are_user_errors(car, capsys, monkeypatch):
    from vehicle.app import cli
    from vehicle.app.cli import main

    monkeypatch.setattr(cli, "COMMAND_MODULES", ("vehicle.app.commands.calibrate",))

    assert main(["calibrate", "--channel", "16", "--mock", "--car", str(car)]) == 2
    assert "channels 0-15" in capsys.readouterr().err
    assert main(["calibrate", "--channel", "0", "--bus", "5", "--car", str(car)]) == 2
    err = capsys.readouterr().err
    assert "/dev/i2c-5 not found" in err and "PCA9685_I2C_BUSNUM" in err
    assert main(["calibrate", "--channel", "0", "--address", "0x90", "--mock", "--car", str(car)]) == 2
    assert "7-bit address" in capsys.readouterr().err
    assert main(["calibrate", "--channel", "0", "--freq", "5000", "--mock", "--car", str(car)]) == 2
    assert "outside what the PCA9685 can make" in capsys.readouterr().err


def test_cli_runs_despite_an_invalid_myconfig(tmp_path, capsys, monkeypatch):
    from vehicle.app import cli

    monkeypatch.setattr(cli, "COMMAND_MODULES", ("vehicle.app.commands.calibrate",))
    monkeypatch.setattr("sys.stdin", io.StringIO("400\nq\n"))
    (tmp_path / "myconfig.py").write_text("STEERING_LEFT_PMW = 400\n")  # typo: unknown setting
    assert cli.main(["calibrate", "--channel", "0", "--mock", "--car", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "Did you mean STEERING_LEFT_PWM?" in captured.err and "using the default settings" in captured.err
    assert "channel 0 <- 400 ticks" in captured.out


def test_cli_saves_into_the_myconfig_it_read(tmp_path, capsys, monkeypatch):
    from vehicle.app import cli

    monkeypatch.setattr(cli, "COMMAND_MODULES", ("vehicle.app.commands.calibrate",))
    monkeypatch.setattr("sys.stdin", io.StringIO("360\nstopped\nq\n"))
    (tmp_path / "myconfig.py").write_text("# the main settings\n")
    (tmp_path / "bench.py").write_text("DRIVE_LOOP_HZ = 30\n")
    assert cli.main(["calibrate", "--channel", "0", "--mock", "--car", str(tmp_path), "--myconfig", "bench.py",
                     "--save"]) == 0
    assert "THROTTLE_STOPPED_PWM = 360" in (tmp_path / "bench.py").read_text()
    assert (tmp_path / "myconfig.py").read_text() == "# the main settings\n"
