"""Fixtures of the pilots tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest


# -- pilot part / export / registry (5b) --------------------------------------------------------------
@pytest.fixture
def frame() -> np.ndarray:
    """A reproducible 120x160 RGB camera frame."""
    return np.random.default_rng(7).integers(0, 256, (120, 160, 3), dtype=np.uint8)


@pytest.fixture
def make_model_file(tmp_path: Path) -> Callable[..., Path]:
    """``make_model_file(type, name=None, **options) -> path``: an untrained model file written by
    save_model, with the preprocessing a car uses (crop 40 rows of sky, 120x160 frames)."""
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    def make(model_type: str = "linear", name: str | None = None, seed: int = 0, **options) -> Path:
        torch.manual_seed(seed)
        pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
        model = create_model(model_type, pre.output_shape((120, 160, 3)), **options)
        path = tmp_path / "models" / f"{name or model_type}.pt"
        meta = {"preprocess": pre.to_dict(), "datasets": ["data/tub_1"], "metrics": {"val_loss": 0.5}}
        return save_model(path, model, meta)

    return make


# -- models, data, training (5a) -----------------------------------------------------------------------
TUB_INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode", "behavior/one_hot_state_array"]
TUB_TYPES = ["image_array", "float", "float", "str", "list"]


def write_tub(path: Path, n: int = 60, sessions: int = 2, size: tuple[int, int] = (64, 64), seed: int = 0,
              local_every: int = 0) -> Path:
    """A tub of ``sessions`` recording sessions of ``n`` records each: a bright bar whose column
    follows the steering (learnable), throttle 0.3 + 0.2 * angle, two behaviours alternating per
    20 records; every ``local_every``-th record is in mode "local" (0 = none)."""
    from parts.tub import Tub

    rng = np.random.default_rng(seed)
    h, w = size
    i = 0
    for _ in range(sessions):
        tub = Tub(path, inputs=TUB_INPUTS, types=TUB_TYPES)
        for _ in range(n):
            angle = float(np.sin(i / 7.0))
            img = rng.integers(0, 40, (h, w, 3), dtype=np.uint8)
            x = int(round((angle + 1) / 2 * (w - 8)))
            img[:, x:x + 8] = (220, 200, 60)
            behavior = [1.0, 0.0] if (i // 20) % 2 == 0 else [0.0, 1.0]
            mode = "local" if local_every and i % local_every == local_every - 1 else "user"
            tub.write_record({"cam/image_array": img, "user/angle": angle, "user/throttle": 0.3 + 0.2 * angle,
                              "user/mode": mode, "behavior/one_hot_state_array": behavior})
            i += 1
        tub.close()
    return path


@pytest.fixture(scope="session")
def tiny_tub(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """120 records (2 sessions x 60) of 64x64 frames; read-only for tests (copy before changing)."""
    return write_tub(tmp_path_factory.mktemp("tubs") / "tub_1")


@pytest.fixture
def torch_one_thread():
    """Keep torch on one thread (the machine is shared); restores the previous count."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def make_tub(tmp_path: Path) -> Callable[..., Path]:
    """``make_tub(name="tub", **write_tub options) -> path`` under this test's tmp_path."""

    def make(name: str = "tub", **options) -> Path:
        return write_tub(tmp_path / name, **options)

    return make
