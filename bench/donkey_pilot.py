"""DonkeyCar 5.3's own linear pilot beside ours, closed loop in our simulator, on the same data.

    .venv/bin/python bench/donkey_pilot.py train --tub demo/data/demo_tub --car /tmp/donkeycar
    .venv/bin/python bench/donkey_pilot.py eval --car /tmp/donkeycar --ours demo/models/demo_linear.pt

``train`` makes a DonkeyCar car (``donkey createcar``) and trains its ``linear`` pilot with ``donkey
train`` and DonkeyCar's defaults (Keras, no crop, no augmentation, no transformations) but
MAX_EPOCHS = 10, on the tub our demo recorded (our tubs are DonkeyCar tub v2: it reads them as
they are). ``eval`` drives that model in our built-in simulator as a part (:class:`DonkeyPilot`:
DonkeyCar's ``KerasLinear.run`` — its own preprocessing, ``normalize_image`` — in a DonkeyCar +
TensorFlow virtual environment behind a pipe, one frame in, angle and throttle out), and our pilot
beside it, in six conditions: road, indoor and park (never trained) x each theme's plain look and a
hidden randomisation draw, on tracks neither was trained on. Prints one table and writes JSON.

The DonkeyCar venv (``--venv``, default $DONKEY_VENV or .bench/donkey-venv) needs tensorflow:
``bash bench/setup_donkey_venv.sh`` then ``pip install tensorflow-cpu==2.15.0 'numpy<2'`` into it,
and for ``donkey train`` also ``pandas progress`` and albumentations, which DonkeyCar imports even
with no augmentation (docs/benchmarks.md, "DonkeyCar's pilot", says how the measured run had them).
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
DEFAULT_VENV = Path(os.environ.get("DONKEY_VENV", ROOT / ".bench" / "donkey-venv"))
THEMES = ("road", "indoor", "park")

#: runs in the DonkeyCar venv: loads the model as DonkeyCar's drive loop does, then answers frames
SERVER = r"""
import contextlib, os, struct, sys
import numpy as np
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
car, model, h, w = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
with contextlib.redirect_stdout(sys.stderr):  # donkeycar prints a banner
    import donkeycar as dk
    from donkeycar.utils import get_model_by_type
    cfg = dk.load_config(config_path=os.path.join(car, "config.py"))
    pilot = get_model_by_type("linear", cfg)
    pilot.load(model)
    pilot.run(np.zeros((h, w, 3), np.uint8))  # the first call traces the graph
out, inp = sys.stdout.buffer, sys.stdin.buffer
out.write(b"ok"); out.flush()
size = h * w * 3
while True:
    buf = inp.read(size)
    if len(buf) < size:
        break
    angle, throttle = pilot.run(np.frombuffer(buf, np.uint8).reshape(h, w, 3))
    out.write(struct.pack("<dd", float(angle), float(throttle))); out.flush()
