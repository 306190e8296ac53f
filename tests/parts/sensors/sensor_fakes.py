"""Fakes of the sensors' hardware, written from their datasheets and protocol documents.

- :class:`MPU6050Model`: the MPU6050/9250 register file (power-on SLEEP, WHO_AM_I, FS_SEL/AFS_SEL
  scaling of the data registers, burst reads that auto-increment) behind an smbus2-like bus.
- :class:`PtyDevice`: a serial device on a pseudo-terminal: the driver opens the slave's path
  with pyserial, the device thread reads and writes the master side.
- :class:`ArduinoEncoder`, :class:`NmeaSource`, :class:`RPLidarDevice`: DonkeyCar's encoder
  sketch protocol, an NMEA 0183 receiver, a Slamtec RPLidar scanning a scene.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import struct
import threading
import time
import tty
from collections.abc import Callable

# -- I2C: MPU6050 / MPU9250 ------------------------------------------------------------------------
_ACCEL_LSB = {0: 16384.0, 1: 8192.0, 2: 4096.0, 3: 2048.0}  # LSB per g, by AFS_SEL
_GYRO_LSB = {0: 131.0, 1: 65.5, 2: 32.8, 3: 16.4}  # LSB per °/s, by FS_SEL


class MPU6050Model:
    """Registers of one MPU6050 (WHO_AM_I 0x68) or MPU9250 (0x71). ``motion`` holds the true
    acceleration (g) and rotation (°/s) the data registers report while the chip is awake."""

    def __init__(self, who_am_i: int = 0x68) -> None:
        self.regs = bytearray(128)
        self.regs[0x75] = who_am_i
        self.regs[0x6B] = 0x40  # power-on: SLEEP
        self.accel_g = (0.0, 0.0, 1.0)
        self.gyro_dps = (0.0, 0.0, 0.0)
        self.temp_raw = 0
        self.writes: list[tuple[int, int]] = []

    def _sample(self) -> None:
        if self.regs[0x6B] & 0x40:  # asleep: the data registers keep their last values
            return
        a_lsb = _ACCEL_LSB[(self.regs[0x1C] >> 3) & 3]
        g_lsb = _GYRO_LSB[(self.regs[0x1B] >> 3) & 3]
        clamp = lambda v: max(-32768, min(32767, int(round(v))))  # noqa: E731 - saturating ADC
        values = [clamp(a * a_lsb) for a in self.accel_g] + [self.temp_raw] + [clamp(g * g_lsb) for g in self.gyro_dps]
        self.regs[0x3B:0x3B + 14] = struct.pack(">7h", *values)

    def read(self, register: int, n: int) -> list[int]:
        self._sample()
        if register + n > len(self.regs):
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        return list(self.regs[register:register + n])

    def write(self, register: int, value: int) -> None:
        self.writes.append((register, value))
        if register == 0x6B and value & 0x80:  # DEVICE_RESET
            who = self.regs[0x75]
            self.regs[:] = bytes(128)
            self.regs[0x75], self.regs[0x6B] = who, 0x40
            return
        self.regs[register] = value & 0xFF


class FakeSMBus:
    """smbus2.SMBus look-alike over models by address; a missing address does not acknowledge."""

    def __init__(self, devices: dict[int, MPU6050Model]) -> None:
        self.devices = devices
        self.closed = False

    def _dev(self, address: int) -> MPU6050Model:
        if address not in self.devices:
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        return self.devices[address]

    def read_byte_data(self, address: int, register: int) -> int:
        return self._dev(address).read(register, 1)[0]

    def read_i2c_block_data(self, address: int, register: int, length: int) -> list[int]:
        return self._dev(address).read(register, length)

    def write_byte_data(self, address: int, register: int, value: int) -> None:
        self._dev(address).write(register, value)

    def close(self) -> None:
        self.closed = True


# -- serial devices on a pty --------------------------------------------------------------------------
class PtyDevice:
    """A serial device on a pseudo-terminal; subclasses answer :meth:`on_bytes`."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.path = os.ttyname(self.slave)
        self.received = bytearray()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if ready:
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    return
                with self._lock:
                    self.received += data
                self.on_bytes(data)
            self.tick()

    def on_bytes(self, data: bytes) -> None:
        """Bytes the host wrote."""

    def tick(self) -> None:
        """Called about every 20 ms (a device that streams writes here)."""

    def send(self, data: bytes) -> None:
        os.write(self.master, data)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class ArduinoEncoder(PtyDevice):
    """DonkeyCar's encoder sketch: ``r`` resets, ``p`` sends ``ticks,ms[;ticks,ms]\\n`` at once."""

    def __init__(self, channels: int = 1) -> None:
        self.ticks = [0] * channels
        self.millis = 0
        self._line = b""
        self.silent = False  # a hung microcontroller
        self.step = 0  # ticks added to every encoder per 20 ms of wall time (a turning wheel)
        self._last_tick = time.monotonic()
        super().__init__()

    def tick(self) -> None:
        # by elapsed time, not per call: the loop runs more often while the host polls, and a
        # wheel's speed must not depend on how often it is asked
        now = time.monotonic()
        periods = int((now - self._last_tick) / 0.02)
        if periods:
            self._last_tick += periods * 0.02
            if self.step:
                self.ticks = [t + self.step * periods for t in self.ticks]

    def on_bytes(self, data: bytes) -> None:
        self._line += data
        while b"\n" in self._line:
            cmd, self._line = self._line.split(b"\n", 1)
            cmd = cmd.strip()
            if cmd == b"r":
                self.ticks = [0] * len(self.ticks)
            elif cmd == b"p" and not self.silent:
                self.send((";".join(f"{t},{self.millis}" for t in self.ticks) + "\r\n").encode())


