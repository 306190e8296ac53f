"""A drive loop's view of a recording part: call ``run`` at a fixed rate and time each call.

Imported by bench/tub.py, and by the DonkeyCar script it runs in DonkeyCar's own venv (with the
project root on its path), so both recorders are driven by the same loop: our ``RateKeeper``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from vehicle.clock import MonotonicClock, RateKeeper


def paced(run: Callable[..., Any], frames: np.ndarray, rate_hz: float, seconds: float,
          finish: Callable[[], Any]) -> dict[str, float]:
    """Call ``run(frame, angle, throttle, mode)`` at ``rate_hz`` for ``seconds``, then ``finish()``.

    The slots are ``RateKeeper``'s, as in our Vehicle loop: absolute deadlines, missed slots
    skipped and counted as overruns. Returns the calls' p50/p99/max in µs, how many calls were
    made, the overruns, and the process's CPU time (all threads, user + system, ``finish()``
    included) per second of recording, in percent of one core.
    """
    slots = max(1, round(rate_hz * seconds))
    keeper = RateKeeper(rate_hz, MonotonicClock())
    calls: list[float] = []  # seconds per run() call
    cpu0 = time.process_time()
    while keeper.slot < slots:
        i = len(calls)
        t0 = time.perf_counter()
        run(frames[i % len(frames)], (i % 200) / 100 - 1, 0.3, "user")
        calls.append(time.perf_counter() - t0)
        keeper.wait()
    finish()
    cpu = time.process_time() - cpu0
    us = np.array(calls) * 1e6
    return {"records": len(calls), "overruns": keeper.overruns, "p50_us": float(np.percentile(us, 50)),
            "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max()),
            "cpu_pct": 100.0 * cpu / (slots * keeper.period)}
