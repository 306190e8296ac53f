"""The source documents' recipes (seed 000, 001, 002): every stated value set, preprocessing and
augmentation against references written from the documents' text, parameter counts against their
layer lists, and the recipe through `vehicle train`."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import pytest
import torch

from parts.pilots.models import create_model
from parts.pilots.preprocess import preprocess_from_config
from training.augment import Augmenter, AugmentSettings
from training.recipes import LEFT_KEY, RECIPES, RIGHT_KEY, recipe
from vehicle.config import Config


def _cfg(name: str) -> Config:
    return Config.defaults(**RECIPES[name].settings)


def _frame(h: int, w: int, seed: int = 3) -> np.ndarray:
    """A textured RGB frame: smooth gradients plus noise, so blur, resize and colour all show."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    base = np.stack([x / w * 255, y / h * 255, (x + y) / (w + h) * 255], axis=2)
    return np.clip(base + rng.normal(0, 25, (h, w, 3)), 0, 255).astype(np.uint8)


def _preprocess(name: str):
    r = RECIPES[name]
    return preprocess_from_config(_cfg(name), r.model_type, (*r.frame_shape, 3))


# -- preprocessing, as each document writes it


def test_track_driver_ai_preprocessing_is_the_documents_pixel_for_pixel():
    """seed 000, preprocess_image: image[60:135]; RGB2YUV; GaussianBlur((3, 3), 0); cv2.resize(image,
    (200, 66)); image / 255."""
    frame = _frame(160, 320)
    ref = frame[60:135, :, :]
    ref = cv2.cvtColor(ref, cv2.COLOR_RGB2YUV)
    ref = cv2.GaussianBlur(ref, (3, 3), 0)
    ref = cv2.resize(ref, (200, 66))
    ref = ref / 255
    ours = _preprocess("track-driver-ai").array(frame)  # (C, H, W) float32
    assert ours.shape == (3, 66, 200)
    np.testing.assert_allclose(ours.transpose(1, 2, 0), ref, rtol=0, atol=1e-6)


def test_udacity_bc_preprocessing_is_the_documents():
    """seed 001 (and the issue's reading of it): Cropping2D(((50, 20), (0, 0))), resize to 66x200
    (tf.image.resize: bilinear), YUV, x / 127 - 1. Within 1e-6: OpenCV's bilinear resize is the
    reference's resampling."""
    frame = _frame(160, 320, seed=5)
    ref = frame[50:160 - 20, :, :]
    ref = cv2.resize(ref, (200, 66), interpolation=cv2.INTER_LINEAR)
    ref = cv2.cvtColor(ref, cv2.COLOR_RGB2YUV)
    ref = ref / 127.0 - 1.0
    ours = _preprocess("udacity-bc").array(frame)
    assert ours.shape == (3, 66, 200)
    np.testing.assert_allclose(ours.transpose(1, 2, 0), ref, rtol=0, atol=1e-6)
    white = _preprocess("udacity-bc").array(np.full((160, 320, 3), 255, np.uint8))
    assert white[0].max() == pytest.approx(255 / 127 - 1)  # 1.008: the document's scaling, not [-1, 1]


def test_donkey_thesis_preprocessing_is_donkeycars():
    """seed 002, §8.5.1 on DonkeyCar: the 120x160 frame as it is, scaled to [0, 1]."""
    frame = _frame(120, 160, seed=7)
    ours = _preprocess("donkey-thesis").array(frame)
    np.testing.assert_allclose(ours.transpose(1, 2, 0), frame / 255, rtol=0, atol=1e-6)


# -- seed 000's augmenter


def _doc_pan(image: np.ndarray, fx: float, fy: float) -> np.ndarray:
    """iaa.Affine(translate_percent={"x": fx, "y": fy}): shift by a fraction of the size, black edge."""
    h, w = image.shape[:2]
    dx, dy = int(round(fx * w)), int(round(fy * h))
    out = np.zeros_like(image)
    ys, yd = (slice(0, h - dy), slice(dy, h)) if dy >= 0 else (slice(-dy, h), slice(0, h + dy))
    xs, xd = (slice(0, w - dx), slice(dx, w)) if dx >= 0 else (slice(-dx, w), slice(0, w + dx))
    out[yd, xd] = image[ys, xs]
    return out


