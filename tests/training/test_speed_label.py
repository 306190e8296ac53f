"""TRAIN_THROTTLE_LABEL = "speed": the model learns the recorded speed, and the pilot drives to it."""

from __future__ import annotations

import numpy as np
import pytest

from parts.pilots import load_pilot
from parts.pilots.modelfile import load_model, save_model
from parts.pilots.pilot import Pilot, speed_scale
from training.dataset import read_drive_data
from training.trainer import train
from vehicle.config import Config

KEYS = ["cam/image_array", "user/angle", "user/throttle", "user/mode", "sim/speed"]
TYPES = ["image_array", "float", "float", "str", "float"]


@pytest.fixture(scope="module")
def speed_tub(tmp_path_factory):
    """80 records whose frame shows a bar where the steering is and whose speed is 1 + |angle| m/s
    while the throttle stays 0.2 (what a frame cannot tell a throttle-trained pilot)."""
    from parts.tub import Tub

    path = tmp_path_factory.mktemp("tubs") / "speed_tub"
    rng = np.random.default_rng(0)
    tub = Tub(path, inputs=KEYS, types=TYPES)
    for i in range(80):
        angle = float(np.sin(i / 5.0))
        img = rng.integers(0, 40, (64, 64, 3), dtype=np.uint8)
        x = int(round((angle + 1) / 2 * 56))
        img[:, x:x + 8] = (220, 200, 60)
        tub.write_record({"cam/image_array": img, "user/angle": angle, "user/throttle": 0.2, "user/mode": "user",
                          "sim/speed": 1.0 + abs(angle)})
    tub.close()
    return path


def test_speed_label_reads_the_measured_speed_over_the_scale(speed_tub, tiny_tub):
    plain = read_drive_data([speed_tub])
    assert np.allclose(plain.throttles, 0.2)
    data = read_drive_data([speed_tub], speed_scale=4.0)
    assert np.allclose(data.throttles, (1.0 + np.abs(plain.angles)) / 4.0, atol=1e-6)
    assert np.allclose(read_drive_data([speed_tub], speed_scale=1.5).throttles.max(), 1.0)  # clipped at 1
    with pytest.raises(ValueError, match="TRAIN_THROTTLE_LABEL = 'speed' needs a measured speed"):
        read_drive_data([tiny_tub], speed_scale=4.0)  # recorded without a speed


def test_training_on_speeds_stores_the_label_in_the_model(speed_tub, tmp_path, torch_one_thread):
    cfg = Config.defaults(BATCH_SIZE=16, MAX_EPOCHS=1, TRAIN_SEED=0, TRAIN_THROTTLE_LABEL="speed",
                          TRAIN_SPEED_SCALE=3.0)
    path = tmp_path / "speed.pt"
    train(cfg, [speed_tub], path, register=False)
    _, meta = load_model(path)
    assert meta["training"]["throttle_label"] == "speed" and speed_scale(meta) == 3.0
    train(cfg.replace(TRAIN_THROTTLE_LABEL="throttle"), [speed_tub], tmp_path / "t.pt", register=False)
    assert speed_scale(load_model(tmp_path / "t.pt")[1]) is None
    with pytest.raises(Exception, match="TRAIN_SPEED_SCALE"):
        Config.defaults(TRAIN_SPEED_SCALE=0.0)


def test_pilot_drives_to_the_predicted_speed(make_model_file, monkeypatch):
    path = make_model_file("linear")
    model, meta = load_model(path)
    save_model(path, model, {**{k: v for k, v in meta.items() if k != "model"},
                             "training": {"throttle_label": "speed", "speed_scale": 4.0}})
    pilot = load_pilot(path, backend="torch", speed_key="sim/speed")
    assert pilot.inputs == ["cam/image_array", "sim/speed"]
    monkeypatch.setattr(Pilot, "_predict", lambda self, active, views, extra: (0.1, 0.5))  # 2 m/s wanted
    frame = np.zeros((120, 160, 3), np.uint8)
    angle, slow = pilot.run(frame, 0.5)
    assert angle == 0.1 and slow > 0.3  # far below 2 m/s: the PI controller accelerates
    pilot.reset()
    _, fast = pilot.run(frame, 3.0)
    assert fast == 0.0  # above the target: no throttle
    plain = load_pilot(make_model_file("linear", name="plain"), backend="torch")
    assert plain.inputs == ["cam/image_array"]  # a throttle model takes no speed