def nmea(body: str) -> bytes:
    """A complete NMEA sentence: ``$body*CS\\r\\n``, CS the XOR of the bytes of ``body`` (NMEA 0183)."""
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return f"${body}*{cs:02X}\r\n".encode("ascii")


def nmea_latlon(lat: float, lon: float) -> str:
    """``ddmm.mmmmm,N,dddmm.mmmmm,E`` fields (5 decimals of minutes, as u-blox receivers send)."""
    def field(v: float, width: int) -> str:
        a = abs(v)
        d = int(a)
        return f"{d:0{width}d}{(a - d) * 60:08.5f}"
    return f"{field(lat, 2)},{'N' if lat >= 0 else 'S'},{field(lon, 3)},{'E' if lon >= 0 else 'W'}"


def gga(lat: float, lon: float, quality: int = 1, hdop: float = 0.9) -> bytes:
    return nmea(f"GPGGA,123519.00,{nmea_latlon(lat, lon)},{quality},08,{hdop:.1f},545.4,M,46.9,M,,")


def rmc(lat: float, lon: float, status: str = "A", knots: float = 0.0) -> bytes:
    return nmea(f"GPRMC,123519.00,{status},{nmea_latlon(lat, lon)},{knots:.2f},84.4,230394,3.1,W")


class NmeaSource(PtyDevice):
    """A GPS receiver: sends its current ``sentences`` about every 100 ms (10 Hz), as a receiver
    streams them whether anyone listens or not."""

    def __init__(self) -> None:
        self.sentences: list[bytes] = []
        self._ticks = 0
        super().__init__()

    def tick(self) -> None:
        self._ticks += 1
        if self._ticks % 5:
            return
        with self._lock:
            out = b"".join(self.sentences)
        if out:
            self.send(out)


def lidar_node(angle_deg: float, distance_m: float, start: bool, quality: int = 47) -> bytes:
    """One 5-byte RPLidar scan node (Slamtec protocol: S/!S, C = 1, angle q6, distance q2)."""
    q6 = int(round(angle_deg * 64)) & 0x7FFF
    q2 = int(round(distance_m * 4000)) & 0xFFFF
    b0 = (quality << 2) | (0 if start else 2) | (1 if start else 0)
    return bytes((b0 & 0xFF, ((q6 & 0x7F) << 1) | 1, q6 >> 7, q2 & 0xFF, q2 >> 8))


class RPLidarDevice(PtyDevice):
    """An RPLidar: STOP (A5 25) stops streaming, SCAN (A5 20) answers the descriptor and streams
    turns of ``points_per_turn`` nodes measuring ``scene(angle_deg) -> metres`` (0 = no return)."""

    def __init__(self, scene: Callable[[float], float], points_per_turn: int = 360, turns_per_tick: int = 1) -> None:
        self.scene = scene
        self.points_per_turn = points_per_turn
        self.turns_per_tick = turns_per_tick
        self.scanning = False
        self.garbage = b""  # bytes to insert before the next turn (a framing error)
        self.commands: list[int] = []
        self._pending = b""
        super().__init__()

    def on_bytes(self, data: bytes) -> None:
        self._pending += data
        while len(self._pending) >= 2:
            if self._pending[0] != 0xA5:
                self._pending = self._pending[1:]
                continue
            cmd, self._pending = self._pending[1], self._pending[2:]
            self.commands.append(cmd)
            if cmd == 0x25:
                self.scanning = False
            elif cmd == 0x20:
                self.send(bytes((0xA5, 0x5A, 0x05, 0x00, 0x00, 0x40, 0x81)))
                self.scanning = True

    def tick(self) -> None:
        if not self.scanning:
            return
        out = bytearray(self.garbage)
        self.garbage = b""
        for _ in range(self.turns_per_tick):
            for i in range(self.points_per_turn):
                angle = i * 360.0 / self.points_per_turn
                out += lidar_node(angle, self.scene(angle), start=i == 0)
        self.send(bytes(out))


def wait_for(predicate: Callable[[], object], timeout: float = 5.0) -> None:
    """Poll ``predicate`` until it is true (something the fake device's thread does), or fail."""
    pause = threading.Event()
    for _ in range(500):
        if predicate():
            return
        pause.wait(timeout / 500)
    raise AssertionError("the fake device did not get there")
