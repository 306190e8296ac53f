"""The RPLidar driver against a fake that speaks Slamtec's scan protocol on a pty; binning; the
obstacle stop part."""

from __future__ import annotations

import math

import pytest
from sensor_fakes import RPLidarDevice, lidar_node, wait_for

from parts.drive.obstacle import ObstacleStop
from parts.sensors.lidar import RPLidar, bin_scan, decode_node, front_distance


def test_node_decoding_matches_the_protocol() -> None:
    assert decode_node(lidar_node(123.5, 2.25, start=True)) == (True, 47, 123.5, 2.25)
    assert decode_node(lidar_node(359.984375, 0.0, start=False))[1:] == (47, 359.984375, 0.0)
    bad = bytearray(lidar_node(10.0, 1.0, start=True))
    bad[0] |= 2  # S and !S both set
    assert decode_node(bytes(bad)) is None
    bad = bytearray(lidar_node(10.0, 1.0, start=True))
    bad[1] &= 0xFE  # C bit clear
    assert decode_node(bytes(bad)) is None


def test_binning_is_counter_clockwise_from_the_front() -> None:
    # a sensor angle of 90 degrees clockwise is the car's right = 270 counter-clockwise
    # and 0.5 degrees clockwise is 359.5 counter-clockwise, in the last bin
    out = bin_scan([(90.0, 1.0), (270.0, 2.0), (0.0, 3.0), (0.5, 0.7), (180.0, 0.0), (200.0, 13.0)], bins=4)
    assert out == [3.0, 2.0, 0.0, 0.7]
    # mounted backwards: sensor angle 180 is the car's front
    assert bin_scan([(180.0, 1.5)], bins=4, offset_deg=180.0) == [1.5, 0.0, 0.0, 0.0]
    assert front_distance([0.0, 3.0, 0.0, 0.9], 90.0) == 0.9
    assert front_distance([0.0, 0.0, 0.0, 0.0], 30.0) == math.inf


def _scene(angle: float) -> float:
    """A wall 1.2 m in front (sensor angles 350-10), an object 0.6 m at the car's left, else nothing."""
    if angle >= 350 or angle < 10:
        return 1.2
    if 265 <= angle < 275:  # clockwise 270 = left
        return 0.6
    return 0.0


def test_rplidar_scan_session_and_resync() -> None:
    device = RPLidarDevice(_scene, points_per_turn=360)
    clock = [0.0]
    part = RPLidar(device.path, bins=36, max_age=0.5, clock=lambda: clock[0])
    try:
        out: list = []
        wait_for(lambda: out.append(part.run()) or out[-1][-1])
        assert device.commands[:2] == [0x25, 0x20]  # STOP, then SCAN
        dist = out[-1][0]
        assert len(dist) == 36 and dist[0] == pytest.approx(1.2) and dist[35] == pytest.approx(1.2)
        assert dist[9] == pytest.approx(0.6)  # bin 9 = 90-100 degrees counter-clockwise: left
        assert dist[18] == 0.0
        device.garbage = b"\x00\x17\x42"  # a framing error: the driver finds the nodes again
        before = part.resyncs
        wait_for(lambda: part.run() and part.resyncs > before)
        turns = part._version
        wait_for(lambda: part.run() and part._version > turns)  # a whole turn after the garbage
        assert part.run()[0][9] == pytest.approx(0.6) and part.resyncs - before <= len(device.garbage) + 5
        device.scanning = False  # the motor stalls
        part._serial.timeout = 0.05
        clock[0] = 1.0
        assert part.run() == (None, False)
        part.shutdown()
        # the fake reads the pty on its own thread: wait until the bytes written on shutdown arrived
        wait_for(lambda: device.commands[-1] == 0x25)  # stopped on shutdown
    finally:
        part.shutdown()
        device.close()


def test_rplidar_that_does_not_answer_is_named() -> None:
    from parts.sensors.lidar import LidarError

    device = RPLidarDevice(_scene)
    device.on_bytes = lambda data: None  # deaf
    part = RPLidar(device.path)
    part._factory = None
    try:
        import serial

        part._factory = lambda p, b, t: serial.serial_for_url(p, baudrate=b, timeout=0.1)
        with pytest.raises(LidarError, match="SCAN answered nothing"):
            part.open()
    finally:
        part.close()
        device.close()


