"""The console's job queue: trainings and evaluations, one at a time, each in a worker process.

Jobs are rows of ``console_jobs`` in the car's model database database, so the queue and the history
survive a restart of the console. The running job's worker (:mod:`vehicle.app.console.worker`)
reports events on its standard output; each event updates the job's state (phase, progress with
ETA, epochs, formatted log, result), is appended to ``<models>/.jobs/<id>.jsonl`` and is handed to
every listening browser. A page that (re)connects asks for the job's state and then applies the
events numbered after it, so a reload or a second browser sees the same run.

Cancelling a queued job drops it; cancelling the running job asks its worker to stop cleanly
(a training keeps its best model so far), then terminates it if it does not within
:data:`CANCEL_GRACE_S`.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import sqlite3
import sys
import time
from collections import deque
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

#: seconds a worker has to stop after a cancel before it is terminated (SIGTERM, then SIGKILL)
CANCEL_GRACE_S = 30.0
#: log lines kept per job in memory (the file keeps them all)
LOG_LINES = 2000
#: events one slow browser may have pending before it is dropped (it reconnects and catches up)
LISTENER_QUEUE = 2000
#: jobs listed
LIST_LIMIT = 100
#: running-loss points kept per training for the live chart (thinned to half when full)
BATCH_POINTS = 1000
#: seconds between two batch events written to the job's file (the page gets every one)
FILE_PROGRESS_INTERVAL_S = 2.0

_TABLE = """
CREATE TABLE IF NOT EXISTS console_jobs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    kind TEXT NOT NULL,
    status TEXT NOT NULL,
    title TEXT NOT NULL,
    params TEXT NOT NULL,
    created TEXT NOT NULL,
    started TEXT,
    finished TEXT,
    result TEXT,
    message TEXT
)
"""
FINAL = ("done", "failed", "cancelled", "interrupted")


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


class Job:
    """One job's state, rebuilt from its events."""

    def __init__(self, row: tuple[Any, ...]) -> None:
        jid, kind, status, title, params, created, started, finished, result, message = row
        self.id, self.kind, self.status, self.title = jid, kind, status, title
        self.params: dict[str, Any] = json.loads(params)
        self.created, self.started, self.finished = created, started, finished
        self.result: dict[str, Any] | None = json.loads(result) if result else None
        self.message: str | None = message
        self.seq = 0
        self.phase: str | None = None
        self.info: dict[str, Any] = {}
        self.progress: dict[str, Any] | None = None
        self.epochs: list[dict[str, Any]] = []
        #: [fractional epoch, running loss] of the batch events: the chart moves within an epoch
        self.batches: list[list[float]] = []
        self.log: deque[dict[str, Any]] = deque(maxlen=LOG_LINES)
        self.eta_s: float | None = None
        self.loaded = False  # events read from the file (or seen live)

    def summary(self) -> dict[str, Any]:
        """What the job list shows."""
        return {"id": self.id, "kind": self.kind, "status": self.status, "title": self.title,
                "created": self.created, "started": self.started, "finished": self.finished,
                "message": self.message, "phase": self.phase, "progress": self.progress, "eta_s": self.eta_s,
                "result": self.result, "epochs_done": len(self.epochs)}

    def snapshot(self) -> dict[str, Any]:
        """Everything a run page needs, with the sequence number of the last event applied."""
        return {**self.summary(), "params": self.params, "seq": self.seq, "info": self.info,
                "epochs": self.epochs, "batches": self.batches, "log": list(self.log)}

    def apply(self, event: dict[str, Any]) -> None:
        """Update the state with one worker event."""
        kind = event.get("event")
        if kind == "phase":
            self.phase = event.get("phase")
        elif kind == "start":
            self.info = {k: v for k, v in event.items() if k != "event"}
        elif kind in ("batch", "eval_progress", "track"):
            self.progress = {k: v for k, v in event.items()}
            if kind == "batch":
                self.eta_s = self._eta(event)
                self._add_batch_point(event)
        elif kind == "epoch":
            self.epochs.append({k: v for k, v in event.items() if k != "event"})
        elif kind in ("log", "stderr"):
            self.log.append({k: v for k, v in event.items() if k != "event"})
        elif kind == "result":
            self.result = {k: v for k, v in event.items() if k != "event"}
        elif kind == "status":
            self.status = event["status"]
            self.message = event.get("message", self.message)
            self.started = event.get("started", self.started)
            self.finished = event.get("finished", self.finished)
            if self.status in FINAL:
                self.eta_s = None

    def _add_batch_point(self, b: dict[str, Any]) -> None:
        try:
            x = b["epoch"] - 1 + b["batch"] / b["batches"]
            loss = float(b["loss"])
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            return
        if self.batches and x <= self.batches[-1][0]:
            return  # the file holds some of the events seen live: never twice, always in order
        self.batches.append([x, loss])
        if len(self.batches) > BATCH_POINTS:
            self.batches = self.batches[::2]

    def _eta(self, b: dict[str, Any]) -> float | None:
        """Seconds left at most (early stopping may end sooner), from the pace so far."""
        try:
            per_batch = b["samples"] / b["samples_per_s"] / b["batch"]
        except (KeyError, TypeError, ZeroDivisionError):
            return None
        per_epoch = sum(e["seconds"] for e in self.epochs) / len(self.epochs) if self.epochs else \
            per_batch * b["batches"]
        return max(0.0, (b["batches"] - b["batch"]) * per_batch + (b["epochs"] - b["epoch"]) * per_epoch)


