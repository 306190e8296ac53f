"""Settings of the simulator bridges (Udacity and Donkey simulators).

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from parts.bridges.registry import SIMULATORS
from vehicle.config_checks import Range

# == Simulator bridges ==

# Which simulator a simulator car drives: "builtin" (ours, in this process), "udacity" (the
# Udacity self-driving-car simulator, which connects to us) or "donkey" (the Donkey simulator or
# `vehicle sim serve`, which we connect to). `manage.py drive --sim NAME` overrides it.
SIM_TYPE: Annotated[str, SIMULATORS.choice()] = "builtin"
# Seconds without telemetry from the Udacity or Donkey simulator before its camera counts as
# stale (cam/ok False: the camera watchdog takes the pilot out) and one line says what to check.
SIM_TIMEOUT_S: Annotated[float, Range(0.1, 10, unit="s")] = 1.0
# Address of the Donkey simulator (DonkeyCar's name); it often runs on another machine.
SIM_HOST: str = "127.0.0.1"
# TCP port of the Donkey simulator (9091 unless it was started with --port).
SIM_PORT: Annotated[int, Range(1, 65535)] = 9091
# Seconds a drive keeps trying to reach the Donkey simulator at start (it may still be starting).
SIM_CONNECT_TIMEOUT_S: Annotated[float, Range(0, 3600, lo_open=True, unit="s")] = 10.0
# The Donkey simulator's executable, which a drive then starts itself (DonkeyCar's setting: it runs
# `EXE --port SIM_PORT --host SIM_HOST -logFile logs/unitylog.txt`, waits for the port and ends it
# on exit); None or "remote": a simulator you start yourself, at SIM_HOST:SIM_PORT.
DONKEY_SIM_PATH: str | None = None
# Seconds to wait for a simulator started from DONKEY_SIM_PATH to listen (Unity takes 5-30 s).
DONKEY_SIM_START_TIMEOUT: Annotated[float, Range(1, 600, unit="s")] = 60.0
# Scene the Donkey simulator loads: a gym id (DonkeyCar's setting: donkey-generated-track-v0,
# donkey-warren-track-v0 ...) or a scene name (generated_track, warren, track_5 on `vehicle sim serve`).
DONKEY_GYM_ENV_NAME: str = "donkey-generated-track-v0"
# How the car looks in the Donkey simulator (DonkeyCar's GYM_CONF): body_style (donkey, bare,
# car01, f1, cybertruck), body_rgb, car_name, font_size; racer_name, country, bio, guid for races.
GYM_CONF: dict[str, Any] = {"body_style": "donkey", "body_rgb": (128, 128, 128), "car_name": "car",
                            "font_size": 100}
# |cte| beyond which the Donkey simulator's car is off the track, in the simulator's units
# (gym-donkeycar's max_cte; `vehicle sim serve` reports metres: use half the road width there).
# None: only hits count.
DONKEY_MAX_CTE: Annotated[float | None, Range(0, lo_open=True)] = 8.0
# Interface the Udacity simulator connects to. The simulator connects to 127.0.0.1 only; use
# "0.0.0.0" when it runs on another machine (e.g. Windows, with this in WSL2).
UDACITY_HOST: str = "127.0.0.1"
# Port the Udacity simulator connects to (4567 is built into the simulator).
UDACITY_PORT: Annotated[int, Range(1, 65535)] = 4567
# Decimal separator of steer values: "auto" (the one the simulator's telemetry uses: a
# simulator on a comma-decimal locale parses "0,5"), "." or ",".
UDACITY_DECIMAL: Literal["auto", ".", ","] = "auto"
# Telemetry keys of a research fork of the Udacity simulator to publish as their own memory keys
# (sim/<key in snake case>, e.g. ["sim_time", "crash"]); cte and lapNumber always go to sim/cte
# and sim/lap, all others to the sim/extra dict.
UDACITY_EXTRA_KEYS: list[str] = []
