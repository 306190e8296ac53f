"""The two-stream `lanes` model against the thesis (seed 002, Appendix 5.2), its preprocessing and
the behaviour input."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from parts.pilots import load_pilot
from parts.pilots.models import create_model
from parts.pilots.preprocess import Preprocess, preprocess_from_config
from training.augment import Augmenter, AugmentSettings
from training.dataset import PilotDataset, behavior_mirror, behavior_names, build_samples, read_drive_data
from training.framecache import FrameCache
from vehicle.config import Config


def _conv(cin: int, cout: int, k: int) -> int:
    return (k * k * cin + 1) * cout


def _dense(n_in: int, n_out: int) -> int:
    return (n_in + 1) * n_out


def _valid(size: int, k: int, s: int) -> int:
    return (size - k) // s + 1


def thesis_parameter_count(h: int, w: int, behaviours: int | None) -> int:
    """Parameters of the thesis's oriModel from its layer list alone: Appendix 5.2, or with
    ``behaviours`` None the first iteration (Appendix 4.2)."""
    convs = [(24, 5, 2), (32, 5, 2), (64, 5, 2), (64, 3, 1), (64, 3, 1)]
    stream, cin = 0, 3
    for cout, k, s in convs:
        stream += _conv(cin, cout, k)
        h, w, cin = _valid(h, k, s), _valid(w, k, s), cout
    stream += _dense(h * w * 64, 100)
    if behaviours is None:
        return 2 * stream + _dense(200, 100) + _dense(100, 50) + 2 * _dense(50, 1)
    b = 2 * behaviours
    head = _dense(behaviours, b) + 2 * _dense(b, b) + _dense(200, 100) + _dense(b + 100, 100) + _dense(100, 50)
    return 2 * stream + head + 2 * _dense(50, 1)


def test_parameter_count_is_the_thesiss_at_its_input_size():
    # the thesis's frames are 320x180 RGB; the preprocessing appends the lane channel
    model = create_model("lanes", (4, 180, 320), num_behaviors=2)
    expected = thesis_parameter_count(180, 320, 2)
    assert expected == 6_664_356
    assert sum(p.numel() for p in model.parameters()) == expected
    # the first iteration (no behaviour subnetwork) is the "about 6.5 million" of §9.1
    assert thesis_parameter_count(180, 320, None) == 6_653_804


def test_layer_structure_follows_appendix_5():
    model = create_model("lanes", (4, 180, 320), num_behaviors=3)
    for stream in (model.image_convs, model.lane_convs):
        convs = [m for m in stream if isinstance(m, torch.nn.Conv2d)]
        assert [(c.in_channels, c.out_channels, c.kernel_size, c.stride, c.padding) for c in convs] == [
            (3, 24, (5, 5), (2, 2), (0, 0)), (24, 32, (5, 5), (2, 2), (0, 0)), (32, 64, (5, 5), (2, 2), (0, 0)),
            (64, 64, (3, 3), (1, 1), (0, 0)), (64, 64, (3, 3), (1, 1), (0, 0))]
        acts = [m for m in stream if isinstance(m, torch.nn.LeakyReLU)]
        assert len(acts) == 5 and all(a.negative_slope == 0.3 for a in acts)  # Keras's LeakyReLU()
    drops = [[m.p for m in s if isinstance(m, torch.nn.Dropout)] for s in (model.image_convs, model.lane_convs)]
    assert drops == [[0.1] * 5, [0.1] * 4]  # keep_prob 0.9; none after the lane stream's last conv
    assert model.image_convs[-2].__class__ is torch.nn.Dropout and model.lane_convs[-2].__class__ is torch.nn.LeakyReLU
    for dense in (model.image_dense, model.lane_dense):  # Dense(100), linear, then Dropout
        assert [type(m) for m in dense] == [torch.nn.Linear, torch.nn.Dropout] and dense[0].out_features == 100
        assert dense[0].in_features == 64 * 15 * 33
    behaviour = [m for m in model.behavior if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in behaviour] == [(3, 6), (6, 6), (6, 6)]
    assert sum(isinstance(m, torch.nn.ReLU) for m in model.behavior) == 3
    assert (model.merge[0].in_features, model.merge[0].out_features) == (200, 100)
    decide = [m for m in model.decide if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in decide] == [(106, 100), (100, 50)]
    assert (model.steering_out.out_features, model.throttle_out.out_features) == (1, 1)


def test_behaviour_input_changes_the_output(fit_steps):
    torch.manual_seed(0)
    model = create_model("lanes", (4, 64, 96), num_behaviors=2)
    images = torch.rand(1, 4, 64, 96).repeat(8, 1, 1, 1)  # the same frame 8 times
    behaviour = torch.tensor([[1.0, 0.0], [0.0, 1.0]]).repeat(4, 1)
    target = torch.tensor([[0.5, 0.3], [-0.5, 0.3]]).repeat(4, 1)  # left lane: steer left ...
    model.eval()
    with torch.no_grad():
        before = model(images[:2], behaviour[:2])
    assert not torch.equal(before[0], before[1])  # the one-hot reaches the output even untrained
    fit_steps(model, images, behaviour, target, 150)
    model.eval()
    with torch.no_grad():
        out = model(images[:2], behaviour[:2])
    # the image is the same: only the behaviour tells the two commands apart
    assert out[0, 0] - out[1, 0] > 0.8
    with pytest.raises(ValueError, match="behaviour one-hot"):
        model(images[:1], None)
    with pytest.raises(ValueError, match="lane channel"):
        create_model("lanes", (1, 64, 96))


# at the demo's input; 43 and 44: TRAIN_SEED of `vehicle demo --lanes --seed 2` and `--seed 3`
@pytest.mark.parametrize("seed", [3, 43, 44])
def test_every_seed_starts_with_a_behaviour_path_that_tells_the_behaviours_apart(seed):
    # The behaviour subnetwork is three ReLU layers of 2 x behaviours units: torch's default draw
    # left a layer dead for some behaviour (all zeros) in 1 seed of 4, or both behaviours the same in
    # 1 of 10, and a dead ReLU passes no gradient, so such a model never learnt the command.
    torch.manual_seed(seed)
    model = create_model("lanes", (4, 80, 160), num_behaviors=2)
    with torch.no_grad():
        h = torch.eye(2)
        for layer in model.behavior:
            h = layer(h)
            if isinstance(layer, torch.nn.ReLU):
                assert not torch.equal(h[0], h[1]), f"layer {layer} gives both behaviours the same output"
                assert bool((h > 0).any(dim=1).all()), "a behaviour reaches no unit of the layer"


def test_preprocessing_adds_the_lane_image_from_the_whole_raw_frame():
    cfg = Config.defaults(ROI_CROP_TOP=40)
    pre = preprocess_from_config(cfg, "lanes", (120, 160, 3))
    assert pre.normalize == "unit" and pre.lanes is not None and pre.output_shape((120, 160, 3)) == (4, 80, 160)
    frame = np.full((120, 160, 3), 90, np.uint8)
    frame[60:, 40:46] = (230, 190, 40)  # a yellow (saturated) line in the region of interest
    x = pre(frame)
    assert x.shape == (4, 80, 160) and x.dtype == torch.float32
    assert set(torch.unique(x[3]).tolist()) == {0.0, 1.0} and x[3].sum() > 20
    assert torch.allclose(x[:3], torch.from_numpy(frame[40:].transpose(2, 0, 1)).float() / 255)
    again = Preprocess.from_dict(pre.to_dict())
    assert again == pre and torch.equal(again(frame), x)
    other = preprocess_from_config(cfg.replace(LANE_S_THRESHOLD=(200, 255)), "lanes", (120, 160, 3))
    assert other != pre and other(frame)[3].sum() < x[3].sum()


def test_pilot_drives_a_lanes_model_file(make_model_file, frame):
    pilot = load_pilot(make_model_file("lanes"), backend="torch")
    assert pilot.inputs == ["cam/image_array", "behavior/one_hot_state_array"]
    assert pilot.runner.input_shape == (4, 80, 160)
    left = pilot.run(frame, [1.0, 0.0])
    right = pilot.run(frame, [0.0, 1.0])
    assert all(-1.0 <= v <= 1.0 for v in left + right) and left != right
    with pytest.raises(ValueError, match="BEHAVIOR_LIST"):
        pilot.run(frame, [1.0, 0.0, 0.0])


def test_flipped_frames_swap_left_and_right_lane_behaviours(tmp_path):
    from parts.tub import Tub

    tub = Tub(tmp_path / "tub", inputs=["cam/image_array", "user/angle", "user/throttle", "behavior/state",
                                         "behavior/label", "behavior/one_hot_state_array"],
              types=["image_array", "float", "float", "int", "str", "list"])
    for i in range(4):
        state = i % 2
        tub.write_record({"cam/image_array": np.zeros((32, 32, 3), np.uint8), "user/angle": 0.4,
                          "user/throttle": 0.3, "behavior/state": state,
                          "behavior/label": ["Left_Lane", "Right_Lane"][state],
                          "behavior/one_hot_state_array": [1.0 - state, float(state)]})
    tub.close()
    data = read_drive_data([tmp_path / "tub"])
    names = behavior_names(data)
    assert names == ["Left_Lane", "Right_Lane"]
    mirror = behavior_mirror(names)
    assert mirror.tolist() == [1, 0]
    assert behavior_mirror(["Left_Lane", "Center"]) is None
    assert behavior_mirror(["Center", "Stop"]).tolist() == [0, 1]
    samples = build_samples(data, range(len(data)))
    flip_all = Augmenter(AugmentSettings(names=("flip",), flip_p=1.0))
    ds = PilotDataset(data, samples, FrameCache(data.records, ["cam/image_array"]), Preprocess(), extra_key=
                      "behavior/one_hot_state_array", extra_size=2, augmenter=flip_all, extra_mirror=mirror)
    _, extra, target = ds[0]
    assert extra.tolist() == [0.0, 1.0] and target[0].item() == pytest.approx(-0.4)  # left lane, mirrored


def test_a_training_sample_is_what_the_pilot_computes_from_the_same_frame(tmp_path):
    """Training and driving share one path: the dataset's uint8 sample of a lanes model, normalised
    as the trainer does, equals the pilot runner's preprocessing of the recorded frame."""
    from parts.pilots.backends import open_runner
    from parts.pilots.modelfile import save_model
    from parts.tub import Tub

    cfg = Config.defaults(LANE_COLOR_MASK="white")
    rng = np.random.default_rng(3)
    tub = Tub(tmp_path / "tub", inputs=["cam/image_array", "user/angle", "user/throttle",
                                         "behavior/one_hot_state_array"],
              types=["image_array", "float", "float", "list"])
    for i in range(3):
        frame = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
        frame[60:, 70:76] = 255  # a white lane line
        tub.write_record({"cam/image_array": frame, "user/angle": 0.1 * i, "user/throttle": 0.3,
                          "behavior/one_hot_state_array": [1.0, 0.0]})
    tub.close()
    data = read_drive_data([tmp_path / "tub"])
    pre = preprocess_from_config(cfg, "lanes", (120, 160, 3))
    assert pre.lanes is not None and pre.lanes["color_mask"] == "white"  # the car's LANE_COLOR_MASK reached it
    model = create_model("lanes", pre.output_shape((120, 160, 3)), num_behaviors=2)
    path = save_model(tmp_path / "lanes.pt", model, {"preprocess": pre.to_dict()})
    runner = open_runner(path, "torch")
    ds = PilotDataset(data, build_samples(data, range(len(data))), FrameCache(data.records, ["cam/image_array"]), pre,
                      extra_key="behavior/one_hot_state_array", extra_size=2)
    for i in range(len(ds)):
        x, _, _ = ds[i]
        assert x.dtype == torch.uint8 and x.shape == (4, 120, 160)  # RGB + the lane image
        trained = pre.normalize_batch(x[None])[0].numpy()
        driven = runner.preprocess(data.records[i].image("cam/image_array"))
        assert driven.shape == trained.shape
        np.testing.assert_allclose(trained, driven, atol=1e-6)
        assert trained[3].max() > 0.5  # the lane channel shows the line
