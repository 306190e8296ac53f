"""From tubs to samples: filters, labels, history, side cameras, the frame cache, and the one
preprocessing path shared by training and driving."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from parts.pilots.modelfile import load_model, save_model
from parts.pilots.models import create_model
from parts.pilots.preprocess import Preprocess, preprocess_from_config
from training.augment import Augmenter, AugmentSettings
from training.dataset import PilotDataset, build_samples, read_drive_data
from training.framecache import FrameCache
from vehicle.config import Config


def test_records_labels_sessions_and_continuity(tiny_tub):
    data = read_drive_data([tiny_tub])
    assert len(data) == 120 and data.tubs == [str(tiny_tub)]
    assert data.angles[7] == pytest.approx(np.sin(1.0), abs=1e-6)
    assert data.throttles[7] == pytest.approx(0.3 + 0.2 * np.sin(1.0), abs=1e-6)
    assert list(np.unique(data.segments)) == [0, 1]  # two recording sessions
    assert data.prev[0] == -1 and data.prev[1] == 0
    assert data.prev[60] == -1  # a new session starts a new history


def test_filters_modes_and_train_filter(make_tub, tmp_path):
    tub = make_tub(n=40, sessions=1, local_every=4)
    assert len(read_drive_data([tub])) == 30  # the 10 records driven by the pilot are skipped
    assert len(read_drive_data([tub], modes=None)) == 40
    data = read_drive_data([tub], record_filter=lambda r: r["user/angle"] >= 0)
    assert len(data) > 0 and (data.angles >= 0).all()
    # a filtered-out record breaks the history of the one after it
    assert (data.prev[1:] == -1).sum() >= 1
    with pytest.raises(ValueError, match="no training records"):
        read_drive_data([tub], record_filter=lambda r: False)
    with pytest.raises(ValueError, match="no such tub"):
        read_drive_data([tmp_path / "nope"])


def test_history_chains_skip_records_without_full_history(tiny_tub):
    data = read_drive_data([tiny_tub])
    samples = build_samples(data, np.arange(len(data)), depth=2)
    assert len(samples) == 120 - 2 * 2  # the first two records of each session have no history
    assert np.array_equal(samples.chain[0], [2, 1, 0])


def test_memory_and_sequence_items(tiny_tub):
    data = read_drive_data([tiny_tub])
    cache = FrameCache(data.records, ["cam/image_array"])
    pre = Preprocess()
    samples = build_samples(data, np.arange(len(data)), depth=3)
    mem = PilotDataset(data, samples, cache, pre, command_history=3, extra_size=6)
    x, extra, y = mem[0]  # record 3 with records 0, 1, 2 before it
    assert x.shape == (3, 64, 64) and x.dtype == torch.uint8
    expected = np.stack([data.angles[[0, 1, 2]], data.throttles[[0, 1, 2]]], 1).reshape(-1)
    assert torch.allclose(extra, torch.from_numpy(expected))
    assert y.tolist() == pytest.approx([data.angles[3], data.throttles[3]])
    seq = PilotDataset(data, samples, cache, pre, frames=3)
    x, extra, _ = seq[0]
    assert x.shape == (3, 3, 64, 64) and extra.numel() == 0
    assert torch.equal(x[0], Preprocess.to_chw(data.records[1].image()))  # oldest first
    assert torch.equal(x[2], Preprocess.to_chw(data.records[3].image()))
    beh = PilotDataset(data, samples, cache, pre, extra_key="behavior/one_hot_state_array", extra_size=2)
    assert beh[0][1].tolist() == [1.0, 0.0]
    bad = PilotDataset(data, samples, cache, pre, extra_key="behavior/one_hot_state_array", extra_size=3)
    with pytest.raises(ValueError, match="has 2 values, the model expects 3"):
        bad[0]


def test_flip_negates_memory_angles_too(tiny_tub):
    data = read_drive_data([tiny_tub])
    samples = build_samples(data, np.arange(len(data)), depth=2)
    flip = Augmenter(AugmentSettings(names=("flip",), flip_p=1.0))
    ds = PilotDataset(data, samples, FrameCache(data.records, ["cam/image_array"]), Preprocess(),
                      command_history=2, extra_size=4, augmenter=flip)
    x, extra, y = ds[10]
    pos = samples.chain[10]
    assert y[0].item() == pytest.approx(-data.angles[pos[0]])
    assert extra[0].item() == pytest.approx(-data.angles[pos[2]])
    assert extra[1].item() == pytest.approx(data.throttles[pos[2]])
    assert torch.equal(x, Preprocess.to_chw(data.records[pos[0]].image()[:, ::-1]))


def test_frame_cache_decodes_once_and_holds_raw_frames(tiny_tub):
    data = read_drive_data([tiny_tub])
    cache = FrameCache(data.records, ["cam/image_array"])
    assert cache.fill(np.arange(len(data))).size == 0
    decoded = cache.decodes
    assert decoded == 120 + 1  # every frame once (+ the probe of the first)
    aug = Augmenter(AugmentSettings(names=("flip", "brightness", "shift"), flip_p=1, brightness_p=1, shift_p=1))
    ds = PilotDataset(data, build_samples(data, np.arange(len(data))), cache,
                      Preprocess(crop=(10, 0, 0, 0), resize=(32, 32), color="yuv"), augmenter=aug)
    for epoch in range(2):
        ds.set_epoch(epoch)
        for i in range(len(ds)):
            ds[i]
    assert cache.decodes == decoded  # later epochs never decode a JPEG again
    # the cache still holds the frame exactly as decoded: never a processed or augmented one
    assert np.array_equal(cache.get(5), data.records[5].image())
    limited = FrameCache(data.records, ["cam/image_array"], max_mb=0.01)
    limited.fill(np.arange(len(data)))
    assert not limited.cached and np.array_equal(limited.get(5), data.records[5].image())


def test_augmented_items_are_reproducible_per_epoch(tiny_tub):
    data = read_drive_data([tiny_tub])
    aug = Augmenter(AugmentSettings(names=("brightness", "shift"), brightness_p=1, shift_p=1))
    ds = PilotDataset(data, build_samples(data, np.arange(len(data))),
                      FrameCache(data.records, ["cam/image_array"]), Preprocess(), augmenter=aug, seed=1)
    first = ds[3]
    assert torch.equal(first[0], ds[3][0])
    ds.set_epoch(1)
    assert not torch.equal(first[0], ds[3][0])


def test_side_cameras_add_samples_with_steering_offset(tmp_path):
    from parts.tub import Tub

    tub = Tub(tmp_path / "udacity", inputs=["cam/image_array", "cam/left_image_array", "cam/right_image_array",
                                             "user/angle", "user/throttle"],
              types=["image_array", "image_array", "image_array", "float", "float"])
    for i in range(10):
        frames = {k: np.full((64, 64, 3), v + i, np.uint8) for k, v in
                  (("cam/image_array", 100), ("cam/left_image_array", 50), ("cam/right_image_array", 200))}
        tub.write_record({**frames, "user/angle": 0.1, "user/throttle": 0.5})
    tub.close()
    data = read_drive_data([tmp_path / "udacity"])
    keys = ["cam/image_array", "cam/left_image_array", "cam/right_image_array"]
    samples = build_samples(data, np.arange(10), n_keys=3)
    ds = PilotDataset(data, samples, FrameCache(data.records, keys), Preprocess(),
                      key_offsets=[0.0, 0.15, -0.15])
    assert len(ds) == 30
    labels = [round(ds[i][2][0].item(), 4) for i in range(3)]
    assert labels == [0.1, 0.25, -0.05]
    means = [ds[i][0].float().mean().item() for i in range(3)]
    assert means == pytest.approx([100, 50, 200], abs=3)  # each sample reads its own camera


def test_recorded_frame_gives_identical_tensor_in_training_and_driving(tiny_tub, tmp_path):
    cfg = Config.defaults(ROI_CROP_TOP=12, ROI_CROP_BOTTOM=4, ROI_CROP_LEFT=2)
    data = read_drive_data([tiny_tub])
    pre = preprocess_from_config(cfg, "pilotnet", (64, 64, 3))
    assert pre.to_dict() == {"crop": [12, 4, 2, 0], "resize": [66, 200], "color": "yuv",
                             "normalize": "symmetric", "image_shape": [64, 64, 3]}
    model = create_model("pilotnet", pre.output_shape((64, 64, 3)))
    path = save_model(tmp_path / "p.pt", model, {"preprocess": pre.to_dict()})
    # training path: dataset item (uint8) -> batch -> normalize on the training device
    ds = PilotDataset(data, build_samples(data, np.arange(len(data))),
                      FrameCache(data.records, ["cam/image_array"]), pre)
    x, _, _ = ds[17]
    trained_on = pre.normalize_batch(x[None])[0]
    # driving path: the model file's preprocessing on the recorded frame as the camera delivers it
    _, meta = load_model(path)
    driving = Preprocess.from_dict(meta["preprocess"])(data.records[17].image())
    assert driving.shape == (3, 66, 200) and driving.dtype == torch.float32
    assert torch.equal(trained_on, driving)
    assert -1.0 <= float(driving.min()) and float(driving.max()) <= 1.0


@pytest.mark.parametrize("normalize", ["unit", "symmetric"])
@pytest.mark.parametrize("color", ["rgb", "yuv", "hsv", "gray"])
def test_inference_normalisation_is_bit_identical_to_the_batch_one(normalize, color):
    frame = np.random.default_rng(5).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    pre = Preprocess(crop=(40, 0, 0, 0), resize=(66, 200) if color == "yuv" else None, color=color,
                     normalize=normalize)
    driving = pre(frame)  # numpy arithmetic, one frame
    batch = pre.normalize_batch(Preprocess.to_chw(pre.frame(frame))[None])[0]  # torch, training
    assert driving.is_contiguous() and driving.dtype == torch.float32
    assert torch.equal(driving, batch)


def test_preprocess_validates_and_explains():
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
    assert pre.output_shape((120, 160, 3)) == (3, 80, 160)
    assert Preprocess(color="gray").output_shape((120, 160)) == (1, 120, 160)
    with pytest.raises(ValueError, match="trained on 120x160x3 frames"):
        pre(np.zeros((240, 320, 3), np.uint8))
    with pytest.raises(ValueError, match="leaves nothing"):
        Preprocess(crop=(60, 60, 0, 0), image_shape=(120, 160, 3))
    with pytest.raises(ValueError, match="uint8 HxWx3"):
        pre(np.zeros((120, 160, 3), np.float32))
    with pytest.raises(ValueError, match="color must be one of"):
        Preprocess(color="lab")
    with pytest.raises(ValueError, match="unknown preprocessing"):
        Preprocess.from_dict({"crop": [0, 0, 0, 0], "gamma": 2})
    unit = Preprocess()(np.full((4, 4, 3), 255, np.uint8))
    assert float(unit.max()) == 1.0


def test_default_preprocessing_centres_pixels_and_a_setting_overrides_it():
    pre = preprocess_from_config(Config.defaults(), "linear", (120, 160, 3))
    assert (pre.normalize, pre.color, pre.resize) == ("symmetric", "rgb", None)
    x = pre.normalize_batch(torch.tensor([[[[0, 255]]]], dtype=torch.uint8).expand(1, 3, 1, 2))
    assert x.min().item() == -1.0 and x.max().item() == 1.0
    unit = preprocess_from_config(Config.defaults(PREPROCESS_NORMALIZE="unit"), "linear", (120, 160, 3))
    assert unit.normalize == "unit"


def test_frame_cache_counts_only_the_frames_it_holds(tiny_tub, tmp_path, caplog):
    # issue 21: it logged "cached 120 decoded frames" after skipping some
    import logging
    import shutil

    tub = tmp_path / "tub"
    shutil.copytree(tiny_tub, tub)
    next((tub / "images").glob("7_*")).write_bytes(bytes(range(256)))  # not an image
    data = read_drive_data([tub])
    with caplog.at_level(logging.INFO):
        bad = FrameCache(data.records, ["cam/image_array"]).fill(np.arange(len(data)))
    assert list(bad) == [7]
    assert "cached 119 decoded frames" in caplog.text and "1 record skipped" in caplog.text


def _side_camera_tub(path, left: str, right: str, n: int = 12):
    """A Udacity-style tub: centre, left and right frames of distinct brightness under ``left``/``right``."""
    from parts.tub import Tub

    tub = Tub(path, inputs=["cam/image_array", left, right, "user/angle", "user/throttle"],
              types=["image_array"] * 3 + ["float", "float"])
    for _ in range(n):
        tub.write_record({"cam/image_array": np.full((64, 64, 3), 100, np.uint8),
                          left: np.full((64, 64, 3), 50, np.uint8), right: np.full((64, 64, 3), 200, np.uint8),
                          "user/angle": 0.1, "user/throttle": 0.5})
    tub.close()
    return path


@pytest.mark.parametrize("written, configured", [
    ("image_array_{}", "image_array_{}"),   # what `vehicle tub import-udacity` writes, the documented name
    ("image_array_{}", "{}_image_array"),   # issue 27: docs/training.md once named them so
    ("{}_image_array", "image_array_{}"),   # a tub written under the old name
])
def test_side_cameras_are_read_under_either_name(tmp_path, written, configured):
    # issue 27: the docs' names did not match import-udacity's: 600 warnings asking for
    # `tub check --repair`, then "no training samples left"
    from training.trainer import prepare_data

    tub = _side_camera_tub(tmp_path / "t", *(f"cam/{written.format(s)}" for s in ("left", "right")))
    side = {f"cam/{configured.format('left')}": 0.2, f"cam/{configured.format('right')}": -0.2}
    cfg = Config.defaults(TRAIN_SIDE_CAMERAS=side, TRAIN_TEST_SPLIT=1.0, AUGMENTATIONS=[])
    prep = prepare_data(cfg, read_drive_data([tub]), create_model("linear", (3, 64, 64)), Preprocess())
    assert prep.info["train_samples"] == 3 * 12
    labels = sorted({round(prep.train[i][2][0].item(), 4) for i in range(len(prep.train))})
    assert labels == [-0.1, 0.1, 0.3]
    means = {round(prep.train[i][2][0].item(), 4): prep.train[i][0].float().mean().item() for i in range(3)}
    assert means == pytest.approx({0.1: 100, 0.3: 50, -0.1: 200}, abs=3)  # each offset on its own camera


def test_a_side_camera_the_tubs_lack_is_one_error_naming_the_key(tmp_path):
    from training.trainer import prepare_data

    tub = _side_camera_tub(tmp_path / "t", "cam/image_array_left", "cam/image_array_right")
    cfg = Config.defaults(TRAIN_SIDE_CAMERAS={"cam/image_array_rear": 0.1}, TRAIN_TEST_SPLIT=1.0)
    with pytest.raises(ValueError, match=r"TRAIN_SIDE_CAMERAS.*'cam/image_array_rear'.*12 of 12 records") as err:
        prepare_data(cfg, read_drive_data([tub]), create_model("linear", (3, 64, 64)), Preprocess())
    assert "cam/image_array_left" in str(err.value)  # what the tubs do hold
    assert "--repair" not in str(err.value)


def test_the_docs_name_the_side_cameras_as_import_udacity_writes_them():
    from pathlib import Path

    from parts.tub.udacity import SIDES

    root = Path(__file__).resolve().parents[2]
    assert dict(SIDES)["left"] == "cam/image_array_left"  # what import-udacity writes
    for doc in ("docs/config.md", "training/settings.py"):
        text = (root / doc).read_text()
        assert "left_image_array" not in text and "right_image_array" not in text, doc
    assert 'TRAIN_SIDE_CAMERAS = {"cam/image_array_left": ' in (root / "docs/training.md").read_text()
