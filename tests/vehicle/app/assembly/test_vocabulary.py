"""The cars the assembly helpers build use only standard or namespaced keys, in a valid order."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from vehicle import Vehicle
from vehicle.app import assembly
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.errors import WiringError
from vehicle.keys import STANDARD_KEYS, is_valid_key

ASSEMBLY = Path(assembly.__file__).parent


def basic_car(tmp_path: Path, **settings) -> Vehicle:
    """The basic template's drive(), on the simulated board and camera."""
    cfg = Config.defaults(CAR_PATH=str(tmp_path), CAMERA_TYPE="MOCK", DRIVE_TRAIN_TYPE="MOCK",
                          TRAIN_BEHAVIORS=True, **settings)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_camera(V, cfg)
    assembly.add_controller(V, cfg)
    assembly.add_camera_watchdog(V, cfg)
    assembly.add_behavior(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_throttle_filter(V, cfg)
    assembly.add_drivetrain(V, cfg)
    assembly.add_recording_rules(V, cfg)
    assembly.add_tub_writer(V, cfg)
    return V


def sim_car(tmp_path: Path) -> Vehicle:
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_TEXTURE_RES=0.02)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(V, cfg, seeds=[3])
    assembly.add_controller(V, cfg)
    assembly.add_drive_mode(V, cfg)
    assembly.add_tub_writer(V, cfg)
    return V


def path_car(tmp_path: Path, localizer: str = "fused") -> Vehicle:
    """The path_follow template's drive --sim."""
    from vehicle.app.path_sim import sensor_config

    cfg = sensor_config(Config.defaults(CAR_PATH=str(tmp_path), SIM_TEXTURE_RES=0.02, PATH_LOCALIZER=localizer),
                        localizer)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(V, cfg, seeds=[3])
    assembly.add_controller(V, cfg)
    assembly.add_path_follow(V, cfg)
    assembly.add_drive_mode(V, cfg)
    return V


@pytest.mark.parametrize("build", [
    lambda p: basic_car(p),
    lambda p: basic_car(p, USE_JOYSTICK_AS_DEFAULT=True, CONTROLLER_TYPE="generic",
                        JOYSTICK_DEVICE_FILE=str(p / "no-js0")),
    sim_car,
    path_car,
    lambda p: path_car(p, "gps"),
], ids=["basic", "basic+gamepad", "simulator", "path_follow", "path_follow+gps"])
def test_assembled_cars_use_standard_or_namespaced_keys_and_wire_cleanly(tmp_path, build):
    V = build(tmp_path)
    V.check_wiring()
    keys = {k for e in V.parts for k in (*e.inputs, *e.outputs, *([e.run_condition] if e.run_condition else []))}
    assert keys and sorted(k for k in keys if not is_valid_key(k)) == []
    assert not any(k in V.mem for k in keys if not k.startswith("loop/")), "helpers must not seed memory"
    for e in V.parts:
        shutdown = getattr(e.part, "shutdown", None)
        if callable(shutdown):
            shutdown()


def test_every_key_literal_in_the_assembly_code_is_valid():
    literals = set()
    for path in ASSEMBLY.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and "/" in node.value \
                    and " " not in node.value and not node.value.endswith((".py", ".json", ".mp4")):
                literals.add(node.value)
    assert "cam/timestamp" in literals and "js/angle" in literals  # the scan sees the keys
    assert sorted(k for k in literals if not is_valid_key(k)) == []


def test_standard_keys_follow_the_rule():
    assert sorted(k for k in STANDARD_KEYS if not is_valid_key(k)) == []


def test_drive_mode_before_the_controller_is_a_wiring_error(tmp_path):
    cfg = Config.defaults(CAR_PATH=str(tmp_path), SIM_TEXTURE_RES=0.02)
    V = Vehicle(clock=SimulatedClock())
    assembly.add_simulator(V, cfg, seeds=[3])
    assembly.add_drive_mode(V, cfg)  # moved above add_controller: it would act on last loop's commands
    web = assembly.add_controller(V, cfg)
    with pytest.raises(WiringError, match="'DriveMode' input 'user/mode' is read before part 'WebController'"):
        V.check_wiring()
    web.shutdown()


def declared_parts() -> dict[str, type]:
    """Every class in parts/ that declares its keys (INPUTS or OUTPUTS as a class attribute)."""
    import importlib
    import pkgutil

    import parts

    found = {}
    for info in pkgutil.walk_packages(parts.__path__, "parts."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, type) and obj.__module__ == info.name and (
                    isinstance(vars(obj).get("INPUTS"), tuple) or isinstance(vars(obj).get("OUTPUTS"), tuple)):
                found[f"{info.name}.{obj.__name__}"] = obj
    return found


def test_every_part_declaration_uses_valid_keys_and_consistent_lists():
    found = declared_parts()
    assert {"parts.drive.modes.DriveMode", "parts.sim.simulator.SimCar", "parts.web.controller.WebController",
            "parts.cameras.base.Camera"} <= set(found)
    bad = {}
    for name, cls in found.items():
        declared = {label: getattr(cls, label, ()) for label in ("INPUTS", "OUTPUTS", "OPTIONAL_INPUTS", "FEEDBACK")}
        keys = [k for label, value in declared.items() if isinstance(value, tuple) for k in value]
        wrong = [k for k in keys if not is_valid_key(k)]
        stray = [k for label in ("OPTIONAL_INPUTS", "FEEDBACK") if isinstance(declared[label], tuple)
                 for k in declared[label] if isinstance(declared["INPUTS"], tuple) and k not in declared["INPUTS"]]
        if wrong or stray:
            bad[name] = {"invalid keys": wrong, "optional/feedback not among INPUTS": stray}
    assert bad == {}
