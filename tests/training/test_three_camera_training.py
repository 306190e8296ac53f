"""Training the three-camera model: three views per sample, one augmentation draw for all of them, a
flip that mirrors each view and swaps left and right; from Udacity recordings and from the built-in
simulator's side cameras, end to end."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from parts.pilots.modelfile import load_model
from parts.pilots.preprocess import Preprocess
from training.augment import Augmenter, AugmentSettings
from training.dataset import DriveData, PilotDataset, build_samples
from training.framecache import FrameCache
from training.views import view_mirror
from vehicle.config import Config

VIEWS = ["cam/image_array_left", "cam/image_array", "cam/image_array_right"]


@dataclass
class Record:
    """A record whose three frames are given arrays (what FrameCache reads)."""

    frames: dict[str, np.ndarray]
    index: int = 0
    tub: str = "tub"

    @property
    def data(self) -> dict[str, str]:
        return {key: f"{self.index}_{key}.jpg" for key in self.frames}

    def image(self, key: str, out: np.ndarray | None = None) -> np.ndarray:
        return self.frames[key].copy()


def distinct_views() -> dict[str, np.ndarray]:
    """Three 24x32 frames, each with a bright bar at its own column (not symmetric)."""
    frames = {}
    for i, key in enumerate(VIEWS):
        img = np.full((24, 32, 3), 40, np.uint8)
        img[:, 3 + 5 * i:6 + 5 * i] = (200, 60 + 60 * i, 30)
        frames[key] = img
    return frames


def dataset(augment: tuple[str, ...], mirror: bool = False, **settings) -> tuple[PilotDataset, dict]:
    frames = distinct_views()
    data = DriveData([Record(frames)], np.array([0.3], np.float32), np.array([0.5], np.float32),
                     np.zeros(1, np.int64), np.full(1, -1, np.int64), ["tub"])
    samples = build_samples(data, np.arange(1))
    if mirror:
        samples = samples.with_mirrored_copies().subset(np.array([False, True]))
    augmenter = Augmenter(AugmentSettings(names=augment, **settings)) if augment else None
    ds = PilotDataset(data, samples, FrameCache(data.records, VIEWS, enabled=False), Preprocess(),
                      augmenter=augmenter, views=3)
    return ds, frames


def chw(img: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1)))


def test_a_flip_mirrors_each_view_and_swaps_left_and_right():
    assert view_mirror(VIEWS).tolist() == [2, 1, 0]
    plain, frames = dataset(())
    x, _, y = plain[0]
    assert x.shape == (3, 3, 24, 32) and x.dtype == torch.uint8
    for i, key in enumerate(VIEWS):
        assert torch.equal(x[i], chw(frames[key]))
    assert y.tolist() == pytest.approx([0.3, 0.5])

    flipped, _ = dataset(("flip",), flip_p=1.0)
    x, _, y = flipped[0]
    mirror = {key: cv2.flip(img, 1) for key, img in frames.items()}
    # the left slot shows the mirrored right frame (what a left camera sees in the mirrored world)
    assert torch.equal(x[0], chw(mirror["cam/image_array_right"]))
    assert torch.equal(x[1], chw(mirror["cam/image_array"]))
    assert torch.equal(x[2], chw(mirror["cam/image_array_left"]))
    assert y.tolist() == pytest.approx([-0.3, 0.5])

    copy, _ = dataset((), mirror=True)  # TRAIN_FLIP_COPY's mirrored copy: the same
    assert torch.equal(copy[0][0], x) and copy[0][2].tolist() == pytest.approx([-0.3, 0.5])
    both, _ = dataset(("flip",), mirror=True, flip_p=1.0)  # mirrored twice: as recorded, no swap
    assert torch.equal(both[0][0], plain[0][0]) and both[0][2].tolist() == pytest.approx([0.3, 0.5])


def test_every_view_gets_the_same_augmentation_draw():
    ds, frames = dataset(("shift", "multiply"), shift_p=1.0, multiply_p=1.0, shift_x=0.2, shift_y=0.0,
                         shift_steering=0.0)
    x, _, _ = ds[0]
    ops = ds.augmenter.draw(np.random.default_rng((ds.seed, ds.epoch, 0)))
    assert [name for name, _ in ops] == ["shift", "multiply"]
    for i, key in enumerate(VIEWS):
        assert torch.equal(x[i], chw(ds.augmenter.apply(frames[key], ops)))


def write_udacity_recording(folder: Path, rows: int) -> Path:
    """A driving_log.csv with centre/left/right JPEGs of 160x320 (the Udacity simulator's frames)."""
    (folder / "IMG").mkdir(parents=True)
    rng = np.random.default_rng(0)
    with open(folder / "driving_log.csv", "w", newline="") as f:
        out = csv.writer(f)
        for i in range(rows):
            names = []
            for side in ("center", "left", "right"):
                img = rng.integers(0, 256, (160, 320, 3), dtype=np.uint8)
                name = f"IMG/{side}_2016_12_01_13_30_{i // 10:02d}_{i % 10}00.jpg"
                cv2.imwrite(str(folder / name), img)
                names.append(name)
            out.writerow([*names, f"{np.sin(i / 5):.3f}", "0.4", "0", "20.0"])
    return folder / "driving_log.csv"


def test_trains_from_a_udacity_recording_and_refuses_tubs_without_side_cameras(tmp_path, tiny_tub,
                                                                                torch_one_thread):
    from parts.tub.udacity import import_udacity
    from training.trainer import train

    tub = tmp_path / "tub"
    import_udacity(write_udacity_recording(tmp_path / "rec", 24), tub)
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SHOW_PLOT=False, BATCH_SIZE=8, ROI_CROP_TOP=60,
                          ROI_CROP_BOTTOM=25, PREPROCESS_RESIZE=[66, 100], TRAIN_SIDE_CAMERAS={})
    metrics = train(cfg, [tub], tmp_path / "three.pt", model_type_name="three_camera", epochs=1,
                    register=False, workers=0)
    assert metrics["epochs"] == 1 and np.isfinite(metrics["train_loss"][0])
    model, meta = load_model(tmp_path / "three.pt")
    assert meta["model"]["image_inputs"] == VIEWS and meta["training"]["camera_keys"] == VIEWS
    assert model.input_shape == (3, 66, 100)
    # one sample per record (the views are one input, not extra samples with a steering offset)
    assert meta["training"]["train_samples"] + meta["training"]["val_samples"] == 24

    with pytest.raises(ValueError, match=r"lack .*no cam/image_array_left, cam/image_array_right.*import-udacity"):
        train(cfg, [tiny_tub], tmp_path / "no.pt", model_type_name="three_camera", epochs=1, register=False)


