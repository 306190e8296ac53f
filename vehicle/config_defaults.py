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
from typing import Annotated, Any, Literal

from vehicle.config_checks import PULSE_VALID, WATCHDOG_OFF, Checked, Length, Range
from vehicle.keys import Mode

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

# == Camera ==

# Width in pixels of the images the camera delivers and the tub records.
IMAGE_W: Annotated[int, Range(8, 4096, unit="pixels")] = 160
# Height in pixels of the camera images.
IMAGE_H: Annotated[int, Range(8, 4096, unit="pixels")] = 120
# Colour channels of the camera images (3 = RGB).
IMAGE_DEPTH: Literal[1, 3] = 3
# Frames per second asked of the camera; follows the loop rate unless set.
CAMERA_FRAMERATE: Annotated[int, Range(1, 1000, unit="Hz")] = DRIVE_LOOP_HZ
# Camera driver: "PICAM" (Raspberry Pi camera via picamera2), "CVCAM" or "WEBCAM" (USB camera via
# OpenCV/V4L2), "CSIC" (Jetson CSI camera via GStreamer), "VIDEO" (replays CAMERA_VIDEO_PATH),
# "IMAGE_LIST" (replays CAMERA_IMAGE_PATH: a folder of images or a tub), "MOCK" (a generated moving
# pattern: no hardware).
CAMERA_TYPE: Literal["PICAM", "CVCAM", "WEBCAM", "CSIC", "VIDEO", "IMAGE_LIST", "MOCK"] = "PICAM"
# Which camera: N of /dev/videoN (CVCAM, WEBCAM), the sensor id (CSIC) or camera number (PICAM).
CAMERA_INDEX: Annotated[int, Range(0)] = 0
# Flip the image upside down (a camera mounted the other way round).
CAMERA_VFLIP: bool = False
# Mirror the image left-right.
CAMERA_HFLIP: bool = False
# No new frame for this many seconds: cam/ok goes False, an error is logged and a driving pilot is
# disengaged (user mode, throttle 0). A few frame periods; USB cameras stall for ~0.3 s at times.
CAMERA_TIMEOUT_S: Annotated[float, Range(0.1, 5, unit="s")] = 1.0
# CVCAM/WEBCAM: pixel format asked of the camera ("MJPG" gives full frame rates over USB 2;
# "YUYV" for cameras without MJPG); None = the driver's default.
CAMERA_FOURCC: str | None = "MJPG"
# CSIC: width of the sensor mode captured before the GPU scales it to IMAGE_W x IMAGE_H (IMX219:
# 1280x720 at 60, 1640x1232 at 30 frames per second).
CSIC_CAPTURE_WIDTH: Annotated[int, Range(8, 8192, unit="pixels")] = 1280
# CSIC: height of the captured sensor mode.
CSIC_CAPTURE_HEIGHT: Annotated[int, Range(8, 8192, unit="pixels")] = 720
# CSIC: frame rate of the captured sensor mode (must be one the sensor offers at that size).
CSIC_CAPTURE_FPS: Annotated[int, Range(1, 1000, unit="Hz")] = 60
# VIDEO: video file replayed as the camera, paced at CAMERA_FRAMERATE (relative to CAR_PATH).
CAMERA_VIDEO_PATH: str | None = None
# IMAGE_LIST: folder of images, or a tub, replayed as the camera in natural name order (relative to
# CAR_PATH).
CAMERA_IMAGE_PATH: str | None = None
# VIDEO / IMAGE_LIST: start again after the last frame (False: the camera stops and cam/ok goes
# False after CAMERA_TIMEOUT_S).
CAMERA_REPLAY_LOOP: bool = True

# == Vision ==

