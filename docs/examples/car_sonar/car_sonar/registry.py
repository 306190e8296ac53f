"""The sonar kind: its table of types, added to the car by HAVE_SONAR."""

from __future__ import annotations

from vehicle.registry import Registry

#: rangefinders (SONAR_TYPE); `vehicle hw check --only sonar` checks them
SONARS = Registry("SONAR_TYPE", {"MAXSONAR": "car_sonar.sonar:MaxSonar"}, enabled_by="HAVE_SONAR",
                  kind="sonar")
#: the kinds of sensor this package adds: vehicle-rc builds, records and checks them
SENSOR_TABLES = (SONARS,)
