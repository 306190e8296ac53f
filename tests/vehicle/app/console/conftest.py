"""Fixtures of the trainer console tests: a car folder with small tubs, a real console server on a
free port in a thread, and Debian's chromium driven by Playwright."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fixtures.browser import scaled_ms
from fixtures.tubs import build_donkey_tub

pytest.importorskip("aiohttp")


@pytest.fixture
def car(tmp_path: Path) -> Path:
    """A car folder: myconfig.py tuned for fast tests, two tubs (60 and 40 records) in data/."""
    car = tmp_path / "car"
    (car / "data").mkdir(parents=True)
    (car / "models").mkdir()
    (car / "myconfig.py").write_text(
        "# small and fast for tests\n"
        "SIM_EVAL_MAX_TIME = 3.0\n"
        "SIM_EVAL_TRACK_SEEDS = [101]\n"
        "SIM_EVAL_LAPS = 1\n"
        "BATCH_SIZE = 8\n"
        "MAX_EPOCHS = 3\n")
    build_donkey_tub(car / "data" / "tub_1_26-01-01", 60, max_len=25, sessions=("26-01-01_0", "26-01-01_1"))
    build_donkey_tub(car / "data" / "tub_2_26-01-02", 40, max_len=25)
    past = time.time() - 60  # recorded a minute ago: not being recorded into (the console waits for that)
    for tub in (car / "data").iterdir():
        for f in tub.iterdir():
            os.utime(f, (past, past))
    return car


@pytest.fixture
def config(car: Path) -> Any:
    from vehicle.config import load_config

    return load_config(car_path=car)


@pytest.fixture
def console_factory(config: Any) -> Iterator[Callable[..., Any]]:
    """Start consoles of the test car on free ports; all are closed after the test."""
    from vehicle.app.console.server import ConsoleApp

    started: list[ConsoleApp] = []

    def make(**kwargs: Any) -> ConsoleApp:
        kwargs.setdefault("port", 0)
        kwargs.setdefault("host", "127.0.0.1")
        app = ConsoleApp(config, **kwargs).start_in_thread()
        started.append(app)
        return app

    yield make
    for app in started:
        app.close()


@pytest.fixture
def console(console_factory: Callable[..., Any]) -> Any:
    return console_factory()


@pytest.fixture
def url(console: Any) -> str:
    return f"http://127.0.0.1:{console.port}/"


@pytest.fixture
def page_factory(browser: Any) -> Iterator[Callable[..., Any]]:
    """New pages (each in its own browser context, like two browsers) of the session's chromium
    (fixtures.browser); waits scale with the machine's load; page errors fail the test."""
    contexts: list[Any] = []
    errors: list[str] = []

    def make(width: int = 1280, height: int = 900) -> Any:
        ctx = browser.new_context(viewport={"width": width, "height": height})
        ctx.set_default_timeout(scaled_ms(15_000))
        contexts.append(ctx)
        page = ctx.new_page()
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        return page

    yield make
    for ctx in contexts:
        ctx.close()
    assert not errors, errors


@pytest.fixture
def page(page_factory: Callable[..., Any]) -> Any:
    return page_factory()


@pytest.fixture
def registered_model(config: Any) -> Callable[..., Path]:
    """``registered_model(name, val_loss=0.5)``: an untrained linear model file in the car's models/,
    registered with the car's tubs as its datasets."""
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from training.model_db import register_model

    def make(name: str, val_loss: float = 0.5, seed: int = 0) -> Path:
        torch.manual_seed(seed)
        pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
        model = create_model("linear", pre.output_shape((120, 160, 3)))
        path = config.path("MODELS_PATH") / f"{name}.pt"
        tubs = sorted(str(p) for p in config.path("DATA_PATH").iterdir())
        meta = {"type": "linear", "preprocess": pre.to_dict(), "datasets": tubs,
                "training": {"epochs": 3, "learning_rate": 0.001, "batch_size": 8,
                             "augmentations": {"names": ["flip"], "flip_p": 0.5}},
                "metrics": {"best_val_loss": val_loss, "best_epoch": 2, "epochs": 3,
                            "train_loss": [0.9, 0.6, 0.5], "val_loss": [0.8, val_loss, val_loss + 0.1]}}
        save_model(path, model, meta)
        register_model(path, meta)
        return path

    return make