"""


class DonkeyPilot:
    """Part: DonkeyCar's linear pilot (``model``, a .h5 or .savedmodel) in its own venv; run(frame)
    -> (angle, throttle) through DonkeyCar's ``KerasLinear.run``."""

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle", "pilot/throttle")
    name = "donkeycar-linear"

    def __init__(self, venv: Path, car: Path, model: Path, shape: tuple[int, int] = (120, 160)) -> None:
        self.shape = shape
        self.seconds = 0.0
        self.frames = 0
        self.proc = subprocess.Popen([str(venv / "bin" / "python"), "-c", SERVER, str(car), str(model),
                                      str(shape[0]), str(shape[1])],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        if self.proc.stdout.read(2) != b"ok":
            raise RuntimeError(f"the DonkeyCar pilot did not start (venv {venv}, model {model})")

    def run(self, image: np.ndarray | None) -> tuple[float, float]:
        if image is None:
            return 0.0, 0.0
        if image.shape[:2] != self.shape:
            raise ValueError(f"frames of {image.shape[:2]}, the model takes {self.shape}")
        t = time.perf_counter()
        self.proc.stdin.write(np.ascontiguousarray(image, np.uint8).tobytes())
        self.proc.stdin.flush()
        angle, throttle = struct.unpack("<dd", self.proc.stdout.read(16))
        self.seconds += time.perf_counter() - t
        self.frames += 1
        return angle, throttle

    def shutdown(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=30)


#: runs in the DonkeyCar venv: what `donkey createcar` and `donkey train --type linear` do (their
#: code in donkeycar.management.base), without importing that module, which pulls in the web
#: server's and other parts' dependencies (tornado ...) that training never uses
TRAIN = r"""
import os, shutil, sys
car, tub, model, epochs = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
import donkeycar as dk
templates = os.path.join(os.path.dirname(dk.__file__), "templates")
for d in ("models", "data", "logs"):
    os.makedirs(os.path.join(car, d), exist_ok=True)
if not os.path.exists(os.path.join(car, "config.py")):  # createcar's copies, template "complete"
    shutil.copyfile(os.path.join(templates, "cfg_complete.py"), os.path.join(car, "config.py"))
    shutil.copyfile(os.path.join(templates, "complete.py"), os.path.join(car, "manage.py"))
    shutil.copyfile(os.path.join(templates, "myconfig.py"), os.path.join(car, "myconfig.py"))
    with open(os.path.join(car, "myconfig.py"), "a") as f:
        f.write(f"\nMAX_EPOCHS = {epochs}\n")
from donkeycar.pipeline.training import train
cfg = dk.load_config(config_path=os.path.join(car, "config.py"), myconfig="myconfig.py")
train(cfg, tub, model, "linear", None, None)  # Train.run with --type linear
"""


def donkey_train(venv: Path, tub: Path, car: Path, epochs: int) -> dict[str, Any]:
    """``donkey createcar`` + ``donkey train --type linear`` with MAX_EPOCHS = ``epochs``."""
    model = car / "models" / "linear.h5"
    t = time.perf_counter()
    subprocess.run([str(venv / "bin" / "python"), "-c", TRAIN, str(car), str(tub), str(model), str(epochs)],
                   cwd=car.parent, check=True, env={**os.environ, "TF_CPP_MIN_LOG_LEVEL": "2"})
    return {"model": str(model), "train_s": round(time.perf_counter() - t, 1), "epochs": epochs}


def conditions(draw: int) -> list[tuple[str, int | None]]:
    return [(theme, r) for theme in THEMES for r in (None, draw)]


def drive(pilot: Any, tracks: list[int], laps: int, draw: int, workers: int) -> dict[str, Any]:
    from vehicle.app.demo import DEMO_SETTINGS
    from vehicle.app.evaluate import evaluate
    from vehicle.config import Config

    base = Config.defaults(**DEMO_SETTINGS)
    rows: dict[str, Any] = {}
    for theme, randomize in conditions(draw):
        cfg = base.replace(SIM_THEME=theme, SIM_RANDOMIZE=randomize)
        o = evaluate(pilot, tracks, laps, cfg=cfg, workers=workers if isinstance(pilot, str | Path) else 1)["overall"]
        rows[f"{theme}/{'off' if randomize is None else randomize}"] = {
            k: o.get(k) for k in ("autonomy", "interventions", "laps_completed", "mean_abs_cte", "mean_speed")}
        print(theme, randomize, rows[f"{theme}/{'off' if randomize is None else randomize}"], flush=True)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("--tub", type=Path, required=True)
    t.add_argument("--car", type=Path, required=True)
    t.add_argument("--epochs", type=int, default=10)
    e = sub.add_parser("eval")
    e.add_argument("--car", type=Path, required=True)
    e.add_argument("--ours", type=Path, nargs="*", default=[], help="our model files to drive beside it")
    e.add_argument("--tracks", type=int, nargs="+", default=[101, 102, 103, 104, 105])
    e.add_argument("--laps", type=int, default=2)
    e.add_argument("--draw", type=int, default=777, help="the hidden randomisation seed")
    e.add_argument("--workers", type=int, default=1)
    e.add_argument("--ours-only", action="store_true",
                   help="drive only --ours, added to the car's comparison.json from an earlier run (every episode "
                        "depends only on its seeds: DonkeyCar's rows stay valid for the same tracks, laps and draw)")
    for p in (t, e):
        p.add_argument("--venv", type=Path, default=DEFAULT_VENV)
    args = parser.parse_args()
    car = args.car.resolve()
    if args.cmd == "train":
        print(json.dumps(donkey_train(args.venv, args.tub.resolve(), car, args.epochs)))
        return 0
    import logging

    logging.basicConfig(level=logging.WARNING)
    results: dict[str, Any] = {}
    if args.ours_only:
        results = json.loads((car / "comparison.json").read_text())
    else:
        donkey = DonkeyPilot(args.venv, car, car / "models" / "linear.h5")
        try:
            results["donkeycar-linear"] = drive(donkey, args.tracks, args.laps, args.draw, 1)
            results["donkeycar-linear"]["_ms_per_frame"] = round(1000 * donkey.seconds / max(donkey.frames, 1), 2)
        finally:
            donkey.shutdown()
    for model in args.ours:
        results[model.name] = drive(model.resolve(), args.tracks, args.laps, args.draw, args.workers)
    (car / "comparison.json").write_text(json.dumps(results, indent=1))
    keys = [f"{th}/{'off' if r is None else r}" for th, r in conditions(args.draw)]
    print(f"{'pilot':24} " + " ".join(f"{k:>14}" for k in keys) + "      mean  interv.")
    for name, rows in results.items():
        cells = " ".join(f"{rows[k]['autonomy']:7.1f} % {rows[k]['interventions']:3d}" for k in keys)
        mean = sum(rows[k]["autonomy"] for k in keys) / len(keys)
        print(f"{name:24} {cells}  {mean:7.1f} {sum(rows[k]['interventions'] for k in keys):6d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
