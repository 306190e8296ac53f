"""A 2-D LiDAR of the Slamtec RPLidar A1/A2 class over serial -> a distance array by angle.

Protocol (Slamtec "RPLIDAR Interface Protocol and Application Notes"): a request is ``0xA5 cmd``
(STOP 0x25, RESET 0x40, SCAN 0x20, GET_HEALTH 0x52). A response starts with a 7-byte descriptor
``0xA5 0x5A`` + 32-bit little-endian word (length: low 30 bits, send mode: top 2 bits) + data type.
SCAN answers ``A5 5A 05 00 00 40 81`` and then streams 5-byte nodes:

    byte 0: quality (bits 7:2) | !S (bit 1) | S (bit 0)   S = 1 on the first node of a new turn
    byte 1: angle_q6 bits 6:0 (bits 7:1) | C (bit 0)        C is always 1
    byte 2: angle_q6 bits 14:7                              angle = angle_q6 / 64 degrees, clockwise
    bytes 3-4: distance_q2, little-endian                   distance = distance_q2 / 4 mm, 0 = no return

A node whose check bits are wrong means the stream lost its framing: the driver drops one byte
and looks again. The A1's motor runs while DTR is low (pyserial ``dtr = False``).

The check bits are weak: a quarter of shifted byte windows pass them, so line noise fakes nodes,
some with S set. The driver therefore trusts the angles, not the S bit: a node is kept only when its
angle lies at most ``max_gap`` degrees after the previous kept node (two consecutive nodes that agree
with each other re-anchor the chain after a real gap), a turn ends where the kept angles wrap past
360, and a turn is published only with at least ``360 / max_gap`` nodes. Bins inside a gap wider
than ``max_gap`` have no reading: they keep an earlier turn's reading while it is at most
``max_age`` old and read :data:`UNKNOWN` after that; the obstacle stop treats an unknown bin ahead
as blind.

:func:`bin_scan` turns a turn's (angle, distance) points into ``lidar/dist_array``: the nearest
return per angle bin, bins counter-clockwise from straight ahead (the car's frame, as ``pos/angle``),
metres, 0.0 where nothing returned, :data:`UNKNOWN` (-1.0) where there is no fresh reading.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any, ClassVar

import numpy as np

from parts.sensors.freshness import SensorPart
from parts.serial_port import pyserial_port
from vehicle.config import check_settings
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

SYNC, SYNC2 = 0xA5, 0x5A
STOP, RESET, SCAN, GET_HEALTH = 0x25, 0x40, 0x20, 0x52
SCAN_DESCRIPTOR = bytes((SYNC, SYNC2, 0x05, 0x00, 0x00, 0x40, 0x81))
NODE_SIZE = 5
UNKNOWN = -1.0  # a bin of lidar/dist_array without a fresh reading (JSON-safe, unlike NaN: tubs store it)


class LidarError(VehicleError):
    """The LiDAR does not answer or answers another protocol."""


def decode_node(node: bytes) -> tuple[bool, int, float, float] | None:
    """(new turn, quality, angle in degrees clockwise, distance in metres) of a 5-byte node, or None
    when its check bits are wrong."""
    b0, b1 = node[0], node[1]
    start, inverse = b0 & 1, (b0 >> 1) & 1
    if start == inverse or not b1 & 1:
        return None
    angle = ((node[2] << 7) | (b1 >> 1)) / 64.0
    distance = (node[3] | (node[4] << 8)) / 4000.0
    return bool(start), b0 >> 2, angle, distance


def bin_scan(points: Iterable[tuple[float, float]], bins: int = 360, *, offset_deg: float = 0.0,
             clockwise: bool = True, max_range: float = 12.0) -> list[float]:
    """Nearest return per angle bin: ``out[i]`` covers [i, i+1) x 360/bins degrees counter-clockwise
    from the car's front, metres, 0.0 for no return.

    Args:
        points: (angle in degrees, distance in metres) in the sensor's frame.
        offset_deg: the sensor angle that points to the car's front (LIDAR_ANGLE_OFFSET).
        clockwise: the sensor's angles turn clockwise (RPLidar: yes).
        max_range: returns beyond this many metres are ignored.
    """
    out = np.full(bins, np.inf)
    for angle, dist in points:
        if not 0.0 < dist <= max_range:
            continue
        a = (angle - offset_deg) % 360.0
        ccw = (360.0 - a) % 360.0 if clockwise else a
        i = int(ccw * bins / 360.0) % bins
        if dist < out[i]:
            out[i] = dist
    out[np.isinf(out)] = 0.0
    return out.tolist()


class RPLidar(SensorPart):
    """Part: one full turn of an RPLidar -> ``lidar/dist_array`` (see :func:`bin_scan`) and
    ``lidar/ok``. Add it threaded: it reads the serial stream continuously.

    Args:
        port: serial device (LIDAR_SERIAL) or pyserial URL; baudrate 115200 (A1/A2) or 256000 (A3).
        bins: length of the distance array (LIDAR_BINS).
        offset_deg, max_range: see :func:`bin_scan`.
        max_age: seconds without a full turn after which the array reads None, and after which a bin
            without a reading reads UNKNOWN.
        max_gap: degrees between two consecutive nodes above which the bins between them are not
            read (LIDAR_MAX_GAP); it also bounds how far a node may follow the previous one.
        serial_factory: ``factory(port, baudrate, timeout)`` -> pyserial-like (tests: a pty).
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("lidar/dist_array", "lidar/ok")
    RECORDED: ClassVar[Mapping[str, str]] = {"lidar/dist_array": "vector"}

    def __init__(self, port: str, baudrate: int = 115200, *, bins: int = 360, offset_deg: float = 0.0,
                 max_range: float = 12.0, max_age: float = 0.5, max_gap: float = 5.0,
                 serial_factory: Callable[..., Any] | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        check_settings(LIDAR_SERIAL_BAUDRATE=baudrate, LIDAR_BINS=bins, LIDAR_ANGLE_OFFSET=offset_deg,
                       LIDAR_MAX_RANGE=max_range, LIDAR_MAX_AGE_S=max_age, LIDAR_MAX_GAP=max_gap)
        super().__init__(max_age, clock)
        self.port, self.baudrate, self.bins = port, int(baudrate), int(bins)
        self.offset_deg, self.max_range, self.max_gap = float(offset_deg), float(max_range), float(max_gap)
        self.min_nodes = int(math.ceil(360.0 / self.max_gap))  # fewer cannot cover a turn without a wider gap
        self._factory = serial_factory
        self._serial: Any = None
        self._buffer = bytearray()
        self._turn: list[tuple[float, float]] = []
        self._candidate: tuple[float, float] | None = None  # the latest node that did not follow the chain
        self._bins = np.full(self.bins, UNKNOWN)  # latest reading per bin ...
        self._seen = np.full(self.bins, -math.inf)  # ... and its clock time
        self.resyncs = 0  # bytes dropped to find the node framing again
        self.rejected_nodes = 0  # nodes whose check bits passed but whose angle did not fit the turn
        self.rejected_turns = 0  # turns with too few nodes: not published

    @classmethod
    def from_config(cls, cfg: Any, clock: Callable[[], float] | None = None) -> RPLidar:
        """LIDAR_SERIAL, LIDAR_SERIAL_BAUDRATE, LIDAR_BINS, LIDAR_ANGLE_OFFSET, LIDAR_MAX_RANGE,
        LIDAR_MAX_AGE_S, LIDAR_MAX_GAP."""
        return cls(cfg.LIDAR_SERIAL, cfg.LIDAR_SERIAL_BAUDRATE, bins=cfg.LIDAR_BINS,
                   offset_deg=cfg.LIDAR_ANGLE_OFFSET, max_range=cfg.LIDAR_MAX_RANGE, max_age=cfg.LIDAR_MAX_AGE_S,
                   max_gap=cfg.LIDAR_MAX_GAP, clock=clock or time.monotonic)

    def open(self) -> None:
        """Open the port, stop any scan, start the motor and a scan, check the descriptor."""
        factory = self._factory or pyserial_port
        try:
            self._serial = factory(self.port, self.baudrate, 0.5)
        except (OSError, ValueError) as exc:
            raise LidarError(f"LiDAR serial port {self.port}: {exc} (check LIDAR_SERIAL and the 'dialout' "
                             "group)") from exc
        s = self._serial
        s.write(bytes((SYNC, STOP)))
        time.sleep(0.002)  # the protocol asks the host to wait 1 ms after STOP
        s.reset_input_buffer()
        with contextlib.suppress(AttributeError, OSError, ValueError):  # a port without modem lines
            s.dtr = False  # A1: motor on
        s.write(bytes((SYNC, SCAN)))
        descriptor = s.read(len(SCAN_DESCRIPTOR))
        if bytes(descriptor) != SCAN_DESCRIPTOR:
            raise LidarError(f"LiDAR at {self.port}: SCAN answered {bytes(descriptor).hex(' ') or 'nothing'}, "
                             f"expected {SCAN_DESCRIPTOR.hex(' ')}: is it an RPLidar, at LIDAR_SERIAL_BAUDRATE?")

    def read(self) -> tuple[object, ...] | None:
        """Read what has arrived; the binned turn when one completed, else None."""
        s = self._serial
        if s is None:
            return None
        self._buffer += s.read(max(NODE_SIZE, getattr(s, "in_waiting", 0) or 0))
        result = None
        buf = self._buffer
        i = 0
        while len(buf) - i >= NODE_SIZE:
            node = decode_node(bytes(buf[i:i + NODE_SIZE]))
            if node is None:
                i += 1
                self.resyncs += 1
                continue
            i += NODE_SIZE
            _start, _quality, angle, distance = node  # S is not trusted: noise forges it (module docstring)
            turn = self._follow(angle, distance)
            if turn is not None:
                result = turn
        del buf[:i]
        return result

    def _follow(self, angle: float, distance: float) -> tuple[list[float]] | None:
        """Add one decoded node to the turn; the published array when it completed a plausible turn."""
        if angle >= 360.0:  # angle_q6 reaches 512 degrees: only a forged node gets there
            self.rejected_nodes += 1
            return None
        turn = self._turn
        if not turn or 0.0 < (angle - turn[-1][0]) % 360.0 <= self.max_gap:
            self._candidate = None
            return self._extend(angle, distance)
        cand, self._candidate = self._candidate, (angle, distance)
        if cand is None or not 0.0 < (angle - cand[0]) % 360.0 <= self.max_gap:
            self.rejected_nodes += 1
            return None
        # two consecutive nodes agree with each other, not with the chain: a real gap (the chain goes
        # on from them), or forged nodes just ahead of the true angles (dropped)
        self._candidate = None
        if (cand[0] - turn[-1][0]) % 360.0 >= 180.0:
            while turn and turn[-1][0] >= cand[0]:
                turn.pop()
                self.rejected_nodes += 1
        published = self._extend(*cand)
        return self._extend(angle, distance) or published

    def _extend(self, angle: float, distance: float) -> tuple[list[float]] | None:
        """Append a node that follows the chain; a wrap past 360 ends the turn and starts the next."""
        turn = self._turn
        if turn and angle < turn[-1][0]:
            self._turn = [(angle, distance)]
            return self._publish(turn)
        turn.append((angle, distance))
        return None

    def _publish(self, turn: list[tuple[float, float]]) -> tuple[list[float]] | None:
        """Merge a completed turn into the bins; the array (bins without a fresh reading: UNKNOWN)."""
        if len(turn) < self.min_nodes:
            self.rejected_turns += 1
            logger.debug("LiDAR turn of %d nodes dropped (< %d)", len(turn), self.min_nodes)
            return None
        values, read = self._read_bins(turn)
        now = self.freshness.clock()
        self._bins[read] = values[read]
        self._seen[read] = now
        out = np.where(now - self._seen <= self.freshness.max_age, self._bins, UNKNOWN)
        return (out.tolist(),)

    def _read_bins(self, turn: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
        """The turn's car-frame bins and the mask of those it read: bins holding a node, and bins
        swept between two consecutive nodes (the last to the first across 360) at most ``max_gap``
        apart, which take the nearer return of those two nodes (the beams' spacing is the sensor's
        resolution; the nearer one keeps an obstacle between them)."""
        n = self.bins
        values = np.asarray(bin_scan(turn, n, offset_deg=self.offset_deg, max_range=self.max_range))
        angles = np.asarray([a for a, _ in turn])
        has_node = np.zeros(n, dtype=bool)
        has_node[np.floor(((self.offset_deg - angles) % 360.0) * n / 360.0).astype(int) % n] = True
        read = has_node.copy()
        fill = np.full(n, np.inf)
        nxt = [*turn[1:], (turn[0][0] + 360.0, turn[0][1])]
        for (a, da), (b, db) in zip(turn, nxt, strict=True):
            if b - a > self.max_gap:
                continue
            near = [d for d in (da, db) if 0.0 < d <= self.max_range]
            x = ((self.offset_deg - b) % 360.0) * n / 360.0  # bin_scan's frame: ccw = offset - angle
            for i in range(int(x), int(x + (b - a) * n / 360.0) + 1):
                read[i % n] = True
                fill[i % n] = min(fill[i % n], min(near, default=0.0))
        swept = read & ~has_node
        values[swept] = fill[swept]
        return values, read

    def close(self) -> None:
        """Stop the scan and the motor, close the port."""
        if self._serial is not None:
            with contextlib.suppress(AttributeError, OSError, ValueError):
                self._serial.write(bytes((SYNC, STOP)))
                self._serial.dtr = True
            self._serial.close()
            self._serial = None

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """How many bins have a return, and the nearest one's distance and angle."""
        ok, text = super().describe(values)
        if not ok:
            return ok, text
        dist = list(values[0])  # type: ignore[call-overload]
        hits = [(d, i) for i, d in enumerate(dist) if d > 0]
        if not hits:
            return True, f"{self.where()}: {len(dist)} bins, no return: is anything within LIDAR_MAX_RANGE?"
        d, i = min(hits)
        return True, (f"{self.where()}: {len(dist)} bins, {len(hits)} with a return, nearest {d:.2f} m at "
                      f"{i * 360 / len(dist):.0f} degrees")


def front_distance(dist_array: list[float] | np.ndarray, half_angle_deg: float) -> float:
    """The nearest return within ``half_angle_deg`` either side of straight ahead (inf: none; NaN:
    a bin in that cone is :data:`UNKNOWN`, so nothing can be said)."""
    d = np.asarray(dist_array, dtype=float)
    n = len(d)
    k = int(math.ceil(half_angle_deg * n / 360.0))
    idx = np.r_[0:k, n - k:n] if k > 0 else np.array([0])
    ahead = d[idx]
    if (ahead < 0).any() or np.isnan(ahead).any():
        return math.nan
    ahead = ahead[ahead > 0]
    return float(ahead.min()) if ahead.size else math.inf
