"""Tub write/read throughput and bytes per record: ours vs DonkeyCar 5.3 in the same run.

    .venv/bin/python bench/tub.py [--records 2000] [--runs 5] [--donkey-python .bench/donkey-venv/bin/python]
                                  [--workdir DIR] [--paced 20,60 [--paced-seconds 10]]

Write: records/s through the recording part (ours: TubWriter.run() for every record, waiting
while its queue of 100 is full, then shutdown() which waits until all is on disk; DonkeyCar:
TubWriter.run(), which writes before it returns), and ours through
Tub.write_record in one thread. Read: records/s of
"training reads" (catalog records + decoded 160x120 RGB image; ours: iter_images over
iter_records (a decoding thread per core, up to 4), the training frame cache's fill (2 threads decoding
into one array) and TubRecord.image() in one thread; DonkeyCar: Tub iteration + its pipeline
TubRecord.image()). Images: a rendered gradient with noise and a moving shape, so
JPEG sizes are realistic. Dirty pages are flushed (os.sync) before every timed phase. Prints
medians over --runs runs and the ratios. DonkeyCar runs in its own
venv (bench/setup_donkey_venv.sh); without it only our figures are printed.

--paced 20,60 also records at those loop rates (bench/paced.py, once, after the runs): the loop's
time in each run() call and the process's CPU, ours with and without fsync and DonkeyCar's.
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
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
TYPES = ["image_array", "float", "float", "str"]

DONKEY_SCRIPT = r"""
import contextlib, io, json, sys, time, os
import numpy as np
with contextlib.redirect_stdout(io.StringIO()):
    import donkeycar
import logging
logging.disable(logging.CRITICAL)
from donkeycar.parts.tub_v2 import Tub, TubWriter
from donkeycar.pipeline.types import TubRecord
from donkeycar.config import Config
frames = np.load(sys.argv[1])
path = sys.argv[2]
n = int(sys.argv[3])
mode = sys.argv[4]
out = {}
if mode in ("write", "both"):
    t0 = time.perf_counter()
    w = TubWriter(path, inputs=json.loads(sys.argv[5]), types=json.loads(sys.argv[6]))
    for i in range(n):
        w.run(frames[i % len(frames)], (i % 200) / 100 - 1, 0.3, "user")
    w.shutdown()
    out["write_s"] = time.perf_counter() - t0
if mode in ("read", "both"):
    cfg = Config()
    cfg.IMAGE_W, cfg.IMAGE_H, cfg.IMAGE_DEPTH, cfg.CACHE_POLICY = 160, 120, 3, "NOCACHE"
    os.sync()
    t0 = time.perf_counter()
    tub = Tub(path, read_only=True)
    count, total = 0, 0
    for rec in tub:
        img = TubRecord(cfg, tub.base_path, rec).image()
        count += 1
        total += int(img[0, 0, 0])
    out["read_s"] = time.perf_counter() - t0
    out["read_n"] = count
    out["first"] = next(iter(Tub(path, read_only=True)))
if mode == "paced":  # n: the rate in Hz; argv[7]: seconds; argv[8]: the project root
    sys.path.append(sys.argv[8])  # appended: the project must not shadow DonkeyCar's imports
    from bench.paced import paced
    w = TubWriter(path, inputs=json.loads(sys.argv[5]), types=json.loads(sys.argv[6]))
    out = paced(w.run, frames, n, float(sys.argv[7]), w.shutdown)
    out["in_tub"] = len(Tub(path, read_only=True))
print(json.dumps(out))
"""


def make_frames(n: int = 200, h: int = 120, w: int = 160) -> np.ndarray:
    """Camera-like frames: gradients, noise and a moving blob (realistic JPEG sizes)."""
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    frames = np.empty((n, h, w, 3), np.uint8)
    for i in range(n):
        cx, cy = (i * 3) % w, h * 0.6 + 10 * np.sin(i / 10)
        blob = 120 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 300)
        base = np.stack([x * 255 / w, y * 255 / h * 0.8 + 30, 255 - x * 200 / w], -1) + blob[..., None]
        frames[i] = np.clip(base + rng.normal(0, 6, base.shape), 0, 255).astype(np.uint8)
    return frames


def dir_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def settle() -> None:
    """Flush every dirty page before a timed phase, so no phase pays for the previous one's writeback."""
    os.sync()


def ours_write(frames: np.ndarray, path: Path, n: int, fsync: bool) -> float:
    from parts.tub.writer import TubWriter

    settle()
    t0 = time.perf_counter()
    w = TubWriter(path, INPUTS, TYPES, fsync=fsync)
    for i in range(n):
        # Sustained throughput: like a loop faster than the disk, but waiting instead of dropping
        # when the default queue (100 records) is full. Queueing all n frames at once would time
        # the allocation of n frame copies instead.
        while w.pending() >= w.queue_size:
            time.sleep(0.0005)
        w.run(frames[i % len(frames)], (i % 200) / 100 - 1, 0.3, "user")
    w.shutdown()
    assert w.stats.written == n and w.stats.dropped == 0
    return time.perf_counter() - t0