# Remove lens distortion from every camera frame with the car's calibration (Undistort part, one
# precomputed remap per frame). Make the calibration first: `vehicle camera calibrate`.
CAMERA_UNDISTORT: bool = False
# The camera calibration file (camera matrix, distortion coefficients, reprojection error),
# relative to CAR_PATH; written by `vehicle camera calibrate`.
CAMERA_CALIBRATION_PATH: str = "camera_calibration.json"
# Undistorted view: 0 = zoom so that only valid pixels show (no black border), 1 = keep every
# source pixel (black corners with a wide lens).
CAMERA_UNDISTORT_ALPHA: Annotated[float, Range(0, 1)] = 0.0
# Chessboard used for calibration: inner corners per row and per column (where four squares
# meet; the thesis's board: 10 x 7, an 11 x 8 squares print). The counts must differ.
CAMERA_CALIB_BOARD: Annotated[tuple[int, int], Range(2, 100)] = (10, 7)
# Side of one chessboard square as printed, in millimetres (only the board poses depend on it).
CAMERA_CALIB_SQUARE_MM: Annotated[float, Range(0, 1000, lo_open=True, unit="mm")] = 25.0
# Distortion model fitted: "standard" = k1, k2, p1, p2, k3 (the thesis's code); "rational" adds
# k4..k6 for very wide lenses (the thesis's equation 6.3).
CAMERA_CALIB_MODEL: Literal["standard", "rational"] = "standard"
# Lane extraction (thesis chapter 7), used by the `lanes` model type and the LaneExtraction part:
# the region of interest on the road as four (x, y) pixel points of a LANE_POINTS_SIZE frame,
# bottom left, top left, top right, bottom right. Default: the thesis's points for its 320x180
# simulator camera; tune them for your camera with `vehicle lanes preview`.
LANE_SOURCE_POINTS: Annotated[list[tuple[float, float]], Length(min=4, max=4), Range(unit="pixels")] = [
    (0.0, 180.0), (112.5, 87.5), (200.0, 87.5), (307.5, 180.0)]
# Where the source points go in the bird's-eye image, same order and frame size (the thesis's).
LANE_DESTINATION_POINTS: Annotated[list[tuple[float, float]], Length(min=4, max=4), Range(unit="pixels")] = [
    (80.0, 180.0), (80.0, 0.25), (230.0, 0.25), (230.0, 180.0)]
# (width, height) of the frame the lane points are given for; they are scaled to the real
# camera size (same field of view assumed).
LANE_POINTS_SIZE: Annotated[tuple[int, int], Range(8, 8192, unit="pixels")] = (320, 180)
# HLS saturation range of lane pixels after the warp: S in (low, high] (thesis: 65, 255, i.e.
# S > 65); None leaves the S threshold out (then LANE_COLOR_MASK must be set).
LANE_S_THRESHOLD: Annotated[tuple[int, int] | None, Range(0, 255)] = (65, 255)
# Also count white and/or yellow pixels as lane pixels: white tape has almost no saturation, so
# the S threshold alone misses it. None, "white", "yellow" or "white_yellow".
LANE_COLOR_MASK: Literal["white", "yellow", "white_yellow"] | None = None
# HLS lightness (0-255, after LANE_NORMALIZE) from which a pixel is white (LANE_COLOR_MASK).
LANE_WHITE_MIN_LIGHTNESS: Annotated[int, Range(0, 255)] = 200
# OpenCV hue range (0-180) of yellow lane pixels (LANE_COLOR_MASK).
LANE_YELLOW_HUE: Annotated[tuple[int, int], Range(0, 180)] = (15, 35)
# Least HLS saturation (0-255) of a yellow lane pixel (LANE_COLOR_MASK).
LANE_YELLOW_MIN_SATURATION: Annotated[int, Range(0, 255)] = 80
# Stretch the warped image to the full 0-255 range before thresholding (the thesis does).
LANE_NORMALIZE: bool = True

# == Drive modes ==

# Mode at start: "user" (human drives), "local_angle" (pilot steers), "local" (pilot drives).
# The web page, the gamepad and the drive-mode part all start from it (DonkeyCar: WEB_INIT_MODE);
# `manage.py drive --mode MODE` sets it for one drive.
DEFAULT_MODE: Mode = "user"
# Pilot throttle is multiplied by this in "local" mode (1.0 = as predicted).
AI_THROTTLE_MULT: Annotated[float, Range(0, 2)] = 1.0

# == Training ==

