"""Model files: round trip, metadata, and the refusal of anything that could run code."""

from __future__ import annotations

import pathlib
import zipfile

import pytest
import torch

from parts.pilots.modelfile import FORMAT, ModelFileError, load_model, read_meta, save_model
from parts.pilots.models import create_model
from vehicle.errors import VehicleError

TYPES = ["linear", "linear_tanh", "categorical", "inferred", "pilotnet", "memory", "behavior", "rnn", "3d", "lanes"]


@pytest.mark.parametrize("name", TYPES)
def test_round_trip_gives_identical_outputs(name, tmp_path, torch_one_thread):
    torch.manual_seed(1)
    model = create_model(name, (3, 64, 64)).eval()
    meta = {"preprocess": {"crop": [0, 0, 0, 0]}, "datasets": ["data/tub_1"], "metrics": {"val_loss": 0.25},
            "training": {"epochs": 3, "lr": 1e-3, "aug": ("flip", "shift")}}
    path = save_model(tmp_path / "m.pt", model, meta)
    loaded, got = load_model(path)
    assert not loaded.training
    images = torch.rand(2, model.frames, 3, 64, 64) if model.frames > 1 else torch.rand(2, 3, 64, 64)
    extra = torch.rand(2, model.extra_size) if model.extra_size else None
    with torch.no_grad():
        assert torch.equal(model(images, extra), loaded(images, extra))
    assert got["model"]["type"] == name
    assert got["model"]["input_shape"] == [3, 64, 64]
    assert got["training"]["aug"] == ["flip", "shift"]  # tuples are stored as lists
    assert got["metrics"] == {"val_loss": 0.25}
    assert set(got["versions"]) == {"vehicle", "torch", "python"}
    assert read_meta(path) == got


def test_file_is_plain_and_loads_with_weights_only(tmp_path):
    path = save_model(tmp_path / "m.pt", create_model("linear", (3, 64, 64)), {"preprocess": {}})
    data = torch.load(path, weights_only=True)
    assert data["format"] == FORMAT and data["format_version"] == 1
    assert all(isinstance(v, torch.Tensor) for v in data["state_dict"].values())
    assert not list(tmp_path.glob(".*tmp*"))  # the temporary file of the atomic write is gone


def test_pickled_object_is_refused(tmp_path):
    path = tmp_path / "evil.pt"
    model = create_model("linear", (3, 64, 64))
    torch.save({"format": FORMAT, "format_version": 1, "state_dict": model.state_dict(),
                "meta": {"model": {"type": "linear", "input_shape": [3, 64, 64]},
                         "note": pathlib.PurePosixPath("x")}}, path)
    with pytest.raises(ModelFileError, match="refused: the file contains pickled Python objects") as exc:
        load_model(path)
    assert "PurePosixPath" in str(exc.value)
    assert isinstance(exc.value, VehicleError)  # the CLI prints it and exits 2


def test_whole_pickled_module_is_refused(tmp_path):
    path = tmp_path / "module.pt"
    torch.save(create_model("linear", (3, 64, 64)), path)  # the DonkeyCar/fastai habit
    with pytest.raises(ModelFileError, match="refused"):
        load_model(path)


def test_corrupt_and_foreign_files_give_clear_errors(tmp_path):
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a model at all")
    with pytest.raises(ModelFileError, match="not a model file"):
        load_model(junk)
    good = save_model(tmp_path / "good.pt", create_model("linear", (3, 64, 64)), {})
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(ModelFileError, match="truncated|not a model file"):
        load_model(truncated)
    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(ModelFileError, match="not a vehicle-pilot model file"):
        load_model(foreign)
    with pytest.raises(ModelFileError, match="no such model file"):
        load_model(tmp_path / "missing.pt")
    with pytest.raises(ModelFileError, match="is a folder"):
        load_model(tmp_path)
    assert zipfile.is_zipfile(good)


def test_incompatible_files(tmp_path):
    model = create_model("linear", (3, 64, 64))
    newer = tmp_path / "newer.pt"
    torch.save({"format": FORMAT, "format_version": 99, "state_dict": {}, "meta": {"model": {}}}, newer)
    with pytest.raises(ModelFileError, match="newer than this software"):
        load_model(newer)
    wrong = tmp_path / "wrong.pt"
    torch.save({"format": FORMAT, "format_version": 1, "state_dict": model.state_dict(),
                "meta": {"model": {"type": "linear", "input_shape": [3, 96, 96], "options": {}}}}, wrong)
    with pytest.raises(ModelFileError, match="weights do not fit"):
        load_model(wrong)
    unknown = tmp_path / "unknown.pt"
    torch.save({"format": FORMAT, "format_version": 1, "state_dict": {},
                "meta": {"model": {"type": "transformer", "input_shape": [3, 64, 64]}}}, unknown)
    with pytest.raises(ModelFileError, match="unknown model type 'transformer'"):
        load_model(unknown)


def test_nan_weights_are_refused(tmp_path):
    model = create_model("linear", (3, 64, 64))
    with torch.no_grad():
        model.head[-1].weight.fill_(float("nan"))
    path = save_model(tmp_path / "nan.pt", model, {})
    with pytest.raises(ModelFileError, match="NaN"):
        load_model(path)


def test_metadata_must_be_plain(tmp_path):
    model = create_model("linear", (3, 64, 64))
    with pytest.raises(TypeError, match="meta.bad"):
        save_model(tmp_path / "m.pt", model, {"bad": object()})
    with pytest.raises(TypeError, match="PilotModel"):
        save_model(tmp_path / "m.pt", torch.nn.Linear(2, 2), {})
    assert not (tmp_path / "m.pt").exists()


@pytest.mark.parametrize("name, said", [("model.h5", "a Keras/TensorFlow model cannot be loaded"),
                                        ("pilot.tflite", "a Keras/TensorFlow model cannot be loaded"),
                                        ("pilot.onnx", "an export for driving only")])
def test_models_of_other_kinds_say_what_to_do(tmp_path, name, said):
    # acceptance: a drive.py student's model.h5 (and an ONNX export given to --transfer) got
    # "not a model file (... corrupt, truncated or another format)"
    (tmp_path / name).write_bytes(b"\x89HDF\r\n\x1a\n")
    with pytest.raises(ModelFileError, match=said):
        load_model(tmp_path / name)


def test_a_model_damaged_inside_its_zip_is_refused_naming_the_member(tmp_path):
    """Hardening item 14: 64 bytes flipped at a third of a model file loaded silently (torch does
    not check the archive's CRC-32s); Python's zip reader (PKZIP's CRC per member) names it."""
    good = save_model(tmp_path / "good.pt", create_model("linear", (3, 64, 64)), {})
    data = bytearray(good.read_bytes())
    third = len(data) // 3
    data[third:third + 64] = bytes(b ^ 0xFF for b in data[third:third + 64])
    damaged = tmp_path / "damaged.pt"
    damaged.write_bytes(bytes(data))
    with zipfile.ZipFile(damaged) as zf:
        member = zf.testzip()
    assert member is not None  # the damage is inside a member, not in the archive's directory
    with pytest.raises(ModelFileError, match=f"damaged: {member} fails its CRC-32 check"):
        load_model(damaged)
    with pytest.raises(ModelFileError, match="damaged"):
        read_meta(damaged)
    load_model(good)  # an intact file still loads
