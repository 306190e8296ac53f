"""Settings of the Pilot part: runtime backend and speed control.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from vehicle.config_checks import Range

# == Pilot ==

# Runtime that drives a .pt model: "auto" runs NAME.onnx next to it when onnxruntime is installed
# and that export was made from this very .pt (same SHA-256; `vehicle models export NAME`), else
# PyTorch; "torch", "onnx" and "torchscript" force one (a missing or stale export is an error);
# "onnx-int8" runs the int8 export NAME.int8.onnx (`vehicle models export NAME --format onnx-int8`;
# check its speed and steering against the float export with bench/int8.py first).
PILOT_BACKEND: Literal["auto", "torch", "onnx", "onnx-int8", "torchscript"] = "auto"
# ONNX Runtime intra-op threads for the pilot. 1: batch-1 inference gains little from more, and
# the drive loop's other parts need the other cores.
PILOT_ONNX_THREADS: Annotated[int, Range(0, 256)] = 1
# Speed control that replaces the pilot's throttle while PILOT_SPEED_LIMIT is set: "off", "pi"
# (PI controller with PILOT_SPEED_LIMIT as target speed, as Udacity's drive.py) or "limit"
# (throttle = 1 - speed / limit, Track Driver AI's driver). The web page's speed limit is another
# thing: a cap on the car's speed in every mode, whatever this says.
PILOT_SPEED_CONTROL: Literal["off", "pi", "limit"] = "off"
# Target speed of PILOT_SPEED_CONTROL in m/s; None = no speed control, the model's throttle drives.
PILOT_SPEED_LIMIT: Annotated[float | None, Range(0, 100, lo_open=True, unit="m/s")] = None
# Memory key of the measured speed in m/s (speed control and the web page's speed limit); None =
# sim/speed when the simulator is in the vehicle, else enc/speed.
PILOT_SPEED_KEY: str | None = None
# Proportional gain of the PI speed controller (and of the web page's speed limit): throttle per
# m/s of speed error.
PILOT_SPEED_KP: Annotated[float, Range(0, 100)] = 0.3
# Integral gain of the PI speed controller (and of the speed limit): throttle per m/s of error per
# second.
PILOT_SPEED_KI: Annotated[float, Range(0, 100)] = 0.6
# Highest throttle the speed controller commands (lower it for a first run on a real car).
PILOT_SPEED_MAX_THROTTLE: Annotated[float, Range(0, 1, lo_open=True)] = 1.0