def ours_write_sync(frames: np.ndarray, path: Path, n: int) -> float:
    """Tub.write_record in the caller's thread (what import tools use), default fsync window."""
    from parts.tub.tub import Tub

    settle()
    t0 = time.perf_counter()
    with Tub(path, INPUTS, TYPES) as tub:
        for i in range(n):
            tub.write_record({"cam/image_array": frames[i % len(frames)], "user/angle": (i % 200) / 100 - 1,
                              "user/throttle": 0.3, "user/mode": "user"})
    return time.perf_counter() - t0


def ours_paced(frames: np.ndarray, path: Path, rate: int, seconds: float, fsync: bool) -> dict[str, float]:
    """Our TubWriter fed by a loop at ``rate`` Hz: what recording costs the drive loop."""
    from bench.paced import paced
    from parts.tub.writer import TubWriter

    settle()
    w = TubWriter(path, INPUTS, TYPES, fsync=fsync)
    out = paced(w.run, frames, rate, seconds, w.shutdown)
    if w.stats.written + w.stats.dropped != out["records"]:
        raise RuntimeError(f"paced recording at {rate} Hz lost records: {w.stats}")
    return out | {"dropped": w.stats.dropped}


def rates(text: str) -> list[int]:
    """``--paced`` value: loop rates in Hz, comma-separated ("20,60")."""
    try:
        return [int(r) for r in text.split(",") if r.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected whole rates in Hz separated by commas, got {text!r}") from None


def ours_read(path: Path, how: str) -> tuple[float, int]:
    """Records with decoded images, three ways: "iter" iterates ``iter_images(iter_records(tub,
    check_images=False))`` (frames decoded by a thread per core up to 4, catalogs parsed meanwhile;
    missing or empty images are reported when read); "cache" fills the training
    frame cache (``load_records``, then every frame decoded by 2 threads into one array held in
    memory); "serial" calls TubRecord.image() in a loop in one thread."""
    from parts.tub.reader import iter_images, iter_records, load_records
    from training.framecache import FrameCache

    settle()
    t0 = time.perf_counter()
    count = 0
    if how == "iter":
        for _rec, img in iter_images(iter_records(path, check_images=False)):
            count += int(img[0, 0, 0] >= 0)
    elif how == "cache":
        records = load_records(path)
        cache = FrameCache(records, ["cam/image_array"], threads=2)
        bad = cache.fill(np.arange(len(records)))
        count = len(records) - len(bad) if cache.cached else 0
    else:
        for rec in load_records(path):
            count += int(rec.image()[0, 0, 0] >= 0)
    return time.perf_counter() - t0, count


def create_cost_us(folder: Path, n: int = 200) -> float:
    """Median µs to create one small file in ``folder``: the floor of every image write there.

    On ext4 without a journal (this VM's disk) it jumps from ~15 µs to 0.2-1 ms for several minutes
    after many files were deleted: the allocator skips inodes freed in the last 1-6 minutes.
    """
    folder.mkdir()
    times = []
    for i in range(n):
        t0 = time.perf_counter()
        fd = os.open(folder / f"{i}.jpg", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        times.append(time.perf_counter() - t0)
        os.write(fd, b"x" * 3000)
        os.close(fd)
    return statistics.median(times) * 1e6


def donkey(python: str, frames_file: Path, path: Path, n: int, mode: str, seconds: float = 0.0) -> dict:
    """Run DonkeyCar's side in its venv: write and/or read ``n`` records, or (mode "paced") record
    at ``n`` Hz for ``seconds``."""
    settle()
    res = subprocess.run([python, "-c", DONKEY_SCRIPT, str(frames_file), str(path), str(n), mode,
                          json.dumps(INPUTS), json.dumps(TYPES), str(seconds), str(ROOT)],
                         capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"DonkeyCar run failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=2000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--donkey-python", default=str(ROOT / ".bench/donkey-venv/bin/python"))
    ap.add_argument("--workdir", default=str(ROOT / ".bench"), help="where temporary tubs go (same disk)")
    ap.add_argument("--paced", type=rates, default=[], metavar="HZ,HZ",
                    help="also record at these loop rates (e.g. 20,60): the loop's time in run() and CPU")
    ap.add_argument("--paced-seconds", type=float, default=10.0, help="seconds recorded per --paced rate")
    args = ap.parse_args()
    n = args.records
    have_donkey = Path(args.donkey_python).exists()
    if not have_donkey:
        print(f"DonkeyCar venv not found at {args.donkey_python}: run bench/setup_donkey_venv.sh "
              "for the comparison", file=sys.stderr)
    Path(args.workdir).mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="tubbench-", dir=args.workdir))
    results: dict[str, list[float]] = {}
    paced_rows: dict[str, dict[str, float]] = {}

    def add(key: str, value: float) -> None:
        results.setdefault(key, []).append(value)

    try:
        print(f"creating a file in {args.workdir}: {create_cost_us(work / 'probe'):.0f} µs (median)")
        frames = make_frames()
        frames_file = work / "frames.npy"
        np.save(frames_file, frames)
        for run in range(args.runs):
            if have_donkey:
                dk = work / f"donkey_{run}"
                r = donkey(args.donkey_python, frames_file, dk, n, "both")
                assert r["read_n"] == n
                add("donkey write", n / r["write_s"])
                add("donkey read", n / r["read_s"])
                add("donkey bytes/record", dir_bytes(dk) / n)
            ours = work / f"ours_{run}"
            add("ours write (durability window 20 rec/500 ms)", n / ours_write(frames, ours, n, True))
            add("ours write (Tub.write_record, one thread)", n / ours_write_sync(frames, work / f"sync_{run}", n))
            nosync = work / f"nosync_{run}"
            add("ours write (no fsync, like DonkeyCar)", n / ours_write(frames, nosync, n, False))
            add("ours bytes/record", dir_bytes(ours) / n)
            for how, label in (("iter", "iter_images, a thread per core up to 4"),
                               ("cache", "training FrameCache fill"), ("serial", "one thread")):
                t, count = ours_read(ours, how)
                assert count == n
                add(f"ours read ({label})", n / t)
            if have_donkey and run == 0:
                # compatibility both ways: DonkeyCar reads our tub, we read DonkeyCar's
                theirs = donkey(args.donkey_python, frames_file, ours, n, "read")
                from parts.tub.reader import load_records

                mine = load_records(dk)
                assert theirs["read_n"] == n and len(mine) == n
                first = load_records(ours)[0].data
                assert theirs["first"] == first, (theirs["first"], first)
                print("compatibility: DonkeyCar read all our records; we read all of DonkeyCar's")
            # Tubs are removed only at the end: deleting thousands of files (ext4 with `discard`)
            # slows down the file creation of the runs that follow.
            print(f"run {run + 1}/{args.runs} done", file=sys.stderr)
        for rate in args.paced:
            secs = args.paced_seconds
            for label, fsync in (("durability window", True), ("fsync=False", False)):
                paced_rows[f"{rate} Hz, ours, {label}"] = ours_paced(frames, work / f"paced_{rate}_{fsync}", rate,
                                                                     secs, fsync)
            if have_donkey:
                r = donkey(args.donkey_python, frames_file, work / f"paced_dk_{rate}", rate, "paced", secs)
                if r["in_tub"] != r["records"]:
                    raise RuntimeError(f"DonkeyCar's paced tub holds {r['in_tub']} of {r['records']} records")
                paced_rows[f"{rate} Hz, DonkeyCar 5.3"] = r
    finally:
        shutil.rmtree(work, ignore_errors=True)
        os.sync()  # ext4 without a journal skips freed inodes 1 minute if on clean blocks, else 6

    if have_donkey:  # ratios within each run first: the machine's load drifts between runs
        for k in list(results):
            base = "donkey write" if k.startswith("ours write") else "donkey read" if k.startswith("ours read") \
                else None
            if base:
                results[f"ratio {k}"] = [a / b for a, b in zip(results[k], results[base], strict=True)]
    med = {k: statistics.median(v) for k, v in results.items()}
    print(f"\n{n} records of 160x120 RGB per run, median of {args.runs} runs, cpus={os.cpu_count()}")
    for k, v in med.items():
        if k.startswith("ratio "):
            continue
        spread = f"(min {min(results[k]):,.0f}, max {max(results[k]):,.0f})"
        print(f"  {k:42s} {v:10,.0f} {spread}")
    if have_donkey:
        print("ratios vs DonkeyCar 5.3 (median of the per-run ratios):")
        for k in med:
            if k.startswith("ratio "):
                r = results[k]
                print(f"  {k[6:]:42s} {med[k]:.2f}x (min {min(r):.2f}, max {max(r):.2f})")
        print(f"  {'bytes/record ours / DonkeyCar':42s} {med['ours bytes/record'] / med['donkey bytes/record']:.2f}")
    if paced_rows:
        print(f"\nrecording at a loop rate, {args.paced_seconds:g} s each: the loop's time in run() (µs) and the "
              "process's CPU (% of one core, all threads)")
        for k, r in paced_rows.items():
            dropped = r.get("dropped", "-")  # DonkeyCar's run() writes before it returns: it cannot drop
            print(f"  {k:36s} run() p50 {r['p50_us']:7.0f}  p99 {r['p99_us']:7.0f}  max {r['max_us']:7.0f}  "
                  f"CPU {r['cpu_pct']:5.1f}%  records {r['records']}  overruns {r['overruns']}  dropped {dropped}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