class JobQueue:
    """The queue of one car. Create it in the server's event loop, then :meth:`start`.

    Args:
        db_path: the car's registry database (the jobs table lives there too).
        car_path: the car folder (the worker loads its config).
        myconfig: another override file, as ``--myconfig``.
        python: interpreter of the worker processes.
    """

    def __init__(self, db_path: Path, car_path: Path, myconfig: str | None = None,
                 python: str = sys.executable) -> None:
        self.db_path = Path(db_path)
        self.car_path = Path(car_path)
        self.myconfig = myconfig
        self.python = python
        self.jobs_dir = self.db_path.parent / ".jobs"
        self.on_change: Callable[[Job], None] | None = None  # e.g. refresh caches after a training
        self._jobs: dict[int, Job] = {}
        self._listeners: set[asyncio.Queue[dict[str, Any]]] = set()
        self._wake = asyncio.Event()
        self._runner: asyncio.Task[None] | None = None
        self._proc: asyncio.subprocess.Process | None = None
        self._running: Job | None = None
        self._cancel_requested: set[int] = set()
        self._closing = False
        self._file_progress_at = 0.0

    # -- storage ----------------------------------------------------------------------------------
    def _db(self) -> sqlite3.Connection:
        conn = sqlite3.connect(self.db_path, timeout=10.0)
        conn.execute(_TABLE)
        return conn

    _COLUMNS = "id, kind, status, title, params, created, started, finished, result, message"

    def _store(self, job: Job) -> None:
        with contextlib.closing(self._db()) as conn, conn:
            conn.execute("UPDATE console_jobs SET status = ?, started = ?, finished = ?, result = ?, message = ? "
                         "WHERE id = ?", (job.status, job.started, job.finished,
                                          json.dumps(job.result) if job.result is not None else None,
                                          job.message, job.id))

    def _events_file(self, job_id: int) -> Path:
        return self.jobs_dir / f"{job_id}.jsonl"

    def _load(self, job: Job) -> Job:
        """Rebuild a finished job's epochs, log and result from its events file."""
        if job.loaded:
            return job
        path = self._events_file(job.id)
        status = (job.status, job.message, job.started, job.finished)
        stored_result = job.result
        if path.is_file():
            with path.open(encoding="utf-8") as f:
                for line in f:
                    with contextlib.suppress(ValueError):
                        job.apply(json.loads(line))
        job.status, job.message, job.started, job.finished = status  # the table is authoritative
        if stored_result is not None:
            job.result = stored_result  # ... and its result follows renames of the model
        job.loaded = True
        return job

    # -- lifecycle --------------------------------------------------------------------------------
    async def start(self) -> None:
        """Load the jobs, settle those left running by a previous console and start the runner.

        A job left running is marked interrupted, unless its worker still holds the car's worker
        lock (the previous console was killed and the worker is stopping after its current step):
        then the queue waits for it, and shows what the worker itself wrote at its end.
        """
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        if not self._worker_busy():
            self._mark_interrupted()
        with contextlib.closing(self._db()) as conn, conn:
            rows = conn.execute(f"SELECT {self._COLUMNS} FROM console_jobs ORDER BY id DESC LIMIT ?",
                                (LIST_LIMIT,)).fetchall()
        for row in reversed(rows):
            job = Job(row)
            self._jobs[job.id] = job
        self._runner = asyncio.create_task(self._run_queue(), name="console-jobs")
        self._wake.set()

    def _mark_interrupted(self) -> None:
        with contextlib.closing(self._db()) as conn, conn:
            conn.execute("UPDATE console_jobs SET status = 'interrupted', finished = ?, "
                         "message = 'the console stopped while this job ran' WHERE status IN ('running', "
                         "'cancelling')", (_now(),))

    def _worker_busy(self) -> bool:
        """Whether a worker process (of this console or another) holds the car's worker lock."""
        import fcntl

        from vehicle.app.console.worker import LOCK_NAME

        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.jobs_dir / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        finally:
            os.close(fd)  # closing releases a lock taken here
        return False

    async def _settle_orphans(self) -> None:
        """Wait for a worker left by a previous console, then load the end it wrote for its job."""
        orphans = [j for j in self._jobs.values() if j.status in ("running", "cancelling")]
        if not orphans:
            return
        while await asyncio.to_thread(self._worker_busy):
            await asyncio.sleep(0.5)
        self._mark_interrupted()
        with contextlib.closing(self._db()) as conn, conn:
            for old in orphans:
                row = conn.execute(f"SELECT {self._COLUMNS} FROM console_jobs WHERE id = ?", (old.id,)).fetchone()
                if row is None:
                    continue
                job = Job(row)
                self._jobs[job.id] = job
                self._publish(job, {"event": "status", "status": job.status, "message": job.message,
                                    "finished": job.finished}, store=False)

    async def close(self) -> None:
        """Stop the runner; a running job is cancelled cleanly (its best model is kept)."""
        self._closing = True
        if self._running is not None:
            await self.cancel(self._running.id)
            if self._proc is not None:
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(self._proc.wait(), CANCEL_GRACE_S)
        if self._runner is not None:
            self._runner.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._runner
        if self._proc is not None and self._proc.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                self._proc.kill()
            await self._proc.wait()

    # -- API --------------------------------------------------------------------------------------
    def submit(self, kind: str, title: str, params: dict[str, Any]) -> Job:
        """Queue a job; it runs when the jobs before it have finished."""
        with contextlib.closing(self._db()) as conn, conn:
            cur = conn.execute("INSERT INTO console_jobs (kind, status, title, params, created) VALUES (?, ?, ?, ?, ?)",
                               (kind, "queued", title, json.dumps(params), _now()))
            row = conn.execute(f"SELECT {self._COLUMNS} FROM console_jobs WHERE id = ?", (cur.lastrowid,)).fetchone()
        job = Job(row)
        job.loaded = True
        self._jobs[job.id] = job
        self._publish(job, {"event": "status", "status": "queued"}, store=False)
        self._wake.set()
        logger.info("queued job %d: %s", job.id, title)
        return job

    def list(self) -> list[dict[str, Any]]:
        """Every known job, newest first."""
        return [j.summary() for j in sorted(self._jobs.values(), key=lambda j: -j.id)]

    def get(self, job_id: int) -> Job | None:
        """A job with its epochs and log (None if unknown)."""
        job = self._jobs.get(int(job_id))
        return self._load(job) if job is not None else None

    def model_renamed(self, old: str, new: str) -> None:
        """A model was renamed: the jobs that made or evaluated it name it ``new`` from now on (their
        pages link to the model)."""
        with contextlib.closing(self._db()) as conn, conn:
            for job in self._jobs.values():
                self._load(job)
                changed = False
                if job.result and job.result.get("model") == old:
                    job.result["model"] = new
                    changed = True
                if job.params.get("model") == old:
                    job.params["model"] = new
                    changed = True
                if changed:
                    conn.execute("UPDATE console_jobs SET params = ?, result = ? WHERE id = ?",
                                 (json.dumps(job.params), json.dumps(job.result) if job.result is not None else None,
                                  job.id))

    def running(self) -> Job | None:
        """The job whose worker runs now."""
        return self._running

    def busy_paths(self) -> set[Path]:
        """Tub folders read by queued or running trainings (the datasets page leaves them alone)."""
        out: set[Path] = set()
        for job in self._jobs.values():
            if job.kind == "train" and job.status in ("queued", "running", "cancelling"):
                out.update(Path(t).resolve() for t in job.params.get("tubs", []))
        return out

    async def cancel(self, job_id: int) -> Job:
        """Cancel a queued job, or ask the running one to stop cleanly."""
        job = self._jobs.get(int(job_id))
        if job is None:
            raise KeyError(job_id)
        if job.status == "queued":
            self._finish(job, "cancelled", "cancelled before it started")
        elif job.status == "running" and job is self._running and self._proc is not None:
            self._cancel_requested.add(job.id)
            self._publish(job, {"event": "status", "status": "cancelling",
                                "message": "stopping after the current step; the best model so far is kept"})
            with contextlib.suppress(BrokenPipeError, ConnectionResetError, RuntimeError, AttributeError):
                self._proc.stdin.write(b"cancel\n")  # type: ignore[union-attr]
                await self._proc.stdin.drain()  # type: ignore[union-attr]
            asyncio.get_running_loop().call_later(CANCEL_GRACE_S, self._terminate, job.id)
        return job

    def listen(self) -> asyncio.Queue[dict[str, Any]]:
        """A queue receiving every job event from now on (``unlisten`` it when done)."""
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(LISTENER_QUEUE)
        self._listeners.add(q)
        return q

    def unlisten(self, q: asyncio.Queue[dict[str, Any]]) -> None:
        """Stop sending events to ``q``."""
        self._listeners.discard(q)

    # -- internals --------------------------------------------------------------------------------
    def _publish(self, job: Job, event: dict[str, Any], store: bool = True) -> None:
        job.seq += 1
        job.apply(event)
        if store and (event.get("event") != "batch" or self._file_due()):
            self.jobs_dir.mkdir(parents=True, exist_ok=True)
            with self._events_file(job.id).open("a", encoding="utf-8") as f:
                f.write(json.dumps(event) + "\n")
        message = {"job": job.id, "seq": job.seq, **event}
        if event.get("event") == "status":
            message["summary"] = job.summary()
        for q in list(self._listeners):
            try:
                q.put_nowait(message)
            except asyncio.QueueFull:  # a stalled browser: drop it, it resynchronises on reconnect
                self._listeners.discard(q)
                with contextlib.suppress(asyncio.QueueFull):
                    q.put_nowait({"event": "overflow"})

    def _file_due(self) -> bool:
        now = time.monotonic()
        if now - self._file_progress_at >= FILE_PROGRESS_INTERVAL_S:
            self._file_progress_at = now
            return True
        return False

    def _finish(self, job: Job, status: str, message: str | None) -> None:
        self._publish(job, {"event": "status", "status": status, "message": message, "finished": _now()})
        self._store(job)
        if self.on_change is not None:
            try:
                self.on_change(job)
            except Exception:  # noqa: BLE001 - a cache refresh must not stop the queue
                logger.exception("job %d: after-job hook failed", job.id)

    def _terminate(self, job_id: int) -> None:
        proc = self._proc
        if self._running is not None and self._running.id == job_id and proc is not None and proc.returncode is None:
            logger.warning("job %d did not stop within %.0f s of its cancel: terminating it", job_id, CANCEL_GRACE_S)
            with contextlib.suppress(ProcessLookupError):
                proc.terminate()

            def kill() -> None:
                if proc.returncode is None:
                    with contextlib.suppress(ProcessLookupError):
                        proc.kill()

            asyncio.get_running_loop().call_later(10.0, kill)

    async def _run_queue(self) -> None:
        await self._settle_orphans()
        while not self._closing:
            await self._wake.wait()
            self._wake.clear()
            while not self._closing:
                queued = sorted((j for j in self._jobs.values() if j.status == "queued"), key=lambda j: j.id)
                if not queued:
                    break
                try:
                    await self._run(queued[0])
                except asyncio.CancelledError:
                    raise
                except Exception as exc:  # noqa: BLE001 - one broken job must not stop the queue
                    logger.exception("job %d could not run", queued[0].id)
                    self._finish(queued[0], "failed", f"the worker could not run: {exc}")

    async def _run(self, job: Job) -> None:
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        job_file = self.jobs_dir / f"{job.id}.job.json"
        job_file.write_text(json.dumps({"id": job.id, "kind": job.kind, "car": str(self.car_path),
                                        "db": str(self.db_path), "myconfig": self.myconfig, "params": job.params}))
        self._events_file(job.id).unlink(missing_ok=True)
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        self._running = job
        self._publish(job, {"event": "status", "status": "running", "started": _now(), "message": None})
        self._store(job)
        # a session of its own: a Ctrl-C in the console's terminal reaches the console, which then
        # cancels the job cleanly, instead of killing the worker in the middle of writing its model
        proc = await asyncio.create_subprocess_exec(
            self.python, "-m", "vehicle.app.console.worker", "run", str(job_file), cwd=str(self.car_path), env=env,
            stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
            limit=1 << 22, start_new_session=True)
        self._proc = proc
        end: dict[str, Any] = {}
        try:
            await asyncio.gather(self._read_events(job, proc.stdout, end), self._read_stderr(job, proc.stderr))
            code = await proc.wait()
        finally:
            self._running, self._proc = None, None
            with contextlib.suppress(OSError):
                job_file.unlink()
        status = end.get("status")
        if status is None:
            status = "cancelled" if job.id in self._cancel_requested else "failed"
            message = f"the worker ended without a result (exit code {code}); see the log"
        else:
            message = end.get("message")
        self._cancel_requested.discard(job.id)
        self._finish(job, status, message)
        logger.info("job %d %s: %s", job.id, status, message)

    async def _read_events(self, job: Job, stream: asyncio.StreamReader | None, end: dict[str, Any]) -> None:
        assert stream is not None  # noqa: S101 - created with stdout=PIPE
        while line := await stream.readline():
            text = line.decode("utf-8", "replace").strip()
            if not text:
                continue
            try:
                event = json.loads(text)
                if not isinstance(event, dict) or not isinstance(event.get("event"), str):
                    raise ValueError
            except ValueError:
                event = {"event": "stderr", "time": time.time(), "level": "OUTPUT", "message": text}
            if event["event"] == "end":
                end.update(event)
                continue
            if event["event"] == "status":  # only the queue sets the status
                continue
            self._publish(job, event)

    async def _read_stderr(self, job: Job, stream: asyncio.StreamReader | None) -> None:
        assert stream is not None  # noqa: S101 - created with stderr=PIPE
        while line := await stream.readline():
            text = line.decode("utf-8", "replace").rstrip()
            if text:
                self._publish(job, {"event": "stderr", "time": time.time(), "level": "STDERR", "message": text})
