"""The last part of a loop that drives an external simulator: it sends this loop's command now.

A simulator part runs first in the loop (it produces the camera frame), so the ``angle`` and
``throttle`` it reads are the previous loop's, and a command computed from a frame would leave one
loop period later. Added after every part that changes the commands, :class:`SendCommands` hands
them to the simulator part as soon as they are final: the Udacity simulator's answer for a frame
leaves in the loop that saw the frame (half the round trip at 20 Hz), the Donkey simulator's
``control`` one period sooner.
"""

from __future__ import annotations

from typing import Any, ClassVar

from vehicle.part import part_name


class SendCommands:
    """Part: ``run(angle, throttle)`` calls ``bridge.command(angle, throttle)``.

    Args:
        bridge: a simulator part with ``command(angle, throttle)`` (UdacitySim, DonkeySim).
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")

    def __init__(self, bridge: Any) -> None:
        if not callable(getattr(bridge, "command", None)):
            raise TypeError(f"SendCommands needs a simulator part with command(angle, throttle), "
                            f"got {type(bridge).__name__}")
        self.bridge = bridge
        self.name = f"{part_name(bridge)}.commands"

    def run(self, angle: Any, throttle: Any) -> None:
        """Send the loop's final commands to the simulator."""
        self.bridge.command(angle, throttle)
