"""Robo HAT MM1 over serial (DRIVE_TRAIN_TYPE = "MM1").

The MM1's SAMD51 runs DonkeyCar's CircuitPython firmware (``donkeycar/contrib/robohat/code.py``):
it reads lines ``"SSSS, TTTT\\r"`` at 115200 baud, steering and throttle pulse widths in µs
(first and last four characters), and drives its servo outputs with them at 60 Hz. When nothing
arrives for 10 s it hands the outputs back to the RC receiver; it also sends the receiver's
pulses, ``"SSSS, TTTT\\r\\n"``, which this part discards.

Pulses follow DonkeyCar's mapping (floored): steering -1 -> 2000 µs, 0 -> MM1_STEERING_MID,
+1 -> 1000 µs; throttle -1 -> MM1_MAX_REVERSE, 0 -> MM1_STOPPED_PWM, +1 -> MM1_MAX_FORWARD.
Neutral is (MM1_STEERING_MID, MM1_STOPPED_PWM); the board has no brake of its own.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from parts.actuators.drivetrain import Drivetrain, DrivetrainError, clamp
from parts.actuators.pwm import map_range
from parts.serial_port import close_serial, open_serial, serial_link

logger = logging.getLogger(__name__)

PULSE_MIN_US, PULSE_MAX_US = 1000, 2000  # the firmware reads four digits per pulse
MM1_PWM_HZ = 60.0  # the firmware's servo output frequency
BAUDRATE = 115200
SETTING = "MM1_SERIAL_PORT"
#: what happens to the outputs when this computer cannot reach the board (the firmware's fallback)
SILENT = "the MM1 keeps its last pulses for 10 s, then hands the outputs to the RC receiver"


class RoboHatMM1(Drivetrain):
    """The MM1 drivetrain part (see the module doc); inputs ``angle``, ``throttle``."""

    def __init__(self, port: str, *, steering_mid: int = 1500, max_forward: int = 2000, stopped: int = 1500,
                 max_reverse: int = 1000, serial_factory: Callable[[str, int], Any] | None = None,
                 **safety: Any) -> None:
        safety.setdefault("arm_s", 1.5)
        super().__init__(**safety)
        for name, value in (("MM1_STEERING_MID", steering_mid), ("MM1_MAX_FORWARD", max_forward),
                            ("MM1_STOPPED_PWM", stopped), ("MM1_MAX_REVERSE", max_reverse)):
            if isinstance(value, bool) or not isinstance(value, int) or not PULSE_MIN_US <= value <= PULSE_MAX_US:
                raise ValueError(f"{name} must be a pulse in µs, an int {PULSE_MIN_US}-{PULSE_MAX_US}, got {value!r}")
        if not max_reverse < stopped < max_forward:
            raise ValueError(f"MM1_STOPPED_PWM ({stopped}) must lie strictly between MM1_MAX_REVERSE ({max_reverse}) "
                             f"and MM1_MAX_FORWARD ({max_forward})")
        self.port_name = port
        self.steering_mid = steering_mid
        self.max_forward, self.stopped, self.max_reverse = max_forward, stopped, max_reverse
        self._factory = serial_factory or (lambda p, b: open_serial(p, b, SETTING, DrivetrainError))
        self._serial: Any = None
        self.last_pulses: tuple[int, int] | None = None  # (steering, throttle) µs last sent

    @classmethod
    def from_config(cls, cfg: Any, *, serial_factory: Callable[[str, int], Any] | None = None,
                    clock: Callable[[], float] | None = None, **_: Any) -> RoboHatMM1:
        """DRIVE_TRAIN_TYPE = "MM1": DonkeyCar's MM1_* settings."""
        from parts.actuators.drivetrain_config import safety_from_config  # noqa: PLC0415

        return cls(cfg.MM1_SERIAL_PORT, steering_mid=cfg.MM1_STEERING_MID, max_forward=cfg.MM1_MAX_FORWARD,
                   stopped=cfg.MM1_STOPPED_PWM, max_reverse=cfg.MM1_MAX_REVERSE, serial_factory=serial_factory,
                   **safety_from_config(cfg, clock))

    def describe(self) -> str:
        return (f"Robo HAT MM1 on {self.port_name} (steering centre {self.steering_mid} µs, throttle "
                f"{self.max_reverse}/{self.stopped}/{self.max_forward} µs)")

    def pulses(self, angle: float, throttle: float) -> tuple[int, int]:
        """(steering, throttle) pulse widths in µs for commands in [-1, 1]."""
        a, t = clamp(angle, -1.0, 1.0), clamp(throttle, -1.0, 1.0)
        steering = (map_range(a, 0, 1, self.steering_mid, PULSE_MIN_US) if a > 0
                    else map_range(a, -1, 0, PULSE_MAX_US, self.steering_mid))
        power = (map_range(t, 0, 1, self.stopped, self.max_forward) if t > 0
                 else map_range(t, -1, 0, self.max_reverse, self.stopped))
        return steering, power

    def _open_hardware(self) -> None:
        self._serial = self._factory(self.port_name, BAUDRATE)

    def _drive(self, angle: float, throttle: float) -> None:
        self._send(*self.pulses(angle, throttle))

    def _neutral_outputs(self) -> None:
        self._send(self.steering_mid, self.stopped)

    def _hold_seconds(self) -> float:
        return max(self.hold_s, 2.0 / MM1_PWM_HZ)

    def _close_hardware(self) -> None:
        port, self._serial = self._serial, None
        close_serial(port, SETTING, self.port_name, SILENT, DrivetrainError)

    def _send(self, steering: int, throttle: int) -> None:
        port = self._serial
        if port is None:
            return
        with serial_link(SETTING, self.port_name, SILENT, DrivetrainError):
            if port.in_waiting:
                port.reset_input_buffer()  # the RC receiver's pulses: not ours to use here
            port.write(b"%d, %d\r" % (steering, throttle))
        self.last_pulses = (steering, throttle)
