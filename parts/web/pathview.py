"""The driver page's path view: what the web controller sends of a path-following car.

The keys are the path-follow contract's (``parts/path/keys.py``): the pose ``loc/*``, the path
``path/*``. Two messages carry them to the page:

- every ``state`` message (``WEB_TELEMETRY_HZ``) has ``telemetry.path``: the pose, the target
  point and the follower's state (:func:`path_telemetry`), a few dozen bytes; ``null`` on a car
  without path follow (the page then hides the view);
- the ``path`` event carries the path itself (:func:`encode_path`): sent when ``path/version``
  changes (at most :data:`PATH_SEND_HZ` times a second, the newest version) and to each browser on
  connect, never with every state message: a recorded lap is kilobytes.

Everything here is plain Python over numbers: no socket, no thread (:class:`PathSlot` is the one
lock-protected hand-over from the loop thread to the web thread; :class:`PathSender` decides in the
web thread which browsers get the path, and when).
"""

from __future__ import annotations

import math
import threading
from typing import Any, Final

import numpy as np

#: the path-follow keys the web controller reads (all optional: a car without path follow has none)
PATH_INPUTS: Final = ("loc/x", "loc/y", "loc/angle", "loc/std", "loc/ok", "loc/source", "path/xy",
                      "path/version", "path/target_x", "path/target_y", "path/cte", "path/state")
#: the buttons' commands, the contract's ``path/command`` values
PATH_COMMANDS: Final = ("record", "save", "load", "clear", "reset_origin")
#: most points a ``path`` message carries; a longer path is thinned to every k-th point (the last
#: always kept). 2000 points at PATH_MIN_DIST 0.3 m are 600 m of route, more than a phone's view
#: has pixels for, and about 30 KB of JSON
MAX_PATH_POINTS: Final = 2000
#: coordinates are sent rounded to this many decimals of a metre (2: a centimetre)
PATH_DECIMALS: Final = 2
#: most ``path`` messages per second while a path grows (recording adds a point every few loops):
#: the newest version goes out, the ones in between are skipped
PATH_SEND_HZ: Final = 2.0
#: states the follower reports (``path/state``)
PATH_STATES: Final = ("empty", "recording", "ready", "following", "done", "lost")
LOC_SOURCES: Final = ("odometry", "gps", "fused")


def _num(value: Any, decimals: int) -> float | None:
    """``value`` as a finite float rounded to ``decimals``, or None (absent, bool, NaN, not a number)."""
    if value is None or isinstance(value, bool | np.bool_):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return round(out, decimals) if math.isfinite(out) else None


def path_telemetry(values: dict[str, Any]) -> dict[str, Any] | None:
    """The per-frame part of the path view from one loop's ``values`` (key -> value).

    Returns ``{"state", "version", "x", "y", "angle", "std", "ok", "source", "target", "cte"}``
    (metres rounded to mm, radians to 1e-3; ``target`` is ``[x, y]`` or None; a value the car does
    not produce is None), or None when the car produces none of the path keys.
    """
    if all(values.get(k) is None for k in PATH_INPUTS):
        return None
    x, y = _num(values.get("loc/x"), 3), _num(values.get("loc/y"), 3)
    tx, ty = _num(values.get("path/target_x"), 3), _num(values.get("path/target_y"), 3)
    state, source = values.get("path/state"), values.get("loc/source")
    ok = values.get("loc/ok")
    version = values.get("path/version")
    return {
        "state": state if state in PATH_STATES else None,
        "version": int(version) if isinstance(version, int | np.integer) and not isinstance(version, bool) else None,
        "x": x if y is not None else None, "y": y if x is not None else None,
        "angle": _num(values.get("loc/angle"), 3),
        "std": _num(values.get("loc/std"), 3),
        "ok": bool(ok) if isinstance(ok, bool | np.bool_) else None,
        "source": source if source in LOC_SOURCES else None,
        "target": [tx, ty] if tx is not None and ty is not None else None,
        "cte": _num(values.get("path/cte"), 3),
    }


