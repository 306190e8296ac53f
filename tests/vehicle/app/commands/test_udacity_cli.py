"""``vehicle udacity drive``: a trained pilot drives the faithful fake Udacity simulator end to end."""

from __future__ import annotations

import socket
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("socketio")
pytest.importorskip("wsproto")

from fixtures.fake_road import road_view  # noqa: E402
from fixtures.fake_udacity_client import FakeUdacityClient  # noqa: E402

from vehicle.app.cli import main  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def train_road_pilot(tmp_path: Path) -> Path:
    """A tiny pilot trained on the fake simulator's view: steer back to the road centre."""
    from parts.tub import Tub
    from training.trainer import train
    from vehicle.config import Config

    rng = np.random.default_rng(0)
    tub = Tub(tmp_path / "data" / "tub_1", inputs=["cam/image_array", "user/angle", "user/throttle", "user/mode"],
              types=["image_array", "float", "float", "str"])
    for _ in range(64):
        lateral, heading = rng.uniform(-1.5, 1.5), rng.uniform(-0.3, 0.3)
        angle = float(np.clip(-0.4 * lateral - 1.5 * heading, -1, 1))
        tub.write_record({"cam/image_array": road_view(320, 160, lateral / 2, heading), "user/angle": angle,
                          "user/throttle": 0.3, "user/mode": "user"})
    tub.close()
    cfg = Config.defaults(CAR_PATH=str(tmp_path), BATCH_SIZE=32, MAX_EPOCHS=2, AUGMENTATIONS=[], TRAIN_SEED=0,
                          ROI_CROP_TOP=40, PREPROCESS_RESIZE=(80, 160))  # 160x320 -> sky cropped, halved
    model = tmp_path / "models" / "road.pt"
    train(cfg, [tmp_path / "data" / "tub_1"], model, register=False, progress=False)
    return model