def _noisy_turns(turns: int, places: int, junk: int, seed: int) -> bytes:
    """RPLidar turns (360 nodes, S on the first) of a wall 0.4 m ahead (sensor angles 341-20: bins 340-19) with
    ``junk`` random bytes inserted at ``places`` random places in each turn (line noise)."""
    import random

    rng = random.Random(seed)
    out = bytearray()
    for _ in range(turns):
        nodes = [lidar_node(a, 0.4 if (a > 340 or a <= 20) else 3.0, start=a == 0) for a in range(360)]
        cuts = set(rng.sample(range(1, 360), places))
        for i, node in enumerate(nodes):
            if i in cuts:
                out += bytes(rng.randrange(256) for _ in range(junk))
            out += node
    return bytes(out)


class _ByteStream:
    """A pyserial-like port that hands out a fixed byte stream (what the RPLidar sent) in chunks."""

    def __init__(self, data: bytes, chunk: int = 64) -> None:
        self.data, self.pos, self.chunk = data, 0, chunk

    @property
    def in_waiting(self) -> int:
        return min(self.chunk, len(self.data) - self.pos)

    def read(self, n: int) -> bytes:
        out = self.data[self.pos:self.pos + n]
        self.pos += len(out)
        return out


@pytest.mark.parametrize("places", [2, 5, 20])
def test_line_noise_never_shows_a_clear_way_through_a_wall(places: int) -> None:
    """Forged nodes (shifted bytes pass the check bits, some with S set) must not publish a partial
    turn whose missing bins read 'no return' ahead: every published turn sees the wall or says unknown."""
    clock = [0.0]
    part = RPLidar("unused", bins=360, max_age=0.5, clock=lambda: clock[0])
    part._serial = _ByteStream(_noisy_turns(60, places, 8, seed=places))
    stop = ObstacleStop(0.5, half_angle_deg=20)
    published = passed = good = 0
    while part._serial.in_waiting:
        clock[0] += 0.002
        turn = part.read()
        if turn is None:
            continue
        published += 1
        dist = turn[0]
        assert len(dist) == 360
        throttle, stopping, _near = stop.run(0.5, dist, True, 1.0)
        passed += throttle > 0
        assert stopping, f"turn {published}: nothing ahead in {dist[:21]} ... {dist[-20:]}"
        ahead = [d for d in dist[:20] + dist[-20:] if d >= 0]
        assert all(d == pytest.approx(0.4) for d in ahead)  # the wall, or unknown
        good += sum(d == pytest.approx(0.4) for d in ahead) >= 38
    assert passed == 0 and published >= 40 and good >= 0.9 * published  # most turns still come through
    assert part.resyncs > 0 and part.rejected_nodes > 0


def test_a_turn_with_a_hole_reads_unknown_there_once_its_old_readings_are_stale() -> None:
    clock = [0.0]
    part = RPLidar("unused", bins=36, max_age=0.5, max_gap=5.0, clock=lambda: clock[0])
    full = b"".join(lidar_node(a, 2.0, start=a == 0) for a in range(360))
    holed = b"".join(lidar_node(a, 2.0, start=a == 0) for a in range(360) if not 100 <= a < 150)
    part._serial = _ByteStream(full + full + holed + holed + lidar_node(0.0, 2.0, start=True))
    turns = []
    while part._serial.in_waiting:
        clock[0] += 0.001
        turns += [t for t in [part.read()] if t is not None]
    assert len(turns) == 4 and part.rejected_turns == 0
    # sensor angles 100-150 clockwise = car-frame bins 21-26 (210-260 degrees counter-clockwise)
    assert turns[2][0][21:26] == [2.0] * 5  # the previous full turn's readings are still fresh
    assert turns[3][0][21:26] == [2.0] * 5
    clock[0] += 1.0
    part._serial = _ByteStream(holed + lidar_node(0.0, 2.0, start=True))
    while (t := part.read()) is None:
        pass
    assert t[0][22:26] == [-1.0] * 4 and t[0][21] == t[0][26] == t[0][0] == 2.0  # 21, 26: nodes 150, 100
    assert ObstacleStop(0.5, half_angle_deg=20).run(0.5, [-1.0] + [5.0] * 35, True, 0.0)[:2] == (0.0, True)
    assert ObstacleStop(0.5, half_angle_deg=20).run(0.5, [5.0] * 18 + [-1.0] + [5.0] * 17, True, 0.0)[:2] == \
        (0.5, False)  # unknown behind: no matter