def _doc_zoom(image: np.ndarray, scale: float) -> np.ndarray:
    """iaa.Affine(scale=s), s >= 1: the centre 1/s of the frame blown up to the whole frame."""
    h, w = image.shape[:2]
    ch, cw = h / scale, w / scale
    m = np.float32([[cw / w, 0, (w - cw) / 2], [0, ch / h, (h - ch) / 2]])  # output -> input
    return cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)


def _doc_multiply(image: np.ndarray, factor: float) -> np.ndarray:
    """iaa.Multiply(f): every value times f in float32 (imgaug's lookup table), saturated to uint8."""
    return np.clip(np.rint(image.astype(np.float32) * np.float32(factor)), 0, 255).astype(np.uint8)


def test_track_driver_ai_augmenter_settings_are_the_documents():
    s = AugmentSettings.from_config(_cfg("track-driver-ai"))
    assert s.names == ("shift", "zoom", "multiply", "flip")  # random_augment: pan, zoom, brightness, flip
    assert (s.shift_p, s.zoom_p, s.multiply_p, s.flip_p) == (0.5, 0.5, 0.5, 0.5)  # p = 0.5 each
    assert (s.shift_x, s.shift_y, s.shift_steering) == (0.1, 0.1, 0.0)  # +-10 % in x and y, no correction
    assert s.zoom_range == pytest.approx(0.3) and s.multiply_range == (0.2, 1.2) and s.border == "constant"


@pytest.mark.parametrize("ops", [
    [("shift", {"dx": 0.1, "dy": -0.1})],
    [("shift", {"dx": -0.05, "dy": 0.05})],
    [("multiply", {"factor": 0.2})],
    [("multiply", {"factor": 1.2})],
    [("flip", {})],
    [("zoom", {"scale": 1.25})],
    [("shift", {"dx": 0.1, "dy": 0.1}), ("multiply", {"factor": 0.7}), ("flip", {})],
])
def test_track_driver_ai_augmentations_match_the_documents(ops):
    """Each operation and a combination, on fixed parameters, against the reference: exact, but for
    the zoom's bilinear resampling (mean difference < 1 grey level)."""
    frame = _frame(160, 320, seed=11)
    aug = Augmenter(AugmentSettings.from_config(_cfg("track-driver-ai")))
    ref, angle = frame, 0.3
    for name, p in ops:
        if name == "shift":
            ref = _doc_pan(ref, p["dx"], p["dy"])
        elif name == "zoom":
            ref = _doc_zoom(ref, p["scale"])
        elif name == "multiply":
            ref = _doc_multiply(ref, p["factor"])
        else:
            ref, angle = cv2.flip(ref, 1), -angle
    ours = aug.apply(frame, ops)
    assert aug.steering(0.3, ops) == pytest.approx(angle)  # the pan corrects nothing
    diff = np.abs(ours.astype(np.int16) - ref.astype(np.int16))
    if any(name == "zoom" for name, _ in ops):
        assert diff.mean() < 1.0
    else:
        assert diff.max() == 0


def test_track_driver_ai_augmenter_draws_each_operation_half_the_time_in_order():
    aug = Augmenter(AugmentSettings.from_config(_cfg("track-driver-ai")))
    rng = np.random.default_rng(0)
    draws = [aug.draw(rng) for _ in range(4000)]
    for name in ("shift", "zoom", "multiply", "flip"):
        share = np.mean([any(n == name for n, _ in d) for d in draws])
        assert 0.46 < share < 0.54, (name, share)
    order = {"shift": 0, "zoom": 1, "multiply": 2, "flip": 3}
    assert all([order[n] for n, _ in d] == sorted(order[n] for n, _ in d) for d in draws)
    factors = [p["factor"] for d in draws for n, p in d if n == "multiply"]
    scales = [p["scale"] for d in draws for n, p in d if n == "zoom"]
    assert 0.2 <= min(factors) < 0.25 and 1.15 < max(factors) <= 1.2
    assert 1.0 <= min(scales) < 1.02 and 1.28 < max(scales) <= 1.3


# -- architectures, counted from the documents' layer lists


