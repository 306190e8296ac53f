"""Compare TubWriter write throughput of two git revisions, alternating in one machine state.

    .venv/bin/python bench/tub_compare.py f0cfaa6 HEAD [--runs 4] [--no-fsync] [--workdir .bench]

Each revision is exported with ``git archive`` to a temporary folder; each run starts one Python
process per revision, in turn, which writes 2000 records twice with ``bench/tub.py``'s
``ours_write`` (so the revision must have it). Alternating keeps slow drifts of a shared machine
(page cache, a noisy host, file-creation cost on the disk) out of the comparison. Prints the
median records/s of each revision and their ratio.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, os, sys, tempfile
sys.path.insert(0, os.getcwd())
from pathlib import Path
import bench.tub as bt
frames = bt.make_frames()
work = Path(tempfile.mkdtemp(prefix="compare-", dir=sys.argv[1]))
print(json.dumps([2000 / bt.ours_write(frames, work / f"w{i}", 2000, sys.argv[2] == "1") for i in range(2)]))
"""


def export(rev: str, into: Path) -> Path:
    """The tree of ``rev`` in a folder of its own."""
    folder = into / rev.replace("/", "_")
    folder.mkdir()
    archive = subprocess.run(["git", "archive", rev], cwd=ROOT, capture_output=True, check=True).stdout
    tar = into / f"{folder.name}.tar"
    tar.write_bytes(archive)
    with tarfile.open(tar) as t:
        t.extractall(folder, filter="data")
    return folder


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("revisions", nargs=2)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--no-fsync", action="store_true", help="time TubWriter(fsync=False)")
    ap.add_argument("--workdir", default=str(ROOT / ".bench"), help="where the tubs go (the disk tested)")
    args = ap.parse_args()
    Path(args.workdir).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="tub-compare-") as tmp:
        trees = {rev: export(rev, Path(tmp)) for rev in args.revisions}
        work = Path(tempfile.mkdtemp(prefix="tub-compare-", dir=args.workdir))
        results: dict[str, list[float]] = {rev: [] for rev in args.revisions}
        for run in range(args.runs):
            for rev, tree in trees.items():
                out = subprocess.run([sys.executable, "-c", CHILD, str(work), "0" if args.no_fsync else "1"],
                                     cwd=tree, capture_output=True, text=True, check=True)
                results[rev] += json.loads(out.stdout.strip().splitlines()[-1])
            print(f"run {run + 1}/{args.runs} done", file=sys.stderr)
    # the tubs stay in `work`: deleting thousands of files slows file creation on some disks
    # for minutes (see docs/benchmarks.md); remove the folder when the comparison is done
    a, b = args.revisions
    med = {rev: statistics.median(v) for rev, v in results.items()}
    for rev, v in results.items():
        print(f"{rev:>12}: median {med[rev]:8,.0f} records/s  runs {[round(x) for x in v]}")
    print(f"{b} / {a}: {med[b] / med[a]:.2f}x   (tubs left in {work})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
