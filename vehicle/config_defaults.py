"""Default settings of every car. A car's ``myconfig.py`` overrides any of them.

Rules of this module (the config loader and the generated reference rely on them):

- one annotated assignment per setting, ``NAME: type = value``, UPPERCASE names;
- the comment lines right above a setting document it (units and reasons);
- a value may be an expression of settings above it (``CAMERA_FRAMERATE: int = DRIVE_LOOP_HZ``):
  such derived values are recomputed after the user's overrides unless the user set them too;
- section headers are comment lines of the form ``# == Title ==``.

docs/config.md is generated from this file (``python -m vehicle.config_docs``) and a test keeps
it in sync.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

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
DRIVE_LOOP_HZ: int = 20
# Stop after this many loops (None = run until stopped). Handy for scripted runs.
MAX_LOOPS: int | None = None

# == Camera ==

# Width in pixels of the images the camera delivers and the tub records.
IMAGE_W: int = 160
# Height in pixels of the camera images.
IMAGE_H: int = 120
# Colour channels of the camera images (3 = RGB).
IMAGE_DEPTH: int = 3
# Frames per second asked of the camera; follows the loop rate unless set.
CAMERA_FRAMERATE: int = DRIVE_LOOP_HZ

# == Drive modes ==

# Mode at start: "user" (human drives), "local_angle" (pilot steers), "local" (pilot drives).
DEFAULT_MODE: Literal["user", "local_angle", "local"] = "user"
# Pilot throttle is multiplied by this in "local" mode (1.0 = as predicted).
AI_THROTTLE_MULT: float = 1.0

# == Training ==

# Model type used when training without --type.
DEFAULT_MODEL_TYPE: str = "linear"
# Optional function record -> bool choosing which tub records are trained on (None = all).
TRAIN_FILTER: Callable[[dict[str, Any]], bool] | None = None

# == Simulator ==

# Seeds of the generated tracks the simulated car drives (several: it moves to the next track
# after each completed lap). Different seeds give different tracks; the same seed the same track.
SIM_TRACK_SEEDS: list[int] = [1]
# Held-out tracks `vehicle sim eval` drives when --tracks is not given (keep them out of training).
SIM_EVAL_TRACK_SEEDS: list[int] = [101, 102, 103]
# Rough size of a generated track in metres (mean diameter of the loop); a 1:10 car at 2 m/s
# needs about 15 s for a lap of the default size.
SIM_TRACK_SIZE: float = 8.0
# Tightest turn radius of the centre line in metres (the car's own turning circle is ~0.55 m).
SIM_TRACK_MIN_RADIUS: float = 1.2
# Width of the road in metres, edge line to edge line (a 1:10 car is about 0.2 m wide).
SIM_ROAD_WIDTH: float = 0.8
# Number of lanes: 1 (dashed centre line as a guide) or 2 (the dashed line splits two lanes and
# the expert keeps to its lane; widen SIM_ROAD_WIDTH for comfortable lanes).
SIM_LANES: Literal[1, 2] = 1
# Width of the painted lines in metres.
SIM_LINE_WIDTH: float = 0.04
# Resolution of the top-down track texture in metres per pixel (smaller = sharper, more memory).
SIM_TEXTURE_RES: float = 0.01
# Strength of the per-track lighting variation (brightness, contrast, colour tint, shading);
# 0 renders every track in the same light.
SIM_LIGHTING_VARIATION: float = 0.25
# Run the simulator in real time (the loop paces itself at DRIVE_LOOP_HZ). False = simulated
# time, as fast as the CPU allows (recording and evaluation always use simulated time). The car
# always advances 1 / DRIVE_LOOP_HZ per loop, so a run is deterministic either way.
SIM_REALTIME: bool = True
# Put the car back on the road when it leaves it (|cte| > SIM_OFF_TRACK_CTE).
SIM_RESET_OFF_TRACK: bool = True
# Where a reset puts the car: "start" (start line, lap restarts) or "nearest" (on the centre line
# next to where it left the road, like a person re-centring it).
SIM_RESET_TO: Literal["start", "nearest"] = "start"
# |cross-track error| in metres beyond which the car counts as off the road (default: the car's
# centre crosses the road edge).
SIM_OFF_TRACK_CTE: float = SIM_ROAD_WIDTH / 2
# Camera height above the ground in metres.
SIM_CAMERA_HEIGHT: float = 0.2
# Camera tilt below the horizon in degrees.
SIM_CAMERA_PITCH: float = 20.0
# Horizontal field of view of the (pinhole) camera in degrees.
SIM_CAMERA_FOV: float = 100.0
# Camera position ahead of the rear axle in metres.
SIM_CAMERA_FORWARD: float = 0.2
# Size of the rendered image in pixels; follows the camera settings unless set (e.g. 320x160
# like the Udacity simulator).
SIM_CAMERA_W: int = IMAGE_W
SIM_CAMERA_H: int = IMAGE_H
# Standard deviation of per-pixel Gaussian noise on the image (0-255 units; 0 = off).
SIM_IMAGE_NOISE: float = 0.0
# Box blur kernel size in pixels (0 or 1 = off).
SIM_IMAGE_BLUR: int = 0
# Per-frame brightness jitter: each frame is scaled by a factor in [1 - x, 1 + x] (0 = off).
SIM_BRIGHTNESS_JITTER: float = 0.0
# Seed of the simulator's random parts (image jitter, expert noise).
SIM_SEED: int = 0
# Car model (kinematic bicycle, 1:10 RC scale). Distance between the axles in metres.
SIM_WHEELBASE: float = 0.26
# Front wheel angle at full steering (angle = +-1), degrees.
SIM_MAX_STEER_DEG: float = 25.0
# How fast the steering servo turns the wheels, degrees per second.
SIM_STEER_RATE_DEG: float = 400.0
# Acceleration at full throttle from standstill, m/s^2.
SIM_MAX_ACCEL: float = 4.0
# Drag: deceleration per unit speed, 1/s (with SIM_MAX_ACCEL it sets the free top speed, 5 m/s).
SIM_DRAG: float = 0.8
# Rolling resistance, m/s^2: a coasting car stops.
SIM_ROLLING_DECEL: float = 0.3
# Deceleration at full brake (negative throttle while moving forward), m/s^2.
SIM_BRAKE_DECEL: float = 6.0
# Speed limits forward and in reverse, m/s.
SIM_MAX_SPEED: float = 4.0
SIM_MAX_REVERSE_SPEED: float = 1.0
# Expert driver (pure pursuit). Highest target speed in m/s; curves lower it.
SIM_EXPERT_SPEED: float = 2.0
# Lateral acceleration the expert allows in curves, m/s^2 (target speed = sqrt(a / curvature)).
SIM_EXPERT_LAT_ACCEL: float = 2.5
# Pure-pursuit look-ahead distance: base in metres plus this many seconds at the current speed.
SIM_EXPERT_LOOKAHEAD: float = 0.5
SIM_EXPERT_LOOKAHEAD_TIME: float = 0.25
# Which line the expert follows: "auto" (centre on one lane, right lane on two), "center",
# "left" or "right".
SIM_EXPERT_LANE: Literal["auto", "center", "left", "right"] = "auto"
# Noise injection: amplitude of the steering perturbation added to the executed command while
# the expert's clean label is recorded, so demonstrations contain recoveries (0 = off).
SIM_EXPERT_NOISE: float = 0.0
# Mean time between perturbations and the length of one, seconds.
SIM_EXPERT_NOISE_EVERY: float = 3.0
SIM_EXPERT_NOISE_DURATION: float = 0.8
# Laps per track in `vehicle sim eval` when --laps is not given.
SIM_EVAL_LAPS: int = 2
# Seconds charged per intervention in the DAVE-2 autonomy figure.
SIM_INTERVENTION_PENALTY: float = 6.0
# Longest simulated time of one evaluation episode in seconds (None: 60 s per lap), so a pilot
# that stands still cannot hang the evaluation.
SIM_EVAL_MAX_TIME: float | None = None
