"""Reader for Linux joystick devices (``/dev/input/jsN``), also fed by FIFOs and pipes in tests.

The file is opened unbuffered and read with ``select`` so a read never blocks past its timeout.
Capabilities come from the JSIOC* ioctls; a carrier that does not answer them (a FIFO, a pipe, a
pty: ENOTTY) uses the fallback :class:`~parts.controllers.events.Caps` of the layout. End of file,
ENODEV (unplugged) and POLLHUP raise :class:`~parts.controllers.events.DeviceLost`.
"""

from __future__ import annotations

import array
import errno
import logging
import os
import select
import stat
import time

from parts.controllers.events import (
    ABS_CNT,
    JS_EVENT_SIZE,
    JSIOCGAXES,
    JSIOCGAXMAP,
    JSIOCGBTNMAP,
    JSIOCGBUTTONS,
    JSIOCGNAME,
    KEY_MAP_LEN,
    NAME_LEN,
    Caps,
    DeviceLost,
    PadEvent,
    parse_events,
)

logger = logging.getLogger(__name__)


def query_caps(fd: int, fallback: Caps) -> Caps:
    """Ask the device for its name and axis/button code maps; use ``fallback`` where it cannot answer.

    A FIFO, pipe or pty answers every JSIOC* with ENOTTY: then the fallback is returned whole.
    """
    try:
        import fcntl
    except ImportError:  # not Linux/Unix
        return fallback
    try:
        name_buf = array.array("B", [0] * NAME_LEN)
        fcntl.ioctl(fd, JSIOCGNAME, name_buf)
        name = name_buf.tobytes().split(b"\0", 1)[0].decode("utf-8", "replace")
        count = array.array("B", [0])
        fcntl.ioctl(fd, JSIOCGAXES, count)
        n_axes = count[0]
        fcntl.ioctl(fd, JSIOCGBUTTONS, count)
        n_buttons = count[0]
        axmap = array.array("B", [0] * ABS_CNT)
        fcntl.ioctl(fd, JSIOCGAXMAP, axmap)
        btnmap = array.array("H", [0] * KEY_MAP_LEN)
        fcntl.ioctl(fd, JSIOCGBTNMAP, btnmap)
    except OSError as exc:
        if exc.errno in (errno.ENOTTY, errno.EINVAL, errno.ENOSYS):
            logger.info("device does not answer joystick ioctls (%s): using the layout's codes for %s",
                        os.strerror(exc.errno), fallback.name)
            return fallback
        if exc.errno == errno.ENODEV:
            raise DeviceLost(errno.ENODEV, "joystick unplugged while querying it") from exc
        raise
    return Caps(name or fallback.name, tuple(axmap[:n_axes]), tuple(btnmap[:n_buttons]))