@pytest.mark.slow
def test_record_train_and_drive_with_three_cameras_in_the_builtin_simulator(tmp_path, torch_one_thread):
    from parts.pilots.pilot import Pilot
    from parts.tub.reader import load_records
    from training.trainer import train
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.app.record import record_expert
    from vehicle.clock import SimulatedClock

    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_SIDE_CAMERAS_OFFSET=0.1, SIM_TEXTURE_RES=0.02,
                          SHOW_PLOT=False, BATCH_SIZE=32, ROI_CROP_TOP=40, PREPROCESS_RESIZE=[66, 100],
                          SIM_REALTIME=False)
    tub = record_expert(cfg, [1], 300, tmp_path / "tub")
    records = load_records(tub)
    assert len(records) == 300
    left, centre, right = (records[100].image(key) for key in VIEWS)
    assert left.shape == centre.shape == right.shape == (120, 160, 3)
    assert not np.array_equal(left, centre) and not np.array_equal(right, centre)

    train(cfg, [tub], tmp_path / "models" / "three.pt", model_type_name="three_camera", epochs=1,
          register=False, workers=0)

    V = Vehicle(clock=SimulatedClock())
    # no human: the pilot drives from the first loop
    V.mem.update({"user/mode": "local", "user/angle": 0.0, "user/throttle": 0.0})
    sim = assembly.add_simulator(V, cfg, seeds=[1])
    assert "cam/image_array_left" in V.parts[0].outputs
    pilot = assembly.add_pilot(V, cfg, tmp_path / "models" / "three.pt")
    assert pilot.inputs == VIEWS and V.find(Pilot)
    assembly.add_drive_mode(V, cfg)
    seen: list[tuple[float, float]] = []
    V.add(lambda a, v: seen.append((a, v)), inputs=["pilot/angle", "sim/speed"])
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=60)
    angles, speeds = zip(*seen, strict=True)
    assert len(angles) == 60 and all(np.isfinite(angles)) and len(set(angles)) > 1
    assert max(speeds) > 0.2 and sim.steps == 60  # the car drove under the pilot's throttle
    pilot.shutdown()

    from vehicle.app.evaluate import evaluate  # `vehicle sim eval` gets the side frames too

    report = evaluate(tmp_path / "models" / "three.pt", [2], 1, cfg=cfg, max_time=2.0)
    assert report["overall"]["frames"] == 2.0 * cfg.DRIVE_LOOP_HZ
