"""The part contract and the ThreadedPart base class.

A part is any object with ``run(*inputs)`` returning one value, a tuple (one item per output key)
or None. Optional: ``shutdown()``; ``update()`` + ``run_threaded(*inputs)`` for parts added with
``threaded=True``; ``neutral()`` for actuators (called first on every stop path). This is
DonkeyCar's contract, so existing Donkey parts run unmodified.

A part class may also declare the memory keys it reads and writes, as class attributes
``ClassVar[tuple[str, ...]]`` (or read-only properties returning a tuple, where the keys depend on
how the part was built; see :mod:`vehicle.keys`) that :meth:`vehicle.Vehicle.add` uses when it is
not given them:

- ``INPUTS`` / ``OUTPUTS``: tuples of keys, in the order of ``run``'s arguments / return values;
- ``OPTIONAL_INPUTS``: inputs that may be produced by no part of a car (they read None);
- ``FEEDBACK``: inputs produced by a part added after this one, read from the previous loop on
  purpose.
- ``OUTPUT_SHAPES`` / ``INPUT_SHAPES``: ``{key: shape}`` of what it makes and of what it expects
  (:mod:`vehicle.shapes`), compared by the wiring check before the first loop.
- ``RECORDED``: ``{output key: tub type}`` of the outputs every drive records while the part is in
  the car (a sensor's readings: ``{"imu/acl_x": "float", ...}``); the tub writer asks
  :meth:`vehicle.Vehicle.recorded`, so a new kind of part is recorded without a list to edit.

Key names follow :mod:`vehicle.keys`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Coroutine
from typing import TYPE_CHECKING, Any, Final

from vehicle.errors import VehicleError

if TYPE_CHECKING:
    import asyncio

logger = logging.getLogger(__name__)


def part_name(part: Any) -> str:
    """The name used for a part in messages: its ``name`` attribute, else its class name."""
    name = getattr(part, "name", None)
    return name if isinstance(name, str) and name else type(part).__name__


def is_actuator(part: Any) -> bool:
    """Whether the part drives something physical and so has a ``neutral()`` command."""
    return callable(getattr(part, "neutral", None))


class Lambda:
    """Wrap a plain function as a part (``Vehicle.add`` does this for any callable without run())."""

    def __init__(self, fn: Any, name: str | None = None) -> None:
        self.fn = fn
        fn_name = getattr(fn, "__name__", type(fn).__name__)
        self.name = name or ("lambda" if fn_name == "<lambda>" else fn_name)

    def run(self, *inputs: Any) -> Any:
        """Call the function with the inputs."""
        return self.fn(*inputs)


class _Nothing:
    def __repr__(self) -> str:
        return "ThreadedPart.NOTHING"


class ThreadedPart:
    """Base for a part whose work runs in its own thread (camera, gamepad, web server ...).

    Subclasses implement :meth:`poll`, which blocks until it has the next value (a frame, an event)
    and returns it, or returns ``ThreadedPart.NOTHING``. The loop thread only calls
    :meth:`run_threaded`, which stores the loop's inputs and returns the latest value without
    blocking. Optional hooks: :meth:`open` (in the thread, before the first poll: acquire devices
    here so that errors name the device) and :meth:`close` (once, on shutdown).

    Set ``period`` (seconds) to rest between polls; the rest waits on the stop event, so shutdown
    never waits for a full period and the thread never spins.
    """

    NOTHING: Final = _Nothing()
    #: seconds to rest between polls (None = poll again at once; poll() must then block)
    period: float | None = None
    #: seconds shutdown() waits for the thread to end
    join_timeout: float = 2.0

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._fresh = threading.Condition(self._lock)
        self.stop_event = threading.Event()
        self._latest: Any = None
        self._latest_at: float | None = None  # time.monotonic() of the latest value
        self._version = 0
        self._inputs: tuple[Any, ...] = ()
        self._thread: threading.Thread | None = None
        self._opened = False
        self._closed = False
        self.error: BaseException | None = None  # what ended the thread, if it failed

    # -- to implement -------------------------------------------------------------------------
    def poll(self) -> Any:
        """Produce the next value (block until there is one) or return ``NOTHING``."""
        raise NotImplementedError(f"{type(self).__name__} must implement poll()")

    def open(self) -> None:  # noqa: B027 - optional hook
        """Acquire resources; called once before the first poll."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release resources; called once on shutdown."""

    # -- DonkeyCar contract ---------------------------------------------------------------------
    def update(self) -> None:
        """Thread body: open, then poll until stopped, publishing each value."""
        try:
            self._ensure_open()
            while not self.stop_event.is_set():
                value = self.poll()
                if value is not self.NOTHING:
                    self.publish(value)
                if self.period is not None and self.stop_event.wait(self.period):
                    break
        except BaseException as exc:  # the parts reading ``error`` report it to the loop
            self.error = exc
            if isinstance(exc, VehicleError):  # its message says the fix: one line, the traceback for -vv
                logger.error("%s: background thread failed: %s", type(self).__name__, exc)
                logger.debug("%s: traceback", type(self).__name__, exc_info=exc)
            else:
                logger.exception("%s: background thread failed", type(self).__name__)

    def run_threaded(self, *inputs: Any) -> Any:
        """Store the loop's inputs and return the latest value (never blocks on the work)."""
        with self._lock:
            self._inputs = inputs
            return self._latest

    def run(self, *inputs: Any) -> Any:
        """Non-threaded use: store the inputs and do one poll inline."""
        self._ensure_open()
        with self._lock:
            self._inputs = inputs
        value = self.poll()
        if value is not self.NOTHING:
            self.publish(value)
        return self.latest()

    def shutdown(self) -> None:
        """Stop the thread, join it, then close. Safe to call more than once."""
        self.stop_event.set()
        with self._fresh:
            self._fresh.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(self.join_timeout)
            if thread.is_alive():
                logger.warning("%s: thread did not stop within %.1f s", type(self).__name__,
                               self.join_timeout)
        if not self._closed:
            self._closed = True
            self.close()

    # -- helpers for subclasses and users ---------------------------------------------------------
    def start(self) -> ThreadedPart:
        """Start the part's thread (the Vehicle does this for parts added with threaded=True)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self.update, name=type(self).__name__, daemon=True)
            self._thread.start()
        return self

    @property
    def inputs(self) -> tuple[Any, ...]:
        """The inputs of the latest loop (empty before the first)."""
        with self._lock:
            return self._inputs

    @property
    def running(self) -> bool:
        """Whether the part's thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def publish(self, value: Any) -> None:
        """Make ``value`` the latest value and wake anyone waiting for a fresh one."""
        with self._fresh:
            self._latest = value
            self._latest_at = time.monotonic()
            self._version += 1
            self._fresh.notify_all()

    def latest(self, max_age: float | None = None) -> Any:
        """The latest value, or None if there is none or it is older than ``max_age`` seconds."""
        with self._lock:
            if max_age is not None and (self._latest_at is None
                                        or time.monotonic() - self._latest_at > max_age):
                return None
            return self._latest

    def age(self) -> float | None:
        """Seconds since the latest value was published (None if never)."""
        with self._lock:
            return None if self._latest_at is None else time.monotonic() - self._latest_at

    def _ensure_open(self) -> None:
        if not self._opened:
            self._opened = True
            self.open()


def run_event_loop(loop: asyncio.AbstractEventLoop, main: Coroutine[Any, Any, Any]) -> None:
    """Run ``main`` on ``loop`` (a part's own event loop, in its thread), then cancel what is left
    of its tasks and close the loop, so no task is destroyed while pending."""
    import asyncio

    try:
        loop.run_until_complete(main)
    finally:
        pending = asyncio.all_tasks(loop)
        for task in pending:
            task.cancel()
        loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
        loop.run_until_complete(loop.shutdown_asyncgens())
        loop.close()
