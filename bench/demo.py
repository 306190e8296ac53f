"""`vehicle demo` end to end: wall time and CPU time of each step, and the pilot's result.

    .venv/bin/python bench/demo.py                        # 1 run at 2 threads and 1 at 1 thread
    .venv/bin/python bench/demo.py --threads 1 --repeats 3

Each run is a fresh process (imports included, as a user runs the demo once installed) running
``vehicle.app.demo.run_demo`` with the demo's defaults in a temporary folder. Wall time depends on
what else the machine runs; CPU time (user + system, this process and its evaluation workers)
does much less, so the table gives both with the load average before and after each run. The
issue's goal: ≤ 90 s wall time on the 2-core machine with 100 % autonomy, every lap and mean
|CTE| ≤ 0.0253 m on the 5 unseen tracks.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def child(out: str, threads: int) -> None:
    import logging

    import torch

    from vehicle.app.demo import DEFAULTS, run_demo

    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(threads)
    r = run_demo(Path(out), **DEFAULTS)
    runs = [pair["pilot"]["overall"] for pair in r["reports"].values()]  # every theme the demo drove
    print(json.dumps({"seconds": r["seconds"], "cpu": r["cpu_seconds"],
                      "autonomy": min(o["autonomy"] for o in runs),
                      "laps": sum(o["laps_completed"] for o in runs),
                      "interventions": sum(o["interventions"] for o in runs),
                      "mean_abs_cte": max(o["mean_abs_cte"] for o in runs), "epochs": r["metrics"]["epochs"]}))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", default="2,1", help="comma-separated torch thread counts, run in turn")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--child", nargs=2, metavar=("OUT", "THREADS"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child[0], int(args.child[1]))
        return 0
    rows = []
    for _ in range(args.repeats):
        for threads in (int(t) for t in args.threads.split(",")):
            with tempfile.TemporaryDirectory() as tmp:
                before = os.getloadavg()[0]
                t = time.perf_counter()
                proc = subprocess.run([sys.executable, __file__, "--child", tmp, str(threads)], check=True,
                                      capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
                total = time.perf_counter() - t
                r = json.loads(proc.stdout.strip().splitlines()[-1])
                rows.append((threads, total, r, before, os.getloadavg()[0]))
                print(f"  {threads} thread(s): {total:.0f} s", flush=True)
    print("\n| torch threads | wall s | record / train / export / evaluate, wall s | CPU s (same steps) | "
          "epochs | worst theme's autonomy, laps, interventions, worst mean abs CTE | load average before → after |")
    print("|---|---|---|---|---|---|---|")
    for threads, total, r, before, after in rows:
        wall = " / ".join(f"{v:.0f}" for v in r["seconds"].values())
        cpu = " / ".join(f"{v:.0f}" for v in r["cpu"].values())
        print(f"| {threads} | {total:.0f} | {wall} | {cpu} | {r['epochs']} | {r['autonomy']:.1f} %, {r['laps']}, "
              f"{r['interventions']}, {r['mean_abs_cte']:.4f} m | {before:.1f} → {after:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