# Model type used when training without --type.
DEFAULT_MODEL_TYPE: str = "linear"
# Optional function record -> bool choosing which tub records are trained on (None = all).
# It receives the record's catalog fields (dict: user/angle, user/throttle, user/mode, ...).
TRAIN_FILTER: Callable[[dict[str, Any]], bool] | None = None
# Train only on records whose user/mode is listed (records driven by a pilot teach nothing new).
TRAIN_MODES: Annotated[list[Mode], Length(min=1)] = ["user"]
# Samples per training step.
BATCH_SIZE: Annotated[int, Range(1)] = 128
# Fraction of the records used for training; the rest validates. The split takes whole sessions or
# contiguous blocks, never random frames (neighbouring frames are near copies and would leak).
TRAIN_TEST_SPLIT: Annotated[float, Range(0, 1, note="1 trains on every record, without validation; at "
                                                      "least one block always trains")] = 0.8
# "session": validate on whole recording sessions when the data has at least 2; "block": on
# contiguous blocks of TRAIN_SPLIT_BLOCK records of every tub.
TRAIN_SPLIT_BY: Literal["session", "block"] = "block"
# Length of one block of the block split, in records (100 = 5 s at 20 Hz).
TRAIN_SPLIT_BLOCK: Annotated[int, Range(1)] = 100
# Seed of the split, balancing, shuffling and augmentations (same seed, same run).
TRAIN_SEED: Annotated[int, Range(0, 2**32 - 1)] = 42
# Most epochs to train (one epoch = every training sample once).
MAX_EPOCHS: Annotated[int, Range(1)] = 100
# Stop training when the validation loss stops improving (see the next two settings).
USE_EARLY_STOP: bool = True
# Epochs without an improvement of the validation loss before training stops.
EARLY_STOP_PATIENCE: Annotated[int, Range(1)] = 5
# Smallest decrease of the validation loss that resets early stopping's patience (the model kept is
# the lowest loss, whatever the decrease).
MIN_DELTA: Annotated[float, Range(0)] = 0.0005
# Adam learning rate.
LEARNING_RATE: Annotated[float, Range(0, lo_open=True)] = 0.001
# Training steps (batches) per epoch; None = every training sample once. Fewer steps make epochs
# shorter on a large data set (each epoch then sees a different random part of it).
TRAIN_STEPS_PER_EPOCH: Annotated[int | None, Range(1)] = None
# Validation steps (batches) per epoch; None = every validation sample.
TRAIN_VAL_STEPS: Annotated[int | None, Range(1)] = None
# Adam weight decay (L2 penalty on the weights), 0 = off.
TRAIN_WEIGHT_DECAY: Annotated[float, Range(0)] = 0.0
# Where to train: "auto" = the GPU when there is one (cuda), else cpu; or "cpu", "cuda", "cuda:1".
TRAIN_DEVICE: str = "auto"
# DataLoader worker processes (0 = load in the training process; cheap thanks to the frame cache).
TRAIN_NUM_WORKERS: Annotated[int, Range(0, 64)] = 0
# Keep the decoded frames (uint8, as recorded) in memory so that JPEGs are decoded only once.
TRAIN_CACHE_IMAGES: bool = True
# Largest frame cache in MB; with more frames than fit, frames are decoded every epoch instead.
TRAIN_CACHE_MAX_MB: Annotated[int, Range(0, unit="MB")] = 4096
# Arithmetic precision of training. "auto": bf16 autocast on CPUs with AVX512-BF16 or AMX and on
# GPUs of compute capability 8.0+, fp16 with a gradient scaler on GPUs of 7.x, else fp32; the choice
# is logged at start. "fp32" forces full precision; "bf16"/"fp16" force autocast in that type. The
# weights and the model file stay float32 either way (docs/training.md, "Speed").
TRAIN_PRECISION: Literal["auto", "fp32", "bf16", "fp16"] = "auto"
# Compile the model with torch.compile before training (needs a C++ compiler on CPUs, Triton on
# GPUs). Off by default: on the measured CPUs its compile time outweighs what it saves
# (docs/benchmarks.md, "training").
TRAIN_COMPILE: bool = False
# Write the loss curve as a PNG next to the model.
SHOW_PLOT: bool = True
# Log the model's layers and parameter count before training.
PRINT_MODEL_SUMMARY: bool = False
# Balance the training set by steering: cut the range into TRAIN_BALANCE_BINS bins and keep at most
# TRAIN_BALANCE_MAX_PER_BIN random records per bin (straight driving otherwise dominates).
TRAIN_BALANCE: bool = False
# Number of equal-width steering bins for balancing (Track Driver AI's trainer: num_bins).
TRAIN_BALANCE_BINS: Annotated[int, Range(1)] = 25
# Most training records kept per steering bin (Track Driver AI's trainer: max_samples_per_bin).
TRAIN_BALANCE_MAX_PER_BIN: Annotated[int, Range(1)] = 400
# Udacity-style side cameras: image key -> steering offset added to the label of that camera's frame
# (e.g. {"cam/image_array_left": 0.15, "cam/image_array_right": -0.15}: the left camera sees the road
# as if the car were left of centre, so it must steer right). Empty = centre camera only.
TRAIN_SIDE_CAMERAS: Annotated[dict[str, float], Range(-1, 1)] = {}
# Frames (rnn, 3d) or previous commands (memory) a sequence model sees.
SEQUENCE_LENGTH: Annotated[int, Range(1, 100)] = 3
# Throttle range of the categorical model's throttle bins: [0, this].
MODEL_CATEGORICAL_MAX_THROTTLE_RANGE: Annotated[float, Range(0, 1, lo_open=True)] = 0.8

