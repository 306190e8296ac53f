"""Recorder run by test_tub_crash.py and killed with SIGKILL at a random instant.

Usage: python crash_child.py TUB SEED [FSYNC_RECORDS FSYNC_MS]. Appends records to TUB with a
TubWriter (the real part: queue, writer thread, fsync policy) until killed; it never stops by
itself. The durability window is drawn from SEED unless given.
"""

from __future__ import annotations

import random
import sys
import time

import numpy as np

from parts.tub.writer import TubWriter


def main() -> None:
    path, seed = sys.argv[1], int(sys.argv[2])
    rng = random.Random(seed)
    records, ms = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) > 4 else \
        (rng.choice([1, 3, 10]), rng.choice([5, 50]))
    writer = TubWriter(path, ["cam/image_array", "user/angle", "n", "cam/timestamp"],
                       ["image_array", "float", "int", "float"], max_catalog_len=25,
                       fsync_records=records, fsync_ms=ms)
    frame = np.zeros((24, 32, 3), np.uint8)
    print("ready", flush=True)
    i = 0
    while True:
        frame[:] = (i * 7) % 256
        writer.run(frame, (i % 21 - 10) / 10, i, time.time())
        i += 1
        time.sleep(0.002)


if __name__ == "__main__":
    main()