class LinuxJoystick:
    """A joydev device (or any file/FIFO/pipe carrying js_event records).

    Args:
        path: device or FIFO path, e.g. ``/dev/input/js0``.
        fallback_caps: the codes to assume when the device cannot be queried (from the layout).
        fd: an already open file descriptor to read instead of ``path`` (a pipe in tests); it is
            closed on :meth:`close`.
    """

    kind = "linux"

    def __init__(self, path: str | None = None, fallback_caps: Caps | None = None,
                 fd: int | None = None) -> None:
        if path is None and fd is None:
            raise ValueError("LinuxJoystick needs a device path (e.g. /dev/input/js0) or an open fd")
        self.path = path if path is not None else f"fd {fd}"
        self._given_fd = fd
        self._fd: int | None = None
        self._tail = b""
        self.fallback_caps = fallback_caps or Caps("unknown gamepad")
        self.caps = self.fallback_caps
        self._replay: list[PadEvent] | None = None  # events of a recording file, in order
        self._replay_t0 = 0.0  # time.monotonic() when the recording started
        self._replay_first_ms = 0  # recorded time of its first event

    @property
    def reconnectable(self) -> bool:
        """Whether opening again after a loss can help (not for pipes and recording files)."""
        return self._given_fd is None and self._replay is None and not self.path.startswith("fd ")

    def open(self) -> Caps:
        """Open the device and query it. Raises FileNotFoundError / PermissionError with a hint."""
        if self._given_fd is not None:
            self._fd, self._given_fd = self._given_fd, None
        else:
            try:
                # O_NONBLOCK so opening a FIFO does not wait for its writer; reads use select anyway
                self._fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK)
            except FileNotFoundError as exc:
                raise FileNotFoundError(
                    exc.errno, f"no joystick at {self.path}: is the pad paired/plugged in? "
                    "List devices with `ls /dev/input/js*` or set JOYSTICK_DEVICE_FILE", self.path) from exc
            except PermissionError as exc:
                raise PermissionError(
                    exc.errno, f"no permission to read {self.path}: add the user to the 'input' group "
                    "and log in again", self.path) from exc
        if self._fd is None:
            raise DeviceLost(errno.EBADF, f"{self.path} was closed and cannot be reopened from an fd")
        self._tail = b""
        if stat.S_ISREG(os.fstat(self._fd).st_mode):
            return self._open_recording()
        self.caps = query_caps(self._fd, self.fallback_caps)
        logger.info("joystick %s: %s, %d axes, %d buttons", self.path, self.caps.name,
                    len(self.caps.axis_codes), len(self.caps.button_codes))
        return self.caps

    def _open_recording(self) -> Caps:
        assert self._fd is not None
        with os.fdopen(os.dup(self._fd), "rb") as f:
            data = f.read()
        self.caps = self.fallback_caps
        self._replay, tail = parse_events(data, self.caps)
        if tail:
            logger.warning("%s: %d trailing bytes are not a whole event; ignored", self.path, len(tail))
        self._replay_t0 = time.monotonic()
        self._replay_first_ms = self._replay[0].time_ms if self._replay else 0
        logger.info("replaying %d recorded gamepad events from %s", len(self._replay), self.path)
        return self.caps

    def _read_recording(self, timeout: float) -> list[PadEvent]:
        assert self._replay is not None
        if not self._replay:
            raise DeviceLost(errno.ENODEV, f"end of the recorded gamepad events in {self.path}")
        elapsed_ms = (time.monotonic() - self._replay_t0) * 1000.0
        due_ms = self._replay[0].time_ms - self._replay_first_ms
        if due_ms > elapsed_ms:
            time.sleep(min(timeout, (due_ms - elapsed_ms) / 1000.0))
            elapsed_ms = (time.monotonic() - self._replay_t0) * 1000.0
        n = 0
        while n < len(self._replay) and self._replay[n].time_ms - self._replay_first_ms <= elapsed_ms:
            n += 1
        out, self._replay = self._replay[:n], self._replay[n:]
        return out

    @property
    def fileno(self) -> int | None:
        """The open file descriptor (None when closed)."""
        return self._fd

    def read(self, timeout: float) -> list[PadEvent]:
        """Events available within ``timeout`` seconds ([] if none). Raises DeviceLost."""
        if self._fd is None:
            raise DeviceLost(errno.EBADF, f"joystick {self.path} is not open")
        if self._replay is not None:
            return self._read_recording(timeout)
        try:
            ready, _, _ = select.select([self._fd], [], [], timeout)
        except (OSError, ValueError) as exc:
            raise DeviceLost(errno.EBADF, f"joystick {self.path}: {exc}") from exc
        if not ready:
            return []
        try:
            data = os.read(self._fd, JS_EVENT_SIZE * 64)  # joydev queues at most 64 events
        except BlockingIOError:
            return []
        except OSError as exc:
            if exc.errno in (errno.ENODEV, errno.EIO, errno.EBADF):
                raise DeviceLost(exc.errno, f"joystick {self.path} lost: {exc.strerror}") from exc
            raise
        if not data:
            raise DeviceLost(errno.ENODEV, f"joystick {self.path} lost: end of stream")
        events, self._tail = parse_events(self._tail + data, self.caps)
        return events

    def close(self) -> None:
        """Close the device (safe to call more than once)."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                os.close(fd)
            except OSError:
                logger.debug("closing %s failed", self.path, exc_info=True)
