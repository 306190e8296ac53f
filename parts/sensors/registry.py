"""The sensor family's tables: one per kind of sensor, each from type name to ``"module:Class"``.

A car has any number of sensors, so every kind's table names the bool setting that adds it
(``enabled_by``, DonkeyCar's ``HAVE_IMU``) and the setting that picks its type (``IMU_SENSOR``);
:func:`vehicle.app.assembly.sensors.add_sensors` adds, for every table the car enables, the part
its type setting picks, built by ``Class.from_config(cfg, clock=...)``. A new kind of sensor is
one ``Registry`` in :data:`SENSOR_TABLES` (or, from an installed package of parts, in the
``SENSOR_TABLES`` of its own ``registry.py``: :func:`sensor_tables` finds it); a new type of a kind,
one row of its table. What a kind's parts record and how ``vehicle hw check`` describes them, the
part classes say (``RECORDED``, ``where()``, ``describe()``).
"""

from __future__ import annotations

from vehicle.discovery import family_declarations
from vehicle.registry import Registry

#: wheel encoders (ENCODER_TYPE): ticks -> enc/ticks; the odometer is added after them
ENCODERS = Registry("ENCODER_TYPE", {
    "GPIO": "parts.sensors.encoder:Encoder",
    "ARDUINO": "parts.sensors.encoder:Encoder",
    "arduino": "parts.sensors.encoder:Encoder",  # DonkeyCar's spelling
}, enabled_by="HAVE_ODOM", kind="odom")
#: inertial measurement units (IMU_SENSOR)
IMUS = Registry("IMU_SENSOR", {
    "mpu6050": "parts.sensors.imu:IMU",
    "mpu9250": "parts.sensors.imu:IMU",
}, enabled_by="HAVE_IMU", kind="imu")
#: GPS receivers (GPS_TYPE)
GPSES = Registry("GPS_TYPE", {"NMEA": "parts.sensors.gps:GPS"}, enabled_by="HAVE_GPS", kind="gps")
#: 2-D LiDARs (LIDAR_TYPE)
LIDARS = Registry("LIDAR_TYPE", {"RP": "parts.sensors.lidar:RPLidar"}, enabled_by="USE_LIDAR", kind="lidar")

#: every kind of sensor, in the order their parts join the loop (before the pilot and drive logic)
SENSOR_TABLES: tuple[Registry, ...] = (ENCODERS, IMUS, GPSES, LIDARS)


def sensor_tables() -> tuple[Registry, ...]:
    """Every kind of sensor: :data:`SENSOR_TABLES`, then those other families declare in the
    ``SENSOR_TABLES`` of their ``registry.py`` (an installed package of parts), in discovery order."""
    tables = list(SENSOR_TABLES)
    for module, declared in family_declarations("registry.py", "SENSOR_TABLES"):
        if module != __name__:
            tables += declared
    return tuple(tables)
