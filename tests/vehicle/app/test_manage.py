"""How a car's manage.py ends: every way of stopping gives its exit code and no traceback."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def _records(car: Path) -> int:
    lines = 0
    for catalog in car.glob("data/*/catalog_*.catalog"):
        lines += catalog.read_bytes().count(b"\n")
    return lines


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_drive_expert_stopped_by_a_signal_exits_with_its_code(tmp_path, sig, code):
    # issue 21: Ctrl-C printed a traceback and exited -2, SIGTERM exited 1
    car = tmp_path / "car"
    shutil.copytree(ROOT / "mycar", car, ignore=shutil.ignore_patterns("data", "models", "__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(car / "manage.py"), "drive", "--expert",
                             "--record-records", "1000000"], cwd=car, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 60
        while _records(car) < 30:  # recording: the vehicle loop runs
            assert proc.poll() is None and time.monotonic() < end, proc.communicate()[1][-2000:]
            time.sleep(0.05)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    assert "throttle set to neutral" in err
    assert _records(car) >= 30  # what was recorded is kept


def _sim_car(tmp_path: Path, settings: str = ""):
    """A simulator car made by createcar, its manage.py loaded as a module."""
    import importlib.util

    from vehicle.app.commands.createcar import create_car

    car = tmp_path / "car"
    create_car(car, "simulator")
    (car / "myconfig.py").write_text(settings)
    spec = importlib.util.spec_from_file_location("acceptance_manage", car / "manage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_drive_with_the_web_port_taken_is_a_one_line_error(tmp_path, capsys):
    # acceptance: a second car on the same port printed two tracebacks and exited 1
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        manage = _sim_car(tmp_path, f"WEB_CONTROL_PORT = {port}\n")
        assert manage.main(["drive", "--max-loops", "5"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert f"error: web controller cannot listen on 127.0.0.1:{port}: port {port} is in use" in err
    assert "WEB_CONTROL_PORT" in err


def test_drive_with_a_web_host_not_of_this_machine_names_web_host(tmp_path, capsys):
    manage = _sim_car(tmp_path, 'WEB_HOST = "192.0.2.1"\n')  # TEST-NET-1: never a test machine's
    assert manage.main(["drive", "--max-loops", "5"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert "error: web controller cannot listen on 192.0.2.1:8887: 192.0.2.1 is not an address of this " \
           "machine; set WEB_HOST" in err


@pytest.mark.parametrize("argv, option", [
    (["drive", "--max-loops", "-1"], "--max-loops"),
    (["drive", "--max-loops", "0"], "--max-loops"),
    (["drive", "--expert", "--record-records", "-5"], "--record-records"),
    (["drive", "--expert", "--record-records", "0"], "--record-records"),
    (["drive", "--expert", "--record-records", "10", "--lane-changes", "-2"], "--lane-changes"),
])
def test_drive_rejects_counts_below_one_with_a_usage_error(tmp_path, capsys, argv, option):
    # acceptance: --max-loops -1 and --record-records -5 ended in a ValueError traceback
    manage = _sim_car(tmp_path)
    with pytest.raises(SystemExit) as stop:
        manage.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"error: argument {option}: " in err.splitlines()[-1]


@pytest.mark.parametrize("option", [["--record-records", "100"], ["--lane-changes", "2"]])
def test_expert_options_without_expert_are_an_error(tmp_path, capsys, option):
    # acceptance: `drive --record-records 100` without --expert opened the web page and ignored it
    manage = _sim_car(tmp_path)
    assert manage.main(["drive", *option, "--max-loops", "2"]) == 2
    assert capsys.readouterr().err.strip() == \
        "error: --record-records and --lane-changes are for the expert: add --expert"


@pytest.mark.slow
def test_train_run_from_elsewhere_writes_the_model_and_registry_in_the_car(tmp_path, monkeypatch, capsys):
    # issue 27: `python mycar/manage.py train --tubs data --model models/z.pt` from outside the car
    # wrote the model and a second db under the current folder; `vehicle models` missed it
    from fixtures.pilots import write_tub

    from vehicle.app.cli import main as vehicle

    manage = _sim_car(tmp_path)
    car = tmp_path / "car"
    write_tub(car / "data" / "tub", n=40, sessions=1)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert manage.main(["train", "--tubs", "data", "--model", "models/z.pt", "--epochs", "1",
                        "--type", "linear"]) == 0
    assert (car / "models" / "z.pt").is_file() and (car / "models" / "models.sqlite3").is_file()
    assert not (elsewhere / "models").exists()
    assert str(car / "models" / "z.pt") in capsys.readouterr().out
    assert vehicle(["models", "--car", str(car), "--json"]) == 0
    assert [m["name"] for m in json.loads(capsys.readouterr().out)] == ["z"]


@pytest.mark.parametrize("mode, pilot_runs", [("user", False), ("local_angle", True), ("local", True)])
def test_drive_mode_option_says_who_drives_from_the_first_loop(tmp_path, monkeypatch, make_model_file, mode,
                                                               pilot_runs):
    # issue 27: a headless `drive --model M --max-loops N` never engaged the pilot unless
    # DEFAULT_MODE = "local", which only docs/config.md mentioned
    from vehicle.app import assembly

    manage = _sim_car(tmp_path, "WEB_CONTROL_PORT = 0\n")
    cars = []
    add_drive_mode = assembly.add_drive_mode
    monkeypatch.setattr(assembly, "add_drive_mode", lambda V, cfg: (cars.append(V), add_drive_mode(V, cfg))[1])
    model = make_model_file("linear")
    assert manage.main(["drive", "--model", str(model), "--mode", mode, "--max-loops", "3"]) == 0
    mem = cars[0].mem
    assert mem["user/mode"] == mode and mem["run_pilot"] is pilot_runs
    (pilot_angle,) = mem.get(["pilot/angle"])
    assert (pilot_angle is not None) is pilot_runs
    if mode != "user":
        assert mem["angle"] == pytest.approx(mem["pilot/angle"])


def test_drive_with_a_pilot_mode_and_no_model_is_a_one_line_error(tmp_path, capsys):
    manage = _sim_car(tmp_path, "WEB_CONTROL_PORT = 0\n")
    assert manage.main(["drive", "--mode", "local", "--max-loops", "3"]) == 2
    assert "error: --mode local needs a pilot: add --model FILE" in capsys.readouterr().err


def test_an_older_manage_py_without_the_speed_limit_and_obstacle_stop_is_refused(tmp_path):
    """They came with add_drive_mode before issue 40: a car folder made then must not drive without
    them, it gets the two lines to add."""
    from vehicle import Vehicle
    from vehicle.app import assembly, manage
    from vehicle.clock import SimulatedClock
    from vehicle.config import Config
    from vehicle.errors import UserError

    cfg = Config.defaults(CAR_PATH=str(tmp_path), USE_LIDAR=True, OBSTACLE_STOP=True, LIDAR_BINS=36)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(V, cfg, seeds=[1])
    V.add(lambda: (0.0, 0.0, "user", 1.0), outputs=["user/angle", "user/throttle", "user/mode", "user/speed_limit"])
    assembly.add_drive_mode(V, cfg)
    with pytest.raises(UserError, match=r"not assembly.add_speed_limit\(V, cfg\) and assembly.add_obstacle_stop"):
        manage.run(V, cfg, max_loops=1)
    assembly.add_speed_limit(V, cfg)
    assembly.add_obstacle_stop(V, cfg)
    assert manage.run(V, cfg, max_loops=2) == 0
