"""The Vehicle: runs registered parts in order at a fixed rate over a shared Memory.

Every way of stopping (a part's exception, Ctrl-C, SIGTERM, SIGHUP, ``max_loop_count``,
``stop()``) takes the same safe path: actuators' ``neutral()`` first, then every part's
``shutdown()`` in reverse order, each error logged, then the original exception is re-raised.
"""

from __future__ import annotations

import contextlib
import difflib
import inspect
import logging
import signal
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from time import perf_counter as _perf_counter
from typing import Any

from vehicle.clock import Clock, MonotonicClock, RateKeeper
from vehicle.errors import PartError, VehicleError, VehicleStopped, WiringError, error_text
from vehicle.memory import Memory
from vehicle.part import Lambda, ThreadedPart, is_actuator, part_name
from vehicle.timing import LoopSummary, PartTiming, TimingRing

logger = logging.getLogger(__name__)

#: keys the vehicle itself writes every loop
LOOP_KEYS = ("loop/rate_hz", "loop/overruns", "loop/count")
#: signals that stop a car as Ctrl-C does (a service manager's stop, a dropped ssh session)
STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s)


@dataclass
class _Entry:
    part: Any
    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    threaded: bool
    run_condition: str | None
    optional: frozenset[str] = frozenset()  # inputs no part may produce: they read None
    feedback: frozenset[str] = frozenset()  # inputs read from the previous loop, on purpose
    strict: bool = True  # a lag (read before the producer) is an error, not a warning
    call: Any = None  # bound run or run_threaded
    timing: TimingRing = field(default_factory=TimingRing)
    thread: threading.Thread | None = None


#: add() argument -> the part's class attribute that declares it
DECLARATIONS = {"inputs": "INPUTS", "outputs": "OUTPUTS", "optional_inputs": "OPTIONAL_INPUTS", "feedback": "FEEDBACK"}


def declared_keys(part: Any, attr: str) -> tuple[str, ...] | list[str] | None:
    """The keys ``part`` declares in ``attr`` (a class attribute, a property or an attribute set in
    ``__init__``), or None when it declares none. Looked up statically, so proxies and mocks that
    answer every attribute do not declare anything by accident."""
    instance = vars(part) if hasattr(part, "__dict__") else {}
    if attr in instance:
        return instance[attr]
    try:
        found = inspect.getattr_static(type(part), attr)
    except AttributeError:
        return None
    return getattr(part, attr) if isinstance(found, property) else found


