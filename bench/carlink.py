"""The laptop link: pull throughput of a big tub on loopback, and the car's loop while it serves a
pull and switches its pilot.

    .venv/bin/python bench/carlink.py [--records 10000] [--runs 3] [--hz 20] [--workdir DIR] [--laptop-nice 10]

The car runs in this process as `manage.py drive --model a.pt --mode local` assembles it in the
built-in simulator (SimCar -> web page with the laptop link -> pilot -> drive mode), at --hz, real
time, with a probe part that stamps every loop. Its data folder holds a tub of --records records of
160x120 frames (a rendered gradient with noise and a moving bar, ~4 KB JPEGs: realistic sizes).
The laptop is another process: `vehicle.app.carlink.pull.pull_all` into a fresh folder (fsync on,
as the CLI and the console do), timed from the request to the renamed tub. Baseline in the same
run: a plain local copy of the same folder (shutil.copytree, no fsync), i.e. what rsync on one
machine cannot beat. Then the laptop pushes a second model and switches the pilot to it.

Printed: pull records/s and MB/s (median of --runs), the ratio to the copy, and the car's loop
period p50 / p99 / max and overruns in three phases: idle (5 s), during the pulls, during the
switch (push + load, 3 s after it).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
TOKEN = "Kq3vT9xLm2Rw8ZpN4bYc"

LAPTOP = """
import json, sys, time
from pathlib import Path
from vehicle.app.carlink.client import CarClient, parse_address
from vehicle.app.carlink.pull import pull_all
t = time.perf_counter()
reports = pull_all(CarClient(parse_address(sys.argv[1])), Path(sys.argv[2]), ["tub_big"])
print(json.dumps({"seconds": time.perf_counter() - t, "records": sum(r.received for r in reports)}))
"""


class Probe:
    """Part: the perf_counter of every loop."""

    def __init__(self) -> None:
        self.stamps: list[float] = []

    def run(self) -> None:
        self.stamps.append(time.perf_counter())


def make_tub(path: Path, n: int) -> None:
    from parts.tub import Tub

    rng = np.random.default_rng(0)
    base = np.linspace(0, 180, 160, dtype=np.float32)[None, :, None] + np.zeros((120, 1, 3), np.float32)
    with Tub(path, ["cam/image_array", "user/angle", "user/throttle", "user/mode"],
             ["image_array", "float", "float", "str"], fsync=False) as tub:
        for i in range(n):
            img = np.clip(base + rng.normal(0, 12, base.shape), 0, 255).astype(np.uint8)
            x = (i * 3) % 140
            img[60:90, x:x + 20] = (230, 200, 40)
            tub.write_record({"cam/image_array": img, "user/angle": float(np.sin(i / 9)), "user/throttle": 0.3,
                              "user/mode": "user"})


def model(path: Path, seed: int) -> Path:
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    torch.manual_seed(seed)
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
    return save_model(path, create_model("linear", pre.output_shape((120, 160, 3))), {"preprocess": pre.to_dict()})


def periods(stamps: list[float], start: float, end: float) -> dict[str, float]:
    """Loop period p50 / p99 / max (ms) of the loops stamped within [start, end]."""
    inside = [t for t in stamps if start <= t <= end]
    d = np.diff(inside) * 1000.0
    return {"loops": len(inside), "p50": float(np.percentile(d, 50)), "p99": float(np.percentile(d, 99)),
            "max": float(d.max())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=10000)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--hz", type=int, default=20)
    ap.add_argument("--workdir", type=Path, default=None, help="keep the tub here between runs")
    ap.add_argument("--laptop-nice", type=int, default=0,
                    help="run the laptop's process at this niceness: on one machine it competes with the car for "
                         "the CPU, which two machines do not")
    args = ap.parse_args()
    work = args.workdir or Path(tempfile.mkdtemp(prefix="carlink-bench-"))
    car = work / "car"
    tub = car / "data" / "tub_big"
    if not tub.is_dir():
        print(f"writing a tub of {args.records} records ...", file=sys.stderr)
        make_tub(tub, args.records)
    model(car / "models" / "a.pt", 0)
    second = model(work / "b.pt", 1)
    size = sum(p.stat().st_size for p in tub.rglob("*") if p.is_file())

    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import Config

    cfg = Config.defaults(CAR_PATH=str(car), WEB_CONTROL_PORT=0, WEB_TOKEN=TOKEN, DRIVE_LOOP_HZ=args.hz,
                          DEFAULT_MODE="local", PILOT_BACKEND="torch")
    V = Vehicle(clock=assembly.sim_clock(cfg, None))
    assembly.add_simulator(V, cfg)
    probe = Probe()
    V.add(probe)
    web = assembly.add_controller(V, cfg)
    assembly.add_pilot(V, cfg, car / "models" / "a.pt")
    assembly.add_drive_mode(V, cfg)
    thread = threading.Thread(target=V.start, kwargs={"rate_hz": args.hz}, daemon=True)
    thread.start()
    while web.port == 0 or len(probe.stamps) < 10:
        time.sleep(0.05)
    time.sleep(3)  # warm-up: first frames, first predictions
    url = f"http://127.0.0.1:{web.port}/?token={TOKEN}"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    phases: dict[str, dict[str, float]] = {}
    overruns: dict[str, int] = {}

    def over() -> int:
        return int(V.mem["loop/overruns"] or 0)

    t0, o0 = time.perf_counter(), over()
    time.sleep(5)
    phases["idle"], overruns["idle"] = periods(probe.stamps, t0, time.perf_counter()), over() - o0

    pulls, copies = [], []
    t0, o0 = time.perf_counter(), over()
    for run in range(args.runs):
        laptop = work / f"laptop{run}"
        shutil.rmtree(laptop, ignore_errors=True)
        out = subprocess.run([sys.executable, "-c", LAPTOP, url, str(laptop)], env=env, capture_output=True,
                             text=True, check=True, preexec_fn=lambda: os.nice(args.laptop_nice))
        pulls.append(json.loads(out.stdout.strip().splitlines()[-1]))
        shutil.rmtree(laptop, ignore_errors=True)
    phases["pull"], overruns["pull"] = periods(probe.stamps, t0, time.perf_counter()), over() - o0
    for run in range(args.runs):
        target = work / f"copy{run}"
        os.sync()
        t = time.perf_counter()
        shutil.copytree(tub, target)
        copies.append(time.perf_counter() - t)
        shutil.rmtree(target)

    t0, o0 = time.perf_counter(), over()
    switch = subprocess.run([sys.executable, "-m", "vehicle.app.cli", "car", "push", url, str(second), "--use"],
                            env=env, capture_output=True, text=True)
    time.sleep(3)
    phases["switch"], overruns["switch"] = periods(probe.stamps, t0, time.perf_counter()), over() - o0
    V.stop()
    thread.join(30)

    seconds = statistics.median(p["seconds"] for p in pulls)
    records = pulls[0]["records"]
    copy = statistics.median(copies)
    print(f"tub: {records} records, {size / 1e6:.1f} MB; car loop {args.hz:g} Hz (simulator + web + pilot); "
          f"laptop niceness {args.laptop_nice}")
    print(f"pull (median of {args.runs}): {seconds:.2f} s = {records / seconds:,.0f} records/s, "
          f"{size / 1e6 / seconds:.1f} MB/s; local copytree {copy:.2f} s ({seconds / copy:.1f}x the copy's time)")
    print(f"switch: {switch.stdout.strip() or switch.stderr.strip()}")
    print("phase   loops  period p50 / p99 / max (ms)  overruns")
    for name, p in phases.items():
        print(f"{name:7s} {p['loops']:5d}  {p['p50']:6.1f} / {p['p99']:6.1f} / {p['max']:6.1f}      {overruns[name]}")
    if args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
