"""The vocabulary parts share: the standard memory keys and the drive modes.

Names follow DonkeyCar where it has one, so tubs and parts interoperate. New keys get a
namespace (``sim/...``, ``web/...``): ``<namespace>/<name>`` in lower case. Each entry of
:data:`STANDARD_KEYS` is ``KEY: (type, meaning)``; a user's own parts may use any other string
key, these are the ones the library itself produces or consumes.

Part classes declare the keys they read and write once, as class attributes ``INPUTS`` and
``OUTPUTS`` (and ``OPTIONAL_INPUTS`` / ``FEEDBACK``, see :meth:`vehicle.Vehicle.add`); a car that
needs other keys renames them with :func:`rename`.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping, Sequence
from enum import StrEnum
from typing import NamedTuple

logger = logging.getLogger(__name__)


class Mode(StrEnum):
    """The three drive modes; values are DonkeyCar's strings, as recorded in tubs (``user/mode``)."""

    USER = "user"  # the human steers and sets the throttle
    LOCAL_ANGLE = "local_angle"  # the pilot steers, the human sets the throttle
    LOCAL = "local"  # the pilot steers and sets the throttle

    def next(self) -> Mode:
        """The mode after this one, cycling user -> local_angle -> local -> user."""
        order = list(Mode)
        return order[(order.index(self) + 1) % len(order)]


#: the drive modes' strings, in cycling order
MODES: tuple[str, ...] = tuple(m.value for m in Mode)


def parse_mode(value: object) -> Mode:
    """Mode from a stored value; unknown or missing values mean user mode (the safe choice)."""
    try:
        return Mode(value)
    except ValueError:
        if value is not None:
            logger.warning("unknown drive mode %r: using user mode", value)
        return Mode.USER


class KeyInfo(NamedTuple):
    """What a memory key holds."""

    type: str
    meaning: str


