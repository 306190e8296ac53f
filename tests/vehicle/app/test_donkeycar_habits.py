"""DonkeyCar's command habits the thesis uses: `manage.py drive --js`, `manage.py train --tub ...
--model models/x.h5 --type ...` (a .pt is written, with a note)."""

from __future__ import annotations

import logging

from vehicle.app import manage
from vehicle.app.commands.train import add_train_arguments


def test_drive_js_turns_the_gamepad_on_for_this_run(tmp_path):
    (tmp_path / "myconfig.py").write_text("USE_JOYSTICK_AS_DEFAULT = False\n")
    seen = {}

    def drive(cfg, args):
        seen["js"] = cfg.USE_JOYSTICK_AS_DEFAULT

    parser = manage.command_parser(None)
    d = manage.add_command(parser, "drive", drive, "drive")
    d.add_argument("--js", action="store_true")
    assert manage.main(parser, tmp_path, ["drive", "--js"]) == 0 and seen["js"] is True
    assert manage.main(parser, tmp_path, ["drive"]) == 0 and seen["js"] is False


def test_the_templates_offer_js(tmp_path):
    from pathlib import Path

    import templates

    for manage_py in Path(templates.__file__).parent.glob("*/manage.py"):
        assert 'd.add_argument("--js", action="store_true"' in manage_py.read_text(), manage_py


def test_train_with_donkeycars_tub_and_h5_writes_a_pt(tiny_tub, tmp_path, caplog, torch_one_thread):
    import argparse

    from parts.pilots.modelfile import load_model
    from vehicle.app.commands.train import run_from_args
    from vehicle.config import Config

    parser = argparse.ArgumentParser()
    add_train_arguments(parser)
    args = parser.parse_args(["--tub", str(tiny_tub), "--model", str(tmp_path / "models" / "x.h5"),
                              "--type", "linear", "--epochs", "1", "--batch-size", "16", "--aug"])
    with caplog.at_level(logging.WARNING):
        assert run_from_args(Config.defaults(CAR_PATH=str(tmp_path)), args) == 0
    assert not (tmp_path / "models" / "x.h5").exists()
    _, meta = load_model(tmp_path / "models" / "x.pt")
    assert meta["type"] == "linear"
    notes = [r.getMessage() for r in caplog.records if "Keras file name" in r.getMessage()]
    assert len(notes) == 1 and notes[0].endswith(f"(drive with --model {tmp_path / 'models' / 'x.pt'})")
