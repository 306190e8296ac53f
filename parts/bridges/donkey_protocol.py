"""The Donkey simulator's TCP JSON protocol: framing, parsing and the tables both sides share.

Facts (docs/simulators.md): the simulator (tawnkramer/sdsandbox) is the TCP server, port 9091.
It sends one JSON object plus ``"\\n"`` per message, numbers as JSON numbers (on a comma-decimal
Windows locale Unity writes ``"cte":1,25``). Clients send ``json.dumps(msg)`` without a newline,
every value a string, which the simulator parses with the invariant culture; the simulator treats
each TCP chunk it receives as exactly one message, so a client must never let two messages travel
in one chunk (one ``sendall`` per message and a pause between them).

:class:`JsonStream` reads a stream of concatenated objects, with or without newlines, split across
or packed into chunks, and repairs comma floats.
"""

from __future__ import annotations

import codecs
import json
import logging
import math
import re
from typing import Any, Final

logger = logging.getLogger(__name__)

DEFAULT_PORT: Final = 9091
#: telemetry rate of the simulator (``limitFPS`` in FixedUpdate), Hz
TELEMETRY_HZ: Final = 20
#: degrees of wheel angle at steering 1.0 (``steer_to_angle``)
STEER_TO_ANGLE_DEG: Final = 16.0
#: gym-donkeycar environment id ``donkey-<name>-v0`` -> the simulator's scene (level) name
GYM_SCENES: Final = {
    "generated-roads": "generated_road", "warehouse": "warehouse", "avc-sparkfun": "sparkfun_avc",
    "generated-track": "generated_track", "mountain-track": "mountain_track",
    "roboracingleague-track": "roboracingleague_1", "waveshare": "waveshare",
    "minimonaco-track": "mini_monaco", "warren-track": "warren", "thunderhill-track": "thunderhill",
    "circuit-launch-track": "circuit_launch",
}
#: scene names of the simulator builds, in the order of the table above
SCENE_NAMES: Final = tuple(GYM_SCENES.values())
#: car bodies of ``car_config``
CAR_BODIES: Final = ("donkey", "bare", "car01", "f1", "cybertruck")
#: longest message accepted (a 640x480 PNG camera frame in base64 is ~1.2 MB)
MAX_MESSAGE_BYTES: Final = 16 * 1024 * 1024
#: what ``vehicle sim serve`` adds to its ``protocol_version`` reply (``capabilities``): it steps
#: once per ``control`` in ``step_mode`` synchronous. The Donkey simulator only sets
#: ``Time.timeScale = 0`` there (``OnStepModeRecv``): nothing steps it, telemetry stops, and no later
#: message restarts it, so a client asks for step mode only from a server that says it can.
STEP_MODE_CAPABILITY: Final = "step_mode"

_COMMA_FLOAT = re.compile(r"(:\s*-?\d+),(\d+(?:[eE][-+]?\d+)?)(?=\s*[,}\]])")
_IN_STRING = re.compile(r'["\\]')
_OUTSIDE = re.compile(r'[{}"]')


def scene_for(name: str) -> str:
    """The scene name for a scene or a gym id (``donkey-generated-track-v0`` -> ``generated_track``)."""
    key = name.strip()
    if key.startswith("donkey-") and key.endswith("-v0"):
        key = key[len("donkey-"):-len("-v0")]
    return GYM_SCENES.get(key, name.strip())


