"""Which LeRobot feature holds which tub field: the mapping used both ways.

Export builds the columns from a survey of the tubs; the list is saved in meta/vehicle_rc.json
(``Column.spec``) and import rebuilds the same columns from it (``column_from_spec``) to turn each
row back into a record. Kinds:

- ``camera``: an image field -> ``observation.images.<name>`` (video, or image bytes in the data);
- ``vector``: numbers from one or more tub fields, concatenated (``action`` = user/angle,
  user/throttle; ``observation.state`` = speed + behaviour one-hot; any other numeric field);
  a missing value is NaN (float columns only: a field missing in some records gets one);
- ``text``: a str field as is, or any other value (nested lists ...) as JSON; missing = "".
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

CAMERA_PREFIX = "observation.images."


def camera_name(key: str) -> str:
    """``cam/image_array`` -> ``cam``; ``cam/image_array_left`` -> ``cam_left``."""
    return key.replace("/image_array", "").replace("/", "_") or "cam"


@dataclass
class Part:
    """One tub field inside a vector column: ``width`` numbers (1 for a scalar field)."""

    key: str
    type: str                      # the tub type (float, int, boolean, nparray, list, vector)
    width: int = 1
    items: str = "float"           # list items: float or int (restored as such)
    aliases: tuple[str, ...] = ()  # other keys read for this field (user/steering for user/angle)

    def read(self, data: dict[str, Any]) -> list[float]:
        value = data.get(self.key)
        if value is None:
            for alias in self.aliases:
                value = data.get(alias)
                if value is not None:
                    break
        if value is None:
            return [math.nan] * self.width
        if self.width == 1 and not isinstance(value, list | tuple):
            return [float(value)]
        values = [float(v) for v in value]
        return values if len(values) == self.width else [math.nan] * self.width

    def restore(self, values: list[float], record: dict[str, Any], key: str | None = None) -> None:
        """Put the values back into ``record`` under ``key`` (default: this part's key; one of its
        aliases for a record whose tub used that name)."""
        if any(math.isnan(v) for v in values):
            return  # missing in the tub: left out, as the tub left it out
        key = key or self.key
        if self.type in ("nparray", "list", "vector"):
            record[key] = [int(round(v)) for v in values] if self.items == "int" else list(values)
        elif self.type == "int":
            record[key] = int(round(values[0]))
        elif self.type == "boolean":
            record[key] = bool(values[0])
        else:
            record[key] = values[0]

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"key": self.key, "type": self.type, "width": self.width}
        if self.items != "float":
            out["items"] = self.items
        if self.aliases:
            out["aliases"] = list(self.aliases)
        return out


@dataclass
class Column:
    """A LeRobot feature and the tub fields behind it."""

    name: str
    kind: str                       # camera | vector | text
    feature: dict[str, Any]         # dtype, shape, names (as in info.json)
    key: str = ""                   # camera and text: the tub field
    type: str = ""                  # camera and text: its tub type
    parts: list[Part] = field(default_factory=list)  # vector: the fields, in order
    encoding: str = "plain"         # text: plain (str fields) or json

    @property
    def dtype(self) -> str:
        return self.feature["dtype"]

    def read(self, data: dict[str, Any]) -> Any:
        """The column's value for one record's fields (vector: list of floats; text: str)."""
        if self.kind == "vector":
            out: list[float] = []
            for part in self.parts:
                out.extend(part.read(data))
            return out
        value = data.get(self.key)
        if value is None:
            return ""
        return str(value) if self.encoding == "plain" else json.dumps(value, separators=(",", ":"))

    def restore(self, value: Any, record: dict[str, Any], renames: dict[str, str] | None = None) -> None:
        """Put the column's value of one row back as tub fields into ``record`` (``renames``: tub
        key -> the alias the record's own tub used, e.g. user/angle -> user/steering)."""
        if self.kind == "vector":
            if self.dtype == "float32":
                # the shortest decimal that is this float32: 0.3 comes back as 0.3, not 0.30000001192...
                values = [float(str(v)) for v in np.atleast_1d(np.asarray(value, dtype=np.float32))]
            else:
                values = np.atleast_1d(np.asarray(value, dtype=np.float64)).tolist()
            i = 0
            for part in self.parts:
                part.restore(values[i:i + part.width], record, renames.get(part.key) if renames else None)
                i += part.width
        elif self.kind == "text":
            if value not in (None, ""):
                record[self.key] = value if self.encoding == "plain" else json.loads(value)
        else:
            record[self.key] = value

    def fields(self) -> list[tuple[str, str]]:
        """(tub key, tub type) of every field behind the column."""
        return [(p.key, p.type) for p in self.parts] if self.kind == "vector" else [(self.key, self.type)]

    def renames(self, inputs: list[str]) -> dict[str, str]:
        """For a tub with these inputs: part key -> the alias it used instead (user/angle ->
        user/steering in a DonkeyCar 4.x tub)."""
        out = {}
        for part in self.parts:
            if part.key not in inputs:
                used = next((a for a in part.aliases if a in inputs), None)
                if used:
                    out[part.key] = used
        return out

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"feature": self.name, "kind": self.kind}
        if self.kind == "vector":
            out["parts"] = [p.spec() for p in self.parts]
        else:
            out.update(key=self.key, type=self.type)
            if self.kind == "text":
                out["encoding"] = self.encoding
        return out


def column_from_spec(spec: dict[str, Any], features: dict[str, dict[str, Any]]) -> Column:
    """The column a sidecar entry describes (its feature taken from info.json)."""
    name = spec["feature"]
    if name not in features:
        raise KeyError(name)
    col = Column(name, spec["kind"], features[name], key=spec.get("key", ""), type=spec.get("type", ""),
                 encoding=spec.get("encoding", "plain"))
    col.parts = [Part(p["key"], p["type"], int(p.get("width", 1)), p.get("items", "float"),
                      tuple(p.get("aliases", ()))) for p in spec.get("parts", [])]
    return col
