"""Interactive PWM calibration of one PCA9685 channel (``vehicle calibrate``).

The procedure of Oršolić's thesis (Building a self-driving RC car, 2020) and DonkeyCar's docs,
with the car on a stand: start from neutral, try values in steps of about 10 ticks, and note the
full-left / full-right steering values and the forward / stopped / reverse throttle values.
Values are range-checked before they reach the board, and the channel returns to neutral whenever
the session ends: ``q``, end of input, Ctrl-C, a signal turned into SystemExit, or an error.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from parts.actuators.pca9685 import PULSE_MAX_US, PULSE_MIN_US

if TYPE_CHECKING:
    from parts.actuators.pca9685 import PCA9685

logger = logging.getLogger(__name__)

#: what the user types to record the current value -> the setting it becomes
ROLES: dict[str, str] = {
    "left": "STEERING_LEFT_PWM",
    "right": "STEERING_RIGHT_PWM",
    "forward": "THROTTLE_FORWARD_PWM",
    "stopped": "THROTTLE_STOPPED_PWM",
    "reverse": "THROTTLE_REVERSE_PWM",
}
ALIASES = {"fwd": "forward", "stop": "stopped", "rev": "reverse"}
#: the pulse widths a servo or ESC can safely be sent, in µs (the config checks the same range)
MIN_US, MAX_US = PULSE_MIN_US, PULSE_MAX_US
DEFAULT_STEP = 10

HELP = """\
Commands:
  <number>      send that pulse (ticks, {lo}-{hi} at {freq:.2f} Hz; 1 tick = {tick:.2f} µs)
  + / -         {step} ticks up / down (+25 / -25: any step)
  n             back to neutral ({neutral})
  left, right   record the current value as STEERING_LEFT_PWM / STEERING_RIGHT_PWM
  forward, stopped, reverse (fwd, stop, rev)
                record it as THROTTLE_FORWARD_PWM / _STOPPED_PWM / _REVERSE_PWM
  values        show what has been recorded
  h, ?          this help
  q             neutral and quit (also Ctrl-D, Ctrl-C)
