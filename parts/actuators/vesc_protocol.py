"""The VESC serial protocol: packet framing, CRC, the commands a car needs and COMM_GET_VALUES.

A packet is ``0x02 LEN PAYLOAD CRC_HI CRC_LO 0x03`` for payloads under 256 bytes and
``0x03 LEN_HI LEN_LO PAYLOAD CRC_HI CRC_LO 0x03`` up to 65535 bytes; the CRC is CRC-16/XMODEM
(polynomial 0x1021, initial value 0) of the payload, big-endian. The payload's first byte is the
command id; numbers are big-endian integers scaled as below (VESC firmware ``commands.c``, as
pyvesc writes them).

>>> encode_packet(bytes([COMM_GET_VALUES])).hex(" ")
'02 01 04 40 84 03'
>>> set_duty(0.1).hex(" ")
'02 05 05 00 00 27 10 ae 17 03'
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Iterator
from dataclasses import dataclass

COMM_FW_VERSION = 0
COMM_GET_VALUES = 4
COMM_SET_DUTY = 5
COMM_SET_CURRENT = 6
COMM_SET_CURRENT_BRAKE = 7
COMM_SET_RPM = 8
COMM_SET_SERVO_POS = 12
COMM_ALIVE = 30

SHORT_START, LONG_START, END = 0x02, 0x03, 0x03
#: the first firmware (major, minor) whose COMM_GET_VALUES reply has :class:`Values`' layout
VALUES_SINCE = (3, 33)
MAX_PAYLOAD = 65535


def crc16_xmodem(data: bytes) -> int:
    """CRC-16/XMODEM (binascii's CRC-CCITT with initial value 0); check value 0x31C3.

    >>> hex(crc16_xmodem(b"123456789"))
    '0x31c3'
    """
    return binascii.crc_hqx(data, 0)


def encode_packet(payload: bytes) -> bytes:
    """Frame a payload: the short form under 256 bytes, else the long form."""
    n = len(payload)
    if not 0 < n <= MAX_PAYLOAD:
        raise ValueError(f"VESC payload must be 1-{MAX_PAYLOAD} bytes, got {n}")
    head = bytes([SHORT_START, n]) if n < 256 else bytes([LONG_START, n >> 8, n & 0xFF])
    return head + payload + struct.pack(">HB", crc16_xmodem(payload), END)


def _command(command: int, fmt: str = "", *values: int) -> bytes:
    return encode_packet(struct.pack(">B" + fmt, command, *values))


def set_duty(duty: float) -> bytes:
    """COMM_SET_DUTY: duty cycle in [-1, 1], sent as int32 x 100000."""
    return _command(COMM_SET_DUTY, "i", round(duty * 100_000))


def set_current(amps: float) -> bytes:
    """COMM_SET_CURRENT: motor current in A (negative: reverse torque), sent as int32 mA."""
    return _command(COMM_SET_CURRENT, "i", round(amps * 1000))


def set_current_brake(amps: float) -> bytes:
    """COMM_SET_CURRENT_BRAKE: braking current in A (>= 0), sent as int32 mA."""
    return _command(COMM_SET_CURRENT_BRAKE, "i", round(abs(amps) * 1000))


def set_rpm(erpm: float) -> bytes:
    """COMM_SET_RPM: electrical RPM (motor RPM x pole pairs), int32."""
    return _command(COMM_SET_RPM, "i", round(erpm))


def set_servo_pos(position: float) -> bytes:
    """COMM_SET_SERVO_POS: the VESC's servo output in [0, 1], sent as int16 x 1000."""
    return _command(COMM_SET_SERVO_POS, "h", round(position * 1000))


def get_values() -> bytes:
    """COMM_GET_VALUES request (no arguments)."""
    return _command(COMM_GET_VALUES)


def fw_version() -> bytes:
    """COMM_FW_VERSION request (no arguments)."""
    return _command(COMM_FW_VERSION)


def parse_fw_version(payload: bytes) -> tuple[int, int]:
    """(major, minor) from a COMM_FW_VERSION reply (``0, MAJOR, MINOR, HW_NAME\\0, UUID ...``;
    firmware before 3.x sends only the two numbers); ValueError when it is not one."""
    if len(payload) < 3 or payload[0] != COMM_FW_VERSION:
        raise ValueError("not a COMM_FW_VERSION reply")
    return payload[1], payload[2]


def alive() -> bytes:
    """COMM_ALIVE: keeps the VESC's command timeout from stopping the motor."""
    return _command(COMM_ALIVE)


@dataclass(frozen=True)
class Values:
    """The start of a COMM_GET_VALUES reply in the layout of firmware 3.33 and later (before, the
    reply began with seven temperatures: see :data:`VALUES_SINCE`)."""

    temp_fet_c: float
    temp_motor_c: float
    motor_current_a: float
    input_current_a: float
    duty: float
    erpm: int
    v_in: float

    #: payload layout after the command byte, up to v_in: (format, scale) per field
    LAYOUT = ((">h", 10), (">h", 10), (">i", 100), (">i", 100), (">i", 100), (">i", 100), (">h", 1000),
              (">i", 1), (">h", 10))

    @classmethod
    def parse(cls, payload: bytes) -> Values:
        """Decode a COMM_GET_VALUES payload (ValueError when it is not one or too short)."""
        if not payload or payload[0] != COMM_GET_VALUES:
            raise ValueError("not a COMM_GET_VALUES reply")
        out: list[float] = []
        offset = 1
        for fmt, scale in cls.LAYOUT:
            size = struct.calcsize(fmt)
            if offset + size > len(payload):
                raise ValueError(f"COMM_GET_VALUES reply too short ({len(payload)} bytes)")
            out.append(struct.unpack_from(fmt, payload, offset)[0] / scale)
            offset += size
        temp_fet, temp_motor, i_motor, i_in, _id, _iq, duty, erpm, v_in = out
        return cls(temp_fet, temp_motor, i_motor, i_in, duty, int(erpm), v_in)


class PacketReader:
    """Splits a byte stream into payloads; skips noise and packets with a bad length, CRC or end.

    A start byte inside noise can announce a long packet that never completes; rather than wait
    for it, the reader moves on when a whole valid packet starts further on. ``max_payload``
    bounds the wait (a car's replies are under 100 bytes).
    """

    def __init__(self, max_payload: int = 1024) -> None:
        self._buf = bytearray()
        self.max_payload = max_payload
        self.errors = 0

    def feed(self, data: bytes) -> Iterator[bytes]:
        """Add received bytes; yield every complete, valid payload."""
        self._buf += data
        buf = self._buf
        while buf:
            found = self._packet_at(0)
            if found is None:  # incomplete: wait, unless a whole packet starts later on
                later = next((i for i in range(1, len(buf)) if self._packet_at(i)), None)
                if later is None:
                    return
                del buf[:later]
                self.errors += 1
                continue
            if not found:
                if buf[0] in (SHORT_START, LONG_START):
                    self.errors += 1  # a start byte that began no valid packet
                del buf[0]
                continue
            total, payload = found
            del buf[:total]
            yield payload

    def _packet_at(self, i: int) -> tuple[int, bytes] | None | tuple[()]:
        """At offset ``i``: (length, payload) of a valid packet, None if it may still complete, or
        ``()`` if no packet starts there."""
        buf = self._buf
        start = buf[i]
        if start not in (SHORT_START, LONG_START):
            return ()
        head = 2 if start == SHORT_START else 3
        if len(buf) < i + head:
            return None
        n = buf[i + 1] if start == SHORT_START else buf[i + 1] << 8 | buf[i + 2]
        if n == 0 or n > self.max_payload:
            return ()
        total = head + n + 3
        if len(buf) < i + total:
            return None
        payload = bytes(buf[i + head:i + head + n])
        crc = buf[i + head + n] << 8 | buf[i + head + n + 1]
        if buf[i + total - 1] != END or crc != crc16_xmodem(payload):
            return ()
        return total, payload
