"""``TubWriter``: the drive-loop part that records into a tub without blocking the loop.

``run()`` (loop thread) only copies the values into a queue. The writer's recording thread takes
what is queued in batches, gives the records their indexes in order, JPEG-encodes and writes their
image files (a batch is split with helper threads: the codecs and file system calls release the
GIL), then stores the catalog lines in order; with fsync, a commit thread makes each window
durable while the next one is written (``parts.tub.committer``). When ``queue_size`` records are
in flight (accepted, not yet written) a new record is dropped, counted and a warning is logged (at
most every few seconds): never silently lost, and the loop never waits for the disk.
"""

from __future__ import annotations

import atexit
import logging
import os
import queue
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from parts.tub.format import IMAGE_TYPES
from parts.tub.pools import submit_or_run
from parts.tub.tub import Tub
from vehicle.part import ThreadedPart

logger = logging.getLogger(__name__)

TIMESTAMP_INPUT = "cam/timestamp"
_BATCH = 32  # records the recording thread takes from the queue at once
_WARN_EVERY_S = 5.0


@dataclass
class WriterStats:
    """Counters of a TubWriter (records)."""

    accepted: int = 0   # queued by run()
    written: int = 0    # written to the tub
    dropped: int = 0    # queue full: not recorded
    failed: int = 0     # write raised (logged)


class _Stop:
    pass


class _DeleteLast:
    def __init__(self, n: int) -> None:
        self.n = n