# Preprocessing (stored in the model file, identical when driving): pixels cropped off the top of
# the camera frame (sky).
ROI_CROP_TOP: Annotated[int, Range(0, unit="pixels")] = 0
# Pixels cropped off the bottom of the frame (bonnet).
ROI_CROP_BOTTOM: Annotated[int, Range(0, unit="pixels")] = 0
# Pixels cropped off the left edge of the frame.
ROI_CROP_LEFT: Annotated[int, Range(0, unit="pixels")] = 0
# Pixels cropped off the right edge of the frame.
ROI_CROP_RIGHT: Annotated[int, Range(0, unit="pixels")] = 0
# (height, width) the cropped frame is resized to; None = the model type's default (pilotnet:
# (66, 200), others: the cropped size).
PREPROCESS_RESIZE: Annotated[tuple[int, int] | None, Range(1, 4096, unit="pixels")] = None
# Colour space fed to the model; None = the model type's default (pilotnet: yuv, others: rgb).
PREPROCESS_COLOR: Literal["rgb", "yuv", "hsv", "gray"] | None = None
# Pixel scaling: "unit" = [0, 1] (DonkeyCar's), "symmetric" = [-1, 1]; None = the model type's
# default, [-1, 1] for every type (centred inputs: the linear model learns from the first epoch).
PREPROCESS_NORMALIZE: Literal["unit", "symmetric"] | None = None

# Training-only augmentations, each applied with its probability AUG_<NAME>_P: flip (mirror,
# steering negated), brightness (and contrast), shadow, shift (pan with steering correction),
# zoom, blur, hue. `vehicle train preview-aug` shows them.
AUGMENTATIONS: list[Literal["flip", "brightness", "shadow", "shift", "zoom", "blur", "hue"]] = [
    "flip", "brightness", "shadow", "shift"]
