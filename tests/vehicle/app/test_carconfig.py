"""One loader for every command's car settings: --car, --myconfig, myconfig.py or the defaults."""

from __future__ import annotations

import argparse

import pytest

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.config import ConfigError
from vehicle.errors import UserError


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_car_options(parser)
    return parser.parse_args(list(argv))


def test_rules(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = load_for_command(parse())  # no car folder: the defaults, CAR_PATH = here
    assert cfg.CAR_PATH == str(tmp_path) and cfg.DRIVE_LOOP_HZ == 20
    (tmp_path / "myconfig.py").write_text("DRIVE_LOOP_HZ = 30\n")
    assert load_for_command(parse()).DRIVE_LOOP_HZ == 30
    (tmp_path / "fast.py").write_text("DRIVE_LOOP_HZ = 50\n")
    assert load_for_command(parse("--myconfig", "fast.py")).DRIVE_LOOP_HZ == 50
    car = tmp_path / "car"
    car.mkdir()
    cfg = load_for_command(parse("--car", str(car)))
    assert cfg.CAR_PATH == str(car) and cfg.DRIVE_LOOP_HZ == 20


def test_errors_are_one_line_and_name_the_option(tmp_path):
    with pytest.raises(UserError, match=r"--car .*nowhere: no such folder"):
        load_for_command(parse("--car", str(tmp_path / "nowhere")))
    with pytest.raises(UserError, match=r"--myconfig other.py: no such file in"):
        load_for_command(parse("--car", str(tmp_path), "--myconfig", "other.py"))
    (tmp_path / "myconfig.py").write_text("DRIVE_LOOP_HZZ = 30\n")
    with pytest.raises(ConfigError, match=r"myconfig.py.*unknown setting DRIVE_LOOP_HZZ\. Did you mean DRIVE_LOOP_HZ"):
        load_for_command(parse("--car", str(tmp_path)))


def test_myconfig_without_car_makes_its_folder_the_car(tmp_path, monkeypatch):
    car = tmp_path / "mycar"
    car.mkdir()
    (car / "myconfig.py").write_text("DRIVE_LOOP_HZ = 40\n")
    monkeypatch.chdir(tmp_path)
    cfg = load_for_command(parse("--myconfig", "mycar/myconfig.py"))
    assert cfg.CAR_PATH == str(car) and cfg.DRIVE_LOOP_HZ == 40 and cfg.path("DATA_PATH") == car / "data"
    with pytest.raises(UserError, match="--myconfig mycar/other.py: no such file"):
        load_for_command(parse("--myconfig", "mycar/other.py"))
