"""GPS over serial: NMEA 0183 sentences (parsed by pynmea2, checksums checked) -> position in a
local metric frame.

The frame is the local tangent plane of the WGS-84 ellipsoid (east = x, north = y, metres; the
east-north plane of ENU coordinates, the up component dropped) around an origin: the first fix, or
a latitude/longitude the car is given (GPS_ORIGIN), so recorded paths stay valid between runs.
Against UTM (the ``utm`` package, scale k0 removed on a central meridian) points 500 m away land
within a millimetre at the equator, 47 degrees and +-60 degrees (tests/parts/sensors/test_gps.py).

A lost fix is honest: an RMC sentence with status V or a GGA with fix quality 0 makes ``gps/ok``
False and the position None until the next valid fix; so does silence longer than ``max_age``, and
so does a sentence whose position fields are empty or impossible (pynmea2 would read them as 0.0).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from parts.sensors.freshness import SensorPart
from parts.serial_port import pyserial_port
from vehicle.config import check_settings
from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

WGS84_A = 6_378_137.0  # m, semi-major axis of the WGS-84 ellipsoid (what GPS positions refer to)
WGS84_F = 1 / 298.257223563  # flattening
WGS84_E2 = WGS84_F * (2 - WGS84_F)  # first eccentricity squared
KNOTS = 1852.0 / 3600.0  # m/s per knot
#: user equivalent range error, m: horizontal accuracy ~ HDOP x this (a consumer receiver)
UERE = 5.0


class GPSError(VehicleError):
    """The GPS serial port cannot be opened (the message says what to check)."""


def _ecef(latitude: float, longitude: float) -> tuple[float, float, float]:
    """Earth-centred, Earth-fixed metres of a point on the WGS-84 ellipsoid (height 0)."""
    lat, lon = math.radians(latitude), math.radians(longitude)
    n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(lat) ** 2)  # prime-vertical radius of curvature
    return n * math.cos(lat) * math.cos(lon), n * math.cos(lat) * math.sin(lon), n * (1.0 - WGS84_E2) * math.sin(lat)


class LocalFrame:
    """Latitude/longitude (degrees, WGS-84) <-> x east, y north (metres) in the tangent plane at an
    origin (see the module doc)."""

    def __init__(self, latitude: float, longitude: float) -> None:
        if not (-90 <= latitude <= 90 and -180 <= longitude <= 180):
            raise ValueError(f"GPS origin ({latitude}, {longitude}) is not a latitude/longitude in degrees")
        self.latitude, self.longitude = float(latitude), float(longitude)
        lat, lon = math.radians(latitude), math.radians(longitude)
        self._sin_lat, self._cos_lat = math.sin(lat), math.cos(lat)
        self._sin_lon, self._cos_lon = math.sin(lon), math.cos(lon)
        self._origin = _ecef(latitude, longitude)
        w = 1.0 - WGS84_E2 * self._sin_lat ** 2
        # radii of curvature at the origin, m: the first guess of the inverse
        self._meridian = WGS84_A * (1.0 - WGS84_E2) / w ** 1.5
        self._parallel = WGS84_A / math.sqrt(w) * self._cos_lat

    def to_xy(self, latitude: float, longitude: float) -> tuple[float, float]:
        """Metres east and north of the origin."""
        dx, dy, dz = (p - o for p, o in zip(_ecef(latitude, longitude), self._origin, strict=True))
        east = -self._sin_lon * dx + self._cos_lon * dy
        north = -self._sin_lat * (self._cos_lon * dx + self._sin_lon * dy) + self._cos_lat * dz
        return east, north

    def to_latlon(self, x: float, y: float) -> tuple[float, float]:
        """Latitude and longitude of the point on the ellipsoid ``x`` m east and ``y`` m north of the
        origin (a few Newton steps with the origin's radii; well under a millimetre within 10 km)."""
        lat = self.latitude + math.degrees(y / self._meridian)
        lon = self.longitude + math.degrees(x / self._parallel) if self._parallel > 1e-3 else self.longitude
        for _ in range(4):
            ex, ey = self.to_xy(lat, lon)
            lat += math.degrees((y - ey) / self._meridian)
            if self._parallel > 1e-3:  # at a pole every longitude is the origin
                lon += math.degrees((x - ex) / self._parallel)
        return lat, lon


class NmeaPosition:
    """The receiver's state from NMEA sentences (GGA, RMC): fix, latitude, longitude, HDOP, speed.

    :meth:`feed` takes one sentence (str or bytes, with or without the line end) and returns True
    when it changed the position or the fix. Sentences with a bad or missing checksum are counted
    in :attr:`bad` and ignored.
    """

    def __init__(self) -> None:
        self.fix = False
        self.latitude: float | None = None
        self.longitude: float | None = None
        self.hdop: float | None = None
        self.speed: float | None = None  # m/s over ground (RMC)
        self.bad = 0  # sentences with a bad or missing checksum, or unparsable
        self.sentences = 0  # sentences parsed

    def feed(self, sentence: str | bytes) -> bool:
        """Parse one sentence; True when it was a valid GGA or RMC."""
        import pynmea2  # noqa: PLC0415 - imported when the part starts

        if isinstance(sentence, bytes):
            sentence = sentence.decode("ascii", errors="replace")
        sentence = sentence.strip()
        if not sentence.startswith("$"):
            return False
        try:
            msg = pynmea2.parse(sentence, check=True)
        except (pynmea2.ParseError, ValueError, AttributeError):  # bad checksum, truncated line, noise
            self.bad += 1
            return False
        self.sentences += 1
        kind = getattr(msg, "sentence_type", "")
        try:
            if kind == "GGA":
                self.fix = int(msg.gps_qual or 0) > 0
                self.hdop = float(msg.horizontal_dil) if msg.horizontal_dil else None
            elif kind == "RMC":
                self.fix = msg.status == "A"
                self.speed = float(msg.spd_over_grnd) * KNOTS if msg.spd_over_grnd not in (None, "") else None
            else:
                return False
            if self.fix:  # pynmea2 reads empty fields as 0.0: parse and check them here
                self.latitude = _coordinate(msg.lat, msg.lat_dir, "NS", 90)
                self.longitude = _coordinate(msg.lon, msg.lon_dir, "EW", 180)
        except (TypeError, ValueError) as exc:  # an empty or impossible field although the fix says valid
            logger.debug("GPS: %s: not a fix (%s)", sentence, exc)
            self.bad += 1
            self.fix = False
            return True
        return True


def _coordinate(value: str | None, direction: str | None, hemispheres: str, limit: int) -> float:
    """Degrees of an NMEA ``(d)ddmm.mmmm`` field and its hemisphere letter (``hemispheres``: the
    positive one first); ValueError when either is empty or the angle is impossible."""
    if not value or direction not in tuple(hemispheres):
        raise ValueError(f"position field {value!r} {direction!r} is empty")
    number = float(value)
    degrees, minutes = divmod(number, 100.0)
    if not (number >= 0 and minutes < 60.0 and degrees + minutes / 60.0 <= limit):
        raise ValueError(f"position field {value!r} is not an angle up to {limit} degrees")
    angle = degrees + minutes / 60.0
    return angle if direction == hemispheres[0] else -angle


class GPS(SensorPart):
    """Part: ``gps/x, gps/y`` (m, local frame), ``gps/latitude, gps/longitude`` (degrees),
    ``gps/accuracy`` (m, HDOP x 5 m; None before a GGA), ``gps/speed`` (m/s over ground, from RMC)
    and ``gps/ok`` (a valid fix, fresh). Add it threaded: it blocks on the serial line.

    Args:
        port: serial device (GPS_SERIAL) or pyserial URL.
        baudrate: GPS_SERIAL_BAUDRATE.
        origin: (latitude, longitude) of the frame's origin; None = the first fix.
        max_age: seconds without a valid fix sentence after which the values read None.
        serial_factory: ``factory(port, baudrate, timeout)`` -> pyserial-like (tests: a pty).
        nmea_path: if set, every sentence is appended to this file with its time (GPS_NMEA_PATH).
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("gps/x", "gps/y", "gps/latitude", "gps/longitude", "gps/accuracy",
                                          "gps/speed", "gps/ok")
    RECORDED: ClassVar[Mapping[str, str]] = {**dict.fromkeys(OUTPUTS[:5], "float"), "gps/ok": "boolean"}

    def __init__(self, port: str, baudrate: int = 9600, *, origin: tuple[float, float] | None = None,
                 max_age: float = 2.0, serial_factory: Callable[..., Any] | None = None,
                 nmea_path: str | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        check_settings(GPS_SERIAL_BAUDRATE=baudrate, GPS_MAX_AGE_S=max_age, GPS_ORIGIN=origin)
        super().__init__(max_age, clock)
        self.port, self.baudrate = port, int(baudrate)
        self.frame = None if origin is None else LocalFrame(*origin)
        self.receiver = NmeaPosition()
        self._factory = serial_factory
        self._serial: Any = None
        self.nmea_path = nmea_path
        self._log: Any = None

    @classmethod
    def from_config(cls, cfg: Any, clock: Callable[[], float] | None = None) -> GPS:
        """GPS_SERIAL, GPS_SERIAL_BAUDRATE, GPS_ORIGIN, GPS_MAX_AGE_S, GPS_NMEA_PATH."""
        path = str(cfg.path("GPS_NMEA_PATH")) if cfg.GPS_NMEA_PATH else None
        origin = tuple(cfg.GPS_ORIGIN) if cfg.GPS_ORIGIN is not None else None
        return cls(cfg.GPS_SERIAL, cfg.GPS_SERIAL_BAUDRATE, origin=origin,  # type: ignore[arg-type]
                   max_age=cfg.GPS_MAX_AGE_S, nmea_path=path, clock=clock or time.monotonic)

    def open(self) -> None:
        factory = self._factory or pyserial_port
        try:
            self._serial = factory(self.port, self.baudrate, 0.5)
        except (OSError, ValueError) as exc:
            raise GPSError(f"GPS serial port {self.port}: {exc} (check GPS_SERIAL, GPS_SERIAL_BAUDRATE and that "
                           "your user is in the 'dialout' group)") from exc
        if self.nmea_path:
            self._log = open(self.nmea_path, "a", encoding="ascii", errors="replace")  # noqa: SIM115 - kept open

    def read(self) -> tuple[object, ...] | None:
        """Read one line; the values after a valid fix sentence, None otherwise (also on a lost fix)."""
        line = self._serial.readline() if self._serial is not None else b""
        if not line:
            return None
        if self._log is not None:
            self._log.write(f"{time.time():.3f},{line.decode('ascii', errors='replace').strip()}\n")
        return self.update_from(line)

    def update_from(self, sentence: str | bytes) -> tuple[object, ...] | None:
        """Feed one sentence; the part's values if the receiver has a fix after it."""
        r = self.receiver
        if not r.feed(sentence):
            return None
        if not r.fix or r.latitude is None or r.longitude is None:
            self.freshness.last = None  # a lost fix is stale at once, not after max_age
            with self._lock:
                self._latest = None
            return None
        if self.frame is None:
            self.frame = LocalFrame(r.latitude, r.longitude)
            logger.info("GPS: local frame origin at the first fix %.7f, %.7f", r.latitude, r.longitude)
        x, y = self.frame.to_xy(r.latitude, r.longitude)
        accuracy = None if r.hdop is None else r.hdop * UERE
        return x, y, r.latitude, r.longitude, accuracy, r.speed

    def close(self) -> None:
        if self._serial is not None:
            self._serial.close()
            self._serial = None
        if self._log is not None:
            self._log.close()
            self._log = None

    def describe(self, values: tuple[object, ...]) -> tuple[bool, str]:
        """The fix and its place in the local frame; without one, whether sentences arrive at all."""
        where, r = self.where(), self.receiver
        if not values or values[-1] is not True:
            if r.sentences:
                return False, (f"{where}: no fix yet ({r.sentences} sentences, {r.bad} bad checksums): "
                               "give it open sky and a minute")
            return False, (f"{where}: no NMEA sentences ({r.bad} unreadable lines): check GPS_SERIAL_BAUDRATE "
                           "and the wiring (receiver TX to the Pi's RX)")
        x, y, lat, lon, accuracy = values[:5]
        acc = f"±{accuracy:.1f} m" if accuracy is not None else "accuracy unknown"
        return True, f"{where}: fix {lat:.7f}, {lon:.7f} ({acc}); local x {x:.2f} m, y {y:.2f} m"


class SpeedFromGPS:
    """Part: ``gps/speed`` -> ``enc/speed`` for a car whose only speed source is its GPS (no encoder,
    no VESC), so the speed limit and the page use it; None while the fix is lost or stale."""

    INPUTS: ClassVar[tuple[str, ...]] = ("gps/speed", "gps/ok")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)

    def run(self, speed: float | None, ok: bool | None) -> float | None:
        """The GPS's speed over ground while its fix is valid."""
        return speed if ok else None