@pytest.mark.slow
def test_udacity_drive_drives_the_fake_simulator_with_a_trained_pilot(tmp_path, torch_one_thread, capsys):
    from parts.pilots import load_pilot
    from parts.tub.codec import decode_image
    from parts.tub.reader import load_records

    model = train_road_pilot(tmp_path)
    port = free_port()
    run = tmp_path / "run"
    # the simulator is started first and keeps retrying until the server listens, as the real one does
    with FakeUdacityClient(port, keep_images=5000) as sim:
        code = main(["udacity", "drive", str(model), str(run), "--port", str(port), "--max-loops", "120",
                     "--car", str(tmp_path), "--echo"])
    assert code == 0
    assert sim.stalls == 0 and sim.opens >= 1
    driven = [s for s in sim.steers if s != (0.0, 0.0)]  # (0, 0): the neutral answers at the stop
    assert len(driven) >= 20
    # every steering the simulator got is the pilot's prediction for a frame the simulator sent
    pilot = load_pilot(model, backend="torch")
    predictions = np.array([pilot.run(decode_image(jpeg))[0] for jpeg in sim.sent_images])
    for steering, throttle in driven:
        assert np.abs(predictions - steering).min() < 1e-5
        assert 0.0 <= throttle <= 1.0  # the PI speed controller's throttle, not the model's
    assert len(set(s for s, _ in driven)) > 3  # the pilot reacts to what it sees
    # drive.py's image folder: the driven frames as a tub, each frame once
    records = load_records([run])
    assert len(records) >= 10
    assert all(r.image().shape == (160, 320, 3) for r in records)
    assert all(r.data["user/mode"] == "local" for r in records)
    # the steering recorded with a frame is the one sent for it (the last frames may have been
    # answered by the neutral stop instead)
    answered = np.array([s for s, _ in sim.steers])
    unmatched = [r.data["angle"] for r in records if np.abs(answered - r.data["angle"]).min() > 2e-6]
    assert len(unmatched) <= 2
    # --echo: one line per frame, "steering throttle speed_mph"
    lines = [line.split() for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert len(lines) >= 10 and all(len(parts) == 3 for parts in lines)


def test_udacity_drive_explains_bad_input(tmp_path, capsys):
    assert main(["udacity", "drive", str(tmp_path / "nope.h5"), "--car", str(tmp_path)]) == 2
    assert "no such model file" in capsys.readouterr().err
    model = tmp_path / "m.pt"
    model.write_bytes(b"x")
    assert main(["udacity", "drive", str(model), "--speed-limit", "99", "--car", str(tmp_path)]) == 2
    assert "--speed-limit 99" in capsys.readouterr().err


def test_udacity_drive_port_in_use_is_one_line(tmp_path, capsys):
    model = untrained_udacity_model(tmp_path)  # one that fits: a model of other frames is refused first
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        code = main(["udacity", "drive", str(model), "--port", str(s.getsockname()[1]), "--max-loops", "3",
                     "--car", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: Udacity bridge cannot listen on 127.0.0.1:")


def untrained_udacity_model(tmp_path: Path) -> Path:
    """An untrained linear model for the simulator's 160x320 frames (sky cropped)."""
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    torch.manual_seed(0)
    pre = Preprocess(crop=(40, 0, 0, 0), resize=(80, 160), image_shape=(160, 320, 3))
    model = create_model("linear", pre.output_shape((160, 320, 3)))
    return save_model(tmp_path / "models" / "raw.pt", model, {"preprocess": pre.to_dict()})


def test_udacity_drive_speed_limit_is_the_track_driver_rule(tmp_path, torch_one_thread):
    """--speed-limit MPH: throttle = 1 - speed / limit, the speed in mph as the simulator reports it."""
    model = untrained_udacity_model(tmp_path)
    port = free_port()
    with FakeUdacityClient(port) as sim:
        assert main(["udacity", "drive", str(model), "--port", str(port), "--speed-limit", "20",
                     "--max-loops", "60", "--car", str(tmp_path)]) == 0
    throttles = [t for s, t in sim.steers if (s, t) != (0.0, 0.0)]
    assert throttles and throttles[0] == pytest.approx(1.0)  # standing still: full throttle
    speeds = np.array([float(f["speed"]) for f in sim.sent_fields])
    for throttle in throttles:  # each is the rule applied to a speed the simulator reported
        assert np.abs((1 - speeds / 20) - throttle).min() < 1e-3
    assert min(throttles) < 0.99  # the car sped up and the throttle came down


def test_a_pilot_trained_on_other_frames_stops_with_one_line(tmp_path, make_model_file, capsys, caplog):
    # acceptance: a pilot trained on the built-in simulator's 160x120 frames stopped the drive at the
    # simulator's first 320x160 frame with a traceback and exit code 1
    model = make_model_file("linear")  # 120x160 frames
    port = free_port()
    with FakeUdacityClient(port, keep_images=50):
        code = main(["udacity", "drive", str(model), "--port", str(port), "--max-loops", "400",
                     "--car", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    # refused when it loads, and the advice is not IMAGE_W/IMAGE_H, which do not size these frames
    assert err[-1] == (f"error: cannot drive with {model}: frame is 160x320x3 but the model was trained on "
                       "120x160x3 frames; the Udacity simulator's frames are always 320x160: train on tubs "
                       "recorded in it, or on its driving_log.csv (vehicle tub import-udacity)")
    assert not [r for r in caplog.records if r.exc_info], "no traceback for a user's mistake"


def test_udacity_drive_that_nothing_connected_to_leaves_no_empty_tub(tmp_path, capsys):
    # issue 27: `vehicle udacity drive MODEL DIR` left an empty tub in DIR when no simulator connected
    model = untrained_udacity_model(tmp_path)
    folder = tmp_path / "run1"
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["udacity", "drive", str(model), str(folder), "--port", str(port), "--max-loops", "3",
                 "--car", str(tmp_path)]) == 0
    assert not folder.exists()