STANDARD_KEYS: dict[str, KeyInfo] = {
    # -- camera
    "cam/image_array": KeyInfo("ndarray HxWx3 uint8 RGB", "latest camera frame"),
    "cam/timestamp": KeyInfo("float", "capture time of cam/image_array, seconds (time.time())"),
    "cam/image_array_left": KeyInfo("ndarray HxWx3 uint8 RGB", "frame of a camera left of the centre one (Udacity "
                                    "recordings, the simulator's SIM_SIDE_CAMERAS_OFFSET; training: "
                                    "TRAIN_SIDE_CAMERAS)"),
    "cam/image_array_right": KeyInfo("ndarray HxWx3 uint8 RGB", "frame of a camera right of the centre one"),
    "cam/frame_id": KeyInfo("int", "counter of frames delivered by the camera"),
    "cam/ok": KeyInfo("bool", "False when the camera stopped delivering frames"),
    # -- human input
    "user/angle": KeyInfo("float in [-1, 1]", "steering from the human controller, -1 = full left"),
    "user/throttle": KeyInfo("float in [-1, 1]", "throttle from the human controller, negative = reverse"),
    "user/mode": KeyInfo("str: user | local_angle | local", "who drives: human, pilot steers, pilot drives"),
    "recording": KeyInfo("bool", "whether the tub writer records this loop"),
    "estop": KeyInfo("bool", "emergency stop latched: throttle forced to 0"),
    "user/speed_limit": KeyInfo("float, m/s, or None", "web page's speed limit: caps the speed in every mode"),
    "pilot/model_request": KeyInfo("str path or None", "model file the web picker asks the pilot to load"),
    "controller/active": KeyInfo("str: gamepad | web", "which controller's stick drives (arbitration)"),
    "web/angle": KeyInfo("float in [-1, 1]", "steering from the web page, before arbitration"),
    "web/throttle": KeyInfo("float in [-1, 1]", "throttle from the web page, before arbitration"),
    "web/mode": KeyInfo("str", "drive mode chosen on the web page, before arbitration"),
    "web/recording": KeyInfo("bool", "record toggle of the web page, before arbitration"),
    "web/estop": KeyInfo("bool", "emergency stop latched on the web page"),
    "js/angle": KeyInfo("float in [-1, 1]", "gamepad steering, before arbitration with the web page"),
    "js/throttle": KeyInfo("float in [-1, 1]", "gamepad throttle, before arbitration"),
    "js/mode": KeyInfo("str", "gamepad drive mode, before arbitration"),
    "js/recording": KeyInfo("bool", "gamepad record toggle, before arbitration"),
    "js/estop": KeyInfo("bool", "emergency stop latched on the gamepad"),
    "js/status": KeyInfo("str: connected | silent | lost", "the car's gamepad link (shown on the web page)"),
    # -- pilot
    "pilot/angle": KeyInfo("float in [-1, 1]", "steering from the pilot"),
    "pilot/throttle": KeyInfo("float in [-1, 1]", "throttle from the pilot"),
    "run_pilot": KeyInfo("bool", "True when the pilot must run this loop (mode is not user)"),
    "pilot/model": KeyInfo("str", "file name of the model driving now (after a hot switch: the new one)"),
    "pilot/load_error": KeyInfo("str or None", "why the last model asked for was not loaded (None after a success)"),
    # -- final commands
    "angle": KeyInfo("float in [-1, 1]", "steering command sent to the drivetrain"),
    "throttle": KeyInfo("float in [-1, 1]", "throttle command sent to the drivetrain"),
    # -- behaviour
    "behavior/state": KeyInfo("int", "index of the active behaviour"),
    "behavior/label": KeyInfo("str", "name of the active behaviour, e.g. Left_Lane"),
    "behavior/one_hot_state_array": KeyInfo("list[float]", "one-hot encoding of behavior/state"),
    "behavior/step": KeyInfo("int", "+1 / -1 for one loop: select the next / previous behaviour"),
    "web/behavior_step": KeyInfo("int", "behaviour steps asked on the web page this loop (change lane)"),
    "vision/lane_image": KeyInfo("ndarray HxW uint8", "binary lane image (bird's-eye, 255 = lane pixel)"),
    "calib/image": KeyInfo("ndarray HxWx3 uint8 RGB", "camera frame with the chessboard corners drawn"),
    "calib/views": KeyInfo("int", "chessboard views kept for camera calibration"),
    "calib/found": KeyInfo("bool", "whether the chessboard is in the current frame"),
    # -- recording
    "tub/num_records": KeyInfo("int", "records in the current tub"),
    "tub/erase": KeyInfo("bool", "rising edge: delete the last ERASE_LAST_N_RECORDS records"),
    # -- simulator
    "sim/cte": KeyInfo("float, m", "signed cross-track error, positive = right of the centre line "
                       "(the simulator's own units from the Donkey simulator and Udacity forks)"),
    "sim/heading_error": KeyInfo("float, rad", "car heading minus track heading"),
    "sim/speed": KeyInfo("float, m/s", "speed of the simulated car"),
    "sim/progress": KeyInfo("float in [0, 1)", "fraction of the current lap driven"),
    "sim/lap": KeyInfo("int", "laps completed"),
    "sim/lap_time": KeyInfo("float, s", "duration of the last completed lap"),
    "sim/off_track": KeyInfo("bool", "True while the car is off the road"),
    "sim/pos": KeyInfo("tuple[float, float], m", "car position in track coordinates"),
    "sim/track": KeyInfo("int", "seed of the track the simulated car is on"),
    "sim/reset": KeyInfo("bool", "rising edge puts the simulated car back on its start line"),
    "sim/steering_deg": KeyInfo("float, degrees", "steering the Udacity simulator reports, positive = right"),
    "sim/throttle": KeyInfo("float in [-1, 1]", "throttle the Udacity simulator reports"),
    "sim/manual": KeyInfo("bool", "the user overrides the pilot in the simulator (Udacity: W/S held)"),
    "sim/hit": KeyInfo("str", "what the simulated car hit this loop, or 'none' (Donkey simulator)"),
    "sim/time": KeyInfo("float, s", "the simulator's clock (Donkey simulator: time since the scene loaded)"),
    "sim/extra": KeyInfo("dict", "other telemetry fields of a simulator (Donkey IMU, Udacity fork keys)"),
    # -- the loop itself (written by the Vehicle every loop)
    "loop/rate_hz": KeyInfo("float, Hz", "achieved loop rate over the last second"),
    "loop/overruns": KeyInfo("int", "loops that started late so far"),
    "loop/count": KeyInfo("int", "loops run so far"),
    # -- speed and odometry (DonkeyCar's names)
    "enc/speed": KeyInfo("float, m/s", "measured speed (encoder odometer, VESC RPM or simulator); None when stale"),
    "enc/ticks": KeyInfo("int", "cumulative signed wheel-encoder ticks"),
    "enc/left/ticks": KeyInfo("int", "cumulative ticks of the left wheel's encoder (differential drive)"),
    "enc/right/ticks": KeyInfo("int", "cumulative ticks of the right wheel's encoder (differential drive)"),
    "enc/timestamp": KeyInfo("float, s", "time of the encoder reading, on the vehicle's clock"),
    "enc/distance": KeyInfo("float, m", "signed distance driven since start (odometer)"),
    "enc/left/distance": KeyInfo("float, m", "distance driven by the left wheel"),
    "enc/right/distance": KeyInfo("float, m", "distance driven by the right wheel"),
    "enc/ok": KeyInfo("bool", "False while the encoder has not reported within its max age"),
    "pos/x": KeyInfo("float, m", "odometry pose: x in the start frame"),
    "pos/y": KeyInfo("float, m", "odometry pose: y in the start frame (left of the start heading)"),
    "pos/angle": KeyInfo("float, rad", "odometry heading, counter-clockwise, in [-pi, pi)"),
    "vel/x": KeyInfo("float, m/s", "odometry velocity along x"),
    "vel/y": KeyInfo("float, m/s", "odometry velocity along y"),
    "vel/angle": KeyInfo("float, rad/s", "odometry turn rate, counter-clockwise"),
    # -- IMU (x forward, y left, z up as mounted)
    "imu/acl_x": KeyInfo("float, m/s^2", "IMU acceleration along x"),
    "imu/acl_y": KeyInfo("float, m/s^2", "IMU acceleration along y"),
    "imu/acl_z": KeyInfo("float, m/s^2", "IMU acceleration along z (+9.8 at rest, upright)"),
    "imu/gyr_x": KeyInfo("float, rad/s", "IMU rotation rate about x"),
    "imu/gyr_y": KeyInfo("float, rad/s", "IMU rotation rate about y"),
    "imu/gyr_z": KeyInfo("float, rad/s", "IMU rotation rate about z (counter-clockwise seen from above)"),
    "imu/ok": KeyInfo("bool", "False while the IMU has not reported within its max age"),
    # -- GPS (local metric frame: x east, y north, origin at the first fix or GPS_ORIGIN)
    "gps/x": KeyInfo("float, m", "GPS position east of the local origin; None without a fix"),
    "gps/y": KeyInfo("float, m", "GPS position north of the local origin; None without a fix"),
    "gps/latitude": KeyInfo("float, degrees", "GPS latitude"),
    "gps/longitude": KeyInfo("float, degrees", "GPS longitude"),
    "gps/accuracy": KeyInfo("float, m", "horizontal accuracy estimate (HDOP x 5 m)"),
    "gps/speed": KeyInfo("float, m/s", "speed over ground (NMEA RMC)"),
    "gps/ok": KeyInfo("bool", "a valid, fresh fix"),
    # -- LiDAR and obstacle stop
    "lidar/dist_array": KeyInfo("list[float], m", "nearest return per angle bin, bins counter-clockwise "
                                "from straight ahead, 0.0 = no return"),
    "lidar/ok": KeyInfo("bool", "False while the LiDAR has not completed a turn within its max age"),
    "obstacle/stop": KeyInfo("bool", "the obstacle stop is cutting the throttle this loop"),
    "obstacle/distance": KeyInfo("float, m, or None", "nearest LiDAR return in the cone ahead"),
    "tune/done": KeyInfo("bool", "the speed step test has finished"),
}


