"""Settings of the trainer console.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated

from vehicle.config_checks import Range

# == Trainer console ==

# The trainer console (`vehicle console`, `manage.py console`): datasets, training, models and the
# leaderboard in a browser. Interface it listens on: "127.0.0.1" = this machine only; "0.0.0.0" =
# every network interface, which then requires the pairing token (WEB_TOKEN's rules).
CONSOLE_HOST: str = "127.0.0.1"
# TCP port of the console: http://localhost:8890/
CONSOLE_PORT: Annotated[int, Range(0, 65535, note="0 picks a free port")] = 8890
