"""Background prefetching of training batches so data loading overlaps the model's compute.

The next batches are read (frame cache -> augment -> preprocess -> collate -> float on the device)
in a thread while the training step runs: OpenCV and torch release the GIL while they work, so on
a multi-core machine the data path costs the training loop almost nothing.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import Any

_DONE = object()


class Prefetcher:
    """Iterate ``source`` in a daemon thread, ``depth`` items ahead; exceptions are re-raised in the
    consumer. Use as an iterator; ``close()`` (also on ``with`` exit) stops the thread early."""

    def __init__(self, source: Iterable[Any], depth: int = 2) -> None:
        if depth < 1:
            raise ValueError(f"prefetch depth must be >= 1, got {depth}")
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(iter(source),), name="batch-prefetch",
                                        daemon=True)
        self._thread.start()

    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _run(self, it: Iterator[Any]) -> None:
        try:
            for item in it:
                if not self._put(item):
                    return
        except BaseException as exc:  # forwarded to the consumer, never lost in the thread
            self._put(("__prefetch_error__", exc))
            return
        self._put(_DONE)

    def __iter__(self) -> Prefetcher:
        return self

    def __next__(self) -> Any:
        item = self._queue.get()
        if item is _DONE:
            raise StopIteration
        if isinstance(item, tuple) and len(item) == 2 and item[0] == "__prefetch_error__":
            raise item[1]
        return item

    def close(self) -> None:
        """Stop the thread (it finishes the batch it is reading) and wait for it."""
        self._stop.set()
        while True:  # unblock a producer waiting on a full queue
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        self._thread.join(timeout=10)

    def __enter__(self) -> Prefetcher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