def describe(key: str) -> KeyInfo | None:
    """Return what ``key`` holds, or None for a key outside the standard list."""
    return STANDARD_KEYS.get(key)


#: older names of standard keys -> the standard name. Tubs and settings written with an old name
#: are still read (our docs once named the side cameras ``cam/left_image_array``, which
#: ``vehicle tub import-udacity`` never wrote).
KEY_ALIASES: dict[str, str] = {
    "cam/left_image_array": "cam/image_array_left",
    "cam/right_image_array": "cam/image_array_right",
}


def key_names(key: str) -> tuple[str, ...]:
    """``key`` followed by the other names of the same key (its standard name or its old names)."""
    standard = KEY_ALIASES.get(key, key)
    others = [standard] + [old for old, new in KEY_ALIASES.items() if new == standard]
    return (key, *(k for k in others if k != key))


#: keys at the top level of the namespace (DonkeyCar's names)
ROOT_KEYS: frozenset[str] = frozenset(k for k in STANDARD_KEYS if "/" not in k)
_NAMESPACED = re.compile(r"^[a-z][a-z0-9_]*(/[a-z0-9_]+)+$")


def is_valid_key(key: str) -> bool:
    """Whether ``key`` is a standard key or follows the namespace rule (``sim/cte``, ``web/angle``)."""
    return key in STANDARD_KEYS or bool(_NAMESPACED.match(key))


def rename(keys: Sequence[str], mapping: Mapping[str, str]) -> tuple[str, ...]:
    """``keys`` with some renamed, for a car that wires a part to other keys.

    >>> rename(("user/angle", "user/throttle", "tub/erase"), {"user/angle": "js/angle"})
    ('js/angle', 'user/throttle', 'tub/erase')

    Raises:
        ValueError: a key of ``mapping`` is not among ``keys`` (a typo would silently do nothing).
    """
    stray = [k for k in mapping if k not in keys]
    if stray:
        raise ValueError(f"cannot rename {stray}: not among the keys {list(keys)}")
    return tuple(mapping.get(k, k) for k in keys)
