"""Assembly of the sensors: for each kind the car enables, the part its type setting picks."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from vehicle.config import Config

logger = logging.getLogger(__name__)


def add_sensors(V: Any, cfg: Config, tables: Sequence[Any] | None = None) -> list[Any]:
    """Add one part per enabled sensor kind (:func:`parts.sensors.registry.sensor_tables`: the
    project's and those of installed packages of parts; or ``tables``), each built by its class's
    ``from_config(cfg, clock=...)`` and opened now (a part's ``probe()``: a missing device stops the
    assembly with its one-line reason); threaded when the part has ``run_threaded``; then the
    odometry (:func:`add_odometry`). Returns the parts added.

    Raises:
        VehicleError: a sensor's device is missing or answers another protocol (EncoderError,
            IMUError, GPSError, LidarError: one line naming the device and what to check).
    """
    if tables is None:
        from parts.sensors.registry import sensor_tables

        tables = sensor_tables()
    clock = getattr(getattr(V, "clock", None), "now", None)
    added = []
    for table in tables:
        if not table.enabled(cfg):
            continue
        part = table.from_config(cfg, clock=clock)
        probe = getattr(part, "probe", None)
        if probe is not None:  # open the device now: a missing one is an error before the loop starts
            probe()
        V.add(part, threaded=hasattr(part, "run_threaded"))
        logger.info("sensor: %s = %s", table.setting, cfg[table.setting])
        added.append(part)
    added += add_odometry(V, cfg)
    return added


def add_odometry(V: Any, cfg: Config) -> list[Any]:
    """Add the odometry after the encoder (real or simulated): ticks -> ``enc/distance``,
    ``enc/speed`` and the pose ``pos/*``, ``vel/*`` (bicycle model, or the unicycle model with
    HAVE_ODOM_2). Without an encoder but with a GPS, the GPS's speed over ground becomes
    ``enc/speed``. Returns the parts added (none when the car has neither)."""
    from parts.sensors.gps import SpeedFromGPS
    from parts.sensors.odometry import BicyclePose, DifferentialOdometer, Odometer, UnicyclePose

    parts: list[Any] = []
    if V.produces("enc/left/ticks") and V.produces("enc/right/ticks"):
        parts = [DifferentialOdometer.from_config(cfg), UnicyclePose.from_config(cfg)]
    elif V.produces("enc/ticks"):
        parts = [Odometer.from_config(cfg), BicyclePose.from_config(cfg)]
    elif V.produces("gps/speed") and not V.produces("enc/speed"):
        parts = [SpeedFromGPS()]
    for part in parts:
        V.add(part)
    return parts
