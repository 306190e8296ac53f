"""The console's worker process on its own: what it does when the console goes away under it."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import sqlite3
import subprocess
import sys
import time

import pytest
from fixtures.load import scaled

from training import hyperparams
from training.model_db import ModelDB
from vehicle.app.console.jobs import _TABLE
from vehicle.app.console.worker import LOCK_NAME


def _jobs_dir(config):
    path = config.path("MODELS_PATH") / ".jobs"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _job_file(config, name, job_id=1):
    tubs = sorted(str(p) for p in config.path("DATA_PATH").iterdir())
    hyper, errors = hyperparams.parse({"epochs": "100000", "steps_per_epoch": "1", "val_steps": "1",
                                       "batch_size": "4", "early_stop": "false"})
    assert not errors
    params = {"tubs": tubs, "model_name": name, "model_type": None, "settings": hyperparams.settings_for(hyper)}
    db = ModelDB.for_models_dir(config.path("MODELS_PATH")).db_path
    path = _jobs_dir(config) / f"{job_id}.job.json"
    path.write_text(json.dumps({"id": job_id, "kind": "train", "car": str(config.CAR_PATH), "db": str(db),
                                "myconfig": None, "params": params}))
    return path


def _start(job_file, car):
    return subprocess.Popen([sys.executable, "-m", "vehicle.app.console.worker", "run", str(job_file)], cwd=car,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            start_new_session=True)


def _wait_for(proc, event):
    assert proc.stdout is not None
    for line in proc.stdout:
        if json.loads(line).get("event") == event:
            return
    raise AssertionError(f"the worker ended before a {event!r} event")


def _insert_running_job(config, title="train orphan"):
    db = ModelDB.for_models_dir(config.path("MODELS_PATH"))
    db.list()  # creates the database
    with contextlib.closing(sqlite3.connect(db.db_path)) as conn, conn:
        conn.execute(_TABLE)
        return conn.execute("INSERT INTO console_jobs (kind, status, title, params, created, started) VALUES "
                            "('train', 'running', ?, '{}', '2026-01-01T00:00:00+00:00', "
                            "'2026-01-01T00:00:00+00:00')", (title,)).lastrowid


@pytest.mark.slow
def test_a_console_killed_mid_training_leaves_the_best_model_registered(config, car, console_factory):
    """kill -9 of the console closes the worker's pipes: it stops after the step, keeps its model and
    writes its end into the job's row, which the restarted console shows."""
    job_id = _insert_running_job(config)
    proc = _start(_job_file(config, "orphan", job_id), car)
    _wait_for(proc, "epoch")
    proc.stdout.close()  # the console is gone: nobody reads the events, nobody writes to stdin
    proc.stdin.close()
    assert proc.wait(timeout=scaled(120)) == 0
    entry = ModelDB.for_models_dir(config.path("MODELS_PATH")).get("orphan")
    assert entry.exists and entry.metrics["cancelled"] is True and entry.metrics["epochs"] >= 1
    app = console_factory()
    job = app.jobs.get(job_id)
    assert job.status == "cancelled" and job.result["model"] == "orphan"
    assert "console stopped" in job.message and "best model so far was kept" in job.message


def _hold_worker_lock(config):
    fd = os.open(_jobs_dir(config) / LOCK_NAME, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    return fd


def test_a_worker_waits_for_the_job_that_holds_the_car_and_can_be_cancelled_meanwhile(config, car):
    """Two consoles of one car (or a worker still stopping) never train at the same time."""
    fd = _hold_worker_lock(config)
    try:
        proc = _start(_job_file(config, "second"), car)
        _wait_for(proc, "phase")  # {"phase": "waiting"}
        proc.stdin.write(b"cancel\n")
        proc.stdin.flush()
        out = [json.loads(line) for line in proc.stdout]
        assert proc.wait(timeout=scaled(60)) == 0
    finally:
        os.close(fd)
    assert out[-1]["event"] == "end" and out[-1]["status"] == "cancelled"
    assert not any(e["event"] == "epoch" for e in out)
    assert not (config.path("MODELS_PATH") / "second.pt").exists()


def test_a_restarted_console_waits_for_a_worker_still_stopping(config, console_factory):
    job_id = _insert_running_job(config)
    fd = _hold_worker_lock(config)
    try:
        app = console_factory()
        time.sleep(1.0)
        assert app.jobs.get(job_id).status == "running"  # not interrupted: its worker is still at work
    finally:
        os.close(fd)
    end = time.monotonic() + 30
    while app.jobs.get(job_id).status == "running" and time.monotonic() < end:
        time.sleep(0.1)
    assert app.jobs.get(job_id).status == "interrupted"
