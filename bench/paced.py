"""A drive loop's view of a recording part: call ``run`` at a fixed rate and time each call.

Imported by bench/tub.py, and by the DonkeyCar script it runs in DonkeyCar's own venv, so both
recorders are driven by the same loop. Needs only numpy and the standard library.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np


def paced(run: Callable[..., Any], frames: np.ndarray, rate_hz: float, seconds: float,
          finish: Callable[[], Any]) -> dict[str, float]:
    """Call ``run(frame, angle, throttle, mode)`` every 1/rate_hz s (absolute deadlines, as our
    Vehicle loop) for ``seconds``, then ``finish()`` (untimed by the loop, but in the CPU figure).

    Returns the calls' p50/p99/max in µs, the records, and the process's CPU time (all threads,
    user + system) per second of recording, in percent of one core.
    """
    period = 1.0 / rate_hz
    n = max(1, round(rate_hz * seconds))
    calls = np.empty(n)
    cpu0 = os.times()
    start = time.perf_counter()
    for i in range(n):
        wait = start + i * period - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        t0 = time.perf_counter()
        run(frames[i % len(frames)], (i % 200) / 100 - 1, 0.3, "user")
        calls[i] = time.perf_counter() - t0
    finish()
    cpu1 = os.times()
    cpu = (cpu1.user - cpu0.user) + (cpu1.system - cpu0.system)
    us = calls * 1e6
    return {"records": n, "p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()), "cpu_pct": 100.0 * cpu / (n * period)}
