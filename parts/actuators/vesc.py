"""VESC motor controller over serial (DRIVE_TRAIN_TYPE = "VESC"): drive, steer, and measured speed.

The VESC drives the motor (duty cycle, current or RPM control) and a steering servo on its servo
output; every loop the part sends the commands and a COMM_GET_VALUES request, and reads the
replies that have arrived without waiting for them (the loop never blocks on the serial port).
From the electrical RPM in the reply it reports the car's speed as ``enc/speed`` (m/s):

    speed = ERPM / (MOTOR_POLES / 2) / GEAR_RATIO / 60 * 2 pi WHEEL_RADIUS

and None when no reply arrived for ``stale_s`` seconds (the speed controller then stops trusting
it). Neutral (also a missing or NaN throttle) is the servo centre and a braking current
(``brake_current`` A; 0 = release the motor); a negative throttle while the motor turns forward
(a fresh reply above ``ROLLING_ERPM``) is a braking current of |throttle| x ``max_current`` A, not
reverse. The VESC's own command timeout (VESC Tool: App Settings > General > Timeout) stops the
motor if this computer goes silent.

pyserial is imported when the part opens.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import Any, Literal

from parts.actuators import vesc_protocol as vp
from parts.actuators.drivetrain import Drivetrain, DrivetrainError, clamp
from parts.serial_port import close_serial, open_serial, serial_link
from vehicle.config import check_settings

logger = logging.getLogger(__name__)

ControlMode = Literal["duty", "current", "rpm"]
CONTROL_MODES: tuple[str, ...] = ("duty", "current", "rpm")
#: ERPM above which the motor counts as turning forward, so a negative throttle brakes (a 4-pole
#: motor at 150 rpm; a motor at rest reads a few ERPM of noise)
ROLLING_ERPM = 300.0
#: readings beyond these are not a car's: a mis-framed or foreign reply, dropped like a missing one.
#: 200,000 ERPM is the top of VESC Tool's (and VESC_MAX_ERPM's) range; 100 m/s is above the RC
#: speed record (about 90 m/s)
MAX_ERPM_READING = 200_000
MAX_SPEED_READING = 100.0
SETTING = "VESC_SERIAL_PORT"
#: what still stops the motor when this computer cannot reach the VESC
SILENT = "the VESC's own timeout (VESC Tool: App Settings > General > Timeout) stops the motor"


class VESC(Drivetrain):
    """The VESC drivetrain part: inputs ``angle``, ``throttle``; output ``enc/speed`` when the gear
    ratio is set (see the module doc).

    Args:
        port: serial device or pyserial URL (VESC_SERIAL_PORT).
        baudrate: VESC_BAUDRATE (USB VESCs ignore it).
        mode: "duty" (throttle x ``max_duty``), "current" (x ``max_current`` A) or "rpm"
            (x ``max_erpm``).
        steering_scale, steering_offset: servo position = angle x scale + offset (DonkeyCar's
            VESC_STEERING_SCALE / _OFFSET: 0.5 / 0.5 map [-1, 1] to [0, 1]).
        motor_poles, gear_ratio, wheel_radius: for the speed (poles of the motor, motor turns per
            wheel turn, metres). ``gear_ratio=None``: no speed output.
        serial_factory: ``factory(port, baudrate)`` -> a pyserial-like port (default pyserial).
    """

    #: seconds the open waits for the COMM_FW_VERSION reply (a VESC answers within milliseconds)
    fw_reply_s = 1.0

    def __init__(self, port: str, baudrate: int = 115200, *, mode: ControlMode = "duty",
                 max_duty: float = 0.2, max_current: float = 10.0, max_erpm: float = 10000.0,
                 brake_current: float = 5.0, steering_scale: float = 0.5, steering_offset: float = 0.5,
                 motor_poles: int = 4, gear_ratio: float | None = None, wheel_radius: float = 0.0315,
                 stale_s: float = 0.5, serial_factory: Callable[[str, int], Any] | None = None,
                 **safety: Any) -> None:
        safety.setdefault("arm_s", 0.0)
        super().__init__(**safety)
        check_settings(VESC_BAUDRATE=baudrate, VESC_CONTROL_MODE=mode, VESC_MAX_SPEED_PERCENT=max_duty,
                       VESC_MAX_CURRENT=max_current, VESC_MAX_ERPM=max_erpm, VESC_BRAKE_CURRENT=brake_current,
                       VESC_STEERING_SCALE=steering_scale, VESC_STEERING_OFFSET=steering_offset,
                       VESC_MOTOR_POLES=motor_poles, VESC_GEAR_RATIO=gear_ratio, WHEEL_RADIUS=wheel_radius)
        if motor_poles % 2:  # beyond the setting's range: magnets come in pairs
            raise ValueError(f"VESC_MOTOR_POLES must be an even number (magnet poles of the motor), "
                             f"got {motor_poles!r}")
        self.port_name = port
        self.baudrate = baudrate
        self.mode = mode
        self.max_duty, self.max_current, self.max_erpm = float(max_duty), float(max_current), float(max_erpm)
        self.brake_current = float(brake_current)
        self.steering_scale, self.steering_offset = float(steering_scale), float(steering_offset)
        self.motor_poles = motor_poles
        self.gear_ratio = gear_ratio
        self.wheel_radius = float(wheel_radius)
        self.stale_s = float(stale_s)
        self._factory = serial_factory or (lambda p, b: open_serial(p, b, SETTING, DrivetrainError))
        self._serial: Any = None
        self._reader = vp.PacketReader()
        self.values: vp.Values | None = None
        self._values_at: float | None = None
        self.firmware: tuple[int, int] | None = None  # (major, minor) reported at open
        self.dropped = 0  # GET_VALUES replies dropped as physically impossible

    @classmethod
    def from_config(cls, cfg: Any, *, serial_factory: Callable[[str, int], Any] | None = None,
                    clock: Callable[[], float] | None = None, **_: Any) -> VESC:
        """DRIVE_TRAIN_TYPE = "VESC": DonkeyCar's VESC_* settings plus control mode, brake and speed."""
        from parts.actuators.drivetrain_config import safety_from_config  # noqa: PLC0415

        return cls(cfg.VESC_SERIAL_PORT, cfg.VESC_BAUDRATE, mode=cfg.VESC_CONTROL_MODE,
                   max_duty=cfg.VESC_MAX_SPEED_PERCENT, max_current=cfg.VESC_MAX_CURRENT, max_erpm=cfg.VESC_MAX_ERPM,
                   brake_current=cfg.VESC_BRAKE_CURRENT, steering_scale=cfg.VESC_STEERING_SCALE,
                   steering_offset=cfg.VESC_STEERING_OFFSET, motor_poles=cfg.VESC_MOTOR_POLES,
                   gear_ratio=cfg.VESC_GEAR_RATIO, wheel_radius=cfg.WHEEL_RADIUS, serial_factory=serial_factory,
                   **safety_from_config(cfg, clock))

    @property
    def OUTPUTS(self) -> tuple[str, ...]:  # type: ignore[override]  # noqa: N802 - the part contract's name
        """``enc/speed`` when the speed can be computed (VESC_GEAR_RATIO set)."""
        return ("enc/speed",) if self.gear_ratio is not None else ()

    def describe(self) -> str:
        limit = {"duty": f"duty {self.max_duty:g}", "current": f"{self.max_current:g} A",
                 "rpm": f"{self.max_erpm:g} ERPM"}[self.mode]
        firmware = f"firmware {self.firmware[0]}.{self.firmware[1]:02d}, " if self.firmware else ""
        return f"VESC on {self.port_name} ({firmware}{self.mode} control, full throttle = {limit})"

    # -- Drivetrain hooks -------------------------------------------------------------------------
    def _open_hardware(self) -> None:
        self._serial = self._factory(self.port_name, self.baudrate)
        try:
            self.firmware = self._ask_firmware()
        except BaseException:
            self._close_hardware()
            raise

    def _ask_firmware(self) -> tuple[int, int]:
        """Ask COMM_FW_VERSION and refuse a firmware whose COMM_GET_VALUES layout this part cannot
        read (before 3.33 it starts with seven temperatures: ERPM 6000 read as 1,715.7 m/s)."""
        self._send(vp.fw_version())
        deadline = time.monotonic() + self.fw_reply_s  # an I/O wait, real time whatever the part's clock
        while time.monotonic() < deadline:
            for payload in self._read_payloads():
                if payload[0] != vp.COMM_FW_VERSION:
                    continue
                major, minor = vp.parse_fw_version(payload)
                if (major, minor) < vp.VALUES_SINCE:
                    raise DrivetrainError(
                        f"{SETTING} = {self.port_name!r}: VESC firmware {major}.{minor:02d} reports its values in a "
                        f"layout older than {vp.VALUES_SINCE[0]}.{vp.VALUES_SINCE[1]} that this part does not read "
                        f"(speed and braking would use wrong numbers); update the VESC's firmware in VESC Tool")
                logger.info("VESC firmware %d.%02d on %s", major, minor, self.port_name)
                return major, minor
            time.sleep(0.005)
        raise DrivetrainError(f"{SETTING} = {self.port_name!r}: no answer to COMM_FW_VERSION within "
                              f"{self.fw_reply_s:g} s; check that the VESC is powered (battery connected), the "
                              f"cable, and VESC_BAUDRATE (UART: as set in VESC Tool; {self.baudrate} now)")

    def _drive(self, angle: float, throttle: float) -> None:
        if throttle < 0 and self._rolling_forward():
            # a negative command while rolling forward is a brake (as on a hobby ESC; the obstacle
            # stop brakes so): braking current, never reverse duty/current/RPM against the motion
            self._send(self._servo(angle) + vp.set_current_brake(-throttle * self.max_current) + vp.get_values())
            return
        if self.mode == "duty":
            motor = vp.set_duty(throttle * self.max_duty)
        elif self.mode == "current":
            motor = vp.set_current(throttle * self.max_current)
        else:
            motor = vp.set_rpm(throttle * self.max_erpm)
        self._send(self._servo(angle) + motor + vp.get_values())

    def _neutral_outputs(self) -> None:
        self._send(self._servo(0.0) + self._brake())

    def _drive_without_throttle(self, angle: float) -> None:
        self._send(self._servo(angle) + self._brake() + vp.get_values())  # neutral is the brake current

    def _brake(self) -> bytes:
        return vp.set_current_brake(self.brake_current) if self.brake_current > 0 else vp.set_current(0.0)

    def _rolling_forward(self) -> bool:
        """The latest fresh GET_VALUES reply says the motor turns forward faster than ROLLING_ERPM."""
        fresh = self._values_at is not None and self.clock() - self._values_at <= self.stale_s
        return fresh and self.values is not None and self.values.erpm > ROLLING_ERPM

    def _close_hardware(self) -> None:
        port, self._serial = self._serial, None
        close_serial(port, SETTING, self.port_name, SILENT, DrivetrainError)

    # -- the part ---------------------------------------------------------------------------------
    def run(self, angle: float | None, throttle: float | None) -> float | None:  # type: ignore[override]
        """Drive, then return the measured speed (m/s) when the part has the ``enc/speed`` output."""
        super().run(angle, throttle)
        with self._lock:
            self._receive()
            return self.speed() if self.gear_ratio is not None else None

    def speed(self) -> float | None:
        """The car's speed in m/s from the last GET_VALUES reply; None when stale or never seen."""
        if self.values is None or self.gear_ratio is None or self._values_at is None:
            return None
        if self.clock() - self._values_at > self.stale_s:
            return None
        return self._speed_of(self.values.erpm)

    def _speed_of(self, erpm: float) -> float | None:
        """m/s at ``erpm``; None without a gear ratio."""
        if self.gear_ratio is None:
            return None
        wheel_rpm = erpm / (self.motor_poles / 2) / self.gear_ratio
        return wheel_rpm / 60.0 * 2 * math.pi * self.wheel_radius

    def _servo(self, angle: float) -> bytes:
        return vp.set_servo_pos(clamp(angle * self.steering_scale + self.steering_offset, 0.0, 1.0))

    def _send(self, data: bytes) -> None:
        if self._serial is None:
            return
        with serial_link(SETTING, self.port_name, SILENT, DrivetrainError):
            self._serial.write(data)

    def _read_payloads(self) -> list[bytes]:
        """The complete packets that have arrived (never waits)."""
        port = self._serial
        if port is None:
            return []
        with serial_link(SETTING, self.port_name, SILENT, DrivetrainError):
            waiting = port.in_waiting
            data = port.read(waiting) if waiting else b""
        return list(self._reader.feed(data))

    def _receive(self) -> None:
        for payload in self._read_payloads():
            if payload[0] == vp.COMM_GET_VALUES:
                try:
                    values = vp.Values.parse(payload)
                except ValueError as exc:
                    logger.warning("VESC: %s", exc)
                    continue
                if not self._plausible(values):
                    continue
                self.values = values
                self._values_at = self.clock()

    def _plausible(self, values: vp.Values) -> bool:
        """Whether a reading could come from a car; an impossible one is dropped (the speed goes
        stale as if no reply had come), with a warning the first time."""
        speed = self._speed_of(values.erpm)
        if abs(values.erpm) <= MAX_ERPM_READING and (speed is None or abs(speed) <= MAX_SPEED_READING):
            return True
        if not self.dropped:
            logger.warning("VESC: dropped an impossible reading (%d ERPM%s); the speed counts as stale",
                           values.erpm, "" if speed is None else f", {speed:.1f} m/s")
        self.dropped += 1
        return False
