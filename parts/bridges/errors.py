"""The bridges' own error type: a one-line message for the user that says what to fix."""

from __future__ import annotations

import logging
import re

from vehicle.errors import VehicleError


class BridgeError(VehicleError):
    """A simulator bridge cannot work as configured (port taken, unsupported library, bad scene)."""


class OncePerKind:
    """Logs each kind of problem a peer causes once. The kind is the message with its details
    taken out (numbers, quoted and bracketed text), so a peer cannot make the lines, or the memory
    of what was said, grow by varying them; after ``max_kinds`` kinds one last line says that
    further kinds are only counted (:attr:`count`).

    Args:
        logger: where the lines go.
        max_kinds: kinds remembered.
    """

    _DETAILS = re.compile(r"\([^()]*\)|\[[^\]]*\]|'[^']*'|\"[^\"]*\"|\d+")

    def __init__(self, logger: logging.Logger, max_kinds: int = 16) -> None:
        self.logger = logger
        self.max_kinds = max_kinds
        self._kinds: set[str] = set()
        self.count = 0  # problems reported, said or not

    def __len__(self) -> int:
        return len(self._kinds)

    @classmethod
    def kind(cls, message: str) -> str:
        """``message`` without what a peer chooses (the same kind of problem gives the same text)."""
        previous = None
        while previous != message:  # nested brackets, from the inside out
            previous, message = message, cls._DETAILS.sub("#", message)
        return message[:200]

    def report(self, level: int, message: str, detail: str = "") -> bool:
        """Log ``message`` (+ ``detail``) if its kind is new; returns whether a line was written."""
        self.count += 1
        kind = self.kind(message)
        if kind in self._kinds or len(self._kinds) > self.max_kinds:
            return False
        if len(self._kinds) == self.max_kinds:
            self._kinds.add("")  # the set is full: one last line
            self.logger.log(level, "%s kinds of problems reported already: further ones are only counted",
                            self.max_kinds)
            return True
        self._kinds.add(kind)
        self.logger.log(level, "%.300s%s", message, detail)
        return True
