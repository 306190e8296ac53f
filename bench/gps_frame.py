"""Accuracy of the GPS part's local frame (parts.sensors.gps.LocalFrame) against UTM.

For origins on zone 31's central meridian (3 E, where UTM's grid north is true north and its scale
is K0 = 0.9996) at several latitudes, points on a grid up to ``--radius`` metres from the origin are
placed by the utm package (transverse Mercator on WGS-84) at (E0 + K0 x, N0 + K0 y) and read back
through the frame; printed: the largest distance between (x, y) and what the frame reads, for the
frame and, as the baseline in the same run, for the spherical equirectangular frame it replaced
(mean Earth radius 6 371 008.8 m). The origin is utm's own inverse of (E0, N0), so the bias between
utm's forward and inverse series (up to 0.6 mm at 60 degrees) is not counted against either frame.

Usage: .venv/bin/python bench/gps_frame.py [--radius 500]   (needs the dev extra's utm)
"""

from __future__ import annotations

import argparse
import math

import utm

from parts.sensors.gps import LocalFrame

K0 = 0.9996
SPHERE = 6_371_008.8  # m, the mean Earth radius of the spherical frame


def spherical_xy(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    """The replaced frame: radians of longitude x R cos(lat0), radians of latitude x R."""
    return (math.radians(lon - lon0) * SPHERE * math.cos(math.radians(lat0)), math.radians(lat - lat0) * SPHERE)


def worst(latitude: float, radius: float) -> tuple[float, float]:
    """Largest error (m) of LocalFrame and of the spherical frame over a grid within ``radius``."""
    northern = latitude >= 0
    e0, n0, _, _ = utm.from_latlon(latitude, 3.0, force_zone_number=31, force_northern=northern)
    lat0, lon0 = map(float, utm.to_latlon(e0, n0, 31, northern=northern, strict=False))
    frame = LocalFrame(lat0, lon0)
    ours = sphere = 0.0
    steps = [radius * k / 5 for k in range(-5, 6)]
    for x in steps:
        for y in steps:
            if math.hypot(x, y) > radius:
                continue
            lat, lon = map(float, utm.to_latlon(e0 + K0 * x, n0 + K0 * y, 31, northern=northern, strict=False))
            ours = max(ours, math.dist(frame.to_xy(lat, lon), (x, y)))
            sphere = max(sphere, math.dist(spherical_xy(lat0, lon0, lat, lon), (x, y)))
    return ours, sphere


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--radius", type=float, default=500.0, help="metres from the origin (default 500)")
    args = parser.parse_args()
    print(f"largest error within {args.radius:g} m of the origin, against UTM (utm {utm.__version__})")
    print(f"{'latitude':>9}  {'LocalFrame (WGS-84 tangent plane)':>34}  {'spherical frame':>16}")
    for latitude in (0.0, 30.0, 47.0, 60.0, -60.0):
        ours, sphere = worst(latitude, args.radius)
        print(f"{latitude:>9.0f}  {ours * 1000:>31.4f} mm  {sphere:>14.3f} m")


if __name__ == "__main__":
    main()