# Probability of mirroring a training frame (and negating its steering).
AUG_FLIP_P: Annotated[float, Range(0, 1)] = 0.5
# Probability of a brightness/contrast change.
AUG_BRIGHTNESS_P: Annotated[float, Range(0, 1)] = 0.5
# Largest brightness change, fraction of full scale (0.2 = +-20 %).
AUG_BRIGHTNESS_RANGE: Annotated[float, Range(0, 1)] = 0.2
# Largest contrast change (0.2 = x0.8..1.2 around mid-grey).
AUG_CONTRAST_RANGE: Annotated[float, Range(0, 1)] = 0.2
# Probability of a shadow (one side of a random line from top to bottom darkened).
AUG_SHADOW_P: Annotated[float, Range(0, 1)] = 0.3
# Darkest a shadow gets: pixel values multiplied by down to this factor.
AUG_SHADOW_DARKNESS: Annotated[float, Range(0, 1)] = 0.5
# Probability of a shift (pan) of the frame, with steering correction.
AUG_SHIFT_P: Annotated[float, Range(0, 1)] = 0.5
# Largest horizontal shift, fraction of the frame width.
AUG_SHIFT_X: Annotated[float, Range(0, 1)] = 0.1
# Largest vertical shift, fraction of the frame height (no steering correction).
AUG_SHIFT_Y: Annotated[float, Range(0, 1)] = 0.05
# Steering added per full frame width of horizontal shift (a frame shifted right looks as if the car
# were left of its path, so it must steer right).
AUG_SHIFT_STEERING: Annotated[float, Range(0)] = 1.0
# Probability of a centred zoom in.
AUG_ZOOM_P: Annotated[float, Range(0, 1)] = 0.3
# Largest zoom in, as a fraction (0.3 = up to 130 %), centred.
AUG_ZOOM_RANGE: Annotated[float, Range(0, 1)] = 0.3
# Probability of a Gaussian blur.
AUG_BLUR_P: Annotated[float, Range(0, 1)] = 0.2
# Gaussian blur sigma range in pixels.
AUG_BLUR_RANGE: Annotated[tuple[float, float], Range(0, 20, lo_open=True, unit="pixels")] = (0.5, 1.5)
# Probability of turning the hues round the colour wheel ("hue": yellow tape becomes blue, grass
# purple; greys stay), so a pilot does not steer by one line colour.
AUG_HUE_P: Annotated[float, Range(0, 1)] = 0.3
# Largest hue turn in degrees (180 = any colour).
AUG_HUE_RANGE: Annotated[float, Range(0, 180, unit="degrees")] = 180.0

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
# Standard deviation of per-pixel Gaussian noise on the image (0-255 units; 0 = off).
SIM_IMAGE_NOISE: Annotated[float, Range(0, 255)] = 0.0
# Box blur kernel size in pixels (0 or 1 = off).
SIM_IMAGE_BLUR: Annotated[int, Range(0, 99, unit="pixels")] = 0
# Per-frame brightness jitter: each frame is scaled by a factor in [1 - x, 1 + x] (0 = off).
SIM_BRIGHTNESS_JITTER: Annotated[float, Range(0, 1, hi_open=True)] = 0.0
# Seed of the simulator's random parts (per-frame image effects, expert noise).
SIM_SEED: Annotated[int, Range(0, 2**32 - 1)] = 0
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

# == Simulator bridges ==

# Which simulator a simulator car drives: "builtin" (ours, in this process), "udacity" (the
# Udacity self-driving-car simulator, which connects to us) or "donkey" (the Donkey simulator or
# `vehicle sim serve`, which we connect to). `manage.py drive --sim NAME` overrides it.
SIM_TYPE: Literal["builtin", "udacity", "donkey"] = "builtin"
# Seconds without telemetry from the Udacity or Donkey simulator before its camera counts as
# stale (cam/ok False: the camera watchdog takes the pilot out) and one line says what to check.
SIM_TIMEOUT_S: Annotated[float, Range(0.1, 10, unit="s")] = 1.0
# Address of the Donkey simulator (DonkeyCar's name); it often runs on another machine.
SIM_HOST: str = "127.0.0.1"
# TCP port of the Donkey simulator (9091 unless it was started with --port).
SIM_PORT: Annotated[int, Range(1, 65535)] = 9091
# Seconds a drive keeps trying to reach the Donkey simulator at start (it may still be starting).
SIM_CONNECT_TIMEOUT_S: Annotated[float, Range(0, 3600, lo_open=True, unit="s")] = 10.0
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

# == Drivetrain (PCA9685) ==

