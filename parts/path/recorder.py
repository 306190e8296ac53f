"""The path part: records the pose while the car is driven, saves, loads and clears the path."""

from __future__ import annotations

import logging
import math
import os
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path as FilePath
from typing import Any, ClassVar

import numpy as np

from parts.path.pathfile import Path, PathFileError, load_path, save_path
from vehicle.config import check_settings

logger = logging.getLogger(__name__)

COMMANDS = ("record", "save", "load", "clear", "reset_origin")


class PathRecorder:
    """Part: the current path and its commands.

    ``run(x, y, ok, speed, command)`` with the localiser's ``loc/x, loc/y, loc/ok``, the measured
    speed (``enc/speed``, m/s) and the one-shot ``path/command``:

    - "record" toggles recording: starting clears the path in memory; while recording a point is
      added each time the car has moved ``min_dist`` metres from the last one (with the speed there);
    - "save" writes the path to ``filename`` (CSV), "load" reads it back (in a thread of its own:
      the loop goes on meanwhile, and the path is swapped in by the first loop after it was read),
      "clear" empties it;
    - "reset_origin" is the localiser's (the path stays).

    A failed save or load is logged as one line and changes nothing: the car keeps driving.
    Outputs ``path/xy`` and ``path/speed`` (a new array object whenever the path changes),
    ``path/version`` (increments then) and ``path/recording``.

    Args:
        filename: the path file (PATH_FILENAME).
        min_dist: metres between recorded points (PATH_MIN_DIST).
        load: read ``filename`` at start when it exists (as DonkeyCar's path_follow car does).
    """

    #: the measured speed is ``enc/speed``; a car measuring it elsewhere renames it at ``V.add``
    INPUTS: ClassVar[tuple[str, ...]] = ("loc/x", "loc/y", "loc/ok", "enc/speed", "path/command")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("path/command", "enc/speed")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("path/xy", "path/speed", "path/version", "path/recording")

    def __init__(self, filename: str | os.PathLike[str], min_dist: float = 0.2, *, load: bool = True) -> None:
        check_settings(PATH_MIN_DIST=min_dist)
        self.filename = FilePath(filename)
        self.min_dist = float(min_dist)
        self.path = Path()
        self.version = 0
        self.recording = False
        self._points: list[tuple[float, float, float]] = []
        self._loader: ThreadPoolExecutor | None = None  # started by the first "load" command
        self._loading: Future[Path] | None = None
        if load and self.filename.is_file():
            self.load()

    @classmethod
    def from_config(cls, cfg: Any) -> PathRecorder:
        """PATH_FILENAME (relative to the car folder) and PATH_MIN_DIST."""
        return cls(cfg.path("PATH_FILENAME"), cfg.PATH_MIN_DIST)

    def _set(self, path: Path) -> None:
        self.path = path
        self.version += 1

    def load(self) -> bool:
        """Read the path file now; False (logged) when it is missing or malformed."""
        try:
            path = load_path(self.filename)
        except PathFileError as exc:
            logger.error("path not loaded: %s", exc)
            return False
        self._loaded(path)
        return True

    def _loaded(self, path: Path) -> None:
        self._set(path)
        logger.info("path: loaded %d points (%.1f m) from %s", len(self.path), self.path.length, self.filename)

    def start_load(self) -> None:
        """Read the path file in the part's loader thread; :meth:`run` swaps it in when read."""
        if self._loading is not None:
            logger.info("path: already loading %s", self.filename)
            return
        if self._loader is None:
            self._loader = ThreadPoolExecutor(1, thread_name_prefix="path-load")
        self._loading = self._loader.submit(load_path, self.filename)

    def _take_loaded(self) -> None:
        """Swap in the path the loader read (or log why it could not)."""
        job = self._loading
        if job is None or not job.done():
            return
        self._loading = None
        try:
            path = job.result()
        except PathFileError as exc:
            logger.error("path not loaded: %s", exc)
            return
        except Exception as exc:  # a bug must not stop the car: the path stays as it was
            logger.error("path not loaded from %s: %r", self.filename, exc)
            return
        if self.recording:
            logger.warning("path: %s read, but recording started meanwhile: not loaded", self.filename)
            return
        self._loaded(path)

    def shutdown(self) -> None:
        """Stop the loader thread (a read still running is abandoned)."""
        if self._loader is not None:
            self._loader.shutdown(wait=False, cancel_futures=True)
            self._loader = None

    def save(self) -> bool:
        """Write the path file; False (logged) when there is nothing to save or it cannot be written."""
        if len(self.path) < 2:
            logger.warning("path: nothing to save (%d points): record a path first", len(self.path))
            return False
        try:
            save_path(self.path, self.filename)
        except OSError as exc:
            logger.error("path not saved to %s: %s (check PATH_FILENAME and the folder's permissions)",
                         self.filename, exc.strerror or exc)
            return False
        logger.info("path: saved %d points (%.1f m) to %s", len(self.path), self.path.length, self.filename)
        return True

    def command(self, command: str) -> None:
        """Apply one command (see the class docstring)."""
        if command == "record":
            self.recording = not self.recording
            if self.recording:
                self._points = []
                self._set(Path())
            logger.info("path: recording %s (%d points)", "started" if self.recording else "stopped", len(self.path))
        elif command == "save":
            self.save()
        elif command == "load":
            self.recording = False
            self.start_load()
        elif command == "clear":
            self.recording = False
            self._points = []
            self._set(Path())
            logger.info("path: cleared")
        elif command != "reset_origin":
            logger.warning("path: unknown command %r (expected one of %s)", command, ", ".join(COMMANDS))

    def run(self, x: float | None, y: float | None, ok: bool | None, speed: float | None,
            command: str | None) -> tuple[np.ndarray, np.ndarray, int, bool]:
        """(path/xy, path/speed, path/version, path/recording) after this loop."""
        if command:
            self.command(command)
        self._take_loaded()
        if self.recording and ok and x is not None and y is not None:
            last = self._points[-1] if self._points else None
            if last is None or math.hypot(x - last[0], y - last[1]) >= self.min_dist - 1e-9:
                v = float(speed) if speed is not None and math.isfinite(speed) else 0.0
                self._points.append((float(x), float(y), abs(v)))
                pts = np.array(self._points)
                self._set(Path(pts[:, :2], pts[:, 2]))
        return self.path.xy, self.path.speed, self.version, self.recording