def _check_keys(name: str, label: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise TypeError(f"part {name!r}: {label} must be a list of memory keys, got {type(value).__name__} {value!r}")
    bad = [k for k in value if not isinstance(k, str) or not k]
    if bad:
        raise TypeError(f"part {name!r}: {label} must be non-empty strings, got {bad!r}")
    return tuple(value)


class ShutdownError(RuntimeError):
    """One or more parts failed to shut down (each failure was logged)."""


class Vehicle:
    """A fixed-rate loop over parts that share a named memory.

    Args:
        mem: the memory to share (a new one by default); keys set in it before ``start`` count as
            seeded inputs.
        clock: the time source; ``SimulatedClock()`` runs the loop as fast as the CPU allows.
    """

    def __init__(self, mem: Memory | None = None, clock: Clock | None = None) -> None:
        self.mem = mem if mem is not None else Memory()
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.parts: list[_Entry] = []
        self.on = False
        self.summary: LoopSummary | None = None
        self._stop_requested = threading.Event()
        self._shut_down = False
        self._last_loop_start = 0.0
        self._longest_loop = 0.0  # seconds: the longest single loop of this start()

    # -- building ---------------------------------------------------------------------------------
    def add(self, part: Any, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None,
            threaded: bool = False, run_condition: str | None = None,
            optional_inputs: Sequence[str] | None = None, feedback: Sequence[str] | None = None) -> None:
        """Register a part; parts run in the order added.

        Args:
            part: an object with ``run(*inputs)`` (and ``update()`` + ``run_threaded()`` if threaded),
                or a plain function, which is wrapped in :class:`vehicle.part.Lambda`.
            inputs: memory keys passed to the part, in order. Default: the part's declared
                ``INPUTS`` (see :mod:`vehicle.part`), else none.
            outputs: memory keys that receive the part's return value(s). Default: the part's
                ``OUTPUTS``, else none.
            threaded: run ``part.update()`` in its own thread; the loop calls ``run_threaded()``.
            run_condition: a memory key; the part runs only in loops where that value is truthy.
            optional_inputs: inputs that may be produced by no part of this vehicle (they read
                None). Default: the part's ``OPTIONAL_INPUTS``.
            feedback: inputs the part reads from the previous loop on purpose, because a part
                added later produces them (they read None in the first loop unless seeded).
                Default: the part's ``FEEDBACK``.

        Raises:
            TypeError: an argument has the wrong type or the part lacks a required method.
            ValueError: an output key is listed twice, or an optional/feedback key is not an input.
        """
        if not threaded and not hasattr(part, "run") and callable(part):
            part = Lambda(part)
        name = self._unique_name(part_name(part))
        given = {"inputs": inputs, "outputs": outputs, "optional_inputs": optional_inputs, "feedback": feedback}
        declaration = {label: declared_keys(part, attr) for label, attr in DECLARATIONS.items()}
        keys: dict[str, tuple[str, ...]] = {}
        for label, value in given.items():
            if value is None:
                value = declaration[label] if declaration[label] is not None else ()
            keys[label] = _check_keys(name, label, value)
        if not isinstance(threaded, bool):
            raise TypeError(f"part {name!r}: threaded must be True or False, got {threaded!r}")
        if run_condition is not None and (not isinstance(run_condition, str) or not run_condition):
            raise TypeError(f"part {name!r}: run_condition must be a memory key (str) or None, "
                            f"got {run_condition!r}")
        dupes = sorted({k for k in keys["outputs"] if keys["outputs"].count(k) > 1})
        if dupes:
            raise ValueError(f"part {name!r}: output keys listed more than once: {dupes}")
        own_inputs = _check_keys(name, "INPUTS", declaration["inputs"] or ())
        readable = set(keys["inputs"]) | ({run_condition} if run_condition else set())
        for label in ("optional_inputs", "feedback"):
            if given[label] is None and declaration[label]:
                # the class declares these among its own INPUTS; follow a renaming of the inputs
                typo = [k for k in declaration[label] if k not in own_inputs]
                if typo:
                    raise ValueError(f"part {name!r}: its {DECLARATIONS[label]} {typo} are not among its "
                                     f"INPUTS {list(own_inputs)}")
                if given["inputs"] is not None:
                    renamed = dict(zip(own_inputs, keys["inputs"], strict=False)) \
                        if len(own_inputs) == len(keys["inputs"]) else {}
                    keys[label] = tuple(renamed.get(k, k) for k in keys[label])
                    keys[label] = tuple(k for k in keys[label] if k in readable)
            stray = [k for k in keys[label] if k not in readable]
            if stray:
                raise ValueError(f"part {name!r}: {label} {stray} are not among its inputs {list(keys['inputs'])}")
        # a plain DonkeyCar part wired by hand declares nothing: wiring order is only advised for it
        strict = any(v is not None for v in declaration.values()) or optional_inputs is not None \
            or feedback is not None
        needed = ("update", "run_threaded") if threaded else ("run",)
        missing = [m for m in needed if not callable(getattr(part, m, None))]
        if missing:
            how = "threaded=True needs update() and run_threaded()" if threaded else "a part needs run()"
            raise TypeError(f"part {name!r} ({type(part).__name__}) has no {', '.join(missing)}(): {how}")
        entry = _Entry(part, name, keys["inputs"], keys["outputs"], threaded, run_condition,
                       frozenset(keys["optional_inputs"]), frozenset(keys["feedback"]), strict)
        entry.call = part.run_threaded if threaded else part.run
        self.parts.append(entry)

    def find(self, cls: type) -> list[Any]:
        """The parts added so far that are instances of ``cls``, in run order."""
        return [e.part for e in self.parts if isinstance(e.part, cls)]

    def recorded(self) -> dict[str, str]:
        """What the parts added so far ask every drive to record: output key -> tub type, in run
        order, from each part's ``RECORDED`` declaration (followed through a renaming of its
        outputs)."""
        found: dict[str, str] = {}
        for e in self.parts:
            declared = declared_keys(e.part, "RECORDED") or {}
            own = declared_keys(e.part, "OUTPUTS") or ()
            renamed = dict(zip(own, e.outputs, strict=False)) if len(own) == len(e.outputs) else {}
            for key, tub_type in dict(declared).items():
                key = renamed.get(key, key)
                if key in e.outputs:
                    found.setdefault(key, tub_type)
        return found

    def produces(self, key: str) -> bool:
        """Whether a part added so far writes ``key`` (the vehicle's own ``loop/*`` keys included)."""
        return key in LOOP_KEYS or any(key in e.outputs for e in self.parts)

    def _unique_name(self, base: str) -> str:
        taken = {e.name for e in self.parts}
        if base not in taken:
            return base
        n = 2
        while f"{base}#{n}" in taken:
            n += 1
        return f"{base}#{n}"

    def check_wiring(self) -> None:
        """Raise WiringError if a part reads a key that is not there when it runs.

        A part may read a key seeded in memory before ``start``, a ``loop/*`` key, an output of a
        part added before it, or its own output of the previous loop. Reading the output of a part
        added *after* it is a one-loop lag: allowed only when declared as ``feedback`` (for a plain
        DonkeyCar part that declares nothing it is logged as a warning instead, as DonkeyCar allows
        it). A key that no part produces must be declared in ``optional_inputs`` (it reads None).
        """
        seeded = set(self.mem.keys()) | set(LOOP_KEYS)
        producers: dict[str, list[str]] = {}
        for e in self.parts:
            for key in e.outputs:
                producers.setdefault(key, []).append(e.name)
        everything = sorted(seeded | set(producers))
        available = set(seeded)
        problems = []
        for e in self.parts:
            wanted = dict.fromkeys([*e.inputs, *([e.run_condition] if e.run_condition else [])])
            for key in wanted:
                if key in available or key in e.outputs or key in e.feedback:
                    continue  # produced earlier, the part's own last output, or a declared lag
                role = "input" if key in e.inputs else "run_condition"
                if key in producers:
                    later = producers[key][0]
                    message = (f"part {e.name!r} {role} {key!r} is read before part {later!r} produces it "
                               f"(a one-loop lag): add {e.name!r} after {later!r}, or declare "
                               f"feedback=[{key!r}] if the lag is intended")
                    if e.strict:
                        problems.append(message)
                    else:
                        logger.warning("%s", message)
                elif key not in e.optional:
                    close = difflib.get_close_matches(key, everything, n=1)
                    hint = f" (did you mean {close[0]!r}?)" if close else ""
                    problems.append(f"part {e.name!r} {role} {key!r} is produced by no part and not seeded "
                                    f"in memory{hint}; declare it in optional_inputs if it may be absent")
            available.update(e.outputs)
        from vehicle.shapes import shape_problems  # here: vehicle.shapes reads declarations as add() does

        problems += shape_problems(self.parts)
        if problems:
            raise WiringError("; ".join(problems))

    def describe(self) -> str:
        """The part graph as text, one line per part in run order."""
        lines = []
        for i, e in enumerate(self.parts):
            extra = (" [threaded]" if e.threaded else "") + (
                f" [if {e.run_condition}]" if e.run_condition else "")
            lines.append(f"{i:2d} {e.name}{extra}: {list(e.inputs)} -> {list(e.outputs)}")
        return "\n".join(lines)

    # -- running ----------------------------------------------------------------------------------
    def start(self, rate_hz: float = 10, max_loop_count: int | None = None,
              verbose: bool = False, log_summary: bool = True) -> tuple[int, float]:
        """Run the loop until stopped or ``max_loop_count`` loops; returns (loops, seconds).

        ``verbose`` logs the timing summary every 200 loops; ``log_summary`` logs it once at the
        end (off for loops run many times in a row, e.g. evaluation episodes; :attr:`summary`
        holds it either way).

        Raises:
            WiringError: before anything starts, if the wiring is wrong.
            PartError: a part raised (after the safe stop); the original is its ``__cause__``.
            VehicleStopped: SIGTERM or SIGHUP arrived (after the safe stop).
            KeyboardInterrupt: Ctrl-C (after the safe stop).
        """
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        if max_loop_count is not None and max_loop_count < 1:
            raise ValueError(f"max_loop_count must be >= 1 or None, got {max_loop_count}")
        self.check_wiring()
        signals = contextlib.ExitStack()  # SIGINT/SIGTERM/SIGHUP raise until the safe stop is done
        signals.enter_context(stop_signals_raise())
        loops, t0 = 0, self.clock.now()
        self._last_loop_start = t0
        self._longest_loop = 0.0
        rk = RateKeeper(rate_hz, self.clock)
        failure: BaseException | None = None
        self.on = True
        try:
            self._start_threads()
            rate_window_start, rate_window_loops = t0, 0
            while not self._stop_requested.is_set():
                self._last_loop_start = self.clock.now()
                self._run_once()
                self._longest_loop = max(self._longest_loop, self.clock.now() - self._last_loop_start)
                loops += 1
                rate_window_loops += 1
                now = self.clock.now()
                if now - rate_window_start >= 1.0:  # achieved rate over ~1 s windows
                    self.mem.d["loop/rate_hz"] = rate_window_loops / (now - rate_window_start)
                    rate_window_start, rate_window_loops = now, 0
                self.mem.d["loop/count"] = loops
                self.mem.d["loop/overruns"] = rk.overruns
                if max_loop_count is not None and loops >= max_loop_count:
                    break
                rk.wait()
                if verbose and loops % 200 == 0:
                    logger.info("\n%s", self._summarize(loops, t0, rate_hz, rk.overruns).format())
        except BaseException as exc:
            failure = exc
            raise
        finally:
            self.on = False
            elapsed = self.clock.now() - t0
            self.summary = self._summarize(loops, t0, rate_hz, rk.overruns)
            try:
                self._safe_stop(failure)
            finally:
                signals.close()
            if log_summary:
                logger.info("vehicle stopped\n%s", self.summary.format())
        return loops, elapsed

    def _run_once(self) -> None:
        d = self.mem.d
        perf = _perf_counter
        for e in self.parts:
            if e.run_condition is not None and not d.get(e.run_condition):
                continue
            t = perf()
            try:
                result = e.call(*[d.get(k) for k in e.inputs])
            except (KeyboardInterrupt, VehicleStopped):
                raise
            except Exception as exc:
                raise PartError(e.name, "run_threaded" if e.threaded else "run", exc) from exc
            e.timing.add(perf() - t)
            if e.threaded:
                error = getattr(e.part, "error", None) if isinstance(e.part, ThreadedPart) else None
                if error is not None:
                    raise PartError(e.name, "update", error) from error
            outputs = e.outputs
            if len(outputs) == 1:
                d[outputs[0]] = result
            elif outputs:
                self._store_many(e, result)

    def _store_many(self, e: _Entry, result: Any) -> None:
        d = self.mem.d
        n = len(e.outputs)
        if result is None:
            for k in e.outputs:
                d[k] = None
        elif isinstance(result, list | tuple) and len(result) == n:
            for k, v in zip(e.outputs, result, strict=True):
                d[k] = v
        else:
            got = f"{len(result)} values" if isinstance(result, list | tuple) else f"a single {type(result).__name__}"
            raise PartError(e.name, "run", ValueError(f"returned {got} for {n} outputs {list(e.outputs)}"))

    def stop(self) -> None:
        """Ask the loop to stop after the current iteration; shuts down at once if not running."""
        self._stop_requested.set()
        if not self.on and not self._shut_down:
            self._safe_stop(None)

    def _start_threads(self) -> None:
        for e in self.parts:
            if not e.threaded:
                continue
            if isinstance(e.part, ThreadedPart):
                e.part.start()
            else:
                e.thread = threading.Thread(target=e.part.update, name=e.name, daemon=True)
                e.thread.start()

    def _safe_stop(self, failure: BaseException | None) -> None:
        """Neutral to actuators, then shutdown() in reverse order; no error is swallowed."""
        if self._shut_down:
            return
        self._shut_down = True
        with _ignoring_interrupts():
            self._neutral_and_shutdown(failure)

    def _neutral_and_shutdown(self, failure: BaseException | None) -> None:
        errors: list[str] = []
        for e in self.parts:
            if is_actuator(e.part):
                try:
                    e.part.neutral()
                except Exception as exc:
                    _log_stop_failure(e.name, "go neutral", exc)
                    errors.append(f"{e.name}.neutral()")
        for e in reversed(self.parts):
            shutdown = getattr(e.part, "shutdown", None)
            if callable(shutdown):
                try:
                    shutdown()
                except Exception as exc:
                    _log_stop_failure(e.name, "shut down", exc)
                    errors.append(f"{e.name}.shutdown()")
        for e in self.parts:
            if e.thread is not None:
                e.thread.join(timeout=2.0)
                if e.thread.is_alive():
                    logger.warning("part %r: update() thread still running after shutdown()", e.name)
        if errors:
            message = "failed while stopping: " + ", ".join(errors) + " (see log)"
            if failure is not None:
                failure.add_note(message)
            else:
                raise ShutdownError(message)

    def _summarize(self, loops: int, t0: float, rate_hz: float, overruns: int) -> LoopSummary:
        elapsed = self.clock.now() - t0
        parts = tuple(PartTiming(e.name, e.timing.count, e.timing.percentile(50) * 1e3,
                                 e.timing.percentile(99) * 1e3, e.timing.max * 1e3) for e in self.parts)
        # rate between loop starts, so a run that ends right after its last loop is not flattered
        span = self._last_loop_start - t0
        achieved = (loops - 1) / span if loops > 1 and span > 0 else 0.0
        return LoopSummary(loops, elapsed, rate_hz, achieved, overruns, parts, self._longest_loop)


def _log_stop_failure(name: str, doing: str, exc: BaseException) -> None:
    """One ERROR line naming the part and the error (a pulled serial cable gave two chained
    tracebacks, ~20 lines, at every stop); the traceback only at DEBUG, as vehicle.part does."""
    if isinstance(exc, VehicleError):  # its message is written for the user
        text = error_text(exc)
    else:
        kind = type(exc).__name__ if type(exc).__module__ == "builtins" else \
            f"{type(exc).__module__}.{type(exc).__name__}"  # termios.error, not a bare "error"
        text = f"{kind}: {error_text(exc)}"
    logger.error("part %r failed to %s: %s", name, doing, text)
    logger.debug("part %r: traceback of the failure to %s", name, doing, exc_info=exc)


@contextlib.contextmanager
def handling(signals: Sequence[int], handler: Any) -> Iterator[None]:
    """While inside, ``handler`` handles ``signals``; the previous handlers come back on leaving.
    Only the main thread can set handlers: elsewhere this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _ignoring_interrupts() -> contextlib.AbstractContextManager[None]:
    """A second Ctrl-C or SIGTERM while stopping is logged, not allowed to cut the safe path short."""
    def note(signum: int, _frame: Any) -> None:
        logger.warning("%s ignored: the vehicle is already stopping", signal.Signals(signum).name)
    return handling((signal.SIGINT, *STOP_SIGNALS), note)


@contextlib.contextmanager
def stop_signals_raise() -> Iterator[None]:
    """While inside, SIGTERM and SIGHUP raise :class:`VehicleStopped` and SIGINT raises
    KeyboardInterrupt (main thread only), as in the loop: for work outside a Vehicle that must clean
    up when a service manager stops it. SIGINT is installed explicitly because a process started
    with ``&`` from a script inherits it as ignored, and ``kill -INT`` must still stop the car."""
    with handling((signal.SIGINT,), signal.default_int_handler), handling(STOP_SIGNALS, _raise_stopped):
        yield


def _raise_stopped(signum: int, _frame: Any) -> None:
    # Further stop signals while the safe path runs must not interrupt it.
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    raise VehicleStopped(signum, signal.Signals(signum).name)