# What drives the wheels: "PWM_STEERING_THROTTLE" = steering servo and ESC on a PCA9685 board;
# "MOCK" = the same driver code on a simulated PCA9685 (bench tests without a car).
DRIVE_TRAIN_TYPE: Literal["PWM_STEERING_THROTTLE", "MOCK"] = "PWM_STEERING_THROTTLE"
# 7-bit I2C address of the PCA9685 (0x40 with no address jumpers bridged; `i2cdetect -y 1`).
PCA9685_I2C_ADDR: Annotated[int, Range(0x03, 0x77, note="a 7-bit address, 0x03 to 0x77; 0x40 unless A0-A5 "
                                                      "are bridged")] = 0x40
# I2C bus number (/dev/i2c-N). None = bus 1, the header pins 3/5 on a Raspberry Pi and a Jetson Nano.
PCA9685_I2C_BUSNUM: Annotated[int | None, Range(0, 255)] = None
# Oscillator of the PCA9685 in Hz. Boards run a few % off 25 MHz; set a measured value to get exact
# pulse widths (calibrated tick values stay valid only at the same setting).
PCA9685_OSC_HZ: Annotated[int, Range(1_000_000, 50_000_000, unit="Hz")] = 25_000_000
# PWM frequency in Hz. The *_PWM values below are ticks (1/4096 of a period) at this frequency;
# DonkeyCar calibrations assume 60 Hz (prescale 101, 59.84 Hz, 4.08 µs per tick).
PWM_FREQ: Annotated[int, Checked("what the PCA9685 makes at PCA9685_OSC_HZ (24 to 1525 Hz at 25 MHz); "
                                  "servos and ESCs: 50 to 60")] = 60
# PCA9685 channel of the steering servo (DonkeyCar: 1).
STEERING_CHANNEL: Annotated[int, Range(0, 15)] = 1
# PCA9685 channel of the ESC (DonkeyCar: 0).
THROTTLE_CHANNEL: Annotated[int, Range(0, 15, note="not STEERING_CHANNEL")] = 0
# Steering pulse in ticks at full left (angle -1); the centre is the midpoint of LEFT and RIGHT.
STEERING_LEFT_PWM: Annotated[int, Checked(PULSE_VALID)] = 460
# Steering pulse in ticks at full right (angle +1).
STEERING_RIGHT_PWM: Annotated[int, Checked(PULSE_VALID)] = 290
# Throttle pulse in ticks at full forward (+1).
THROTTLE_FORWARD_PWM: Annotated[int, Checked(PULSE_VALID)] = 500
# Throttle pulse in ticks that stops the motor (0, the ESC's neutral; it beeps when armed).
THROTTLE_STOPPED_PWM: Annotated[int, Checked(PULSE_VALID)] = 370
# Throttle pulse in ticks at full reverse (-1).
THROTTLE_REVERSE_PWM: Annotated[int, Checked(PULSE_VALID)] = 220
# Added to every steering command (steering units, -0.5..0.5) to make the car run straight without
# recalibrating; positive moves the centre to the right.
STEERING_TRIM: Annotated[float, Range(-0.5, 0.5)] = 0.0
# Swap left and right (a servo mounted the other way round).
STEERING_INVERT: bool = False
# Swap forward and reverse (a motor wired the other way round).
THROTTLE_INVERT: bool = False
# Largest forward throttle the drivetrain passes on (fraction of full, 0..1), for every driver,
# human or pilot.
THROTTLE_FORWARD_LIMIT: Annotated[float, Range(0, 1)] = 1.0
# Largest reverse throttle the drivetrain passes on (fraction of full, 0..1).
THROTTLE_REVERSE_LIMIT: Annotated[float, Range(0, 1)] = 1.0
# Fastest growth of the throttle in full-scale units per second (None = no limit). Releasing the
# throttle is never delayed. 4.0 = full throttle reached in 0.25 s.
THROTTLE_SLEW_RATE: Annotated[float | None, Range(0, lo_open=True, unit="per second")] = None
# Seconds of neutral sent to the ESC at start so it arms (beeps); throttle commands pass only after
# this and after the throttle has been at neutral once.
ESC_ARM_TIME_S: Annotated[float, Range(0, 10, unit="s")] = 1.5
# How a negative throttle reaches the ESC: "direct" passes it on (crawler ESCs, or when the drive
# logic's throttle filter already does the double-tap); "double_tap" sends brake, neutral, then
# reverse, as forward/brake/reverse car ESCs need to back up.
ESC_REVERSE_MODE: Literal["direct", "double_tap"] = "direct"
# double_tap: seconds of the first (braking) reverse pulse.
ESC_REVERSE_BRAKE_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# double_tap: seconds of neutral after braking, before the reverse pulses that back the car up.
ESC_REVERSE_NEUTRAL_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# Command watchdog: no fresh drive command for this many seconds -> neutral (None = off). Throttle
# then stays neutral until a command at neutral arrives.
ACTUATOR_WATCHDOG_S: Annotated[float | None, Range(0, 1, lo_open=True, unit="s", note=WATCHDOG_OFF)] = 0.5
# Seconds neutral is held on shutdown before the bus is released (at least two PWM periods).
PWM_SHUTDOWN_HOLD_S: Annotated[float, Range(0, 5, unit="s")] = 0.1
# After that hold, switch both channels off (no pulses: most ESCs stop, the servo goes limp).
PWM_FULL_OFF_ON_SHUTDOWN: bool = False
# MOCK drivetrain: append every output change of the simulated board to this file
# ("<time> <channel> <ticks|off|on>" per line; relative to CAR_PATH). None = keep it in memory.
PCA9685_MOCK_TRACE: str | None = None

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

