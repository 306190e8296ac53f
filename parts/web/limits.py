"""What a browser (or any client) can make the server do before a handler runs, bounded.

- :class:`BoundedPacket`: python-socketio's packet class with limits. An event larger than
  :data:`~parts.web.protocol.MAX_MESSAGE_BYTES`, one that is not valid JSON (a 5,000-digit
  number included) or that is not ``[name, payload]`` reaches the server as the event
  :data:`REFUSED_EVENT` carrying the reason, so it gets the documented error acknowledgement
  instead of an exception in the library. Messages above :data:`HARD_LIMIT_BYTES` are refused by
  Engine.IO, which closes the connection.
- :class:`BoundedLog`: the logger handed to python-socketio and Engine.IO and used for rejected
  messages. Each line is cut to :data:`MAX_LINE_CHARS`, tracebacks become one line, the
  libraries' per-message INFO lines are DEBUG, and at most :data:`LINES_PER_WINDOW` lines are
  written per :data:`WINDOW_S` seconds; the lines held back are counted in the next one.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Callable, MutableMapping
from typing import Any, Final

from parts.web.protocol import MAX_MESSAGE_BYTES

#: event name a refused packet is delivered as (its payload is the reason)
REFUSED_EVENT: Final = "\x00refused"
#: Engine.IO closes a connection whose message is larger than this (bytes)
HARD_LIMIT_BYTES: Final = 64 * 1024
#: longest line a client can make the server log
MAX_LINE_CHARS: Final = 300
#: lines written per window at most (per BoundedLog), and the window
LINES_PER_WINDOW: Final = 20
WINDOW_S: Final = 10.0

# packet type, attachment count, namespace, ack id: everything before the JSON payload
_HEADER = re.compile(r"(\d)(?:\d+-)?(?:/[^,]*,)?\d*")
_EVENT = "2"  # Socket.IO EVENT packet type


def _packet_base() -> type:
    from socketio.packet import Packet

    return Packet


def make_bounded_packet() -> type:
    """The :class:`BoundedPacket` class (python-socketio is imported only when the server starts)."""
    base = _packet_base()

    class BoundedPacket(base):  # type: ignore[misc, valid-type]
        """A Socket.IO packet whose event payload is size-, JSON- and shape-checked on decode."""

        def decode(self, encoded_packet: Any) -> int:
            if not isinstance(encoded_packet, str) or not encoded_packet.startswith(_EVENT):
                return super().decode(encoded_packet)
            header = _HEADER.match(encoded_packet)
            head = header.group(0) if header else encoded_packet[:1]
            size = len(encoded_packet.encode("utf-8", "surrogatepass"))
            if size > MAX_MESSAGE_BYTES:
                return self._refused(head, f"message of {size} bytes is larger than the limit of "
                                           f"{MAX_MESSAGE_BYTES} bytes")
            try:
                count = super().decode(encoded_packet)
            except ValueError as exc:  # JSON (engineio refuses numbers of more than 100 digits)
                return self._refused(head, f"message is not valid JSON ({str(exc)[:80]})")
            data = self.data
            if not (isinstance(data, list) and data and isinstance(data[0], str)):
                return self._refused(head, 'not an event: send ["name", payload]')
            return count

        def _refused(self, head: str, why: str) -> int:
            count = super().decode(head)
            self.data = [REFUSED_EVENT, why]
            return count

    return BoundedPacket


class BoundedLog(logging.LoggerAdapter):
    """A logger whose output a client cannot inflate (see the module docstring).

    Args:
        logger: where the lines go.
        what: what the lines held back are, for the summary line.
        demote_info: log the wrapped code's INFO lines at DEBUG (python-socketio logs every event).
        clock: monotonic seconds (tests).
    """

    def __init__(self, logger: logging.Logger, what: str = "lines", *, demote_info: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(logger, {})
        self.what = what
        self.demote_info = demote_info
        self._clock = clock
        self._lock = threading.Lock()
        self._window_start = -WINDOW_S
        self._written = 0
        self.held = 0  # lines held back in the current window
        self.held_total = 0

    def log(self, level: int, msg: object, *args: Any, exc_info: Any = None, **kwargs: Any) -> None:
        """Log one bounded line: formatted, cut, without traceback, within the rate."""
        if self.demote_info and level == logging.INFO:
            level = logging.DEBUG
        if not self.logger.isEnabledFor(level):
            return
        try:
            text = str(msg) % args if args else str(msg)
        except (TypeError, ValueError):
            text = f"{msg!s} {args!r}"
        if exc_info:
            exc = exc_info if isinstance(exc_info, BaseException) else None
            if exc is None:
                import sys

                exc = sys.exc_info()[1]
            if exc is not None:
                text += f" ({type(exc).__name__}: {str(exc)[:120]})"
        text = " ".join(text.split())  # one line whatever the client sent
        if len(text) > MAX_LINE_CHARS:
            text = text[:MAX_LINE_CHARS] + f"... ({len(text)} characters)"
        with self._lock:
            now = self._clock()
            if now - self._window_start >= WINDOW_S:
                held, self.held = self.held, 0
                self._window_start, self._written = now, 0
                if held:
                    text += f" ({held} more {self.what} held back in the last {WINDOW_S:.0f} s)"
            if self._written >= LINES_PER_WINDOW:
                self.held += 1
                self.held_total += 1
                return
            self._written += 1
        self.logger.log(level, "%s", text, **kwargs)

    def flush(self, force: bool = False) -> None:
        """Write the count of lines held back once their window is over (or now, ``force``)."""
        with self._lock:
            if not self.held or not force and self._clock() - self._window_start < WINDOW_S:
                return
            held, self.held = self.held, 0
            self._window_start, self._written = self._clock(), 1
        self.logger.warning("%d more %s held back in the last %.0f s", held, self.what, WINDOW_S)

    def process(self, msg: Any, kwargs: MutableMapping[str, Any]) -> tuple[Any, MutableMapping[str, Any]]:
        """No extra context (LoggerAdapter's hook)."""
        return msg, kwargs