def encode_path(xy: Any, version: int | None, max_points: int = MAX_PATH_POINTS) -> dict[str, Any]:
    """The ``path`` message for the path ``xy`` ((N, 2) metres).

    Returns ``{"version": int | None, "xy": [x0, y0, x1, y1, ...], "points": N, "step": k}``:
    coordinates rounded to :data:`PATH_DECIMALS` (cm) in one flat list; rows that are not finite
    dropped (JSON has no NaN); more than ``max_points`` points thinned to every ``k``-th one, the
    last point always kept (``points`` is the path's own count, ``step`` the ``k`` used). Anything
    that is not an (N, 2) array of numbers is sent as an empty path.
    """
    try:
        arr = np.asarray(xy, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.empty((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        arr = np.empty((0, 2))
    n = len(arr)
    arr = arr[np.isfinite(arr).all(axis=1)]
    step = max(1, math.ceil(len(arr) / max_points)) if max_points > 0 else 1
    if step > 1:
        last = arr[-1:]
        arr = arr[::step]
        if len(arr) and not np.array_equal(arr[-1], last[0]):
            arr = np.concatenate([arr[: max_points - 1], last])
    flat = np.round(arr, PATH_DECIMALS).ravel()
    return {"version": version, "xy": flat.tolist(), "points": n, "step": step}


class PathSlot:
    """The latest path, handed from the loop thread to the web thread, encoded once per change.

    The loop calls :meth:`put` every loop with ``path/xy`` and ``path/version``; a change is a new
    version (or, from a part that writes no version, a new array object: the contract never mutates
    a path in place). The server calls :meth:`message` to get the encoded path and its change
    counter.
    """

    def __init__(self, max_points: int = MAX_PATH_POINTS) -> None:
        self.max_points = max_points
        self._lock = threading.Lock()
        self._xy: Any = None
        self._version: int | None = None
        self._changes = 0  # how many times the path changed (0: no path reported yet)
        self._encoded: dict[str, Any] | None = None
        self._encoded_at = -1

    @property
    def changes(self) -> int:
        """How many times the path has changed since the start (0: none reported yet)."""
        with self._lock:
            return self._changes

    def put(self, xy: Any, version: Any) -> None:
        """Store this loop's path (loop thread). Cheap when nothing changed: no copy, no encoding."""
        if isinstance(version, bool) or not isinstance(version, int | np.integer):
            version = None
        if xy is None and version is None:
            return
        with self._lock:
            if self._changes and (version == self._version if version is not None else xy is self._xy):
                return
            self._xy, self._version = xy, (int(version) if version is not None else None)
            self._changes += 1

    def message(self) -> tuple[dict[str, Any] | None, int]:
        """The ``path`` message of the latest path (None before any) and its change counter (web
        thread). Encoded at most once per change."""
        with self._lock:
            xy, version, changes = self._xy, self._version, self._changes
            if changes == self._encoded_at:
                return self._encoded, changes
        if changes == 0:
            return None, 0
        encoded = encode_path(xy if xy is not None else np.empty((0, 2)), version, self.max_points)
        with self._lock:
            if changes >= self._encoded_at:
                self._encoded, self._encoded_at = encoded, changes
        return encoded, changes


class PathSender:
    """Which browsers get the ``path`` message, and when (web thread).

    A browser gets the path when it connects (:meth:`for_new`) and then whenever it lacks the
    latest version, at most ``send_hz`` times a second (:meth:`due`: a path that grows while it is
    recorded goes out as its newest version, the ones in between skipped).

    Args:
        slot: the path handed over by the loop.
        send_hz: most path messages per second. Default :data:`PATH_SEND_HZ`.
    """

    def __init__(self, slot: PathSlot, send_hz: float = PATH_SEND_HZ) -> None:
        self.slot = slot
        self.period = 1.0 / send_hz
        self.sent = 0  # path messages handed out (one per browser)
        self._seen: dict[str, int] = {}  # browser -> the slot's change counter it was sent
        self._sent_at = -math.inf

    def for_new(self, sid: str) -> dict[str, Any] | None:
        """The path for a browser that just connected (None: no path yet)."""
        path, changes = self.slot.message()
        if path is not None:
            self._seen[sid] = changes
            self.sent += 1
        return path

    def due(self, sids: Any, now: float) -> tuple[dict[str, Any] | None, list[str]]:
        """The path and the browsers among ``sids`` to send it to now (``now``: seconds, monotonic)."""
        changes = self.slot.changes
        behind = [sid for sid in sids if self._seen.get(sid) != changes]
        if not changes or not behind or now - self._sent_at < self.period:
            return None, []
        path, changes = self.slot.message()
        self._sent_at = now
        for sid in behind:
            self._seen[sid] = changes
        self.sent += len(behind)
        return path, behind

    def forget(self, sid: str) -> None:
        """A browser left."""
        self._seen.pop(sid, None)