def _count(input_hw: tuple[int, int], channels: int, convs: list[tuple[int, int, int]], dense: list[int]) -> int:
    """Parameters of Conv2D('valid') + Dense layers as Keras counts them."""
    h, w = input_hw
    total, c = 0, channels
    for filters, k, s in convs:
        total += filters * (k * k * c + 1)
        h, w, c = (h - k) // s + 1, (w - k) // s + 1, filters
    n = h * w * c
    for units in dense:
        total += units * (n + 1)
        n = units
    return total


DAVE2 = [(24, 5, 2), (36, 5, 2), (48, 5, 2), (64, 3, 1), (64, 3, 1)]


def _params(model: torch.nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def test_track_driver_ai_model_is_dave2_with_elu_and_no_dropout():
    r = RECIPES["track-driver-ai"]
    model = create_model(r.model_type, _preprocess("track-driver-ai").output_shape((160, 320, 3)),
                         **r.settings["MODEL_OPTIONS"])
    assert _params(model) == _count((66, 200), 3, DAVE2, [100, 50, 10, 1]) == 252_219
    acts = [m for m in model.modules() if isinstance(m, torch.nn.ELU | torch.nn.ReLU)]
    assert len(acts) == 8 and all(isinstance(m, torch.nn.ELU) for m in acts)  # 5 conv + 3 dense, all ELU
    assert all(m.p == 0 for m in model.modules() if isinstance(m, torch.nn.Dropout))


def test_udacity_bc_model_is_pilotnet_with_relu_and_dropout_half():
    r = RECIPES["udacity-bc"]
    model = create_model(r.model_type, _preprocess("udacity-bc").output_shape((160, 320, 3)),
                         **r.settings["MODEL_OPTIONS"])
    # the document's model.summary(): "Total params: 252,219"
    assert _params(model) == _count((66, 200), 3, DAVE2, [100, 50, 10, 1]) == 252_219
    assert all(isinstance(m, torch.nn.ReLU) for m in model.modules() if isinstance(m, torch.nn.ELU | torch.nn.ReLU))
    assert [m.p for m in model.modules() if isinstance(m, torch.nn.Dropout) and m.p > 0] == [0.5]


def test_thesis_nvidia_model_follows_its_layer_list():
    """§8.5.1: 120x160x3 input, DAVE-2 convolutions each followed by Dropout(0.1), the first with no
    activation; Dense 100/50/25/10/5 ReLU; two outputs."""
    model = create_model("nvidia", _preprocess("donkey-thesis").output_shape((120, 160, 3)))
    assert _params(model) == _count((120, 160), 3, DAVE2, [100, 50, 25, 10, 5, 2]) == 803_700
    features = list(model.features)
    assert isinstance(features[0], torch.nn.Conv2d) and isinstance(features[1], torch.nn.Dropout)
    assert [m.p for m in features if isinstance(m, torch.nn.Dropout)] == [0.1] * 5
    assert sum(isinstance(m, torch.nn.ReLU) for m in features) == 4
    out = model.eval()(torch.zeros(2, 3, 120, 160))
    assert out.shape == (2, 2)  # steering, throttle


def test_thesis_first_two_stream_model_has_its_parameter_count():
    """§9.1-9.2.1 (oriModel without behaviours) on the thesis's 180x320 frames: two streams of
    Conv 24/32/64 5x5/2, 64/64 3x3 -> Dense 100 each; Dense 100, 50; two outputs."""
    streams = 2 * _count((180, 320), 3, [(24, 5, 2), (32, 5, 2), (64, 5, 2), (64, 3, 1), (64, 3, 1)], [100])
    head = (200 + 1) * 100 + (100 + 1) * 50 + 2 * (50 + 1)
    model = create_model("lanes_basic", (4, 180, 320))
    assert _params(model) == streams + head == 6_653_804
    assert model.eval()(torch.zeros(1, 4, 180, 320)).shape == (1, 2)


def test_batch_norm_switch_adds_a_normalisation_after_each_convolution():
    for name, shape in (("linear", (3, 120, 160)), ("pilotnet", (3, 66, 200)), ("nvidia", (3, 120, 160))):
        plain = create_model(name, shape)
        normed = create_model(name, shape, batch_norm=True)
        norms = [m for m in normed.modules() if isinstance(m, torch.nn.BatchNorm2d)]
        assert len(norms) == 5, name
        # each convolution loses its bias (the norm has one) and gains scale and shift
        assert _params(normed) == _params(plain) + sum(m.num_features for m in norms), name


def test_group_norm_normalises_each_frame_on_its_own():
    from parts.pilots.models.base import GROUP_NORM_GROUPS

    plain = create_model("linear", (3, 80, 160))
    normed = create_model("linear", (3, 80, 160), group_norm=True)
    norms = [m for m in normed.modules() if isinstance(m, torch.nn.GroupNorm)]
    assert [m.num_groups for m in norms] == [GROUP_NORM_GROUPS] * 5
    assert _params(normed) == _params(plain) + sum(m.num_channels for m in norms)
    # per frame: a frame's features do not depend on the other frames of its batch, in training too
    normed.train()
    for m in normed.modules():  # no dropout: deterministic
        if hasattr(m, "p"):
            m.p = 0.0
    torch.manual_seed(0)
    a, b = torch.rand(1, 3, 80, 160), torch.rand(1, 3, 80, 160)
    alone = normed.features(a)
    beside = normed.features(torch.cat([a, 3 * b - 1]))[:1]
    assert torch.allclose(alone, beside, atol=1e-5)
    with pytest.raises(ValueError, match="choose one normalisation"):
        create_model("linear", (3, 80, 160), group_norm=True, batch_norm=True)


def test_he_init_keeps_the_signal_through_the_core_cnn():
    # torch's default initialisation shrinks the signal at every ReLU layer; He's keeps its scale
    torch.manual_seed(0)
    x = torch.rand(32, 3, 80, 160) * 2 - 1
    spread = {}
    for he in (False, True):
        torch.manual_seed(1)
        model = create_model("linear", (3, 80, 160), he_init=he).eval()
        with torch.no_grad():
            spread[he] = model.features(x).std().item()
    assert spread[True] > 5 * spread[False]


# -- the recipes' other values


def test_each_recipe_states_every_documented_value():
    tda = RECIPES["track-driver-ai"].settings
    assert (tda["LEARNING_RATE"], tda["MAX_EPOCHS"], tda["TRAIN_STEPS_PER_EPOCH"], tda["TRAIN_VAL_STEPS"],
            tda["BATCH_SIZE"]) == (1e-3, 10, 300, 200, 100)
    assert (tda["TRAIN_BALANCE"], tda["TRAIN_BALANCE_BINS"], tda["TRAIN_BALANCE_MAX_PER_BIN"]) == (True, 25, 400)
    assert (tda["TRAIN_TEST_SPLIT"], tda["TRAIN_SPLIT_BY"]) == (0.8, "random")
    assert tda["TRAIN_SIDE_CAMERAS"] == {LEFT_KEY: 0.15, RIGHT_KEY: -0.15}
    assert RECIPES["track-driver-ai"].drive_settings["PILOT_SPEED_LIMIT_HEADROOM"] == 1.25
    bc = RECIPES["udacity-bc"].settings
    assert bc["TRAIN_FLIP_COPY"] and bc["AUGMENTATIONS"] == [] and bc["MAX_EPOCHS"] == 10
    assert bc["TRAIN_SIDE_CAMERAS"] == {LEFT_KEY: 0.2, RIGHT_KEY: -0.2} and not bc["USE_EARLY_STOP"]
    assert RECIPES["udacity-bc"].drive_settings["PILOT_SPEED_CONTROL"] == "drivepy"
    for r in RECIPES.values():  # every setting a recipe names is a real one, of a valid value
        Config.defaults(**r.settings, **r.drive_settings)


def test_unknown_recipe_and_wrong_frames_say_what_to_do():
    with pytest.raises(ValueError, match="Did you mean 'udacity-bc'"):
        recipe("udacity_bc")
    with pytest.raises(ValueError, match="SIM_CAMERA_W = 320 and SIM_CAMERA_H = 160"):
        recipe("track-driver-ai").check_frames((120, 160, 3))
    recipe("donkey-thesis").check_frames((120, 160, 3))


def test_flip_copy_doubles_the_data_with_mirrored_frames(tiny_tub):
    from parts.pilots.preprocess import Preprocess
    from training.dataset import PilotDataset, build_samples, read_drive_data
    from training.framecache import FrameCache

    data = read_drive_data([tiny_tub])
    samples = build_samples(data, np.arange(10)).with_mirrored_copies()
    ds = PilotDataset(data, samples, FrameCache(data.records, ["cam/image_array"]), Preprocess())
    assert len(ds) == 20
    for i in range(10):
        x, _, y = ds[i]
        xm, _, ym = ds[10 + i]
        assert torch.equal(xm, x.flip(-1))  # (C, H, W): mirrored left-right
        assert ym[0].item() == pytest.approx(-y[0].item()) and ym[1].item() == pytest.approx(y[1].item())


def _train_args(*argv: str) -> argparse.Namespace:
    from vehicle.app.commands.train import add_train_arguments

    parser = argparse.ArgumentParser()
    add_train_arguments(parser)
    return parser.parse_args(list(argv))


def test_vehicle_train_recipe_trains_as_the_document_and_names_the_model_by_dataset(tmp_path, torch_one_thread):
    from parts.pilots.modelfile import load_model
    from tests.fixtures.pilots import write_tub
    from vehicle.app.commands.train import run_from_args

    tub = write_tub(tmp_path / "drive_1", n=30, sessions=1, size=(160, 320))
    cfg = Config.defaults(CAR_PATH=str(tmp_path))
    # the document's 10 x 300 steps of 100, cut short here by the options, which win over the recipe
    args = _train_args("--tubs", str(tub), "--recipe", "track-driver-ai", "--epochs", "1",
                       "--steps-per-epoch", "2", "--val-steps", "1", "--batch-size", "4")
    assert run_from_args(cfg, args) == 0
    path = tmp_path / "models" / "drive_1_1.pt"  # [dataset]_[N]
    model, meta = load_model(path)
    assert meta["training"]["recipe"] == "track-driver-ai" and meta["type"] == "pilotnet"
    assert meta["model"]["options"]["activation"] == "elu" and meta["model"]["options"]["dropout"] == 0.0
    assert meta["preprocess"]["crop"] == [60, 25, 0, 0] and meta["preprocess"]["blur"] == 3
    assert meta["preprocess"]["color_first"] is True and meta["preprocess"]["normalize"] == "unit"
    assert meta["training"]["batch_size"] == 4 and meta["training"]["steps_per_epoch"] == 2
    assert meta["training"]["balance"] == {"bins": 25, "max_per_bin": 400}
    assert run_from_args(cfg, args) == 0
    assert (tmp_path / "models" / "drive_1_2.pt").is_file()


def test_udacity_bc_recipe_doubles_the_samples(tmp_path, torch_one_thread):
    from training.trainer import train

    tub = __import__("tests.fixtures.pilots", fromlist=["write_tub"]).write_tub(
        tmp_path / "tub", n=20, sessions=1, size=(160, 320))
    cfg = Config.defaults(**{**RECIPES["udacity-bc"].settings, "MAX_EPOCHS": 1, "BATCH_SIZE": 8})
    metrics = train(cfg, [tub], tmp_path / "m.pt", register=False, recipe=RECIPES["udacity-bc"])
    assert metrics["train_samples"] == 2 * 16 and metrics["val_samples"] == 2 * 4  # 80/20 of 20, mirrored


def test_steps_per_epoch_beyond_one_pass_go_round_the_data_again(tiny_tub, tmp_path, torch_one_thread):
    """The document's 300 steps of 100 per epoch are 300 batches whatever the data's size (Keras's
    generator); here 96 training samples make 6 batches of 16 a pass, and an epoch asks for 14."""
    from training.trainer import train

    batches: list[tuple[int, int]] = []

    def on_event(event):
        if event["event"] == "batch":
            batches.append((event["epoch"], event["batch"]))

    cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=2, TRAIN_STEPS_PER_EPOCH=14, AUGMENTATIONS=[], TRAIN_SEED=0)
    train(cfg, [tiny_tub], tmp_path / "m.pt", register=False, on_event=on_event)
    assert [b for e, b in batches if e == 1][-1] == 14 and [b for e, b in batches if e == 2][-1] == 14
