"""One table per part family: type name -> ``"module:Class"``, each class built by ``from_config``.

Gymnasium's ``register(id, entry_point=...)`` is the model. A family declares its table beside its
settings (``parts/cameras/registry.py``), the setting that picks a row declares the table as its
valid values (``CAMERA_TYPE: Annotated[str, OneOf(CAMERAS)]``), and the application only picks and
wires::

    CAMERAS = Registry("CAMERA_TYPE", {"MOCK": "parts.cameras.mock:MockSource", ...})
    source = CAMERAS.from_config(cfg)          # MockSource.from_config(cfg) when CAMERA_TYPE = "MOCK"

Nothing is imported until a row is built, so a table names hardware drivers freely. An installed
package of parts adds rows to a table by declaring them in a ``registry.py`` of its family package
(:mod:`vehicle.discovery`): ``ROWS = {"IMU_SENSOR": {"bno055": "car_bno055.imu:BNO055"}}``; they
join the table when it is first read.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import Any

from vehicle.config_checks import OneOf
from vehicle.discovery import family_declarations


class Registry(Mapping[str, str]):
    """A family's table: type name -> ``"module:Class"`` entry point.

    Args:
        setting: the setting whose value names the row (``"CAMERA_TYPE"``).
        entries: the rows; several names may share an entry (``CVCAM`` and ``WEBCAM``).
        enabled_by: for a family that is optional on a car (a sensor), the bool setting that adds
            it (DonkeyCar's ``HAVE_IMU``); None: the family is always built when asked.
        kind: the kind's short name in commands and messages (``"imu"``: ``vehicle hw check
            --only imu``); default: the setting's name in lower case.
    """

    def __init__(self, setting: str, entries: Mapping[str, str] | None = None,
                 enabled_by: str | None = None, kind: str | None = None) -> None:
        self.setting = setting
        self.enabled_by = enabled_by
        self.kind = kind or setting.lower()
        self._entries: dict[str, str] = {}
        self._extended = False  # whether the installed families' ROWS for this table were added
        for name, entry_point in (entries or {}).items():
            self.register(name, entry_point)

    def register(self, name: str, entry_point: str) -> None:
        """Add a row (``"module.path:Class"``); a name already taken is a programming error."""
        module, _, attr = entry_point.partition(":")
        if not module or not attr:
            raise ValueError(f"{self.setting} {name!r}: entry point {entry_point!r} is not 'module:Class'")
        if name in self._entries:
            raise ValueError(f"{self.setting} {name!r} is already registered as {self._entries[name]}")
        self._entries[name] = entry_point

    def _rows(self) -> dict[str, str]:
        """The table, with the rows families declare in their ``registry.py`` ``ROWS`` (added once)."""
        if not self._extended:
            self._extended = True
            for _module, rows in family_declarations("registry.py", "ROWS"):
                for name, entry_point in rows.get(self.setting, {}).items():
                    if self._entries.get(name) != entry_point:
                        self.register(name, entry_point)
        return self._entries

    def __getitem__(self, name: str) -> str:
        return self._rows()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._rows())

    def __len__(self) -> int:
        return len(self._rows())

    def choice(self) -> OneOf:
        """The constraint for the setting's annotation: one of the table's names."""
        return OneOf(self)

    def load(self, name: str) -> Any:
        """The class of row ``name`` (its module imported now)."""
        rows = self._rows()
        if name not in rows:
            raise KeyError(f"{self.setting} = {name!r} is not one of {', '.join(rows)}")
        module, _, attr = rows[name].partition(":")
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
        return obj

    def enabled(self, cfg: Mapping[str, Any]) -> bool:
        """Whether the car asks for this family (always, unless ``enabled_by`` says otherwise)."""
        return self.enabled_by is None or bool(cfg[self.enabled_by])

    def from_config(self, cfg: Any, name: str | None = None, **wiring: Any) -> Any:
        """Build the row the car's settings pick (or ``name``): ``Class.from_config(cfg, **wiring)``.

        ``wiring`` is what the application passes that is not a setting (a clock, a bus factory).
        """
        return self.load(cfg[self.setting] if name is None else name).from_config(cfg, **wiring)
