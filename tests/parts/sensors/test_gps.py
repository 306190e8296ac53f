"""The GPS part against NMEA 0183 sentences from a fake receiver on a pty."""

from __future__ import annotations

import math

import pytest
from sensor_fakes import NmeaSource, gga, nmea, rmc, wait_for

from parts.sensors.gps import GPS, LocalFrame, NmeaPosition

LAT, LON = 48.1173, 11.5166667


def test_local_frame_round_trip_and_scale() -> None:
    frame = LocalFrame(LAT, LON)
    lat, lon = frame.to_latlon(30.0, -40.0)
    assert frame.to_xy(lat, lon) == pytest.approx((30.0, -40.0), abs=1e-6)
    x, y = frame.to_xy(LAT + 1e-4, LON)
    assert (x, y) == pytest.approx((0.0, 11.1195), abs=1e-3)  # 1e-4 degree of latitude = 11.12 m


def test_checksum_is_checked() -> None:
    r = NmeaPosition()
    good = gga(LAT, LON)
    assert r.feed(good) and r.fix
    bad = good.replace(b"*", b"0*", 1)  # body changed, checksum not
    r2 = NmeaPosition()
    assert not r2.feed(bad) and r2.bad == 1 and not r2.fix
    assert not r2.feed(good.split(b"*")[0])  # no checksum at all
    assert r2.bad == 2


def test_gps_part_position_speed_and_lost_fix() -> None:
    device = NmeaSource()
    clock = [0.0]
    part = GPS(device.path, 9600, max_age=1.0, clock=lambda: clock[0])
    try:
        part.open()
        part._opened = True
        frame = LocalFrame(LAT, LON)
        device.sentences = [gga(LAT, LON, hdop=1.2)]
        values = _next_fix(part)
        assert values[:2] == pytest.approx((0.0, 0.0), abs=0.01)  # origin at the first fix
        assert values[4] == pytest.approx(6.0) and values[-1] is True
        lat, lon = frame.to_latlon(12.0, -5.0)
        satellites = nmea("GPGSV,3,1,11,03,03,111,00,04,15,270,00,06,01,010,00,13,06,292,00")
        device.sentences = [satellites, rmc(lat, lon, knots=3.0)]
        values = _next_fix(part, lambda v: v[0] > 1)
        assert values[:2] == pytest.approx((12.0, -5.0), abs=0.02)  # 5 decimals of minutes: 1.9 cm steps
        assert values[5] == pytest.approx(3.0 * 1852 / 3600)
        device.sentences = [rmc(lat, lon, status="V")]  # the receiver loses its fix
        wait_for(lambda: part.run()[-1] is False)
        assert part.run() == (None,) * 6 + (False,)
        device.sentences = [gga(lat, lon, quality=1)]
        assert _next_fix(part)[:2] == pytest.approx((12.0, -5.0), abs=0.02)
        device.sentences = []  # the receiver goes silent
        part._serial.timeout = 0.05
        wait_for(lambda: part.read() is None)  # what it sent before is read: a read times out
        clock[0] = 5.0
        assert part.run() == (None,) * 6 + (False,)
    finally:
        part.shutdown()
        device.close()


def test_origin_given() -> None:
    frame = LocalFrame(LAT, LON)
    part = GPS("unused", origin=(LAT, LON))
    lat, lon = frame.to_latlon(-3.0, 4.0)
    assert part.update_from(gga(lat, lon))[:2] == pytest.approx((-3.0, 4.0), abs=0.02)


def _next_fix(part: GPS, new=lambda v: True) -> tuple:
    """Read until the part reports a fix for which ``new`` holds (the fake's sentences arrived)."""
    out: list = []
    wait_for(lambda: out.append(part.run()) or (out[-1][-1] is True and new(out[-1])))
    return out[-1]


@pytest.mark.parametrize("lat", [0.0, 47.0, 60.0, -60.0, -33.9])
def test_local_frame_matches_an_independent_wgs84_reference(lat: float) -> None:
    """The frame is WGS-84, not a sphere: against UTM (the `utm` package, independent of our code),
    on a zone's central meridian where the grid's scale is exactly k0 = 0.9996 and its north is true
    north, points up to 500 m away land within a millimetre."""
    import utm

    lon = 3.0  # central meridian of zone 31
    frame = LocalFrame(lat, lon)

    def ref(la: float, lo: float) -> tuple[float, float]:
        e, n, _, _ = utm.from_latlon(la, lo, force_zone_number=31, force_northern=True)
        e0, n0, _, _ = utm.from_latlon(lat, lon, force_zone_number=31, force_northern=True)
        return (e - e0) / 0.9996, (n - n0) / 0.9996

    for dlat, dlon in [(0.0045, 0.0), (0.0, 0.006), (-0.003, 0.004), (0.0025, -0.0035)]:
        x, y = frame.to_xy(lat + dlat, lon + dlon)
        rx, ry = ref(lat + dlat, lon + dlon)
        assert math.hypot(rx, ry) < 700
        assert (x, y) == pytest.approx((rx, ry), abs=1e-3), (dlat, dlon)
        back = frame.to_latlon(x, y)
        assert back == pytest.approx((lat + dlat, lon + dlon), abs=1e-9)  # 0.1 mm
    x, y = frame.to_xy(lat + 100 / 111_000, lon)  # about 100 m north: the sphere read 100.56 m at the equator
    assert y == pytest.approx(ref(lat + 100 / 111_000, lon)[1], abs=1e-4)


@pytest.mark.parametrize("body", [
    "GPGGA,123519.00,,,,,1,08,1.2,545.4,M,46.9,M,,",  # quality 1 but no position at all
    "GPRMC,123519.00,A,,,,,0.00,84.4,230394,3.1,W",  # status A, no position
    "GPGGA,123519.00,4807.038,,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",  # no N/S
    "GPGGA,123519.00,4807.038,N,01131.000,,1,08,0.9,545.4,M,46.9,M,,",  # no E/W
    "GPGGA,123519.00,9959.000,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",  # latitude 99 degrees 59'
    "GPGGA,123519.00,4807.038,N,18130.000,E,1,08,0.9,545.4,M,46.9,M,,",  # longitude 181 degrees 30'
    "GPRMC,123519.00,A,4807.038,N,01175.000,E,0.00,84.4,230394,3.1,W",  # 75 minutes
])
def test_empty_or_impossible_position_fields_are_not_a_fix(body: str) -> None:
    """pynmea2 reads empty fields as 0.0: a sentence without a position must not put the car at
    0 N 0 E, nor become the frame's origin."""
    part = GPS("unused")
    assert part.update_from(nmea(body)) is None
    assert not part.receiver.fix and part.frame is None and part.receiver.bad == 1
    out = part.update_from(gga(LAT, LON))  # the first real fix becomes the origin
    assert out is not None and out[:4] == pytest.approx((0.0, 0.0, LAT, LON), abs=1e-6)
    assert part.frame.latitude == pytest.approx(LAT, abs=1e-6)
