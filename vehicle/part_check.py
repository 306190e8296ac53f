"""``check_part(part)``: does a part keep the part contract? (Gymnasium's ``check_env`` for parts.)

Run it in the tests of a part of your own, on a part built with fakes instead of hardware::

    from vehicle.part_check import check_part

    check_part(MyImu.from_config(cfg, bus_factory=fake_bus))            # declared keys, run, shutdown
    check_part(camera, inputs=(), threaded=True)                         # also the thread's life cycle

It checks, and raises :class:`PartCheckError` listing every problem found:

- declared keys (``INPUTS``, ``OUTPUTS``, ``OPTIONAL_INPUTS``, ``FEEDBACK``): tuples of standard keys
  (:data:`vehicle.keys.STANDARD_KEYS`, docs/keys.md) or namespaced ones (``imu/accel_x``), none
  twice, the optional and feedback ones among the inputs;
- ``run(*inputs)`` (``run_threaded`` for a threaded part) returns what ``OUTPUTS`` declares: one
  value for one key, a tuple of as many values (or None) for several, None for none;
- a threaded part: ``update`` runs in its thread, ``run_threaded`` answers without waiting for the
  work, ``shutdown`` ends the thread, and the thread did not fail;
- an actuator (a part with ``neutral()``): ``neutral()`` works, twice, before shutdown;
- ``shutdown()`` may be called twice (every stop path may call it again).

The part is shut down afterwards: check a part built for the check.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import Any

from vehicle.errors import VehicleError
from vehicle.keys import is_valid_key
from vehicle.part import ThreadedPart, is_actuator, part_name
from vehicle.vehicle import declared_keys

DECLARATIONS = ("INPUTS", "OUTPUTS", "OPTIONAL_INPUTS", "FEEDBACK")


class PartCheckError(VehicleError, AssertionError):
    """A part breaks the part contract; the message lists every problem, separated by ``;``."""


def _declared(part: Any, problems: list[str]) -> dict[str, tuple[str, ...] | None]:
    found: dict[str, tuple[str, ...] | None] = {}
    for attr in DECLARATIONS:
        keys = declared_keys(part, attr)
        if keys is None:
            found[attr] = None
            continue
        if not isinstance(keys, tuple):
            problems.append(f"{attr} must be a tuple of memory keys, not {type(keys).__name__} {keys!r} "
                            "(see vehicle/keys.py: declare keys as a tuple)")
            found[attr] = None
            continue
        bad = [k for k in keys if not (isinstance(k, str) and is_valid_key(k))]
        if bad:
            problems.append(f"{attr} {bad}: neither standard keys (docs/keys.md) nor namespaced "
                            "'family/name' keys (lower case)")
        twice = sorted({k for k in keys if list(keys).count(k) > 1})
        if twice:
            problems.append(f"{attr} lists {twice} more than once")
        found[attr] = tuple(keys)
    inputs = found["INPUTS"] or ()
    for attr in ("OPTIONAL_INPUTS", "FEEDBACK"):
        stray = [k for k in found[attr] or () if k not in inputs]
        if stray:
            problems.append(f"{attr} {stray} are not among its INPUTS {list(inputs)}")
    recorded = declared_keys(part, "RECORDED")
    if recorded is not None:
        if not isinstance(recorded, Mapping) or not all(isinstance(t, str) and t for t in recorded.values()):
            problems.append(f"RECORDED must map output keys to tub types ('float', 'vector' ...), got {recorded!r}")
        else:
            stray = [k for k in recorded if k not in (found["OUTPUTS"] or ())]
            if stray:
                problems.append(f"RECORDED {stray} are not among its OUTPUTS {list(found['OUTPUTS'] or ())}")
    return found


def _check_result(result: Any, outputs: tuple[str, ...] | None, how: str, problems: list[str]) -> None:
    if outputs is None:
        return  # a plain DonkeyCar part: the car wires its outputs
    n = len(outputs)
    if n == 0 and result is not None:
        problems.append(f"{how} returned {type(result).__name__} but OUTPUTS declares no key")
    elif n > 1 and result is not None and not (isinstance(result, list | tuple) and len(result) == n):
        got = f"{len(result)} values" if isinstance(result, list | tuple) else f"a single {type(result).__name__}"
        problems.append(f"{how} returned {got} for the {n} OUTPUTS {list(outputs)}")


def _call(fn: Any, args: Sequence[Any], timeout: float) -> tuple[bool, Any, BaseException | None]:
    """Call ``fn(*args)`` in a helper thread: (finished within ``timeout``, result, exception)."""
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["result"] = fn(*args)
        except BaseException as exc:  # reported as a problem
            box["error"] = exc

    thread = threading.Thread(target=target, name="check_part", daemon=True)
    thread.start()
    thread.join(timeout)
    return not thread.is_alive(), box.get("result"), box.get("error")


def check_part(part: Any, inputs: Sequence[Any] | None = None, *, threaded: bool | None = None,
               timeout: float = 10.0) -> None:
    """Check ``part`` against the part contract (see the module docstring), then shut it down.

    Args:
        part: the part, built with fakes where it needs hardware.
        inputs: values for one call of ``run`` (default: None for each declared input, which a
            part must accept: None means "no value this loop").
        threaded: check it as a threaded part (default: when it is a :class:`ThreadedPart`).
        timeout: seconds a call may take before it counts as hanging.

    Raises:
        PartCheckError: every problem found, in one message.
    """
    problems: list[str] = []
    declared = _declared(part, problems)
    args = tuple(inputs) if inputs is not None else (None,) * len(declared["INPUTS"] or ())
    threaded = isinstance(part, ThreadedPart) if threaded is None else threaded
    thread: threading.Thread | None = None
    if threaded:
        missing = [m for m in ("update", "run_threaded") if not callable(getattr(part, m, None))]
        if missing:
            problems.append(f"a threaded part needs update() and run_threaded(); it has no {', '.join(missing)}()")
        else:
            if isinstance(part, ThreadedPart):
                part.start()
                thread = part._thread
            else:
                thread = threading.Thread(target=part.update, name="check_part update", daemon=True)
                thread.start()
            done, result, error = _call(part.run_threaded, args, min(timeout, 1.0))
            if not done:
                problems.append("run_threaded() blocked: it must return the latest value at once")
            elif error is not None:
                problems.append(f"run_threaded() raised {type(error).__name__}: {error}")
            else:
                _check_result(result, declared["OUTPUTS"], "run_threaded()", problems)
    elif not callable(getattr(part, "run", None)):
        problems.append("a part needs run()")
    else:
        done, result, error = _call(part.run, args, timeout)
        if not done:
            problems.append(f"run() did not return within {timeout:g} s")
        elif error is not None:
            problems.append(f"run() raised {type(error).__name__}: {error}")
        else:
            _check_result(result, declared["OUTPUTS"], "run()", problems)
    if is_actuator(part):
        for attempt in ("neutral()", "neutral() again"):
            done, _, error = _call(part.neutral, (), timeout)
            if not done or error is not None:
                why = "hung" if not done else f"raised {type(error).__name__}: {error}"
                problems.append(f"{attempt} {why}: every stop path calls it")
                break
    shutdown = getattr(part, "shutdown", None)
    if callable(shutdown):
        for attempt in ("shutdown()", "shutdown() a second time"):
            done, _, error = _call(shutdown, (), timeout)
            if not done or error is not None:
                why = "hung" if not done else f"raised {type(error).__name__}: {error}"
                problems.append(f"{attempt} {why}")
                break
    elif thread is not None:
        problems.append("a threaded part needs shutdown() to end its thread")
    if thread is not None:
        thread.join(timeout)
        if thread.is_alive():
            problems.append("its thread still runs after shutdown()")
    error = getattr(part, "error", None) if isinstance(part, ThreadedPart) else None
    if error is not None:
        problems.append(f"its thread failed: {type(error).__name__}: {error}")
    if problems:
        raise PartCheckError(f"part {part_name(part)!r} ({type(part).__name__}): " + "; ".join(problems))
