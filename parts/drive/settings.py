"""Settings of the drive logic: modes, automatic recording, throttle filter, behaviours and the obstacle stop.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Annotated, Any

from vehicle.config_checks import Length, Problem, Range, Rule
from vehicle.keys import Mode

# == Drive modes ==

# Mode at start: "user" (human drives), "local_angle" (pilot steers), "local" (pilot drives).
# The web page, the gamepad and the drive-mode part all start from it (DonkeyCar: WEB_INIT_MODE);
# `manage.py drive --mode MODE` sets it for one drive.
DEFAULT_MODE: Mode = "user"
# Pilot throttle is multiplied by this in "local" mode (1.0 = as predicted).
AI_THROTTLE_MULT: Annotated[float, Range(0, 2)] = 1.0

# == Drive logic ==

# Record while the throttle is off zero (beyond JOYSTICK_DEADZONE) and stop when it is released, so
# tubs hold no standing still; the record button is then ignored.
AUTO_RECORD_ON_THROTTLE: bool = True
# Keep recording while a pilot drives (local_angle, local). Off by default: a pilot's own driving
# teaches the next pilot its mistakes.
RECORD_DURING_AI: bool = False
# DonkeyCar's ThrottleFilter on the final throttle: a held reverse becomes reverse, 0, reverse so a
# car ESC brakes, then backs up. Off for crawler ESCs; skipped when the drivetrain's
# ESC_REVERSE_MODE = "double_tap" does the same.
USE_THROTTLE_FILTER: bool = True

# == Correction mode ==

# Correction mode (DAgger with a person as the expert, docs/dagger.md): while a pilot drives
# ("local" or "local_angle", entered from the web page or the gamepad's mode button as usual), the
# person's steering (and, in "local", throttle) overrides the pilot's while the stick is moved, and
# only those frames are recorded, labelled with what the car did and marked user/correction.
CORRECTION_MODE: bool = False
# Stick travel (fraction of full) beyond which the person's steering or throttle overrides the pilot.
CORRECTION_DEADZONE: Annotated[float, Range(0, 0.99)] = 0.05

# == Behaviour ==

# Drive with behaviour states (e.g. which lane to keep): adds behavior/state, behavior/label and
# behavior/one_hot_state_array to the memory, and every tub records them (as DonkeyCar does); the
# gamepad's behaviour buttons and the web page's "change lane" button step through BEHAVIOR_LIST.
TRAIN_BEHAVIORS: bool = False
# Names of the behaviours in order; the one-hot array has one entry per name.
BEHAVIOR_LIST: Annotated[list[str], Length(min=1)] = ["Left_Lane", "Right_Lane"]
# Behaviour active at start (index into BEHAVIOR_LIST).
BEHAVIOR_INITIAL: Annotated[int, Range(0, note="an index of BEHAVIOR_LIST")] = 0


def _behaviors(v: Mapping[str, Any]) -> Iterator[Problem]:
    n, initial = len(v["BEHAVIOR_LIST"]), v["BEHAVIOR_INITIAL"]
    if n and not 0 <= initial < n:
        yield Problem("BEHAVIOR_INITIAL", f"BEHAVIOR_INITIAL = {initial} is not an index of "
                      f"BEHAVIOR_LIST ({n} behaviours); valid: 0 to {n - 1}", ("BEHAVIOR_LIST",))


# == Obstacle stop ==

# Brake when the LiDAR (or the simulated one) sees something closer than OBSTACLE_STOP_DISTANCE
# ahead, in every drive mode (the final throttle is cut after drive mode and speed limit).
OBSTACLE_STOP: bool = False
# Where the car should stand in front of an obstacle, metres from the LiDAR; the stop starts
# earlier by the stopping distance at the measured speed (OBSTACLE_STOP_DECEL).
OBSTACLE_STOP_DISTANCE: Annotated[float, Range(0.05, 20, unit="m")] = 0.5
# Half width of the watched cone ahead, degrees either side of straight ahead.
OBSTACLE_STOP_ANGLE: Annotated[float, Range(1, 180, unit="degrees")] = 20.0
# Brake command while the car still rolls (0 = cut to neutral only; a hobby ESC brakes on a
# negative throttle while moving).
OBSTACLE_STOP_BRAKE: Annotated[float, Range(0, 1)] = 0.5
# Deceleration the car reaches under that brake, m/s^2; be modest (a wet floor halves it).
OBSTACLE_STOP_DECEL: Annotated[float, Range(0.1, 20, unit="m/s^2")] = 3.0
# A stale LiDAR (no turn within LIDAR_MAX_AGE_S), or one without a fresh reading somewhere in the
# cone ahead, stops the car too: it cannot see.
OBSTACLE_STOP_WHEN_BLIND: bool = True

#: rules across this module's settings, run after every setting passed its own range
RULES: tuple[Rule, ...] = (_behaviors,)
