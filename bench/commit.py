"""What making a window of new image files durable costs: syncfs vs fsync of each file.

    .venv/bin/python bench/commit.py [--windows 25] [--files 20] [--workdir .bench]

Creates ``--files`` files of 3 KB (a 160x120 JPEG) per window and then makes them durable in one
of three ways, as a tub commit would: one syncfs() (Linux), an fsync of each file issued from 8
threads plus the folder, or the fsyncs one after the other. Prints µs per file for creating and
for syncing, per method, in alternating order (the disk's state drifts during a run).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from parts.tub.image_files import syncfs_function  # noqa: E402

DATA = b"x" * 3000


def run(method: str, folder: Path, windows: int, files: int, pool: ThreadPoolExecutor) -> tuple[float, float]:
    folder.mkdir()
    dir_fd = os.open(folder, os.O_RDONLY)
    syncfs = syncfs_function()
    create = sync = 0.0
    try:
        for w in range(windows):
            t0 = time.perf_counter()
            fds = []
            for i in range(files):
                fd = os.open(folder / f"{w}_{i}_cam_image_array_.jpg", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
                os.write(fd, DATA)
                fds.append(fd)
            t1 = time.perf_counter()
            if method == "syncfs":
                assert syncfs is not None and syncfs(dir_fd) == 0
            elif method == "fsync x8 threads":
                list(pool.map(os.fsync, fds))
                os.fsync(dir_fd)
            else:
                for fd in fds:
                    os.fsync(fd)
                os.fsync(dir_fd)
            t2 = time.perf_counter()
            for fd in fds:
                os.close(fd)
            create += t1 - t0
            sync += t2 - t1
    finally:
        os.close(dir_fd)
    n = windows * files
    return create / n * 1e6, sync / n * 1e6


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--windows", type=int, default=25)
    ap.add_argument("--files", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--workdir", default=str(ROOT / ".bench"))
    args = ap.parse_args()
    methods = ["fsync x8 threads", "fsync one by one"]
    if syncfs_function() is not None:
        methods.insert(0, "syncfs")
    Path(args.workdir).mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="commitbench-", dir=args.workdir))
    results: dict[str, list[tuple[float, float]]] = {m: [] for m in methods}
    try:
        with ThreadPoolExecutor(8) as pool:
            for r in range(args.rounds):
                for m in methods:
                    os.sync()
                    results[m].append(run(m, work / f"{r}_{m.replace(' ', '_')}", args.windows, args.files, pool))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{args.windows} windows of {args.files} files, {args.rounds} rounds (median), µs per file:")
    for m, rows in results.items():
        create = sorted(c for c, _ in rows)[len(rows) // 2]
        sync = sorted(s for _, s in rows)[len(rows) // 2]
        print(f"  {m:18s} create {create:7.0f}   make durable {sync:7.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
