"""Each bound is written once, in the setting's annotation: every part built from a table row
refuses, in its own constructor, a value outside the range its settings declare, and names the
setting (issue 40). The parts are built through ``from_config`` from settings that skip the loader's
checks, so only the part's own check stands between the value and the car."""

from __future__ import annotations

import ast
import importlib
from typing import Any

import pytest

from vehicle.config import Config, settings
from vehicle.config_checks import Range


class Unchecked:
    """The settings of ``cfg`` with some values replaced, unchecked; it notes which it was asked."""

    def __init__(self, cfg: Config, replaced: dict[str, Any] | None = None) -> None:
        self._cfg, self._replaced, self.read = cfg, replaced or {}, set()

    def __getattr__(self, name: str) -> Any:
        if name.isupper():
            self.read.add(name)
            if name in self._replaced:
                return self._replaced[name]
        return getattr(self._cfg, name)

    def __getitem__(self, name: str) -> Any:
        self.read.add(name)
        return self._replaced.get(name, self._cfg[name])


def _range(name: str) -> Range | None:
    setting = settings()[name]
    annotation = eval(setting.annotation, vars(importlib.import_module(setting.module)))  # noqa: S307
    return next((m for m in getattr(annotation, "__metadata__", ()) if isinstance(m, Range)), None)


def _outside(r: Range, default: Any) -> list[Any]:
    """A value just below and just above the range (of the default's type)."""
    step = 1 if isinstance(default, int) else 1e-3
    values = []
    if r.lo is not None:
        values.append(r.lo if r.lo_open else r.lo - step)
    if r.hi is not None:
        values.append(r.hi if r.hi_open else r.hi + step)
    return [int(v) if isinstance(default, int) else float(v) for v in values]


def _following(name: str) -> set[str]:
    """``name`` and the settings whose default is computed from it (PWM_STEERING_PIN from
    STEERING_CHANNEL, DonkeyCar's legacy): a refusal may name either."""
    known = settings()
    return {name} | {other for other, s in known.items()
                     if any(isinstance(n, ast.Name) and n.id == name for n in ast.walk(s.expression))}


def _rows() -> list[tuple[Any, str, dict[str, Any], dict[str, Any]]]:
    from parts.actuators.fake_pca9685 import FakeI2C
    from parts.actuators.registry import DRIVETRAINS
    from parts.cameras.registry import CAMERAS
    from parts.sensors.registry import sensor_tables

    i2c = FakeI2C()
    i2c.add_board(1, 0x40)
    paths = {"CAMERA_VIDEO_PATH": "clip.mp4", "CAMERA_IMAGE_PATH": "frames"}
    rows = [(t, n, {"GPIO_MOCK": True}, {}) for t in sensor_tables() for n in t]
    rows += [(CAMERAS, n, paths, {}) for n in CAMERAS]
    rows += [(DRIVETRAINS, n, {"GPIO_MOCK": True}, {"bus_factory": i2c.smbus}) for n in DRIVETRAINS]
    return rows


def test_every_table_row_refuses_what_its_settings_refuse():
    checked, problems = 0, []
    for table, name, base, wiring in _rows():
        cfg = Config.defaults(**{table.setting: name, **base})
        cls = table.load(name)
        probe = Unchecked(cfg)
        cls.from_config(probe, **wiring)
        for setting in sorted(probe.read):
            bound, default = _range(setting), cfg[setting]
            if bound is None or isinstance(default, bool) or not isinstance(default, int | float):
                continue
            for bad in _outside(bound, default):
                checked += 1
                try:
                    cls.from_config(Unchecked(cfg, {setting: bad}), **wiring)
                except (ValueError, TypeError) as exc:
                    if not any(n in str(exc) for n in _following(setting)):
                        problems.append(f"{table.setting}={name}: {setting}={bad!r} refused without naming it: {exc}")
                else:
                    problems.append(f"{table.setting}={name}: {setting}={bad!r} is outside {bound.describe()} "
                                    "but the part took it")
    assert not problems, "\n".join(problems)
    assert checked > 150  # every row, every ranged setting it reads, both ends


@pytest.mark.parametrize("part", ["ObstacleStop", "Odometer", "BicyclePose"])
def test_parts_outside_the_tables_check_with_the_settings_ranges_too(part):
    from parts.drive.obstacle import ObstacleStop
    from parts.sensors.odometry import BicyclePose, Odometer
    from vehicle.config import ConfigError

    build = {"ObstacleStop": lambda: ObstacleStop(25.0), "Odometer": lambda: Odometer(0.0),
             "BicyclePose": lambda: BicyclePose(0.26, 1.6)}[part]
    setting = {"ObstacleStop": "OBSTACLE_STOP_DISTANCE", "Odometer": "MM_PER_TICK",
               "BicyclePose": "MAX_STEERING_ANGLE"}[part]
    with pytest.raises(ConfigError, match=f"{setting} = .* is out of range; valid: {_range(setting).describe()}"):
        build()
