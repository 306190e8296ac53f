"""The console's worker process: trains or evaluates one job, far from the web server's process.

    python -m vehicle.app.console.worker run JOB.json     # a queued job (train | evaluate)
    python -m vehicle.app.console.worker describe         # the registered model types, as JSON
    python -m vehicle.app.console.worker export --car DIR NAME onnx|torchscript
    python -m vehicle.app.console.worker saliency --car DIR NAME OUT   # saliency samples, as JSON

``run`` writes one JSON event per line on its standard output (progress, epochs, log records,
the result, then ``{"event": "end", "status": ...}``); anything else a library prints goes to
standard error. A line ``cancel`` on its standard input, or the input closing (the console went
away), stops the job cleanly: a training ends after the current step and keeps its best model
so far (finished, plotted and registered as usual); an evaluation stops without storing a result.
"""

from __future__ import annotations

import _thread
import argparse
import contextlib
import inspect
import json
import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from vehicle.app.console.jsonsafe import finite

logger = logging.getLogger(__name__)

#: the lock file, next to the job files, that one job of a car holds while it runs
LOCK_NAME = "worker.lock"
#: seconds between two batch/progress events (the page needs a few per second, not thousands)
PROGRESS_INTERVAL_S = 0.25


class Cancelled(Exception):
    """The job was cancelled."""


class Events:
    """Writes events as JSON lines to the real standard output (thread-safe)."""

    def __init__(self, out: TextIO, on_gone: Callable[[], None] | None = None) -> None:
        self.out = out
        self.on_gone = on_gone
        self.gone = False
        self._lock = threading.Lock()
        self._last_progress = 0.0

    def emit(self, event: dict[str, Any]) -> None:
        """Write one event (NaN and infinities become null). When the console has gone away (its
        end of the pipe closed, e.g. killed), events are dropped and ``on_gone`` asks the job to stop
        cleanly: a write error must never end a training between two files."""
        line = json.dumps(finite(event), default=str)
        with self._lock:
            if self.gone:
                return
            try:
                self.out.write(line + "\n")
                self.out.flush()
            except OSError:  # BrokenPipeError: nobody reads the events any more
                self._went_away()
                return
        if self.gone and self.on_gone is not None:
            self.on_gone()

    def _went_away(self) -> None:
        self.gone = True
        devnull = os.open(os.devnull, os.O_WRONLY)
        # whatever still prints (libraries, the interpreter at exit) goes nowhere instead of failing
        for fd in (1, 2):
            with contextlib.suppress(OSError):
                os.dup2(devnull, fd)
        with contextlib.suppress(OSError):
            os.dup2(devnull, self.out.fileno())
        os.close(devnull)

    def progress(self, event: dict[str, Any], force: bool = False) -> None:
        """Write a progress event at most every PROGRESS_INTERVAL_S (``force``: now)."""
        now = time.monotonic()
        if force or now - self._last_progress >= PROGRESS_INTERVAL_S:
            self._last_progress = now
            self.emit(event)


class EventLogHandler(logging.Handler):
    """Log records as ``{"event": "log", ...}`` events."""

    def __init__(self, events: Events) -> None:
        super().__init__(logging.INFO)
        self.events = events

    def emit(self, record: logging.LogRecord) -> None:
        try:
            message = record.getMessage()
            if record.exc_info and record.levelno >= logging.ERROR:
                message += "\n" + logging.Formatter().formatException(record.exc_info)
            self.events.emit({"event": "log", "time": record.created, "level": record.levelname,
                              "logger": record.name, "message": message})
        except Exception:  # noqa: BLE001 - a log line must never end the job
            self.handleError(record)


class StopWatcher:
    """Reads the standard input: ``cancel`` or end of input sets :attr:`stop`. While ``interruptible``
    (reading data, not in the training loop) the main thread is interrupted at once."""

    def __init__(self, stream: TextIO) -> None:
        self.stop = threading.Event()
        self.interruptible = True
        self._stream = stream
        threading.Thread(target=self._watch, name="stop-watcher", daemon=True).start()

    def _watch(self) -> None:
        for line in self._stream:
            if line.strip() == "cancel":
                break
        self.request()

    def request(self) -> None:
        """Ask the job to stop (from any thread)."""
        self.stop.set()
        if self.interruptible:
            _thread.interrupt_main()

    def install_signals(self) -> None:
        """SIGINT (Ctrl-C in the console's terminal reaches the worker too) and SIGTERM stop the job
        the same clean way as a cancel, instead of killing it between two files."""
        import signal

        def handler(signum: int, frame: Any) -> None:
            self.stop.set()
            if self.interruptible:
                raise KeyboardInterrupt

        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, handler)


