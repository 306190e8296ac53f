"""Part family tables: type name -> "module:Class", built by from_config; the setting that picks a
row takes the table as its valid values."""

from __future__ import annotations

import pytest

from vehicle.config import Config, ConfigError
from vehicle.registry import Registry


class Probe:
    """A row target: remembers what from_config got."""

    def __init__(self, size: int, clock: object) -> None:
        self.size, self.clock = size, clock

    @classmethod
    def from_config(cls, cfg, *, clock=None):
        return cls(cfg["IMAGE_W"], clock)

    def run(self) -> None:
        """A part with no inputs and no outputs."""


def test_a_row_is_imported_only_when_built_and_gets_the_config_and_the_wiring():
    table = Registry("CAMERA_TYPE", {"PROBE": f"{__name__}:Probe", "BROKEN": "no_such_module_xyz:Thing"})
    assert list(table) == ["PROBE", "BROKEN"] and table["PROBE"] == f"{__name__}:Probe"
    part = table.from_config({"CAMERA_TYPE": "PROBE", "IMAGE_W": 64}, clock="clk")
    assert (type(part), part.size, part.clock) == (Probe, 64, "clk")
    with pytest.raises(ModuleNotFoundError):
        table.load("BROKEN")


def test_rows_are_checked_when_registered():
    table = Registry("X_TYPE")
    table.register("A", "mod:Cls")
    with pytest.raises(ValueError, match="already registered"):
        table.register("A", "mod:Other")
    with pytest.raises(ValueError, match="not 'module:Class'"):
        table.register("B", "mod.Cls")
    with pytest.raises(KeyError, match="X_TYPE = 'C' is not one of A"):
        table.load("C")


def test_every_row_of_every_family_table_loads_and_has_from_config():
    from parts.actuators.registry import DRIVETRAINS
    from parts.bridges.registry import SIMULATORS
    from parts.cameras.registry import CAMERAS
    from parts.sensors.registry import SENSOR_TABLES

    for table in (CAMERAS, DRIVETRAINS, SIMULATORS, *SENSOR_TABLES):
        for name in table:
            assert callable(getattr(table.load(name), "from_config", None)), f"{table.setting} {name}"


def test_the_type_setting_takes_its_table_as_valid_values(tmp_path):
    (tmp_path / "myconfig.py").write_text('IMAGE_W = 80\nCAMERA_TYPE = "USB"\n')
    from vehicle.config import load_config

    with pytest.raises(ConfigError, match=r'myconfig.py, line 2: CAMERA_TYPE = \'USB\' is unknown; valid: one of '
                                          r'"PICAM", "CVCAM", "WEBCAM", "CSIC", "VIDEO", "IMAGE_LIST", "MOCK"\.'):
        load_config(car_path=tmp_path)
    with pytest.raises(ConfigError, match='DRIVE_TRAIN_TYPE = \'L298N\' is unknown; valid: one of '
                                          '"PWM_STEERING_THROTTLE", "MOCK"'):
        Config.defaults(DRIVE_TRAIN_TYPE="L298N")


def test_the_drivetrain_table_builds_the_mock_drivetrain_on_a_simulated_board():
    from vehicle.app.assembly.drivetrain import build_drivetrain

    part = build_drivetrain(Config.defaults(DRIVE_TRAIN_TYPE="MOCK"))
    part.open()
    try:
        boards = list(part.pins.boards.values())
        assert len(boards) == 1 and boards[0].is_open and part.last_ticks is None
    finally:
        part.shutdown()


def test_add_sensors_adds_the_enabled_kinds_with_the_vehicle_clock():
    from vehicle import Vehicle
    from vehicle.app.assembly.sensors import add_sensors

    on = Registry("CAMERA_TYPE", {"MOCK": f"{__name__}:Probe"}, enabled_by="USE_WEB_CONTROLLER")
    off = Registry("CAMERA_TYPE", {"MOCK": f"{__name__}:Probe"}, enabled_by="TRAIN_BEHAVIORS")
    V = Vehicle()
    added = add_sensors(V, Config.defaults(CAMERA_TYPE="MOCK", IMAGE_W=32), tables=[on, off])
    assert [type(p) for p in added] == [Probe] and added[0].size == 32
    assert added[0].clock == V.clock.now and len(V.parts) == 1
    assert add_sensors(Vehicle(), Config.defaults()) == []  # no sensor kinds registered yet
