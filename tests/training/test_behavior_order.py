"""Tubs recorded with different BEHAVIOR_LIST orders: each record's behaviour is placed by its name."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from parts.pilots.models import create_model
from parts.pilots.preprocess import Preprocess
from training.dataset import behavior_labels, read_drive_data
from training.trainer import model_options, prepare_data
from vehicle.config import Config

FIELDS = (["cam/image_array", "user/angle", "user/throttle", "behavior/state", "behavior/label",
           "behavior/one_hot_state_array"], ["image_array", "float", "float", "int", "str", "list"])


def write_lane_tub(path, order, n=40, label=True):
    """A tub recorded with BEHAVIOR_LIST = ``order``: the car keeps left (angle -0.5) in Left_Lane and
    right (+0.5) in Right_Lane, the behaviour alternating every 10 records."""
    from parts.tub import Tub

    tub = Tub(path, inputs=FIELDS[0], types=FIELDS[1])
    for i in range(n):
        lane = ("Left_Lane", "Right_Lane")[(i // 10) % 2]
        state = order.index(lane)
        record = {"cam/image_array": np.full((64, 64, 3), 40 * state, np.uint8),
                  "user/angle": -0.5 if lane == "Left_Lane" else 0.5, "user/throttle": 0.3,
                  "behavior/state": state, "behavior/label": lane,
                  "behavior/one_hot_state_array": [float(j == state) for j in range(len(order))]}
        if not label:
            del record["behavior/label"]
        tub.write_record(record)
    tub.close()
    return path


@pytest.fixture
def two_orders(tmp_path):
    a = write_lane_tub(tmp_path / "tub_a", ["Left_Lane", "Right_Lane"])
    b = write_lane_tub(tmp_path / "tub_b", ["Right_Lane", "Left_Lane"])
    return a, b


def _one_hot_of(ds):
    """(angle, one-hot) of every sample."""
    return [(round(float(ds[i][2][0]), 3), tuple(ds[i][1].tolist())) for i in range(len(ds))]


def test_opposite_orders_train_on_one_list_by_name(two_orders, caplog):
    cfg = Config.defaults(BEHAVIOR_LIST=["Left_Lane", "Right_Lane"], AUGMENTATIONS=["flip"], TRAIN_BALANCE=False,
                          TRAIN_TEST_SPLIT=1.0)
    data = read_drive_data(two_orders)
    names, index = behavior_labels(data, cfg.BEHAVIOR_LIST)
    assert names == ["Left_Lane", "Right_Lane"]
    assert [names[i] for i in index] == [r.data["behavior/label"] for r in data.records]
    model = create_model("behavior", (3, 64, 64), **model_options(cfg, "behavior", data))
    with caplog.at_level(logging.WARNING):
        prep = prepare_data(cfg, data, model, Preprocess(), augmentations=[])
    assert prep.info["behaviors"] == ["Left_Lane", "Right_Lane"]
    pairs = set(_one_hot_of(prep.train))
    # in both tubs Left_Lane (angle -0.5) is index 0 of the model's one-hot
    assert pairs == {(-0.5, (1.0, 0.0)), (0.5, (0.0, 1.0))}
    assert "do not name" not in caplog.text
    # the car's order decides: with BEHAVIOR_LIST reversed the model's index 0 is Right_Lane
    rev = cfg.replace(BEHAVIOR_LIST=["Right_Lane", "Left_Lane"])
    prep = prepare_data(rev, data, model, Preprocess(), augmentations=[])
    assert prep.info["behaviors"] == ["Right_Lane", "Left_Lane"]
    assert set(_one_hot_of(prep.train)) == {(-0.5, (0.0, 1.0)), (0.5, (1.0, 0.0))}


def test_a_conflict_the_car_cannot_resolve_names_the_tubs_and_both_orders(two_orders):
    data = read_drive_data(two_orders)
    with pytest.raises(ValueError) as err:
        behavior_labels(data, ["Stop", "Go"])
    message = str(err.value)
    assert "\n" not in message and "BEHAVIOR_LIST" in message
    assert "tub_a" in message and "tub_b" in message
    assert "['Left_Lane', 'Right_Lane']" in message and "['Right_Lane', 'Left_Lane']" in message
    assert "do not name" not in message


def test_tubs_without_labels_keep_their_one_hot_and_a_mix_is_refused(tmp_path):
    old = write_lane_tub(tmp_path / "old", ["Left_Lane", "Right_Lane"], label=False)
    assert behavior_labels(read_drive_data([old]), ["Left_Lane", "Right_Lane"]) == (None, None)
    new = write_lane_tub(tmp_path / "new", ["Right_Lane", "Left_Lane"])
    with pytest.raises(ValueError, match="old.*behavior/label"):
        behavior_labels(read_drive_data([old, new]), ["Left_Lane", "Right_Lane"])


def test_the_model_file_records_its_behaviour_order_and_undistortion(two_orders, tmp_path, torch_one_thread):
    from parts.pilots.modelfile import load_model
    from parts.sim.camera import PinholeCamera
    from parts.vision.calibration import CameraCalibration
    from training.trainer import train

    CameraCalibration((320, 240), PinholeCamera(320, 240).intrinsics, np.zeros(5), 0.1).save(
        tmp_path / "camera_calibration.json")
    cfg = Config.defaults(CAR_PATH=str(tmp_path), BATCH_SIZE=16, MAX_EPOCHS=1, AUGMENTATIONS=[], CAMERA_UNDISTORT=True,
                          BEHAVIOR_LIST=["Right_Lane", "Left_Lane"])
    train(cfg, two_orders, tmp_path / "m.pt", model_type_name="behavior", register=False)
    _, meta = load_model(tmp_path / "m.pt")
    assert meta["training"]["behaviors"] == ["Right_Lane", "Left_Lane"]
    assert meta["camera"] == {"undistort": True, "calibration_size": [320, 240]}