def _config(job: dict[str, Any]) -> Any:
    from vehicle.config import load_config

    cfg = load_config(job.get("myconfig"), car_path=job["car"])
    recipe = _recipe(job)
    if recipe is not None:  # the form's values (settings) were filled from it and win over it
        cfg = cfg.replace(**recipe.settings)
    settings = job.get("params", {}).get("settings") or {}
    return cfg.replace(**settings) if settings else cfg


def _recipe(job: dict[str, Any]) -> Any:
    from training.recipes import recipe

    name = job.get("params", {}).get("recipe")
    return recipe(name) if name else None


def run_train(job: dict[str, Any], events: Events, watcher: StopWatcher) -> dict[str, Any]:
    """Train as asked by the console; returns the result event."""
    from training.trainer import train

    params = job["params"]
    cfg = _config(job)
    model_path = cfg.path("MODELS_PATH") / f"{params['model_name']}.pt"

    def on_event(event: dict[str, Any]) -> None:
        if event["event"] == "phase":
            watcher.interruptible = event["phase"] != "training"
            if watcher.stop.is_set() and watcher.interruptible:
                raise Cancelled()
        if event["event"] == "batch":
            events.progress(event, force=event["batch"] == event["batches"])
        else:
            events.emit(event)

    metrics = train(cfg, params["tubs"], model_path, model_type_name=params.get("model_type"),
                    transfer=params.get("transfer"), comment=params.get("comment"), register=True,
                    progress=False, on_event=on_event, should_stop=watcher.stop.is_set, recipe=_recipe(job))
    watcher.interruptible = True
    keys = ("best_epoch", "best_val_loss", "best_train_loss", "epochs", "epochs_planned", "stopped_early",
            "cancelled", "stopped_in_epoch", "kept_model", "train_loss", "val_loss", "wall_seconds",
            "train_samples", "val_samples")
    saved = Path(metrics.get("model_file") or model_path)  # a stopped run keeps a model of that name
    return {"event": "result", "model": saved.stem, "path": str(saved),
            "metrics": {k: metrics.get(k) for k in keys}}


def run_evaluate(job: dict[str, Any], events: Events, watcher: StopWatcher) -> dict[str, Any]:
    """Evaluate a registered model in the built-in simulator and store the result."""
    from training.model_db import ModelDB
    from vehicle.app.eval_store import store_report
    from vehicle.app.evaluate import evaluate

    params = job["params"]
    cfg = _config(job)
    entry = ModelDB.for_models_dir(cfg.path("MODELS_PATH")).get(params["model"])
    tracks, laps = [int(t) for t in params["tracks"]], int(params["laps"])
    state = {"sim": None, "index": -1}

    def on_step(sim: Any) -> None:
        if watcher.stop.is_set():
            raise Cancelled()
        if sim is not state["sim"]:
            state["sim"], state["index"] = sim, state["index"] + 1
            events.emit({"event": "track", "index": state["index"], "tracks": len(tracks),
                         "seed": tracks[min(state["index"], len(tracks) - 1)]})
        tracker = getattr(sim, "tracker", None)
        events.progress({"event": "eval_progress", "index": state["index"], "tracks": len(tracks),
                         "seed": tracks[min(state["index"], len(tracks) - 1)],
                         "sim_time": float(getattr(sim, "time", 0.0)),
                         "laps": int(getattr(tracker, "laps", 0)), "laps_target": laps})

    kwargs: dict[str, Any] = {"cfg": cfg}
    if "on_step" in inspect.signature(evaluate).parameters:
        kwargs["on_step"] = on_step
    if params.get("gallery", True):  # the failures, shown on the evaluation's card
        from vehicle.app.console.insight import insight_dir
        from vehicle.app.failure_moments import GallerySpec

        stamp = time.strftime("%Y%m%d-%H%M%S")
        folder = insight_dir(cfg, "galleries") / f"{entry.name}-{stamp}-{os.getpid()}"
        kwargs["gallery"] = GallerySpec(str(folder), str(entry.path))
    events.emit({"event": "phase", "phase": "evaluating"})
    watcher.interruptible = True
    report = evaluate(str(entry.path), tracks, laps, **kwargs)
    if watcher.stop.is_set():
        raise Cancelled()
    stored = store_report(cfg, entry.name, report)
    return {"event": "result", "model": entry.name, "evaluation_id": stored.id, "overall": stored.overall,
            "per_track": stored.per_track}


