"""The sensor family's tables: one per kind of sensor, each from type name to ``"module:Class"``.

A car has any number of sensors, so every kind's table names the bool setting that adds it
(``enabled_by``, DonkeyCar's ``HAVE_IMU``) and the setting that picks its type (``IMU_SENSOR``);
:func:`vehicle.app.assembly.sensors.add_sensors` adds, for every table the car enables, the part
its type setting picks, built by ``Class.from_config(cfg, clock=...)``. A new kind of sensor is
one ``Registry`` in :data:`SENSOR_TABLES`; a new type of a kind, one row of its table::

    IMUS = Registry("IMU_SENSOR", {"mpu6050": "parts.sensors.imu:MPU6050"}, enabled_by="HAVE_IMU")
    SENSOR_TABLES = (IMUS,)
"""

from __future__ import annotations

from vehicle.registry import Registry

#: every kind of sensor, in the order their parts join the loop (before the pilot and drive logic)
SENSOR_TABLES: tuple[Registry, ...] = ()
