"""A drive loop's view of a recording part: call ``run`` at a fixed rate and time each call.

Imported by bench/tub.py, and by the DonkeyCar script it runs in DonkeyCar's own venv, so both
recorders are driven by the same loop. Needs only numpy and the standard library.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np


def paced(run: Callable[..., Any], frames: np.ndarray, rate_hz: float, seconds: float,
          finish: Callable[[], Any]) -> dict[str, float]:
    """Call ``run(frame, angle, throttle, mode)`` at ``rate_hz`` for ``seconds``, then ``finish()``.

    The slots are absolute deadlines; a call that ends past the next slot makes the loop skip the
    missed slots (no burst to catch up), as ``vehicle.clock.RateKeeper`` does, and counts as an
    overrun. Returns the calls' p50/p99/max in µs, how many calls were made, the overruns, and
    the process's CPU time (all threads, user + system, ``finish()`` included) per second of
    recording, in percent of one core.
    """
    period = 1.0 / rate_hz
    slots = max(1, round(rate_hz * seconds))
    calls: list[float] = []  # seconds per run() call
    overruns = 0
    cpu0 = time.process_time()
    start = time.perf_counter()
    slot = 0
    while slot < slots:
        wait = start + slot * period - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        i = len(calls)
        t0 = time.perf_counter()
        run(frames[i % len(frames)], (i % 200) / 100 - 1, 0.3, "user")
        end = time.perf_counter()
        calls.append(end - t0)
        due = int((end - start) / period) + 1  # the first slot still ahead
        if due > slot + 1:
            overruns += 1
        slot = max(slot + 1, due)
    finish()
    cpu = time.process_time() - cpu0
    us = np.array(calls) * 1e6
    return {"records": len(calls), "overruns": overruns, "p50_us": float(np.percentile(us, 50)),
            "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max()),
            "cpu_pct": 100.0 * cpu / (slots * period)}