def _hold_lock(lock_path: Path, events: Events, watcher: StopWatcher) -> int:
    """Take the car's worker lock (one job at a time per car, even with two consoles or a worker
    left finishing by a console that was killed); waits, cancellable, while another job holds it.
    Returns the descriptor, which holds the lock until the process ends."""
    import fcntl

    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    waiting = False
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return fd
        except BlockingIOError:
            if not waiting:
                waiting = True
                events.emit({"event": "phase", "phase": "waiting"})
                logger.info("another job of this car is still running (another console, or one stopping): "
                            "waiting for it to finish")
            if watcher.stop.is_set():
                os.close(fd)
                raise Cancelled() from None
            time.sleep(0.5)


def _execute(job: dict[str, Any], job_file: Path, events: Events, watcher: StopWatcher) -> tuple[int, list[dict]]:
    """Run the job; returns the exit code and the final events (the result, then the end)."""
    runner = {"train": run_train, "evaluate": run_evaluate}.get(job["kind"])
    if runner is None:
        return 2, [{"event": "end", "status": "failed", "message": f"unknown job kind {job['kind']!r}"}]
    try:
        _hold_lock(job_file.parent / LOCK_NAME, events, watcher)
        result = runner(job, events, watcher)
    except (Cancelled, KeyboardInterrupt):
        return 0, [{"event": "end", "status": "cancelled", "message": "cancelled before a result was saved"}]
    except Exception as exc:  # noqa: BLE001 - every failure becomes a message on the page
        from vehicle.errors import VehicleError

        if watcher.stop.is_set() and "cancelled" in str(exc):
            return 0, [{"event": "end", "status": "cancelled", "message": str(exc)}]
        if not isinstance(exc, ValueError | VehicleError | OSError):
            logger.exception("the job failed")
        return 1, [{"event": "end", "status": "failed", "message": f"{type(exc).__name__}: {exc}"
                    if not isinstance(exc, ValueError | VehicleError) else str(exc)}]
    cancelled = bool(result.get("metrics", {}).get("cancelled"))
    return 0, [result, {"event": "end", "status": "cancelled" if cancelled else "done",
                        "message": "cancelled; the best model so far was kept" if cancelled else "finished"}]


def _record_orphan_end(job: dict[str, Any], job_file: Path, final: list[dict[str, Any]]) -> None:
    """The console went away while this job ran: write its end into the job's row and events file
    (what the console does otherwise), so a restarted console shows what became of it."""
    import sqlite3
    from datetime import UTC, datetime

    db = job.get("db")
    if not db or "id" not in job:
        return
    end = dict(final[-1])
    result = next((e for e in final if e.get("event") == "result"), None)
    message = f"the console stopped while this job ran; {end.get('message')}"
    finished = datetime.now(UTC).isoformat(timespec="seconds")
    status = {"event": "status", "status": end["status"], "message": message, "finished": finished}
    with contextlib.suppress(OSError), (job_file.parent / f"{job['id']}.jsonl").open("a", encoding="utf-8") as f:
        for event in ([result] if result else []) + [status]:
            f.write(json.dumps(finite(event), default=str) + "\n")
    with contextlib.suppress(sqlite3.Error), contextlib.closing(sqlite3.connect(db, timeout=10.0)) as conn, conn:
        conn.execute("UPDATE console_jobs SET status = ?, finished = ?, message = ?, result = COALESCE(?, result) "
                     "WHERE id = ? AND status IN ('running', 'cancelling', 'interrupted')",
                     (end["status"], finished, message,
                      json.dumps(finite({k: v for k, v in result.items() if k != "event"}), default=str)
                      if result else None, int(job["id"])))


