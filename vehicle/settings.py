"""The kernel's settings: where a car keeps its files, and the drive loop.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated

from vehicle.config_checks import Range

# == Paths ==

# Folder of the car. Set by the loader to the folder that holds myconfig.py.
CAR_PATH: str = "."
# Where tubs are recorded and looked up, relative to CAR_PATH unless absolute.
DATA_PATH: str = "data"
# Where trained models live, relative to CAR_PATH unless absolute.
MODELS_PATH: str = "models"
# Where drive logs go, relative to CAR_PATH unless absolute.
LOGS_PATH: str = "logs"

# == Vehicle loop ==

# Rate of the drive loop in Hz. Every part runs once per loop.
DRIVE_LOOP_HZ: Annotated[int, Range(1, 1000, unit="Hz")] = 20
# Stop after this many loops (None = run until stopped). Handy for scripted runs.
MAX_LOOPS: Annotated[int | None, Range(1)] = None
