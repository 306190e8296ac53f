"""Parallel evaluation: worker processes give the serial report, track for track."""

from __future__ import annotations

import logging
import os
import re

import numpy as np
import pytest

from vehicle.app.cli import main
from vehicle.app.evaluate import evaluate


def _same(a: dict, b: dict) -> None:
    a, b = dict(a), dict(b)
    a.pop("wall_time_s"), b.pop("wall_time_s")
    assert a == b


def test_expert_on_four_tracks_in_two_workers_equals_serial(cfg):
    kwargs = {"laps": 1, "cfg": cfg, "max_time": 12.0}
    serial = evaluate("expert", [11, 12, 13, 14], **kwargs)
    parallel = evaluate("expert", [11, 12, 13, 14], workers=2, **kwargs)
    assert [t["seed"] for t in parallel["tracks"]] == [11, 12, 13, 14]
    assert parallel["tracks"][0]["frames"] == 240  # 12 s at 20 Hz: the episodes really ran
    _same(serial, parallel)


def test_workers_drive_each_track_in_its_theme_and_draw(cfg, make_model_file):
    """Themes are dealt to the tracks and conditions drawn per track the same in the workers; a
    model pilot renders, so the frames (and so its commands) depend on the theme it is given."""
    pytest.importorskip("onnxruntime")
    from training.export import export_model

    path = make_model_file("linear", seed=5)
    export_model(path, "onnx")
    c = cfg.replace(SIM_THEME="road,indoor,park", SIM_RANDOMIZE=3)
    kwargs = {"laps": 1, "cfg": c, "max_time": 4.0}
    serial = evaluate(path, [31, 32, 33], **kwargs)
    parallel = evaluate(path, [31, 32, 33], workers=3, **kwargs)
    assert [t["theme"] for t in parallel["tracks"]] == ["road", "indoor", "park"]
    assert parallel["conditions"]["themes"] == ["road", "indoor", "park"]
    _same(serial, parallel)


def test_model_file_pilot_in_workers_equals_serial(cfg, make_model_file, caplog):
    pytest.importorskip("onnxruntime")
    from training.export import export_model

    path = make_model_file("linear", seed=4)
    export_model(path, "onnx")  # ONNX Runtime at 1 thread in both runs: the same arithmetic
    kwargs = {"laps": 1, "cfg": cfg, "max_time": 6.0}
    serial = evaluate(path, [21, 22, 23], **kwargs)
    with caplog.at_level(logging.INFO, logger="vehicle.app.evaluate"):
        parallel = evaluate(path, [21, 22, 23], workers=0, **kwargs)  # 0: one per core
    if (os.cpu_count() or 1) > 1:
        assert re.search(r"evaluating 3 tracks in [23] worker processes", caplog.text)
    assert len(serial["tracks"][0]["trajectory"]) > 10
    _same(serial, parallel)


def test_commanded_lane_changes_in_workers_equal_serial(cfg):
    lanes = cfg.replace(SIM_LANES=2, TRAIN_BEHAVIORS=True, SIM_EXPERT_SPEED=1.5, SIM_EVAL_LANE_CHANGE_EVERY=(7.0, 8.0))
    serial = evaluate("expert", [101, 102], laps=1, cfg=lanes, max_time=12.0)
    parallel = evaluate("expert", [101, 102], laps=1, cfg=lanes, max_time=12.0, workers=2)
    assert parallel["tracks"][0]["lanes"]["lane_changes"] >= 1  # commanded in the workers
    _same(serial, parallel)


def test_hand_made_tracks_travel_to_the_workers(cfg):
    from parts.sim.simulator import register_track
    from parts.sim.track import track_from_points

    theta = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    register_track(track_from_points(np.c_[2.5 * np.cos(theta), 1.8 * np.sin(theta)], seed=9191, width=0.8))
    serial = evaluate("expert", [9191, 11], laps=1, cfg=cfg, max_time=5.0)
    parallel = evaluate("expert", [9191, 11], laps=1, cfg=cfg, max_time=5.0, workers=2)
    _same(serial, parallel)


def test_objects_and_callbacks_run_serially(cfg, caplog):
    class Straight:
        def run(self, image):
            return 0.0, 0.3

    with caplog.at_level(logging.INFO, logger="vehicle.app.evaluate"):
        r = evaluate(Straight(), [11, 12], laps=1, cfg=cfg, max_time=1.0, workers=2)
    assert len(r["tracks"]) == 2 and "one after another" in caplog.text
    with pytest.raises(ValueError, match="workers must be an int >= 0"):
        evaluate("expert", [11], cfg=cfg, workers=-1)