def _run(job_file: Path) -> int:
    job = json.loads(job_file.read_text())
    events = Events(os.fdopen(os.dup(1), "w", buffering=1, encoding="utf-8"))
    os.dup2(2, 1)  # whatever else prints (libraries, C code) goes to stderr, not into the events
    sys.stdout = sys.stderr
    logging.basicConfig(level=logging.INFO, handlers=[EventLogHandler(events)], force=True)
    watcher = StopWatcher(sys.stdin)
    events.on_gone = watcher.request
    watcher.install_signals()
    events.emit({"event": "started", "pid": os.getpid(), "kind": job["kind"]})
    code, final = _execute(job, job_file, events, watcher)
    for event in final:
        events.emit(event)
    if events.gone:
        _record_orphan_end(job, job_file, final)
        with contextlib.suppress(OSError):
            job_file.unlink()
    return code


def describe_model_types() -> list[dict[str, Any]]:
    """Every registered model type: what it is and what it needs from the data."""
    from parts.pilots.models import model_type, model_type_names

    out = []
    for name in model_type_names():
        cls = model_type(name)
        doc = " ".join((inspect.getdoc(cls) or "").split("\n\n")[0].replace("``", "").split())
        defaults = dict(getattr(cls, "defaults", {}))
        needs = ["camera frames (cam/image_array) with the recorded steering and throttle"]
        if "seq_length" in defaults:
            needs.append("SEQUENCE_LENGTH consecutive frames of one session before each sample")
        if "mem_length" in defaults:
            needs.append("the previous SEQUENCE_LENGTH (angle, throttle) commands, read from the records")
        for key in cls.extra_inputs:
            needs.append(f"records with {key} (record with TRAIN_BEHAVIORS = True)")
        if "throttle_decay" in defaults:
            needs.append("learns steering only: the throttle is derived from it")
        out.append({"name": name, "doc": doc, "needs": needs, "extra_inputs": list(cls.extra_inputs),
                    "sequence": "seq_length" in defaults or "mem_length" in defaults,
                    "options": {k: v for k, v in defaults.items() if isinstance(v, int | float | str | bool)}})
    return out


def _export(car: str, name: str, fmt: str) -> int:
    from training.export import export_model
    from training.model_db import ModelDB
    from vehicle.config import load_config

    cfg = load_config(car_path=car)
    entry = ModelDB.for_models_dir(cfg.path("MODELS_PATH")).get(name)
    out = export_model(entry.path, fmt)
    print(json.dumps({"path": str(out), "bytes": Path(out).stat().st_size}))  # noqa: T201 - the answer
    return 0


def _saliency(car: str, name: str, out: Path) -> int:
    from training.model_db import ModelDB
    from vehicle.app.model_insight import saliency_samples
    from vehicle.config import load_config

    cfg = load_config(car_path=car)
    entry = ModelDB.for_models_dir(cfg.path("MODELS_PATH")).get(name)
    data = saliency_samples(entry.path, list(entry.datasets), out)
    print(json.dumps(data))  # noqa: T201 - the answer
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m vehicle.app.console.worker``."""
    parser = argparse.ArgumentParser(prog="python -m vehicle.app.console.worker", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run")
    run.add_argument("job", type=Path)
    sub.add_parser("describe")
    exp = sub.add_parser("export")
    exp.add_argument("--car", required=True)
    exp.add_argument("name")
    exp.add_argument("format", choices=("onnx", "torchscript"))
    sal = sub.add_parser("saliency")
    sal.add_argument("--car", required=True)
    sal.add_argument("name")
    sal.add_argument("out", type=Path)
    args = parser.parse_args(argv)
    if args.command == "run":
        return _run(args.job)
    if args.command == "describe":
        print(json.dumps({"model_types": describe_model_types()}))  # noqa: T201 - the answer
        return 0
    try:
        if args.command == "saliency":
            return _saliency(args.car, args.name, args.out)
        return _export(args.car, args.name, args.format)
    except Exception as exc:  # noqa: BLE001 - the console shows the message
        print(json.dumps({"error": str(exc)}))  # noqa: T201
        return 1


if __name__ == "__main__":
    sys.exit(main())
