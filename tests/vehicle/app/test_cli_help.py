"""What the `vehicle` command and a car's manage.py say: help texts, misspelt options, Ctrl-C."""

from __future__ import annotations

import argparse
import importlib.util
import logging
import re

import pytest

from vehicle.app.cli import build_parser, main, stop_code


def _parsers(parser: argparse.ArgumentParser, path: str = "vehicle"):
    """Every parser of the tree with its command line."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{path} {name}")


def _manage_parser(tmp_path):
    from vehicle.app.commands.createcar import create_car

    create_car(tmp_path / "car", "simulator")
    spec = importlib.util.spec_from_file_location("help_manage", tmp_path / "car" / "manage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    seen = {}

    def capture(parser, car_path, argv=None):
        seen["parser"] = parser
        return 0

    module.manage.main, real = capture, module.manage.main
    try:
        module.main([])
    finally:
        module.manage.main = real
    return seen["parser"]


def test_vehicle_help_opens_with_what_it_is_for(capsys):
    # issue 27: it opened with "The ``vehicle`` command: one root command; each verb group is a
    # module of vehicle.app.commands"
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    first = text.split("\n\n")[1]
    assert first.startswith("Drive, record, train and evaluate pilots"), first
    assert "vehicle.app.commands" not in text and "verb group" not in text


def test_no_help_shows_double_backticks_or_a_second_default(tmp_path):
    # issue 27: ``double backticks`` in several help texts; `vehicle createjs --help` printed
    # "(default: JOYSTICK_MAPPING_PATH of the car) (default: None)"
    parsers = [*_parsers(build_parser()), *_parsers(_manage_parser(tmp_path), "manage.py")]
    assert len(parsers) > 30
    bad = []
    for path, parser in parsers:
        text = parser.format_help()
        if "``" in text:
            bad.append(f"{path}: ``")
        formatter = parser._get_formatter()
        for action in parser._actions:
            if action.help in (None, argparse.SUPPRESS):
                continue
            shown = formatter._expand_help(action)
            if len(re.findall(r"\bdefault\b", shown, re.IGNORECASE)) > 1 or "(default: None)" in shown:
                bad.append(f"{path} {'/'.join(action.option_strings)}: {shown}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("argv, message", [
    (["sim", "eval", "--pilto", "x"], "vehicle sim eval: error: unknown option --pilto: did you mean --pilot?"),
    (["tub", "check", "--reapir"], "vehicle tub check: error: unknown option --reapir: did you mean --repair?"),
    (["createcar", "--pth", "x"], "vehicle createcar: error: unknown option --pth: did you mean --path?"),
])
def test_a_misspelt_option_is_named_by_its_command(capsys, argv, message):
    # issue 27: "the following arguments are required: --pilot", or the root command's
    # "unrecognized arguments"
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    assert message in capsys.readouterr().err


def test_manage_py_names_a_misspelt_option(tmp_path, capsys):
    parser = _manage_parser(tmp_path)
    with pytest.raises(SystemExit):
        parser.parse_args(["drive", "--max-lops", "3"])
    assert "error: unknown option --max-lops: did you mean --max-loops?" in capsys.readouterr().err


def test_ctrl_c_outside_a_drive_mentions_no_throttle(caplog):
    # issue 27: training, evaluation and the demo said "throttle set to neutral" on Ctrl-C
    with caplog.at_level(logging.INFO):
        assert stop_code(KeyboardInterrupt(), driving=False) == 130
        assert "stopped by Ctrl-C" in caplog.text and "throttle" not in caplog.text
        assert stop_code(KeyboardInterrupt()) == 130
    assert "throttle set to neutral" in caplog.text  # a drive still says where the throttle is


def test_an_option_value_that_looks_like_an_option_is_a_value(tmp_path):
    args = build_parser().parse_args(["train", "--car", str(tmp_path), "--comment", "--fast run", "--epochs", "2"])
    assert args.comment == "--fast run" and args.epochs == "2"
