"""Parts of an evaluation episode on a simulator: put the car back when it leaves the road, and
give up when no simulator sends frames."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, ClassVar


class ResetOnOffTrack:
    """Part: an off-track event asks the Donkey simulator for ``reset_car`` (rising ``sim/reset``),
    as a person would put the car back; the simulator puts it on the start line."""

    INPUTS: ClassVar[tuple[str, ...]] = ("sim/off_track",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("sim/reset",)

    def run(self, off_track: Any) -> bool:
        return bool(off_track)


class StopIfNoSimulator:
    """Part: stops the loop when no frame arrived within ``wait_s`` seconds of the start."""

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/ok",)

    def __init__(self, wait_s: float, stop: Callable[[], None]) -> None:
        self.wait_s, self.stop = wait_s, stop
        self.started = time.monotonic()
        self.seen = False
        self.gave_up = False

    def run(self, ok: Any) -> None:
        self.seen = self.seen or bool(ok)
        if not self.seen and time.monotonic() - self.started > self.wait_s:
            self.gave_up = True
            self.stop()