def wire_value(value: Any) -> str:
    """A value as a client sends it: a string; numbers with '.' decimals and no locale."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"cannot send a non-finite number ({value!r}) to the Donkey simulator")
    return repr(number)


def client_message(msg_type: str, **fields: Any) -> bytes:
    """One client -> simulator message: every value a string, no trailing newline."""
    body = {"msg_type": msg_type}
    body.update({k: wire_value(v) for k, v in fields.items()})
    return json.dumps(body, separators=(",", ":")).encode("utf-8")


def sim_message(msg_type: str, **fields: Any) -> bytes:
    """One simulator -> client message: JSON numbers as they are, a trailing newline."""
    body = {"msg_type": msg_type}
    body.update(fields)
    return (json.dumps(body, separators=(",", ":")) + "\n").encode("utf-8")


def number(value: Any, default: float | None = None) -> float | None:
    """A protocol number (a JSON number or a string the simulator would parse); ``default`` if not."""
    if isinstance(value, bool) or value is None:
        return default
    try:
        out = float(value)
    except (TypeError, ValueError):
        return default
    return out if math.isfinite(out) else default


def repair_float_commas(text: str) -> str:
    """``"cte":1,25`` -> ``"cte":1.25`` (Unity's float formatting on comma-decimal locales).

    Only a number right after a ``:`` and followed by digits is touched: a valid object never has
    digits after a comma that follows a value.
    """
    return _COMMA_FLOAT.sub(r"\1.\2", text)


class JsonStream:
    """Incremental reader of concatenated JSON objects from a byte stream.

    ``feed(chunk)`` returns the objects completed by the chunk, in order. Newlines between objects
    are optional; an object may be split across any number of chunks, and one chunk may hold
    several objects. Text outside objects is skipped (and counted in :attr:`junk_bytes`); an
    object that does not parse, even after
    :func:`repair_float_commas`, is counted in :attr:`errors` and skipped.
    """

    def __init__(self, max_message: int = MAX_MESSAGE_BYTES) -> None:
        self.max_message = max_message
        self.errors = 0  # objects that did not parse, and messages over max_message
        self.overflows = 0  # messages over max_message (also counted in errors)
        self.junk_bytes = 0  # characters outside any object, whitespace aside (skipped)
        self._decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
        self._buf = ""
        self._pos = 0  # where scanning goes on
        self._start = -1  # start of the object being read, -1 between objects
        self._depth = 0
        self._in_string = False

    def feed(self, data: bytes) -> list[dict[str, Any]]:
        """Add received bytes; return the objects they complete."""
        self._buf += self._decoder.decode(data)
        out: list[dict[str, Any]] = []
        buf = self._buf
        pos = self._pos
        while True:
            if self._start < 0:
                start = buf.find("{", pos)
                self._count_junk(buf[pos:start] if start >= 0 else buf[pos:])
                if start < 0:
                    buf, pos = "", 0
                    break
                self._start, self._depth, self._in_string, pos = start, 0, False, start
            match = (_IN_STRING if self._in_string else _OUTSIDE).search(buf, pos)
            if match is None:
                pos = max(pos, len(buf))  # past an escape whose character has not arrived yet
                break
            char, pos = match.group(), match.end()
            if self._in_string:
                if char == "\\":
                    pos += 1  # the escaped character (it may arrive with the next chunk)
                else:
                    self._in_string = False
            elif char == '"':
                self._in_string = True
            elif char == "{":
                self._depth += 1
            else:
                self._depth -= 1
                if self._depth == 0:
                    self._emit(buf[self._start:pos], out)
                    self._start = -1
        if self._start > 0:  # keep only the unfinished object
            buf, pos = buf[self._start:], pos - self._start
            self._start = 0
        if self._start == 0 and len(buf) > self.max_message:
            logger.warning("Donkey protocol: dropped a message longer than %d bytes", self.max_message)
            self.errors += 1
            self.overflows += 1
            buf, pos, self._start = "", 0, -1
        self._buf, self._pos = buf, pos
        return out

    def _count_junk(self, text: str) -> None:
        if text:
            self.junk_bytes += len(text) - sum(text.count(c) for c in " \t\r\n")

    def _emit(self, text: str, out: list[dict[str, Any]]) -> None:
        try:
            obj = json.loads(text)
        except RecursionError:  # nested deeper than the interpreter's stack: junk, not a message
            self.errors += 1
            logger.debug("Donkey protocol: skipped a message nested too deeply: %.80s", text)
            return
        except ValueError:  # JSONDecodeError; comma floats of a comma-decimal locale are repaired
            try:
                obj = json.loads(repair_float_commas(text))
            except (ValueError, RecursionError) as exc:
                self.errors += 1
                logger.debug("Donkey protocol: skipped an unreadable message (%s): %.80s", exc, text)
                return
        if isinstance(obj, dict):
            out.append(obj)
