"""Drive-loop benchmark: our Vehicle against DonkeyCar 5.3's, measured in the same run.

    .venv/bin/python bench/loop.py [--seconds 3] [--repeat 3]

Measures, for 20, 100 and 500 Hz with 5 and 20 trivial parts, and with one threaded part:
achieved rate, period jitter |actual - target period| (p50/p99/max), CPU use, and the loop's
overhead per part per loop (loops run back to back, no sleeping). DonkeyCar runs in
.bench/donkey-venv (create it with bench/setup_donkey_venv.sh); without it only our figures print.

The threaded part is a camera at 30 Hz written the way each framework's parts are written:
ours blocks (ThreadedPart, waits for its next frame), DonkeyCar's polls in a loop without
sleeping (as its camera and controller parts do). "donkey-part" also runs that spinning
DonkeyCar part unmodified in our Vehicle.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DONKEY_PY = ROOT / ".bench" / "donkey-venv" / "bin" / "python"
LABELS = {"ours": "ours", "donkey": "DonkeyCar 5.3", "donkey-part": "ours + Donkey-style part"}
CASES = [(rate, parts, threaded) for rate in (20, 100, 500) for parts, threaded in
         ((5, None), (20, None), (5, "camera"))]


class Stamp:
    """First part of every loop: records when the loop started."""

    def __init__(self) -> None:
        self.starts: list[float] = []

    def run(self) -> int:
        self.starts.append(time.perf_counter())
        return 0


class Trivial:
    def run(self, x: int) -> int:
        return x + 1


class SpinningCamera:
    """A DonkeyCar-style threaded part: update() loops without blocking."""

    def __init__(self) -> None:
        self.on = True
        self.frame = 0

    def update(self) -> None:
        next_frame = time.perf_counter()
        while self.on:
            now = time.perf_counter()
            if now >= next_frame:
                self.frame += 1
                next_frame += 1 / 30

    def run_threaded(self) -> int:
        return self.frame

    def shutdown(self) -> None:
        self.on = False


def blocking_camera():  # ours: a ThreadedPart that waits for its next frame
    from vehicle import ThreadedPart

    class BlockingCamera(ThreadedPart):
        period = 1 / 30

        def __init__(self) -> None:
            super().__init__()
            self.frame = 0

        def poll(self) -> int:
            self.frame += 1
            return self.frame

    return BlockingCamera()


def build(framework: str, n_parts: int, threaded: str | None, clock=None):
    if framework == "donkey":
        with contextlib.redirect_stdout(io.StringIO()):
            from donkeycar.vehicle import Vehicle
        V = Vehicle()
    else:
        from vehicle import Vehicle

        V = Vehicle(clock=clock)
    stamp = Stamp()
    V.add(stamp, outputs=["k0"])
    for i in range(1, n_parts):
        V.add(Trivial(), inputs=[f"k{i - 1}"], outputs=[f"k{i}"])
    if threaded:
        cam = SpinningCamera() if framework in ("donkey", "donkey-part") else blocking_camera()
        V.add(cam, outputs=["cam/image_array"], threaded=True)
    return V, stamp


def timed_run(framework: str, rate: float, n_parts: int, threaded: str | None, seconds: float) -> dict:
    V, stamp = build(framework, n_parts, threaded)
    loops = max(int(rate * seconds), 20)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        V.start(rate_hz=rate, max_loop_count=loops)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    starts = stamp.starts
    periods = [b - a for a, b in zip(starts, starts[1:], strict=False)]
    jitter = sorted(abs(p - 1 / rate) * 1e3 for p in periods)
    return {
        "achieved_hz": (len(starts) - 1) / (starts[-1] - starts[0]),
        "jitter_p50_ms": jitter[len(jitter) // 2],
        "jitter_p99_ms": jitter[min(len(jitter) - 1, int(len(jitter) * 0.99))],
        "jitter_max_ms": jitter[-1],
        "cpu_pct": 100 * cpu / wall,
    }


def overhead_us(framework: str, n_parts: int, loops: int = 20000) -> float:
    """Microseconds per part per loop with loops back to back (trivial parts, no sleep)."""
    if framework == "donkey":
        V, _ = build(framework, n_parts, None)
        t = time.perf_counter()
        for _ in range(loops):
            V.update_parts()
        return (time.perf_counter() - t) / loops / n_parts * 1e6
    from vehicle.clock import SimulatedClock

    V, _ = build(framework, n_parts, None, clock=SimulatedClock())
    t = time.perf_counter()
    V.start(rate_hz=1000, max_loop_count=loops)
    return (time.perf_counter() - t) / loops / n_parts * 1e6


def worker(framework: str, seconds: float) -> dict:
    results = {}
    for rate, parts, threaded in CASES:
        if framework == "donkey-part" and not threaded:
            continue
        results[f"{rate}/{parts}/{threaded}"] = timed_run(framework, rate, parts, threaded, seconds)
    if framework != "donkey-part":
        results["overhead"] = {str(n): overhead_us(framework, n) for n in (5, 20)}
    return results


def run_worker(framework: str, seconds: float) -> dict | None:
    python = DONKEY_PY if framework == "donkey" else Path(sys.executable)
    if not python.exists():
        return None
    out = subprocess.run([str(python), __file__, "--worker", framework, "--seconds", str(seconds)],
                         capture_output=True, text=True, cwd=ROOT, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def median_of(runs: list[dict], key: str, metric: str) -> float:
    return statistics.median(r[key][metric] for r in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="duration of each timed case")
    parser.add_argument("--repeat", type=int, default=3, help="runs per framework (medians are reported)")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.seconds)))
        return
    runs: dict[str, list[dict]] = {"ours": [], "donkey": [], "donkey-part": []}
    for _ in range(args.repeat):  # interleaved, so load changes hit both frameworks alike
        for fw in runs:
            result = run_worker(fw, args.seconds)
            if result is not None:
                runs[fw].append(result)
    have_donkey = bool(runs["donkey"])
    print(f"median of {args.repeat} runs, {args.seconds:g} s per case; jitter = |period - target| in ms")
    print("| rate | parts | threaded part | framework | achieved Hz | jitter p50 | p99 | max | CPU % |")
    print("|---|---|---|---|---|---|---|---|---|")
    for rate, parts, threaded in CASES:
        key = f"{rate}/{parts}/{threaded}"
        for fw, label in LABELS.items():
            if not runs[fw] or key not in runs[fw][0]:
                continue
            m = {k: median_of(runs[fw], key, k) for k in runs[fw][0][key]}
            part_kind = {"camera": "blocking" if fw == "ours" else "spinning", None: "-"}[threaded]
            print(f"| {rate} | {parts} | {part_kind} | {label} | {m['achieved_hz']:.2f} "
                  f"| {m['jitter_p50_ms']:.3f} | {m['jitter_p99_ms']:.3f} | {m['jitter_max_ms']:.3f} "
                  f"| {m['cpu_pct']:.0f} |")
    print()
    print("| parts | ours µs/part/loop | DonkeyCar µs/part/loop |")
    print("|---|---|---|")
    for n in ("5", "20"):
        ours = statistics.median(r["overhead"][n] for r in runs["ours"])
        dk = f"{statistics.median(r['overhead'][n] for r in runs['donkey']):.2f}" if have_donkey else "n/a"
        print(f"| {n} | {ours:.2f} | {dk} |")
    if have_donkey:
        ratios = [median_of(runs["donkey"], f"{r}/5/None", "jitter_p50_ms")
                  / max(median_of(runs["ours"], f"{r}/5/None", "jitter_p50_ms"), 1e-6)
                  for r in (20, 100, 500)]
        print("\np50 jitter, DonkeyCar / ours at 20, 100, 500 Hz (5 parts): "
              + ", ".join(f"{x:.1f}x" for x in ratios))


if __name__ == "__main__":
    main()
