"""Settings of path follow: the path file, recording, the follower (pure pursuit + PID on the
cross-track error), its speed, the localiser and the gamepad buttons.

Names follow DonkeyCar's cfg_path_follow.py where it has them (PATH_FILENAME, PATH_MIN_DIST,
PATH_SEARCH_LENGTH, PATH_LOOK_AHEAD, PATH_LOOK_BEHIND, PID_P/I/D, PID_THROTTLE,
USE_CONSTANT_THROTTLE, the *_BTN names). Declared as the config loader reads them (see
:mod:`vehicle.config`).
"""

from __future__ import annotations

from typing import Annotated, Literal

from vehicle.config_checks import Range

# == Path follow ==

# The path file, a CSV of x, y (m) and speed (m/s) per point, relative to the car folder
# (PATH_FILENAME). The save button writes it, the load button reads it.
PATH_FILENAME: str = "donkey_path.csv"
# While recording, a point is added each time the car has moved this far from the last one, metres
# (PATH_MIN_DIST).
PATH_MIN_DIST: Annotated[float, Range(0.01, 10, unit="m")] = 0.2
# Path points searched for the nearest one, starting from the last nearest point (PATH_SEARCH_LENGTH);
# None = the whole path every loop (slower on long paths, and a figure-eight's crossing may confuse it).
PATH_SEARCH_LENGTH: Annotated[int | None, Range(2, 1_000_000, note="None: the whole path")] = None
# Points ahead of the nearest point that define the path's local direction for the cross-track
# error (PATH_LOOK_AHEAD).
PATH_LOOK_AHEAD: Annotated[int, Range(1, 1000)] = 1
# Points behind the nearest point that define the path's local direction (PATH_LOOK_BEHIND).
PATH_LOOK_BEHIND: Annotated[int, Range(0, 1000)] = 1
# Distance ahead along the path of pure pursuit's target point, metres; 0 = no pure pursuit (steer
# from the PID on the cross-track error alone, as DonkeyCar does). Longer is smoother, shorter
# follows tight curves closer.
PATH_LOOK_AHEAD_DIST: Annotated[float, Range(0, 20, unit="m")] = 0.5
# Proportional gain of the PID on the cross-track error: steering per metre off the path (PID_P).
# Left of the path steers right. DonkeyCar's negative gains come from its opposite sign of the
# error: use the magnitude here.
PID_P: Annotated[float, Range(0, 100, unit="steering/m")] = 0.5
# Integral gain: steering per metre-second off the path (PID_I); 0 = off.
PID_I: Annotated[float, Range(0, 100, unit="steering/(m s)")] = 0.0
# Derivative gain: steering per m/s of change of the cross-track error (PID_D).
PID_D: Annotated[float, Range(0, 100, unit="steering s/m")] = 0.2
# Drive at this constant throttle instead of the recorded speed (with USE_CONSTANT_THROTTLE).
PID_THROTTLE: Annotated[float, Range(0, 1)] = 0.3
# True: drive at PID_THROTTLE; False: follow the speed recorded with the path (a PI controller on
# the measured speed, PILOT_SPEED_KP / PILOT_SPEED_KI).
USE_CONSTANT_THROTTLE: bool = False
# Factor on the recorded speed when following (0.5 = half the speed it was driven at).
PATH_SPEED_SCALE: Annotated[float, Range(0.05, 5)] = 1.0
# Highest target speed when following, m/s; None = no cap.
PATH_MAX_SPEED: Annotated[float | None, Range(0.05, 50, unit="m/s", note="None: no cap")] = None
# Lowest target speed when following, m/s: a point recorded while standing still is not a reason
# to stop half-way.
PATH_MIN_SPEED: Annotated[float, Range(0, 50, unit="m/s")] = 0.3
# Drive the path round and round (a closed lap) instead of stopping at its end; None = when its
# end lies within PATH_LOOP_CLOSE_DIST of its start.
PATH_LOOP: bool | None = None
# A path whose end is this close to its start is a closed lap (with PATH_LOOP = None), metres.
PATH_LOOP_CLOSE_DIST: Annotated[float, Range(0, 100, unit="m")] = 1.0

# == Localisation ==

# Where the pose comes from: "odometry" (wheel encoder, pos/*: frame of the start or of the last
# reset origin, x forward, y left), "gps" (gps/x, gps/y: x east, y north around the GPS origin, the
# heading from the course over ground) or "fused" (odometry corrected by GPS fixes, a Kalman filter,
# in the odometry's frame). A path is valid with the localiser that recorded it; odometry and
# fused share a frame.
PATH_LOCALIZER: Literal["odometry", "gps", "fused"] = "odometry"
# Odometry's position error per metre driven, 1-sigma (wheel slip, MM_PER_TICK and heading error):
# loc/std of odometry grows by this much per metre, and the fused filter trusts it accordingly.
LOC_ODOM_DRIFT: Annotated[float, Range(0.001, 1, unit="m/m")] = 0.02
# GPS localiser: the heading is the direction between two fixes at least this far apart, metres.
LOC_GPS_HEADING_DIST: Annotated[float, Range(0.05, 50, unit="m")] = 0.5
# Seconds over which a GPS's error wanders (its correlation time; consumer receivers: tens of
# seconds). The fused filter estimates this slow error instead of following it.
LOC_GPS_TAU: Annotated[float, Range(0.1, 3600, unit="s")] = 10.0
# Fused localiser: metres driven over which the GPS frame (rotation, offset) is fitted to the
# odometry's frame before GPS fixes correct the pose; longer is more precise, the odometry drifts
# meanwhile.
LOC_FUSE_FIT_DIST: Annotated[float, Range(1, 1000, unit="m")] = 8.0
# The pose is not trusted (loc/ok False, path state "lost", throttle 0) when its 1-sigma
# uncertainty exceeds this, metres; None = only when its sources are stale.
LOC_MAX_STD: Annotated[float | None, Range(0.01, 1000, unit="m", note="None: no limit")] = None

# == Path buttons ==

# Gamepad buttons of the path commands, by the layout's button names (docs/controllers.md);
# PS-style names (cross, circle, square, triangle) are translated to the same position on other
# pads (xbox a, b, x, y); None = no button. The driver page has the same buttons.
# Toggle path recording (TOGGLE_RECORDING_BTN; the pad's record button by default).
TOGGLE_RECORDING_BTN: str | None = "circle"
# Save the path to PATH_FILENAME (SAVE_PATH_BTN).
SAVE_PATH_BTN: str | None = "square"
# (Re)load the path from PATH_FILENAME (LOAD_PATH_BTN).
LOAD_PATH_BTN: str | None = "dpad_left"
# Erase the path in memory (ERASE_PATH_BTN).
ERASE_PATH_BTN: str | None = "dpad_down"
# Make the car's current pose the origin (0, 0, heading 0) of the localiser (RESET_ORIGIN_BTN).
RESET_ORIGIN_BTN: str | None = "dpad_up"