class _Recorder(ThreadedPart):
    """The recording thread: takes what is queued in batches, gives the records their indexes in
    queue order, encodes and writes their images (the batch split between this thread and
    ``threads - 1`` helpers: one hand-off per helper and batch, not per record), then stores the
    records in order and commits when due.

    One thread for both stages: a thread of its own for the catalog lines (~5 µs per record) cost
    more in hand-offs and GIL contention than it saved; without it durable writes to disk were
    17% faster (``bench/tub_compare.py``).
    """

    def __init__(self, owner: TubWriter, threads: int) -> None:
        super().__init__()
        self.owner = owner
        self._threads = threads
        self._helpers = ThreadPoolExecutor(threads - 1, thread_name_prefix="tub-encode") if threads > 1 else None
        self._next_index = owner.tub.current_index  # the index the next record gets

    def poll(self) -> Any:
        w = self.owner
        wait = w.tub.seconds_to_commit()
        # at least 20 ms: after a failed commit the window stays due, and retrying it at once
        # would spin, taking the GIL from the drive loop
        timeout = min(max(wait, 0.02), 0.5) if wait is not None else 0.5
        try:
            batch = [w._queue.get(timeout=timeout)]
        except queue.Empty:
            if w.tub.commit_due():  # recording paused: commit the window by its age
                w._guard(w.tub.commit)
            return self.NOTHING
        while len(batch) < _BATCH and not isinstance(batch[-1], _Stop):
            try:
                batch.append(w._queue.get_nowait())
            except queue.Empty:
                break
        stored = self._store_images([item for item in batch if isinstance(item, tuple)])
        for item in batch:  # in queue order: records, deletions and the stop
            if isinstance(item, tuple):
                if id(item[0]) in stored:
                    self._write(*stored[id(item[0])])
            elif isinstance(item, _DeleteLast):
                w._guard(w.tub.delete_last_n_records, item.n)
            elif isinstance(item, _Stop):
                self.stop_event.set()
        return self.NOTHING

    def _store_images(self, records: list[tuple[dict[str, Any], int | None]]
                      ) -> dict[int, tuple[dict[str, Any], int | None, int]]:
        """Give ``records`` their indexes and write their images; returns (values, timestamp,
        index) by ``id(values)`` of the records whose images were written. A record that fails is
        counted and left out: the tub keeps its index as a deleted record (``Tub.write_record``),
        so that indexes stay positions, as DonkeyCar needs."""
        numbered = [(values, ts_ms, self._next_index + i) for i, (values, ts_ms) in enumerate(records)]
        self._next_index += len(numbered)
        ok = self._each(self._store, numbered)
        stored = {id(r[0]): r for r, done in zip(numbered, ok, strict=True) if done}
        if len(stored) < len(numbered):
            self.owner.stats.failed += len(numbered) - len(stored)
        return stored

    def _each(self, fn: Callable[[Any], bool], items: list[Any]) -> list[bool]:
        """``[fn(item) for item in items]``, the list split between this thread and the helpers."""
        if self._helpers is None or len(items) < 2 or not self.owner._image_types:
            return _map(fn, items)
        size = -(-len(items) // self._threads)  # ceil: the batch in up to `threads` slices
        slices = [items[i:i + size] for i in range(0, len(items), size)]
        jobs = [submit_or_run(self._helpers, _map, fn, sl) for sl in slices[1:]]
        ok = _map(fn, slices[0])
        for job in jobs:
            ok.extend(job.result())
        return ok

    def _store(self, record: tuple[dict[str, Any], int | None, int]) -> bool:
        """Encode and write the images of one record (in this thread or a helper)."""
        values, _ts_ms, index = record
        try:
            self.owner.tub.write_images(index, values)
            return True
        except Exception:
            self.owner._log_failure(index)
            return False

    def _write(self, values: dict[str, Any], ts_ms: int | None, index: int) -> None:
        """Store one record whose images are written (its catalog line; commits when due)."""
        w = self.owner
        if w._guard(w.tub.write_record, values, timestamp_ms=ts_ms, index=index) is not None:
            w.stats.written += 1
        else:
            w.stats.failed += 1

    def stop_helpers(self) -> None:
        if self._helpers is not None:
            self._helpers.shutdown(wait=True)


def _map(fn: Callable[[Any], bool], items: list[Any]) -> list[bool]:
    """``fn`` of each item, in this thread (a helper's task, or the recording thread's slice)."""
    return [fn(item) for item in items]


class TubWriter:
    """Record ``inputs`` into a tub each time ``run(*values)`` is called (DonkeyCar's TubWriter).

    Args:
        base_path: the tub folder (created if missing; an existing tub is appended to).
        inputs, types: memory keys and their tub types. An input named ``cam/timestamp`` (capture
            time, seconds) is not stored as a field: it becomes the record's ``_timestamp_ms``.
        metadata: user metadata (dict or ``["k:v"]``).
        max_catalog_len: records per catalog file.
        queue_size: records in flight (accepted by run(), not yet written) before new ones are
            dropped.
        fsync, fsync_records, fsync_ms, jpeg_quality: see :class:`parts.tub.tub.Tub`.
        encode_threads: threads sharing the JPEG encoding and image writes (the recording
            thread and ``encode_threads - 1`` helpers); default 2 on a machine with 2 or more
            cores. A batch is split only when records queued up (a burst, or the disk stalled),
            so at the loop's rate one thread encodes and catching up uses a second core.

    ``run()`` returns the number of records in the tub counting queued ones (``tub/num_records``);
    ``shutdown()`` writes what is queued, commits and closes. Usable without a Vehicle.
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("tub/num_records",)

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The recorded keys, in the tub's order."""
        return tuple(self.inputs)

    def __init__(self, base_path: str | os.PathLike[str], inputs: list[str], types: list[str],
                 metadata: Mapping[str, Any] | Iterable[str] | None = None, max_catalog_len: int = 1000,
                 *, queue_size: int = 100, fsync: bool = True, fsync_records: int = 20,
                 fsync_ms: float = 500.0, jpeg_quality: int = 75,
                 encode_threads: int | None = None) -> None:
        inputs, types = list(inputs), list(types)
        if len(inputs) != len(types):
            raise ValueError(f"TubWriter: {len(inputs)} inputs but {len(types)} types; give one type "
                             "per input")
        if queue_size < 1:
            raise ValueError(f"TubWriter: queue_size must be >= 1, got {queue_size}")
        if encode_threads is None:
            encode_threads = 2 if (os.cpu_count() or 1) >= 2 else 1
        if encode_threads < 1:
            raise ValueError(f"TubWriter: encode_threads must be >= 1, got {encode_threads}")
        self.inputs = inputs
        self._ts_pos = inputs.index(TIMESTAMP_INPUT) if TIMESTAMP_INPUT in inputs else None
        keep = [i for i in range(len(inputs)) if i != self._ts_pos]
        self.tub = Tub(base_path, [inputs[i] for i in keep], [types[i] for i in keep], metadata,
                       max_catalog_len, fsync=fsync, fsync_records=fsync_records, fsync_ms=fsync_ms,
                       jpeg_quality=jpeg_quality, commit_thread=fsync)
        self._keep = keep
        self.queue_size = queue_size
        # Unbounded Queue, the bound is enforced in run(): control items (stop, delete) always fit.
        self._queue: queue.Queue[Any] = queue.Queue()
        self._image_types = {k: t for k, t in zip(self.tub.inputs, self.tub.types, strict=True)
                             if t in IMAGE_TYPES}
        self.stats = WriterStats()
        self._base_count = self.tub.current_index
        self._last_warning = -_WARN_EVERY_S
        self._dropped_since_warning = 0
        self._error_logged_at = -_WARN_EVERY_S
        self._lock = threading.Lock()
        self._closed = False
        self._recorder = _Recorder(self, encode_threads)
        self._recorder.start()
        # Write what is queued if the program ends without shutdown() (the threads are daemons).
        # The tub is closed by shutdown() only, never by its own exit hook from another thread.
        if self.tub._atexit is not None:
            atexit.unregister(self.tub._atexit)
        atexit.register(self.shutdown)

    @property
    def path(self) -> str:
        return str(self.tub.path)

    def run(self, *values: Any) -> int:
        """Queue one record (never blocks on I/O); returns the tub's record count incl. queued ones."""
        if len(values) != len(self.inputs):
            raise ValueError(f"TubWriter expected {len(self.inputs)} inputs {self.inputs}, got {len(values)}")
        if self._closed:
            raise RuntimeError(f"TubWriter for {self.path} is shut down")
        if self.pending() >= self.queue_size:
            self._drop()
        else:
            record = {}
            for i in self._keep:
                v = values[i]
                # copy arrays: a camera may reuse its buffer for the next frame
                record[self.inputs[i]] = v.copy() if isinstance(v, np.ndarray) else v
            ts_ms = None
            if self._ts_pos is not None and values[self._ts_pos] is not None:
                ts_ms = int(round(float(values[self._ts_pos]) * 1000))
            self._queue.put((record, ts_ms))
            self.stats.accepted += 1
        return self._base_count + self.stats.accepted

    def _drop(self) -> None:
        self.stats.dropped += 1
        self._dropped_since_warning += 1
        now = time.monotonic()
        if now - self._last_warning >= _WARN_EVERY_S:
            failed = self._recorder.error
            why = (f"the recording thread failed ({failed!r}): nothing is written any more, see the "
                   "error logged when it failed" if failed is not None else
                   "the disk is too slow for the loop rate: lower TUB_JPEG_QUALITY or raise "
                   "TUB_FSYNC_RECORDS")
            logger.warning("%s: writer queue full (%d records): dropped %d records (%d in total); %s",
                           self.path, self.queue_size, self._dropped_since_warning, self.stats.dropped, why)
            self._last_warning = now
            self._dropped_since_warning = 0

    def _guard(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Run fn in the recording thread; log a failure (rate-limited) and return None."""
        try:
            result = fn(*args, **kwargs)
            return True if result is None else result
        except Exception:
            index = kwargs.get("index")
            self._log_failure(self.tub.current_index if index is None else index)
            return None

    def _log_failure(self, index: int) -> None:
        """Log the exception being handled, at most every few seconds (a failing disk fails often)."""
        now = time.monotonic()
        if now - self._error_logged_at >= _WARN_EVERY_S:
            logger.exception("%s: writing failed (record %d)", self.path, index)
            self._error_logged_at = now

    def delete_last(self, n: int) -> None:
        """Soft-delete the last ``n`` records, including queued ones (done in the recording thread)."""
        self._queue.put(_DeleteLast(int(n)))

    def pending(self) -> int:
        """Records accepted but not written yet."""
        s = self.stats
        return max(0, s.accepted - s.written - s.failed)

    def shutdown(self, timeout: float | None = None) -> None:
        """Write everything queued, commit, close the tub. Safe to call twice."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        atexit.unregister(self.shutdown)
        self._queue.put(_Stop())
        # The closing runs in a thread of its own, so that a timeout is kept even when the disk
        # stalls; the tub is then closed when the recording thread is done with it (it is never
        # used by two threads at once).
        failure: list[BaseException] = []

        def finish() -> None:
            try:
                self._finish()
            except BaseException as exc:
                failure.append(exc)
                logger.exception("%s: closing the tub failed", self.path)

        closer = threading.Thread(target=finish, name=f"tub-close {self.tub.path.name}", daemon=True)
        closer.start()
        closer.join(timeout)
        if closer.is_alive():
            logger.error("%s: recording thread still busy after %.1f s; %d records not written yet; the "
                         "tub is closed when they are", self.path, timeout or 0, self.pending())
        elif failure:
            raise failure[0]

    def _finish(self) -> None:
        """Wait for the recording thread to write what is queued, then close the tub."""
        recorder = self._recorder
        if recorder._thread is not None:
            recorder._thread.join()
        recorder.stop_event.set()
        recorder.stop_helpers()
        self.tub.close()
        if recorder.error is not None:
            logger.error("%s: the recording thread failed (%r); %d accepted records were not written",
                         self.path, recorder.error, self.pending())
        if self.stats.dropped:
            logger.warning("%s: %d records were dropped (queue full)", self.path, self.stats.dropped)
        logger.info("%s: %d records written this session", self.path, self.stats.written)

    close = shutdown


class TubWiper:
    """Part: on a rising edge of its input, soft-delete the last ``num_records`` records.

    ``target`` is a TubWriter (deletion happens in its thread, queued records included) or a Tub.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("tub/erase",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, target: TubWriter | Tub, num_records: int = 100) -> None:
        if num_records < 1:
            raise ValueError(f"TubWiper: num_records must be >= 1, got {num_records}")
        self.target = target
        self.num_records = num_records
        self._active = False

    def run(self, is_delete: Any) -> None:
        if is_delete:
            if not self._active:
                self._active = True
                if isinstance(self.target, TubWriter):
                    self.target.delete_last(self.num_records)
                else:
                    self.target.delete_last_n_records(self.num_records)
                logger.info("erasing the last %d records", self.num_records)
        else:
            self._active = False