# == Behaviour ==

# Drive with behaviour states (e.g. which lane to keep): adds behavior/state, behavior/label and
# behavior/one_hot_state_array to the memory, and every tub records them (as DonkeyCar does); the
# gamepad's behaviour buttons and the web page's "change lane" button step through BEHAVIOR_LIST.
TRAIN_BEHAVIORS: bool = False
# Names of the behaviours in order; the one-hot array has one entry per name.
BEHAVIOR_LIST: Annotated[list[str], Length(min=1)] = ["Left_Lane", "Right_Lane"]
# Behaviour active at start (index into BEHAVIOR_LIST).
BEHAVIOR_INITIAL: Annotated[int, Range(0, note="an index of BEHAVIOR_LIST")] = 0

# == Web controller ==

# Serve the web controller page (camera view, joystick, keyboard, modes, recording, e-stop). With
# USE_JOYSTICK_AS_DEFAULT both drive, arbitrated by CONTROLLER_PRIORITY.
USE_WEB_CONTROLLER: bool = True
# TCP port of the page (DonkeyCar's name and default): http://localhost:8887/
WEB_CONTROL_PORT: Annotated[int, Range(0, 65535, note="0 picks a free port")] = 8887
# Interface the page listens on. "127.0.0.1" = this machine only; "0.0.0.0" = every network
# interface (a phone on the car's Wi-Fi), which then requires the pairing token.
WEB_HOST: str = "127.0.0.1"
# Pairing token browsers must present (in the page URL, ?token=...). None: none on localhost, a
# random one per start when WEB_HOST is a network interface (printed with the URL at start).
# At least 8 characters; when set it is required even on localhost.
WEB_TOKEN: Annotated[str | None, Length(min=8, secret=True,
                                        note="or None: a random token when the page is on the network")] = None
# More host names the page may be opened by, e.g. ["mycar.example.org"] for a DNS name of the car
# or a reverse proxy. IP addresses, localhost, this machine's name (and NAME.local) and WEB_HOST
# are always accepted; a request naming any other host is refused, so that a web site made to
# resolve to the car (DNS rebinding) cannot reach it.
WEB_ALLOWED_HOSTS: list[str] = []
# Dead-man time in seconds: when the driving page sends no control message for this long while
# the throttle is non-zero (or a pilot mode is on), throttle goes to 0 and the mode to user.
WEB_DEADMAN_S: Annotated[float, Range(0.1, 2, unit="s")] = 0.5
# Initial maximum throttle of the page, [0, 1]: the page's full stick gives this throttle; it can be
# changed on the page and is also the constant-throttle value.
WEB_MAX_THROTTLE: Annotated[float, Range(0, 1)] = 0.5
# Largest speed limit the page's slider offers, m/s (sent as user/speed_limit: the car's speed is
# capped at it in every mode; it needs a measured speed, the simulator's or an encoder's).
WEB_MAX_SPEED_LIMIT: Annotated[float, Range(0, 100, lo_open=True, unit="m/s")] = 5.0
# State updates (gauges, counts, loop health) sent to each page per second.
WEB_TELEMETRY_HZ: Annotated[float, Range(0, 100, lo_open=True, unit="Hz")] = 20.0
# JPEG quality of the camera view, 1-100 (80: ~3 KB for a 160x120 frame).
WEB_JPEG_QUALITY: Annotated[int, Range(1, 100)] = 80
# Who drives when both the web page and the gamepad give commands: "gamepad" (the gamepad whenever
# its stick is off centre), "web" (the page whenever its command is off centre) or "latest" (the
# source that moved last). Mode and recording: the latest change from either wins; an emergency
# stop from either holds.
CONTROLLER_PRIORITY: Literal["gamepad", "web", "latest"] = "gamepad"

