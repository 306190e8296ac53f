"""A framework for small self-driving cars: a fixed-rate loop of parts over a shared memory.

>>> from vehicle import Vehicle
>>> V = Vehicle()
>>> V.add(lambda: 1.0, outputs=["user/angle"])
"""

from vehicle.memory import Memory
from vehicle.part import ThreadedPart
from vehicle.vehicle import Vehicle

__all__ = ["Memory", "ThreadedPart", "Vehicle"]
__version__ = "0.1.0"

#: names a car's manage.py imported from ``vehicle`` before the application moved to vehicle.app
_MOVED = {"assembly": "vehicle.app.assembly", "car": "vehicle.app.manage"}


def __getattr__(name: str) -> object:
    # `from vehicle import assembly, car` in a manage.py made by an older createcar: say how to
    # update it instead of a bare ImportError (ImportError, so `from ... import` shows this message)
    if name in _MOVED:
        raise ImportError(f"vehicle.{name} moved to {_MOVED[name]}: this manage.py was made by an older "
                          "`vehicle createcar`; run `vehicle createcar --path <your car> --overwrite` "
                          "(myconfig.py is kept) or import `from vehicle.app import assembly, manage`")
    raise AttributeError(f"module 'vehicle' has no attribute {name!r}")
