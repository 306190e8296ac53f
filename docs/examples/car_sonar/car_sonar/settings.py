"""Settings of the sonar (declared as vehicle.config reads them: comments above each setting)."""

from __future__ import annotations

from typing import Annotated

from car_sonar.registry import SONARS
from vehicle.config_checks import Range

# == Sonar ==

# An ultrasonic rangefinder is fitted: sonar/distance, recorded with every frame.
HAVE_SONAR: bool = False
# Which rangefinder: a type of the sonar table.
SONAR_TYPE: Annotated[str, SONARS.choice()] = "MAXSONAR"
# Serial port of the rangefinder's TX pin (9600 baud, 8N1, "R" + 4 digits in mm + CR).
SONAR_SERIAL: str = "/dev/ttyUSB1"
# Seconds without a reading after which sonar/distance reads None (it reports at ~10 Hz).
SONAR_MAX_AGE_S: Annotated[float, Range(0.1, 5, unit="s")] = 0.5