# == Trainer console ==

# The trainer console (`vehicle console`, `manage.py console`): datasets, training, models and the
# leaderboard in a browser. Interface it listens on: "127.0.0.1" = this machine only; "0.0.0.0" =
# every network interface, which then requires the pairing token (WEB_TOKEN's rules).
CONSOLE_HOST: str = "127.0.0.1"
# TCP port of the console: http://localhost:8890/
CONSOLE_PORT: Annotated[int, Range(0, 65535, note="0 picks a free port")] = 8890

# == Recording ==

# Start a new tub folder DATA_PATH/tub_<N>_<YY-MM-DD> at each drive (True), or append every drive
# to the one tub DATA_PATH (False, DonkeyCar's default). One tub per drive makes a bad drive easy
# to throw away; training reads a tub or a folder of tubs either way.
AUTO_CREATE_NEW_TUB: bool = True
# Memory keys recorded into the tub and their tub types (float, int, str, boolean, nparray, list,
# vector, image_array). With RECORD_DURING_AI, pilot/angle and pilot/throttle are added. The
# camera's cam/timestamp, when some part produces it, becomes each record's _timestamp_ms.
TUB_INPUTS: Annotated[list[str], Length(min=1)] = ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
# Tub type of each TUB_INPUTS key, in the same order.
TUB_TYPES: list[Literal["float", "int", "str", "boolean", "nparray", "list", "vector", "image_array",
                        "gray16_array"]] = ["image_array", "float", "float", "str"]
# User metadata stored in the tub's manifest, "key:value" items (DonkeyCar's --meta), e.g.
# ["driver:ann", "track:garage"].
METADATA: list[str] = []
# Records per catalog file (DonkeyCar's max_catalog_len).
TUB_MAX_CATALOG_LEN: Annotated[int, Range(1)] = 1000
# Durability window: records are made durable (images synced to the disk, then their catalog
# lines appended and fsynced, then the manifest replaced atomically) every TUB_FSYNC_RECORDS records or when the
# oldest unsaved record is TUB_FSYNC_MS milliseconds old, whichever comes first. While recording, a
# crash loses at most two windows and a power cut three, plus the records still queued (see
# TUB_QUEUE_SIZE and docs/data-format.md).
TUB_FSYNC_RECORDS: Annotated[int, Range(0, note="0 commits every record")] = 20
# Age in milliseconds of the oldest unsaved record that triggers a commit (see TUB_FSYNC_RECORDS).
TUB_FSYNC_MS: Annotated[int, Range(0, unit="ms")] = 500
# fsync at each commit (protects against power loss). False: commits still happen per window, but
# only a crash of the process (not a power cut) is survived; faster on slow SD cards.
TUB_FSYNC: bool = True
# Records in flight to the recording thread (accepted, not yet written); beyond it new records are
# dropped, counted and a warning is logged (the loop never waits for the disk). 100 = 5 s at 20 Hz.
TUB_QUEUE_SIZE: Annotated[int, Range(1)] = 100
# JPEG quality of recorded images, 1-100. 75 is DonkeyCar's (PIL's default): ~3-5 KB per 160x120
# frame.
TUB_JPEG_QUALITY: Annotated[int, Range(1, 100)] = 75
