"""Settings of the gamepad.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from vehicle.config_checks import Range

# == Gamepad ==

# Gamepad layout (which stick steers, which button does what): "ps3", "ps4", "xbox" (Xbox One/360/
# Series pad over USB, or Bluetooth with xpadneo), "xbox_bt" (Xbox One over Bluetooth with
# hid-generic), "f710" (Logitech F710 in X mode), "generic" (any pad: the left stick steers and
# drives), "pygame" (any pad SDL knows, read through pygame), or "custom" (the mapping file
# JOYSTICK_MAPPING_PATH written by `vehicle createjs`).
CONTROLLER_TYPE: Literal["ps3", "ps4", "xbox", "xbox_bt", "f710", "generic", "pygame", "custom"] = "xbox"
# Drive with the gamepad by default (True) rather than only the web page.
USE_JOYSTICK_AS_DEFAULT: bool = False
# Linux joystick device read for every CONTROLLER_TYPE but "pygame". A FIFO, or a file of recorded
# 8-byte js_event records (replayed at their recorded pace), works too: bench cars and tests drive
# that way without a pad.
JOYSTICK_DEVICE_FILE: str = "/dev/input/js0"
# "pygame": index of the pad (0 = the first SDL finds).
JOYSTICK_INDEX: Annotated[int, Range(0)] = 0
# CONTROLLER_TYPE "custom": mapping file written by `vehicle createjs` (relative to CAR_PATH).
JOYSTICK_MAPPING_PATH: str = "joystick_mapping.json"
# Throttle at full stick (fraction of full throttle); the throttle up/down buttons change it while
# driving.
JOYSTICK_MAX_THROTTLE: Annotated[float, Range(0, 1, lo_open=True)] = 0.5
# Change of JOYSTICK_MAX_THROTTLE per press of a throttle up/down button.
JOYSTICK_THROTTLE_STEP: Annotated[float, Range(0, 0.5, lo_open=True)] = 0.05
# Steering = stick position x this (below 1 for gentler steering).
JOYSTICK_STEERING_SCALE: Annotated[float, Range(-1, 1)] = 1.0
# -1.0: pushing the throttle stick up (negative on Linux) drives forward; 1.0 swaps it.
JOYSTICK_THROTTLE_DIR: Literal[-1.0, 1.0] = -1.0
# Stick travel (fraction of full) read as zero; also the throttle above which AUTO_RECORD_ON_THROTTLE
# records.
JOYSTICK_DEADZONE: Annotated[float, Range(0, 1, hi_open=True)] = 0.01
# With the throttle off zero, no gamepad event for this many seconds means the link is dead (a
# Bluetooth drop that the driver does not report): throttle 0 and user mode until the pad talks
# again and its throttle is released. Constant throttle also stops after this long without any
# input (a dead-man rule). None = off.
JOYSTICK_SILENCE_TIMEOUT_S: Annotated[float | None, Range(
    0.2, 5, unit="s", note="None switches it off (not recommended: a dropped Bluetooth link then keeps the "
                           "throttle)")] = 2.0
# Seconds between attempts to open a missing or lost gamepad.
JOYSTICK_RETRY_S: Annotated[float, Range(0.1, 3600, unit="s")] = 3.0
# Change the layout's bindings: action -> control name, e.g. {"estop": "circle"}; "" unbinds an
# action. Actions: steering, throttle, throttle_forward, throttle_reverse (triggers), mode_toggle,
# record_toggle, erase_records, estop, throttle_up, throttle_down, constant_throttle,
# behavior_next, behavior_prev. Control names are in docs/controllers.md.
JOYSTICK_BINDINGS: dict[str, str] = {}
# Records deleted per press of the erase button (the tub wiper acts on each tub/erase rising edge).
ERASE_LAST_N_RECORDS: Annotated[int, Range(1)] = 100
