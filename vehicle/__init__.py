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
