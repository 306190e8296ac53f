"""The Udacity simulator's telemetry and steer values: units, keys, and numbers in any locale.

Facts (docs/simulators.md): the simulator sends every number as a string written in its own
locale (``"0,1234"`` on a comma-decimal Windows) and speed in mph; it parses a ``steer``'s
values with ``float.Parse`` in that same locale. Research forks add keys of their own (``cte``,
``lapNumber``). :mod:`parts.bridges.udacity_sim` (the part) uses these; nothing here does I/O.
"""

from __future__ import annotations

import math
import re
from typing import Any, Final

MS_PER_MPH: Final = 0.44704
#: telemetry keys of the stock simulator; everything else is a fork's extra
STOCK_KEYS: Final = ("steering_angle", "throttle", "speed", "image")
#: fork keys with a standard memory key of their own
FORK_KEYS: Final = {"cte": "sim/cte", "lapNumber": "sim/lap"}
DECIMALS: Final = ("auto", ".", ",")
#: (width, height) of the frames the Udacity simulator sends
FRAME_SIZE: Final = (320, 160)
_COMMA_NUMBER = re.compile(r"^\s*[-+]?\d+,\d+\s*$")


def parse_number(value: Any) -> float | None:
    """A telemetry number whatever the simulator's locale; None when it is not a finite number.

    ``"0.1234"``, ``"0,1234"``, ``"1,234.5"``, ``"1.234,5"``, ``"-3"`` and JSON numbers are read;
    with both separators the last one is the decimal separator.
    """
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, int | float):
        out = float(value)
    elif isinstance(value, str):
        text = value.strip().replace("\u00a0", "").replace(" ", "")  # fr: a space groups thousands
        if "," in text and "." in text:
            if text.rfind(",") > text.rfind("."):
                text = text.replace(".", "").replace(",", ".")
            else:
                text = text.replace(",", "")
        elif "," in text:
            text = text.replace(",", ".") if text.count(",") == 1 else text.replace(",", "")
        try:
            out = float(text)
        except ValueError:
            return None
    else:
        return None
    return out if math.isfinite(out) else None


def extra_key(name: str) -> str:
    """The memory key of a fork's telemetry key: ``sim/`` + snake case (``currentWayPoint`` ->
    ``sim/current_way_point``)."""
    snake = re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", name).lower()
    return "sim/" + re.sub(r"[^a-z0-9_]+", "_", snake).strip("_")


def format_command(value: Any, decimal: str = ".") -> str:
    """A steer value as the simulator parses it: a string, fixed point, no exponent; 0 for junk."""
    number = parse_number(value)
    number = 0.0 if number is None else min(1.0, max(-1.0, number))
    text = f"{number:.6f}"
    return text.replace(".", ",") if decimal == "," else text


def uses_decimal_comma(telemetry: dict[str, Any]) -> bool:
    """Whether a telemetry writes its stock numbers with decimal commas (the simulator's locale)."""
    return any(isinstance(telemetry.get(k), str) and _COMMA_NUMBER.match(telemetry[k]) for k in STOCK_KEYS[:3])
