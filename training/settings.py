"""Settings of training: data selection, split, optimiser, augmentations.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any, Literal

from training.form import Form
from vehicle.config_checks import Length, Range, Rule, ordered_pair
from vehicle.keys import Mode

# == Training ==

# Model type used when training without --type.
DEFAULT_MODEL_TYPE: Annotated[str,
                              Form("model_type", "Model type", "Model",
                                   why="only registered model types can be built", flag="--type",
                                   kind="choice")] = "linear"
# Options of the model type that differ from its defaults, e.g. {"dropout": 0.1, "batch_norm":
# True} or, for pilotnet, {"activation": "elu"}; docs/training.md lists each type's options.
MODEL_OPTIONS: dict[str, Any] = {}
# Optional function record -> bool choosing which tub records are trained on (None = all).
# It receives the record's catalog fields (dict: user/angle, user/throttle, user/mode, ...).
TRAIN_FILTER: Callable[[dict[str, Any]], bool] | None = None
# Train only on records whose user/mode is listed (records driven by a pilot teach nothing new).
TRAIN_MODES: Annotated[list[Mode], Length(min=1),
                       Form("modes", "Drive modes", "Data",
                            why="training needs at least one mode to read records from")] = ["user"]
# Samples per training step.
BATCH_SIZE: Annotated[int, Range(1),
                      Form("batch_size", "Batch size", "Optimisation", why="a step needs at least one sample")] = 128
# Fraction of the records used for training; the rest validates. The split takes whole sessions or
# contiguous blocks, never random frames (neighbouring frames are near copies and would leak).
TRAIN_TEST_SPLIT: Annotated[float, Range(0, 1, note="1 trains on every record, without validation; at "
                                                      "least one block always trains"),
                            Form("val_share", "Validation share", "Data", why="it is a share of the records",
                                 help="Share of the records held out for validation (whole sessions or "
                                      "blocks, never single frames; at least one block always trains).",
                                 complement=True)] = 0.8
# "session": validate on whole recording sessions when the data has at least 2; "block": on
# contiguous blocks of TRAIN_SPLIT_BLOCK records of every tub; "random": on single random records
# (the source documents' split: optimistic, since a frame's neighbours then train).
TRAIN_SPLIT_BY: Annotated[Literal["session", "block", "random"],
                          Form("split_by", "Split by", "Data", why="only these splits exist")] = "block"
# Length of one block of the block split, in records (100 = 5 s at 20 Hz).
TRAIN_SPLIT_BLOCK: Annotated[int, Range(1),
                             Form("split_block", "Block length", "Data", why="a block holds at least one record")] = 100
# Seed of the split, balancing, shuffling and augmentations (same seed, same run).
TRAIN_SEED: Annotated[int, Range(0, 2**32 - 1),
                      Form("seed", "Random seed", "Data", why="random generators take seeds ≥ 0")] = 42
# Most epochs to train (one epoch = every training sample once).
MAX_EPOCHS: Annotated[int, Range(1),
                      Form("epochs", "Epochs", "Optimisation", why="training needs at least one epoch")] = 100
# Stop training when the validation loss stops improving (see the next two settings).
USE_EARLY_STOP: Annotated[bool,
                          Form("early_stop", "Early stopping", "Optimisation")] = True
# Epochs without an improvement of the validation loss before training stops.
EARLY_STOP_PATIENCE: Annotated[int, Range(1),
                               Form("patience", "Patience", "Optimisation",
                                    why="at least one epoch must be allowed to improve")] = 5
# Smallest decrease of the validation loss that resets early stopping's patience (the model kept is
# the lowest loss, whatever the decrease).
MIN_DELTA: Annotated[float, Range(0),
                     Form("min_delta", "Minimum improvement", "Optimisation",
                          why="an improvement cannot be negative")] = 0.0005
# Adam learning rate.
LEARNING_RATE: Annotated[float, Range(0, lo_open=True),
                         Form("learning_rate", "Learning rate", "Optimisation",
                              why="a step of size 0 or less never learns", flag="--lr")] = 0.001
# Learning-rate schedule over the whole run: "constant" keeps LEARNING_RATE; "one_cycle" warms up
# from LEARNING_RATE/25 to LEARNING_RATE over the first TRAIN_WARMUP of the steps, then anneals on a
# cosine to ~0 by the last step (Smith's one-cycle, torch's OneCycleLR): the same pilot in fewer
# epochs (docs/benchmarks.md, "demo on a training budget"). The run's length is MAX_EPOCHS, so an
# early stop ends it before the annealing.
TRAIN_LR_SCHEDULE: Annotated[Literal["constant", "one_cycle"],
                             Form("lr_schedule", "Learning-rate schedule", "Optimisation",
                                  why="only these schedules are implemented")] = "constant"
# Share of the run's steps that the one-cycle schedule warms up over.
TRAIN_WARMUP: Annotated[float, Range(0, 1, lo_open=True, hi_open=True),
                        Form("warmup", "Warm-up share", "Optimisation",
                             why="the warm-up is a share of the run, above 0 and below 1")] = 0.2
# Training steps (batches) per epoch; None = every training sample once. Fewer steps make epochs
# shorter on a large data set (each epoch then sees a different random part of it); more than one
# pass goes round the data again in a new order with new augmentations (Keras's steps_per_epoch).
TRAIN_STEPS_PER_EPOCH: Annotated[int | None, Range(1),
                                 Form("steps_per_epoch", "Steps per epoch", "Optimisation",
                                      why="an epoch needs at least one step")] = None
# Validation steps (batches) per epoch; None = every validation sample.
TRAIN_VAL_STEPS: Annotated[int | None, Range(1),
                           Form("val_steps", "Validation steps", "Optimisation",
                                why="validation needs at least one batch")] = None
# Adam weight decay (L2 penalty on the weights), 0 = off.
TRAIN_WEIGHT_DECAY: Annotated[float, Range(0),
                              Form("weight_decay", "Weight decay", "Optimisation",
                                   why="a negative penalty would reward large weights")] = 0.0
# Where to train: "auto" = the GPU when there is one (cuda), else cpu; or "cpu", "cuda", "cuda:1".
TRAIN_DEVICE: Annotated[str,
                        Form("device", "Device", "Hardware", why="torch knows these devices", kind="device")] = "auto"
# DataLoader worker processes (0 = load in the training process; cheap thanks to the frame cache).
TRAIN_NUM_WORKERS: Annotated[int, Range(0, 64),
                             Form("workers", "Data workers", "Hardware",
                                  why="a count of processes cannot be negative")] = 0
# Keep the decoded frames (uint8, as recorded) in memory so that JPEGs are decoded only once.
TRAIN_CACHE_IMAGES: bool = True
# Largest frame cache in MB; with more frames than fit, frames are decoded every epoch instead.
TRAIN_CACHE_MAX_MB: Annotated[int, Range(0, unit="MB")] = 4096
# Arithmetic precision of training. "auto": bf16 autocast on CPUs with AVX512-BF16 or AMX and on
# GPUs of compute capability 8.0+, fp16 with a gradient scaler on GPUs of 7.x, else fp32; the choice
# is logged at start. "fp32" forces full precision; "bf16"/"fp16" force autocast in that type. The
# weights and the model file stay float32 either way (docs/training.md, "Speed").
TRAIN_PRECISION: Annotated[Literal["auto", "fp32", "bf16", "fp16"],
                           Form("precision", "Precision", "Hardware",
                                why="only these precisions are implemented")] = "auto"
# Compile the model with torch.compile before training (needs a C++ compiler on CPUs, Triton on
# GPUs). Off by default: on the measured CPUs its compile time outweighs what it saves
# (docs/benchmarks.md, "training").
TRAIN_COMPILE: Annotated[bool,
                         Form("compile", "Compile", "Hardware")] = False
# Write the loss curve as a PNG next to the model.
SHOW_PLOT: bool = True
# Log the model's layers and parameter count before training.
PRINT_MODEL_SUMMARY: bool = False
# Balance the training set by steering: cut the range into TRAIN_BALANCE_BINS bins and keep at most
# TRAIN_BALANCE_MAX_PER_BIN random records per bin (straight driving otherwise dominates).
TRAIN_BALANCE: Annotated[bool,
                         Form("balance", "Balance by steering", "Data")] = False
# Number of equal-width steering bins for balancing (Track Driver AI's trainer: num_bins).
TRAIN_BALANCE_BINS: Annotated[int, Range(1),
                              Form("balance_bins", "Number of bins", "Data",
                                   why="balancing needs at least one bin")] = 25
# Most training records kept per steering bin (Track Driver AI's trainer: max_samples_per_bin).
TRAIN_BALANCE_MAX_PER_BIN: Annotated[int, Range(1),
                                     Form("max_per_bin", "Samples per bin", "Data",
                                          why="a bin must keep at least one record")] = 400
# Add a mirrored copy of every frame (steering negated, behaviours swapped) to the training and
# validation sets, doubling them: the Udacity behavioural-cloning project's deterministic
# augmentation (a random "flip" augmentation is the other way to the same end).
TRAIN_FLIP_COPY: Annotated[bool, Form("flip_copy", "Mirrored copy", "Data")] = False
# Udacity-style side cameras: image key -> steering offset added to the label of that camera's frame
# (e.g. {"cam/image_array_left": 0.15, "cam/image_array_right": -0.15}: the left camera sees the road
# as if the car were left of centre, so it must steer right). Empty = centre camera only.
TRAIN_SIDE_CAMERAS: Annotated[dict[str, float], Range(-1, 1)] = {}
# Frames (rnn, 3d) or previous commands (memory) a sequence model sees.
SEQUENCE_LENGTH: Annotated[int, Range(1, 100),
                           Form("seq_length", "Sequence length", "Model",
                                why="a sequence holds at least one frame")] = 3
# What the model's throttle output learns: "throttle" = the recorded throttle (user/throttle);
# "speed" = the recorded speed (sim/speed, else enc/speed) / TRAIN_SPEED_SCALE: the pilot then
# predicts a target speed from the frame and a PI controller (PILOT_SPEED_KP, PILOT_SPEED_KI)
# drives to it with the measured speed. A throttle depends on the speed the frame does not show
# (the expert brakes or accelerates against it), so a throttle-trained pilot learns an average and
# drives slower than its teacher; a speed target is what the frame does show (docs/pilot.md).
TRAIN_THROTTLE_LABEL: Annotated[Literal["throttle", "speed"],
                                Form("throttle_label", "Throttle label", "Data",
                                     why="only these labels are implemented")] = "throttle"
# Speed in m/s that a throttle output of 1 stands for when TRAIN_THROTTLE_LABEL = "speed"
# (stored in the model file; speeds above it are clipped).
TRAIN_SPEED_SCALE: Annotated[float, Range(0, 100, lo_open=True, unit="m/s"),
                             Form("speed_scale", "Speed scale", "Data",
                                  why="a speed scale must be a positive number of m/s")] = 4.0
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
# Pixel scaling: "unit" = [0, 1] (DonkeyCar's), "symmetric" = [-1, 1] (x / 127.5 - 1),
# "symmetric127" = x / 127 - 1 (the Udacity behavioural-cloning project's); None = the model type's
# default, [-1, 1] for every type (centred inputs: the linear model learns from the first epoch).
PREPROCESS_NORMALIZE: Literal["unit", "symmetric", "symmetric127"] | None = None
# Convert the colour space (and blur) before resizing: Track Driver AI's order (crop, YUV, blur,
# resize). False: crop, resize, then colour (cheaper: the colour conversion runs on fewer pixels).
PREPROCESS_COLOR_FIRST: bool = False
# Side of a fixed Gaussian blur kernel in pixels (odd; OpenCV's sigma for that size) applied after
# the colour conversion, 0 = none. Track Driver AI blurs 3x3 against sensor noise.
PREPROCESS_BLUR: Annotated[int, Range(0, 31, unit="pixels", note="odd, or 0 for none")] = 0
# Resampling of the resize: "area" averages the pixels a shrunk pixel covers (no aliasing);
# "linear" is OpenCV's and TensorFlow's default, which both Udacity-simulator documents use.
PREPROCESS_INTERPOLATION: Literal["area", "linear"] = "area"

# Training-only augmentations, each applied with its probability AUG_<NAME>_P, in the order listed:
# flip (mirror, steering negated), brightness (and contrast, additive), multiply (brightness as a
# factor), shadow, shift (pan with steering correction), zoom, blur, hue; and on the whole batch at
# once, after those and the preprocessing (RGB models only): light (gamma, contrast, brightness),
# colour (hue and saturation), noise, cutout. `vehicle train preview-aug` shows the per-frame ones.
AUGMENTATIONS: Annotated[list[Literal["flip", "brightness", "multiply", "shadow", "shift", "zoom", "blur", "hue",
                                      "light", "colour", "noise", "cutout"]],
                         Form("augmentations", "Augmentations", "Augmentation",
                              why="only these augmentations exist", flag="--aug")] = [
    "flip", "shift", "brightness", "shadow"]
# Probability of mirroring a training frame (and negating its steering).
AUG_FLIP_P: Annotated[float, Range(0, 1),
                      Form("aug_flip_p", "Flip probability", "Augmentation", why="it is a probability")] = 0.5
# Probability of a brightness/contrast change.
AUG_BRIGHTNESS_P: Annotated[float, Range(0, 1),
                            Form("aug_brightness_p", "Brightness probability", "Augmentation",
                                 why="it is a probability")] = 0.5
# Largest brightness change, fraction of full scale (0.2 = +-20 %).
AUG_BRIGHTNESS_RANGE: Annotated[float, Range(0, 1),
                                Form("aug_brightness_range", "Brightness range", "Augmentation",
                                     why="it is a fraction of full scale")] = 0.2
# Largest contrast change (0.2 = x0.8..1.2 around mid-grey).
AUG_CONTRAST_RANGE: Annotated[float, Range(0, 1),
                              Form("aug_contrast_range", "Contrast range", "Augmentation",
                                   why="a contrast below 0 inverts the image")] = 0.2
# Probability of multiplying every pixel by one random factor (Track Driver AI's brightness).
AUG_MULTIPLY_P: Annotated[float, Range(0, 1),
                          Form("aug_multiply_p", "Multiply probability", "Augmentation",
                               why="it is a probability")] = 0.5
# Range of that factor (0.2, 1.2 = from a fifth of the brightness to 20 % brighter).
AUG_MULTIPLY_RANGE: Annotated[tuple[float, float], Range(0, 10)] = (0.2, 1.2)
# Probability of a shadow (one side of a random line from top to bottom darkened).
AUG_SHADOW_P: Annotated[float, Range(0, 1),
                        Form("aug_shadow_p", "Shadow probability", "Augmentation", why="it is a probability")] = 0.3
# Darkest a shadow gets: pixel values multiplied by down to this factor.
AUG_SHADOW_DARKNESS: Annotated[float, Range(0, 1),
                               Form("aug_shadow_darkness", "Shadow darkness", "Augmentation",
                                    why="it is a brightness factor")] = 0.5
# Probability of a shift (pan) of the frame, with steering correction.
AUG_SHIFT_P: Annotated[float, Range(0, 1),
                       Form("aug_shift_p", "Shift probability", "Augmentation", why="it is a probability")] = 0.5
# Largest horizontal shift, fraction of the frame width.
AUG_SHIFT_X: Annotated[float, Range(0, 1),
                       Form("aug_shift_x", "Shift x", "Augmentation", why="it is a fraction of the width")] = 0.1
# Largest vertical shift, fraction of the frame height (no steering correction).
AUG_SHIFT_Y: Annotated[float, Range(0, 1),
                       Form("aug_shift_y", "Shift y", "Augmentation", why="it is a fraction of the height")] = 0.05
# Steering added per full frame width of horizontal shift (a frame shifted right looks as if the car
# were left of its path, so it must steer right).
AUG_SHIFT_STEERING: Annotated[float, Range(0),
                              Form("aug_shift_steering", "Shift steering", "Augmentation",
                                   why="a shift to the right must steer right, not left")] = 1.0
# What fills the edge a shift or zoom uncovers: "replicate" (the nearest pixels) or "constant"
# (black: imgaug's Affine default, which Track Driver AI used).
AUG_BORDER: Literal["replicate", "constant"] = "replicate"
# Probability of a centred zoom in.
AUG_ZOOM_P: Annotated[float, Range(0, 1),
                      Form("aug_zoom_p", "Zoom probability", "Augmentation", why="it is a probability")] = 0.3
# Largest zoom in, as a fraction (0.3 = up to 130 %), centred.
AUG_ZOOM_RANGE: Annotated[float, Range(0, 1),
                          Form("aug_zoom_range", "Zoom range", "Augmentation",
                               why="it is a fraction of the size")] = 0.3
# Probability of a Gaussian blur.
AUG_BLUR_P: Annotated[float, Range(0, 1),
                      Form("aug_blur_p", "Blur probability", "Augmentation", why="it is a probability")] = 0.2
# Gaussian blur sigma range in pixels.
AUG_BLUR_RANGE: Annotated[tuple[float, float], Range(0, 20, lo_open=True, unit="pixels")] = (0.5, 1.5)
# Probability of turning the hues round the colour wheel ("hue": yellow tape becomes blue, grass
# purple; greys stay), so a pilot does not steer by one line colour.
AUG_HUE_P: Annotated[float, Range(0, 1),
                     Form("aug_hue_p", "Hue probability", "Augmentation", why="it is a probability")] = 0.3
# Largest hue turn in degrees (180 = any colour).
AUG_HUE_RANGE: Annotated[float, Range(0, 180, unit="degrees"),
                         Form("aug_hue_range", "Hue range", "Augmentation",
                              why="half the colour wheel reaches every colour")] = 180.0

# Probability of the batch "light" augmentation: a camera's exposure and response (a tone curve,
# then contrast around mid-grey, then brightness), drawn per sample.
AUG_LIGHT_P: Annotated[float, Range(0, 1),
                       Form("aug_light_p", "Light probability", "Augmentation", why="it is a probability")] = 0.5
# Largest brightness change of "light", fraction of full scale (0.25 = +-25 %).
AUG_LIGHT_BRIGHTNESS: Annotated[float, Range(0, 1),
                                Form("aug_light_brightness", "Light brightness", "Augmentation",
                                     why="it is a fraction of full scale")] = 0.25
# Largest contrast change of "light" (0.3 = x0.7..1.3 around mid-grey).
AUG_LIGHT_CONTRAST: Annotated[float, Range(0, 1),
                              Form("aug_light_contrast", "Light contrast", "Augmentation",
                                   why="a contrast below 0 inverts the image")] = 0.3
# Largest tone curve of "light": v + a * v * (1 - v) on values in [0, 1], a drawn in [-this, this]
# (0.5 lifts mid-grey to 0.625 or lowers it to 0.375, about gamma 0.7 or 1.5; black and white stay).
AUG_LIGHT_CURVE: Annotated[float, Range(0, 1),
                           Form("aug_light_curve", "Light curve", "Augmentation",
                                why="beyond 1 the curve is no longer monotonic")] = 0.5
# Probability of the batch "colour" augmentation (hue turn and saturation change), per sample.
AUG_COLOUR_P: Annotated[float, Range(0, 1),
                        Form("aug_colour_p", "Colour probability", "Augmentation", why="it is a probability")] = 0.5
# Largest hue turn of "colour" in degrees (a colour cast or white balance; "hue" turns further).
AUG_COLOUR_HUE: Annotated[float, Range(0, 180, unit="degrees"),
                          Form("aug_colour_hue", "Colour hue", "Augmentation",
                               why="half the colour wheel reaches every colour")] = 30.0
# Largest saturation change of "colour" (0.5 = x0.5..1.5; 0 = grey is reachable at 1).
AUG_COLOUR_SATURATION: Annotated[float, Range(0, 1),
                                 Form("aug_colour_saturation", "Colour saturation", "Augmentation",
                                      why="a saturation below 0 inverts the colours")] = 0.5
# Probability of Gaussian sensor noise on a sample ("noise").
AUG_NOISE_P: Annotated[float, Range(0, 1),
                       Form("aug_noise_p", "Noise probability", "Augmentation", why="it is a probability")] = 0.3
# Strongest noise of "noise": standard deviation drawn up to this, in 0-255 units.
AUG_NOISE_SIGMA: Annotated[float, Range(0, 128),
                           Form("aug_noise_sigma", "Noise sigma", "Augmentation",
                                why="a standard deviation in 0-255 units")] = 12.0
# Probability of one flat grey rectangle over a sample ("cutout": occlusion).
AUG_CUTOUT_P: Annotated[float, Range(0, 1),
                        Form("aug_cutout_p", "Cutout probability", "Augmentation", why="it is a probability")] = 0.3
# Largest side of the cutout rectangle, fraction of the frame's height and width.
AUG_CUTOUT_SIZE: Annotated[float, Range(0, 1),
                           Form("aug_cutout_size", "Cutout size", "Augmentation",
                                why="it is a fraction of the frame")] = 0.3


#: rules across this module's settings, run after every setting passed its own range
RULES: tuple[Rule, ...] = (ordered_pair("AUG_BLUR_RANGE"),)