Steering: step to each end until the wheels stop turning, without the servo buzzing.
Throttle: the ESC beeps at neutral; reverse needs reverse, neutral, reverse on most car ESCs."""


class LineReader:
    """``input()`` that lets signal handlers run while it waits for a line.

    ``input()`` (and readline) block in C: a SIGTERM or SIGHUP arriving just before the blocking
    read leaves its Python handler pending until the user types something, so the tool would not
    return to neutral when killed. This polls the descriptor with a short timeout instead, so a
    pending handler runs within ``poll_s``. The terminal's own line editing still works.
    """

    def __init__(self, fd: int | None = None, out: Callable[[str], None] | None = None,
                 poll_s: float = 0.2) -> None:
        import sys

        self.fd = sys.stdin.fileno() if fd is None else fd
        self._out = out or (lambda text: (sys.stdout.write(text), sys.stdout.flush()))
        self.poll_s = poll_s
        self._buffer = b""
        self._eof = False

    def __call__(self, prompt: str = "") -> str:
        import os
        import select

        self._out(prompt)
        while b"\n" not in self._buffer:
            if self._eof:
                if self._buffer:  # a last line without a newline
                    line, self._buffer = self._buffer, b""
                    return line.decode(errors="replace")
                raise EOFError
            ready, _, _ = select.select([self.fd], [], [], self.poll_s)
            if ready:
                chunk = os.read(self.fd, 4096)
                if chunk:
                    self._buffer += chunk
                else:
                    self._eof = True
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode(errors="replace")


class CalibrationSession:
    """The read-try-record loop on one channel of an open PCA9685.

    Args:
        driver: an open :class:`PCA9685`.
        channel: the channel to calibrate.
        neutral: the value sent at the start and the end (updated by ``stopped``).
        read: returns the next command line; raises EOFError at end of input.
        write: shows a line to the user.
        step: ticks of ``+`` / ``-``.
        sleep: delay function (holding neutral for two periods at the end).
    """

    def __init__(self, driver: PCA9685, channel: int, neutral: int, *,
                 read: Callable[[str], str] = input, write: Callable[[str], None] = print,
                 step: int = DEFAULT_STEP, sleep: Callable[[float], None] | None = None) -> None:
        self.driver = driver
        self.channel = channel
        self.lo = math.ceil(MIN_US / driver.tick_us)
        self.hi = math.floor(MAX_US / driver.tick_us)
        if not self.lo <= neutral <= self.hi:
            raise ValueError(f"neutral {neutral} ticks is outside the safe range {self.lo}-{self.hi} "
                             f"at {driver.frequency:.2f} Hz")
        self.neutral = neutral
        self.current = neutral
        self.step = step
        self.found: dict[str, int] = {}
        self._read = read
        self._write = write
        if sleep is None:
            import time

            sleep = time.sleep
        self._sleep = sleep

    # -- the loop -----------------------------------------------------------------------------
    def run(self) -> dict[str, int]:
        """Run until the user quits; returns the recorded ``{SETTING: ticks}``. Always ends neutral."""
        try:
            self._write(f"Channel {self.channel} at {self.driver.frequency:.2f} Hz: starting at "
                        f"neutral, {self._describe(self.neutral)}. Type h for help, q to quit.")
            self._send(self.neutral)
            while True:
                try:
                    line = self._read(f"ch {self.channel} [{self.current}] > ")
                except EOFError:
                    self._write("")
                    break
                if not self.handle(line):
                    break
        finally:
            self.finish()
        return dict(self.found)

    def handle(self, line: str) -> bool:
        """Carry out one command line; False when the user quits."""
        cmd = line.strip().lower()
        if not cmd:
            return True
        if cmd in ("q", "quit", "exit"):
            return False
        if cmd in ("h", "?", "help"):
            self._write(HELP.format(lo=self.lo, hi=self.hi, freq=self.driver.frequency,
                                    tick=self.driver.tick_us, step=self.step, neutral=self.neutral))
        elif cmd in ("n", "neutral"):
            self._send(self.neutral)
        elif cmd in ("values", "v"):
            self._write(self.summary() or "nothing recorded yet")
        elif (role := ALIASES.get(cmd, cmd)) in ROLES:
            self.found[ROLES[role]] = self.current
            if role == "stopped":
                self.neutral = self.current  # the ESC's real neutral: used on exit from now on
            self._write(f"{ROLES[role]} = {self.current}")
        elif cmd in ("+", "-") or (cmd[0] in "+-" and cmd[1:].isdigit()):
            delta = int(cmd[1:]) if len(cmd) > 1 else self.step
            self._try(self.current + delta if cmd[0] == "+" else self.current - delta)
        elif cmd.isdigit():
            self._try(int(cmd))
        else:
            self._write(f"'{line.strip()}' is not a command: type a pulse {self.lo}-{self.hi}, + or -, "
                        "a role (left, right, forward, stopped, reverse), h for help or q to quit")
        return True

    def finish(self) -> None:
        """Neutral, held for two PWM periods so the ESC sees it whole."""
        try:
            self._send(self.neutral)
            self._sleep(2.0 / self.driver.frequency)
        except Exception:
            logger.exception("could not return channel %d to neutral", self.channel)
            raise

    def summary(self) -> str:
        """The recorded settings, one per line."""
        return "\n".join(f"{k} = {v}" for k, v in self.found.items())

    # -- helpers ------------------------------------------------------------------------------
    def _try(self, ticks: int) -> None:
        if not self.lo <= ticks <= self.hi:
            self._write(f"{ticks} is out of range: enter {self.lo}-{self.hi} ticks "
                        f"({MIN_US:.0f}-{MAX_US:.0f} µs at {self.driver.frequency:.2f} Hz); not sent")
            return
        self._send(ticks)

    def _send(self, ticks: int) -> None:
        self.driver.set_ticks(self.channel, ticks)
        self.current = ticks
        self._write(f"channel {self.channel} <- {self._describe(ticks)}")

    def _describe(self, ticks: int) -> str:
        return f"{ticks} ticks ({self.driver.ticks_to_us(ticks):.0f} µs)"
