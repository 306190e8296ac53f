"""Settings of the built-in simulator: tracks, themes, camera, car and evaluation.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Annotated, Any, Literal

from parts.cameras.settings import IMAGE_H, IMAGE_W
from vehicle.config_checks import Checked, Length, Problem, Range, Rule, ordered_pair

# == Simulator ==

# Seeds of the generated tracks the simulated car drives (several: it moves to the next track
# after each completed lap). Different seeds give different tracks; the same seed the same track.
SIM_TRACK_SEEDS: Annotated[list[int], Length(min=1), Range(0, 2**32 - 1)] = [1]
# Held-out tracks `vehicle sim eval` drives when --tracks is not given (keep them out of training).
SIM_EVAL_TRACK_SEEDS: Annotated[list[int], Length(min=1), Range(0, 2**32 - 1)] = [101, 102, 103]
# Rough size of a generated track in metres (mean diameter of the loop); a 1:10 car at 2 m/s
# needs about 14 s for a lap of the default size.
SIM_TRACK_SIZE: Annotated[float, Range(2, 1000, unit="m")] = 8.0
# Tightest turn radius of the centre line in metres (the car's own turning circle is ~0.55 m).
SIM_TRACK_MIN_RADIUS: Annotated[float, Range(0, lo_open=True, unit="m")] = 1.2
# Width of the road in metres, edge line to edge line (a 1:10 car is about 0.2 m wide).
SIM_ROAD_WIDTH: Annotated[float, Range(0.1, 20, unit="m")] = 0.8
# Number of lanes: 1 (dashed centre line as a guide) or 2 (the dashed line splits two lanes and
# the expert keeps to its lane; widen SIM_ROAD_WIDTH for comfortable lanes).
SIM_LANES: Literal[1, 2] = 1
# Width of the painted lines in metres.
SIM_LINE_WIDTH: Annotated[float, Range(0, 1, lo_open=True, unit="m")] = 0.04
# Resolution of the top-down track texture in metres per pixel (smaller = sharper, more memory).
SIM_TEXTURE_RES: Annotated[float, Range(0.001, 0.1, unit="m per pixel")] = 0.01
# Strength of the per-track lighting variation (brightness, contrast, colour tint, shading);
# 0 renders every track in the same light.
SIM_LIGHTING_VARIATION: Annotated[float, Range(0, 1)] = 0.25
# Visual theme of the tracks: "road" (asphalt, white edges, dashed centre line, open sky),
# "indoor" (DonkeyCar-style tape lines on concrete, wood or carpet, walls around the floor) or
# "park" (a paved path through a lawn, no painted lines, trees around; one lane only). A list
# (or "road,indoor") deals the themes to the tracks in turn: SIM_TRACK_SEEDS = [1, 2, 3, 4] with
# ["road", "indoor"] gives tracks 1 and 3 the road theme, 2 and 4 the indoor one.
SIM_THEME: str | list[str] = "road"
# Domain randomisation: None = off; an integer = the seed of the draws. Each track then gets its
# own light level and colour temperature, contrast, shadows across the road, colours within its
# theme, camera height/pitch/field of view, lens vignetting, sensor noise, motion blur, JPEG
# quality, a camera-to-command latency of 0-2 loops and distractors beside the road, drawn once
# from the ranges in docs/simulator.md. Same seed, same draws: evaluate with another seed for
# conditions the pilot never saw.
SIM_RANDOMIZE: Annotated[int | None, Range(0, 2**32 - 1)] = None
# Overrides of the randomisation ranges, name -> (low, high), e.g. {"light": (0.8, 1.2),
# "latency": (0, 0)}; names and defaults in docs/simulator.md.
SIM_RANDOMIZE_RANGES: Annotated[dict[str, tuple[float, float]],
                                Checked("known names, each low <= high within its limits (docs/simulator.md)")] = {}
# Road-surface randomisation, for training data: the share of tracks (0 to 1) whose road (on a
# theme without a road surface, such as indoor, the floor) is drawn from a generic pool instead
# of the theme's materials: asphalt of any shade, concrete, gravel, pavers or packed earth, each in
# a broadly drawn colour (docs/simulator.md). Lines, verges and sky stay the theme's. Drawn per
# track from the track seed and SIM_RANDOMIZE. 0 = off: every theme as it is (evaluate that way).
SIM_ROAD_SURFACE_SHARE: Annotated[float, Range(0, 1)] = 0.0
# Static distractors (cones, boxes, parked cars) beside each track when SIM_RANDOMIZE is off
# (randomised tracks draw their number); they never stand on the road.
SIM_DISTRACTORS: Annotated[int, Range(0, 1000)] = 0
# Run the simulator in real time (the loop paces itself at DRIVE_LOOP_HZ). False = simulated
# time, as fast as the CPU allows (recording and evaluation always use simulated time). The car
# always advances 1 / DRIVE_LOOP_HZ per loop, so a run is deterministic either way.
SIM_REALTIME: bool = True
# Put the car back on the road when it leaves it (cross-track error beyond SIM_OFF_TRACK_CTE).
SIM_RESET_OFF_TRACK: bool = True
# Where a reset puts the car: "start" (start line, lap restarts) or "nearest" (on the centre line
# next to where it left the road, like a person re-centring it).
SIM_RESET_TO: Literal["start", "nearest"] = "start"
# Absolute cross-track error in metres beyond which the car counts as off the road (default: the
# car's centre crosses the road edge).
SIM_OFF_TRACK_CTE: Annotated[float, Range(0, lo_open=True, unit="m")] = SIM_ROAD_WIDTH / 2
# Camera height above the ground in metres.
SIM_CAMERA_HEIGHT: Annotated[float, Range(0, 10, lo_open=True, unit="m")] = 0.2
# Camera tilt below the horizon in degrees.
SIM_CAMERA_PITCH: Annotated[float, Range(-10, 89, unit="degrees")] = 20.0
# Horizontal field of view of the (pinhole) camera in degrees.
SIM_CAMERA_FOV: Annotated[float, Range(10, 170, unit="degrees")] = 100.0
# Camera position ahead of the rear axle in metres.
SIM_CAMERA_FORWARD: Annotated[float, Range(-5, 5, unit="m")] = 0.2
# Lens distortion of the simulated camera, OpenCV's coefficients (k1, k2, p1, p2[, k3]; k1 < 0 is
# a wide-angle barrel lens), or None for an ideal pinhole. With it the simulator's frames need
# calibrating and undistorting like a real camera's (`vehicle camera calibrate --sim`).
SIM_CAMERA_DISTORTION: Annotated[list[float] | None, Length(min=4, max=8, note="4, 5 or 8 coefficients"),
                                 Range(-10, 10)] = None
# Width of the rendered image in pixels; follows IMAGE_W unless set (e.g. 320 like the Udacity
# simulator).
SIM_CAMERA_W: Annotated[int, Range(8, 4096, unit="pixels")] = IMAGE_W
# Height of the rendered image in pixels; follows IMAGE_H unless set (e.g. 160).
SIM_CAMERA_H: Annotated[int, Range(8, 4096, unit="pixels")] = IMAGE_H
# Side cameras: metres left and right of the centre camera where two more cameras of the same
# kind look ahead, as the Udacity simulator records them (e.g. 0.1 m on a 1:10 car, whose road is
# SIM_ROAD_WIDTH wide); the car then also writes
# cam/image_array_left and cam/image_array_right (recorded by `vehicle sim record`, fed to the
# three_camera model when driving and in `vehicle sim eval`). None = the centre camera only.
SIM_SIDE_CAMERAS_OFFSET: Annotated[float | None, Range(0, 2, lo_open=True, unit="m")] = None
# Standard deviation of per-pixel Gaussian noise on the image (0-255 units; 0 = off).
SIM_IMAGE_NOISE: Annotated[float, Range(0, 255)] = 0.0
# Box blur kernel size in pixels (0 or 1 = off).
SIM_IMAGE_BLUR: Annotated[int, Range(0, 99, unit="pixels")] = 0
# Per-frame brightness jitter: each frame is scaled by a factor in [1 - x, 1 + x] (0 = off).
SIM_BRIGHTNESS_JITTER: Annotated[float, Range(0, 1, hi_open=True)] = 0.0
# Seed of the simulator's random parts (per-frame image effects, expert noise).
SIM_SEED: Annotated[int, Range(0, 2**32 - 1)] = 0
# Simulated sensors (with HAVE_ODOM, HAVE_IMU, HAVE_GPS, USE_LIDAR in a simulator car): standard
# deviation of the simulated GPS's position error, metres (a consumer receiver ~1-3 m, RTK 0.02);
# the error wanders, correlated over 10 s, as a real receiver's does.
SIM_GPS_NOISE: Annotated[float, Range(0, 100, unit="m")] = 1.0
# Fixes per second of the simulated GPS.
SIM_GPS_HZ: Annotated[float, Range(0.1, 100, unit="Hz")] = 5.0
# White noise of the simulated IMU's accelerometer, m/s^2 (standard deviation per reading).
SIM_IMU_ACCEL_NOISE: Annotated[float, Range(0, 10, unit="m/s^2")] = 0.05
# White noise of the simulated IMU's gyroscope, rad/s.
SIM_IMU_GYRO_NOISE: Annotated[float, Range(0, 1, unit="rad/s")] = 0.005
# Range noise of the simulated LiDAR, metres.
SIM_LIDAR_NOISE: Annotated[float, Range(0, 1, unit="m")] = 0.01
# Car model (kinematic bicycle, 1:10 RC scale). Distance between the axles in metres.
SIM_WHEELBASE: Annotated[float, Range(0, 10, lo_open=True, unit="m")] = 0.26
# Front wheel angle at full steering (angle = +-1), degrees.
SIM_MAX_STEER_DEG: Annotated[float, Range(0, 89, lo_open=True, unit="degrees")] = 25.0
# How fast the steering servo turns the wheels, degrees per second.
SIM_STEER_RATE_DEG: Annotated[float, Range(0, lo_open=True, unit="degrees per second")] = 400.0
# Acceleration at full throttle from standstill, m/s^2.
SIM_MAX_ACCEL: Annotated[float, Range(0, 100, lo_open=True, unit="m/s^2")] = 4.0
# Drag: deceleration per unit speed, 1/s (with SIM_MAX_ACCEL and SIM_ROLLING_DECEL it sets the
# free top speed, (4 - 0.3) / 0.8 = 4.6 m/s, above SIM_MAX_SPEED).
SIM_DRAG: Annotated[float, Range(0, 100, unit="1/s")] = 0.8
# Rolling resistance, m/s^2: a coasting car stops.
SIM_ROLLING_DECEL: Annotated[float, Range(0, 100, unit="m/s^2")] = 0.3
# Deceleration at full brake (negative throttle while moving forward), m/s^2.
SIM_BRAKE_DECEL: Annotated[float, Range(0, 100, lo_open=True, unit="m/s^2")] = 6.0
# Speed limit forward, m/s.
SIM_MAX_SPEED: Annotated[float, Range(0, 100, lo_open=True, unit="m/s")] = 4.0
# Speed limit in reverse, m/s.
SIM_MAX_REVERSE_SPEED: Annotated[float, Range(0, 100, unit="m/s")] = 1.0
# Expert driver (pure pursuit). Highest target speed in m/s; curves lower it.
SIM_EXPERT_SPEED: Annotated[float, Range(0, 100, lo_open=True, unit="m/s")] = 2.0
# Lateral acceleration the expert allows in curves, m/s^2 (target speed = sqrt(a / curvature)).
SIM_EXPERT_LAT_ACCEL: Annotated[float, Range(0, 100, lo_open=True, unit="m/s^2")] = 2.5
# Pure-pursuit look-ahead distance at standstill, metres.
SIM_EXPERT_LOOKAHEAD: Annotated[float, Range(0, 100, lo_open=True, unit="m")] = 0.5
# Extra look-ahead per m/s of speed, seconds (look-ahead = base + this x speed).
SIM_EXPERT_LOOKAHEAD_TIME: Annotated[float, Range(0, 10, unit="s")] = 0.25
# Which line the expert follows: "auto" (centre on one lane, right lane on two), "center",
# "left" or "right".
SIM_EXPERT_LANE: Literal["auto", "center", "left", "right"] = "auto"
# Two-lane tracks with TRAIN_BEHAVIORS: the expert keeps to the lane of the active behaviour
# (BEHAVIOR_LIST names with Left/Right) and changes lane along a smooth path of this many metres.
SIM_EXPERT_LANE_CHANGE_DISTANCE: Annotated[float, Range(0, 100, lo_open=True, unit="m")] = 2.0
# A lane change starts only where the road ahead curves less than this (1/m; 0.4 = radius 2.5 m):
# the expert delays the manoeuvre in tight corners, as the thesis's drivers did.
SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE: Annotated[float, Range(0, 100, lo_open=True, unit="1/m")] = 0.4
# Longest wait (seconds) for a straighter road before a lane change starts anyway.
SIM_EXPERT_LANE_CHANGE_MAX_DELAY: Annotated[float, Range(0, 3600, unit="s")] = 3.0
# Noise injection: amplitude of the steering perturbation added to the executed command while
# the expert's clean label is recorded, so demonstrations contain recoveries (0 = off). Used when
# the expert drives (manage.py drive --expert, vehicle sim record), never in evaluation.
SIM_EXPERT_NOISE: Annotated[float, Range(0, 1)] = 0.3
# Mean time between noise-injection perturbations, seconds.
SIM_EXPERT_NOISE_EVERY: Annotated[float, Range(0, lo_open=True, unit="s")] = 3.0
# Length of one perturbation, seconds.
SIM_EXPERT_NOISE_DURATION: Annotated[float, Range(0, lo_open=True, unit="s")] = 0.8
# Laps per track in `vehicle sim eval` when --laps is not given.
SIM_EVAL_LAPS: Annotated[int, Range(1, 1000)] = 2
# Seconds charged per intervention in the DAVE-2 autonomy figure.
SIM_INTERVENTION_PENALTY: Annotated[float, Range(0, unit="s")] = 6.0
# Longest simulated time of one evaluation episode in seconds (None: 60 s per lap), so a pilot
# that stands still cannot hang the evaluation.
SIM_EVAL_MAX_TIME: Annotated[float | None, Range(0, lo_open=True, unit="s")] = None
# Processes that evaluate tracks in parallel (`vehicle sim eval`, the demo): 0 = one per core
# (capped at the number of tracks), 1 = one track after another. Each runs its own simulator and
# copy of the pilot with cores / workers threads; the report is the same either way.
SIM_EVAL_WORKERS: Annotated[int, Range(0, 256)] = 0
# Evaluation of a behaviour pilot on two-lane tracks: the lane is changed on command (the behaviour
# steps), the first time after 4 s, then every (min, max) seconds, drawn per track from SIM_SEED;
# min at least SIM_EVAL_LANE_CHANGE_TIME_LIMIT + SIM_EVAL_LANE_CHANGE_HOLD (one change judged at a time).
SIM_EVAL_LANE_CHANGE_EVERY: Annotated[tuple[float, float], Range(0, 3600, lo_open=True, unit="s")] = (8.0, 12.0)
# Seconds a commanded lane change may take to count as done: by then the car's centre must be within
# a quarter lane width of the new lane's centre.
SIM_EVAL_LANE_CHANGE_TIME_LIMIT: Annotated[float, Range(0, 3600, lo_open=True, unit="s")] = 6.0
# Seconds the car must then stay that close to the new lane's centre.
SIM_EVAL_LANE_CHANGE_HOLD: Annotated[float, Range(0, 3600, unit="s")] = 1.0

# == Reinforcement learning ==

# Seconds one call of a reward file's reward_function may take (`vehicle rl train`, `vehicle rl
# reward-check`, the Gymnasium environment); a call that takes longer stops training with one line
# naming the file. DeepRacer-style functions take microseconds.
RL_REWARD_TIME_LIMIT_S: Annotated[float, Range(0.001, 600, unit="s")] = 1.0


def _track(v: Mapping[str, Any]) -> Iterator[Problem]:
    radius, width, size = v["SIM_TRACK_MIN_RADIUS"], v["SIM_ROAD_WIDTH"], v["SIM_TRACK_SIZE"]
    low, high = width / 2 + 0.05, size / 2
    if not low <= radius <= high:
        yield Problem("SIM_TRACK_MIN_RADIUS", f"SIM_TRACK_MIN_RADIUS = {radius!r} m does not fit a road "
                      f"of SIM_ROAD_WIDTH = {width!r} m on a track of SIM_TRACK_SIZE = {size!r} m; "
                      f"valid: {low:.2f} to {high:.2f} m (half the road width + 5 cm, up to half "
                      "the track size)", ("SIM_ROAD_WIDTH", "SIM_TRACK_SIZE"))


#: rules across this module's settings, run after every setting passed its own range
def _side_cameras(v: Mapping[str, Any]) -> Iterator[Problem]:
    if v["SIM_SIDE_CAMERAS_OFFSET"] is not None and v.get("CAMERA_UNDISTORT"):
        yield Problem("SIM_SIDE_CAMERAS_OFFSET", "SIM_SIDE_CAMERAS_OFFSET with CAMERA_UNDISTORT: only the centre "
                      "frame is undistorted, the side frames would not match it; set one of them off (the "
                      "simulator's lens is SIM_CAMERA_DISTORTION: None renders undistorted frames)",
                      ("CAMERA_UNDISTORT",))


RULES: tuple[Rule, ...] = (_track, ordered_pair("SIM_EVAL_LANE_CHANGE_EVERY"), _side_cameras)