def test_cli_workers_option(tmp_path, capsys):
    (tmp_path / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\n")
    assert main(["sim", "eval", "--pilot", "expert", "--tracks", "11,12", "--laps", "1", "--max-time", "3",
                 "--workers", "2", "--car", str(tmp_path)]) == 0
    assert "11" in capsys.readouterr().out
    assert main(["sim", "eval", "--pilot", "expert", "--tracks", "11", "--workers", "-2",
                 "--car", str(tmp_path)]) == 2
    assert "--workers -2" in capsys.readouterr().err


#: stands in for a terminal, in a session of its own: starts the command, waits until its workers
#: are being started, then sends a signal to the whole group (a Ctrl-C) or to the command alone
#: (``kill PID``), and exits with the command's exit code (128 + N when signal N killed it).
_TERMINAL = """
import os, signal, subprocess, sys, time
sig, target, cmd = getattr(signal, sys.argv[1]), sys.argv[2], sys.argv[3:]
signal.signal(signal.SIGINT, signal.SIG_IGN)  # our own group's Ctrl-C is for the command
proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True,
                        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
err = []
for line in proc.stderr:
    err.append(line)
    if "worker processes" in line:
        break
time.sleep(0.5)  # the workers are still starting: the signal must not reach them there either
os.killpg(0, sig) if target == "group" else os.kill(proc.pid, sig)
err.append(proc.stderr.read())
sys.stderr.write("".join(err))
code = proc.wait()
sys.exit(128 - code if code < 0 else code)  # killed by signal N: 128 + N, as a shell says
"""


def _signal_a_parallel_evaluation(tmp_path, sig: str, target: str):
    """Run a long `sim eval --workers 2`, signal it once its workers start; returns the exit code,
    the standard error and whether processes of it outlived it."""
    import contextlib
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    (tmp_path / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\n")
    root = Path(__file__).resolve().parents[3]
    cmd = [sys.executable, "-m", "vehicle", "sim", "eval", "--pilot", "expert", "--tracks", "11,12,13", "--laps",
           "5000", "--max-time", "100000", "--workers", "2", "--car", str(tmp_path)]
    terminal = subprocess.Popen([sys.executable, "-c", _TERMINAL, sig, target, *cmd],
                                env=dict(os.environ, PYTHONPATH=str(root)), stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
    try:
        _, err = terminal.communicate(timeout=300)  # a hang guard: the episodes alone would take minutes
        end = time.monotonic() + 30
        while time.monotonic() < end:  # workers watch their parent: after a SIGKILL they follow it
            try:
                os.killpg(terminal.pid, 0)
            except ProcessLookupError:
                return terminal.returncode, err, False
            time.sleep(0.2)
        return terminal.returncode, err, True
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(terminal.pid, signal.SIGKILL)
        terminal.communicate()


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "target", "code"), [
    ("SIGINT", "group", 130),   # a terminal's Ctrl-C, to the command and its workers
    ("SIGTERM", "command", 143),  # a service manager's stop, to the command alone
    ("SIGKILL", "command", 137),   # the command killed: its workers must not run on, orphaned
])
def test_a_stopped_parallel_evaluation_leaves_no_worker_running(tmp_path, sig, target, code):
    # acceptance: Ctrl-C in `sim eval --workers 2` printed "stopped" and then waited for every
    # running and queued episode to finish; later, the command hung at exit (ProcessPoolExecutor's
    # thread blocked on its result pipe), and SIGTERM or SIGKILL left the workers driving for minutes
    returncode, err, left = _signal_a_parallel_evaluation(tmp_path, sig, target)
    assert returncode == code, err[-2000:]
    assert "worker processes" in err and "eval expert on" not in err  # stopped while the episodes ran
    assert "Traceback" not in err
    assert not left


def test_a_ctrl_c_while_workers_start_is_deferred_not_lost():
    # the full suite's run of the test above: a Ctrl-C that came while the workers were being
    # started was ignored (SIG_IGN), so the evaluation ran on until killed; now it is raised
    # (KeyboardInterrupt: the workers are killed), and the workers still never see it
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from vehicle.app.evaluate import _ctrl_c_deferred

    with pytest.raises(KeyboardInterrupt), _ctrl_c_deferred():  # noqa: PT012
        child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
        status = Path(f"/proc/{child.pid}/status").read_text()
        os.kill(os.getpid(), signal.SIGINT)  # pending until the block ends (at once if another thread takes it)
        signal.pthread_sigmask(signal.SIG_BLOCK, set())  # (a call, so the main thread checks for signals)
    child.communicate(b"")
    blocked = next(line for line in status.splitlines() if line.startswith("SigBlk:"))
    assert int(blocked.split()[1], 16) & (1 << (signal.SIGINT - 1))  # a worker started inside is deaf to it


_SPAWN_IN_DEFERRAL = """
import multiprocessing, signal, time
from vehicle.app.evaluate import _ctrl_c_deferred
with _ctrl_c_deferred():
    worker = multiprocessing.get_context("spawn").Process(target=time.sleep, args=(60,), daemon=True)
    worker.start()  # the process's first: multiprocessing starts its resource tracker before it
    still_blocked = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    status = open(f"/proc/{worker.pid}/status").read()
worker.kill()
blocked = int(next(line for line in status.splitlines() if line.startswith("SigBlk:")).split()[1], 16)
print(still_blocked, bool(blocked & (1 << (signal.SIGINT - 1))))
"""


def test_the_first_spawned_worker_is_deaf_to_ctrl_c_too():
    # the full suite's run of the end-to-end Ctrl-C test printed a worker's spawn_main traceback:
    # multiprocessing starts its resource tracker before a process's first spawned child and then
    # unblocks SIGINT (and SIGTERM), so the workers were born hearing Ctrl-C after all
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    out = subprocess.run([sys.executable, "-c", _SPAWN_IN_DEFERRAL], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONPATH=str(root)), check=True)
    assert out.stdout.split() == ["True", "True"], out.stderr  # the parent's block held; the worker inherited it
