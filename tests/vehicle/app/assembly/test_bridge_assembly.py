"""SIM_TYPE / --sim: a simulator car drives the Udacity or the Donkey simulator with the same parts."""

from __future__ import annotations

import importlib.util
import socket
import sys
from pathlib import Path

import pytest
from fixtures.fake_donkey_sim import FakeDonkeySim

from parts.bridges.donkey_client import DonkeySim
from parts.bridges.udacity_sim import UdacitySim
from vehicle import Vehicle
from vehicle.app import assembly
from vehicle.clock import SimulatedClock
from vehicle.config import Config, ConfigError
from vehicle.errors import UserError, VehicleError
from vehicle.keys import is_valid_key


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def sim_car(tmp_path: Path, sim_type: str, **settings) -> Vehicle:
    """The simulator template's drive() without a pilot."""
    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=free_port(), **settings)
    V = Vehicle(clock=assembly.sim_clock(cfg, sim_type))
    assembly.add_simulator(V, cfg, sim_type=sim_type)
    assembly.add_controller(V, cfg)
    assembly.add_camera_watchdog(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_tub_writer(V, cfg)
    return V


@pytest.mark.parametrize(("sim_type", "cls"), [("udacity", UdacitySim), ("donkey", DonkeySim)])
def test_sim_type_swaps_the_simulator_and_nothing_else(tmp_path, sim_type, cls):
    V = sim_car(tmp_path, sim_type, UDACITY_EXTRA_KEYS=["sim_time", "lapNumber"])
    V.check_wiring()
    first = V.parts[0]
    assert isinstance(first.part, cls) and first.threaded
    assert first.feedback == frozenset({"angle", "throttle"})  # last loop's commands, on purpose
    assert V.find(__import__("parts.drive.safety", fromlist=["CameraWatchdog"]).CameraWatchdog)
    keys = {k for e in V.parts for k in (*e.inputs, *e.outputs)}
    assert sorted(k for k in keys if not is_valid_key(k)) == []
    if sim_type == "udacity":
        assert "sim/sim_time" in first.outputs and "sim/lap_number" in first.outputs


def test_sim_clock_is_simulated_only_for_the_builtin_simulator():
    cfg = Config.defaults(SIM_REALTIME=False)
    assert isinstance(assembly.sim_clock(cfg), SimulatedClock)
    assert assembly.sim_clock(cfg, "udacity") is None
    assert assembly.sim_clock(cfg.replace(SIM_TYPE="donkey")) is None


def test_settings_errors_name_the_setting(tmp_path):
    V = Vehicle()
    with pytest.raises(ConfigError, match=r"GYM_CONF has unknown keys \['colour'\]"):
        assembly.add_simulator(V, Config.defaults(GYM_CONF={"colour": "red"}), sim_type="donkey")
    with pytest.raises(ConfigError, match=r"body_style .*GYM_CONF"):
        assembly.add_simulator(V, Config.defaults(GYM_CONF={"body_style": "tank"}), sim_type="donkey")
    with pytest.raises(VehicleError, match=r"UDACITY_PORT = 70000 is out of range; valid: 1 to 65535"):
        assembly.add_simulator(V, Config.defaults(UDACITY_PORT=70000), sim_type="udacity")  # the config refuses it
    with pytest.raises(UserError, match=r"unknown simulator 'carla'"):
        assembly.add_simulator(V, Config.defaults(), sim_type="carla")


# -- the car's manage.py ------------------------------------------------------------------------
def simulator_car(tmp_path: Path, settings: str):
    from vehicle.app.commands.createcar import create_car

    car = tmp_path / "car"
    create_car(car, "simulator")
    (car / "myconfig.py").write_text(f"WEB_CONTROL_PORT = {free_port()}\nDRIVE_LOOP_HZ = 20\n" + settings)
    spec = importlib.util.spec_from_file_location("sim_manage", car / "manage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.modules.pop("sim_manage", None)
    return car, module


def test_manage_py_drives_the_donkey_simulator(tmp_path):
    with FakeDonkeySim(port=0) as sim:
        car, manage = simulator_car(tmp_path, f'SIM_TYPE = "donkey"\nSIM_PORT = {sim.port}\n'
                                              'DONKEY_GYM_ENV_NAME = "donkey-warehouse-v0"\n'
                                              'GYM_CONF = {"body_style": "car01", "body_rgb": (1, 2, 3), '
                                              '"car_name": "mine", "font_size": 50}\n')
        assert manage.main(["drive", "--max-loops", "30"]) == 0
        assert sim.wait_for(lambda s: s.messages(0, "exit_scene"), 5)
    sent = sim.messages(0)
    assert sent[1] == {"msg_type": "load_scene", "scene_name": "warehouse"}
    assert next(m for m in sent if m["msg_type"] == "car_config")["body_style"] == "car01"
    controls = [m for m in sent if m["msg_type"] == "control"]
    assert len(controls) >= 10  # the loop's commands (user mode, nobody at the page: zero)
    assert controls[-1] == {"msg_type": "control", "steering": "0.0", "throttle": "0.0", "brake": "1.0"}


def test_manage_py_drives_the_udacity_simulator_with_sim_option(tmp_path):
    from fixtures.fake_udacity_client import FakeUdacityClient

    port = free_port()
    car, manage = simulator_car(tmp_path, f"UDACITY_PORT = {port}\n")
    with FakeUdacityClient(port) as sim:
        assert manage.main(["drive", "--sim", "udacity", "--max-loops", "40"]) == 0
    assert sim.stalls == 0 and len(sim.steers) >= 10
    assert set(sim.steers) == {(0.0, 0.0)}  # nobody drives: neutral commands only


def test_manage_py_says_what_is_wrong(tmp_path, capsys):
    car, manage = simulator_car(tmp_path, f"SIM_TYPE = \"donkey\"\nSIM_PORT = {free_port()}\n"
                                          "SIM_CONNECT_TIMEOUT_S = 0.5\n")
    assert manage.main(["drive", "--expert", "--record-records", "5"]) == 2
    assert "--expert drives the built-in simulator only" in capsys.readouterr().err
    assert manage.main(["drive", "--max-loops", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: cannot reach the Donkey simulator at 127.0.0.1:")
