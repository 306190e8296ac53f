"""End to end, as a user does it: createcar → record with the expert → train → drive with the model.

Each step runs the car's own ``manage.py`` in a subprocess, in simulated time.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from fixtures.load import scaled

from vehicle.app.cli import main

pytestmark = pytest.mark.slow

# Fast and isolated: simulated time, any free port for the web page, the pilot in charge from the
# start, small batches for a small data set, no loss plot.
OVERRIDES = """
SIM_REALTIME = False
WEB_CONTROL_PORT = 0
DEFAULT_MODE = "local"
ROI_CROP_TOP = 40
BATCH_SIZE = 32
SHOW_PLOT = False
"""


def manage(car, *args, timeout=120):
    proc = subprocess.run([sys.executable, "manage.py", *args], cwd=car, capture_output=True, text=True,
                          timeout=scaled(timeout), env={**os.environ, "SDL_VIDEODRIVER": "dummy",
                                                "OMP_NUM_THREADS": "1"})
    assert proc.returncode == 0, f"manage.py {' '.join(args)} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout + proc.stderr


def test_createcar_record_train_drive(tmp_path, capsys):
    car = tmp_path / "mycar"
    assert main(["createcar", "--path", str(car), "--template", "simulator"]) == 0
    with open(car / "myconfig.py", "a") as f:
        f.write(OVERRIDES)

    manage(car, "drive", "--expert", "--record-records", "300", "--tracks", "1")
    tubs = [p for p in (car / "data").iterdir() if p.is_dir()]
    assert len(tubs) == 1 and len(list((tubs[0] / "images").iterdir())) == 300

    manage(car, "train", "--tubs", "data", "--model", "models/pilot.pt", "--epochs", "2")
    assert (car / "models" / "pilot.pt").is_file()
    capsys.readouterr()
    assert main(["models", "--car", str(car)]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert listing[1].split()[:2] == ["pilot", "linear"] and tubs[0].name in listing[1]

    out = manage(car, "drive", "--model", "models/pilot.pt", "--max-loops", "100")
    assert "pilot: pilot.pt (linear" in out
    # the pilot ran in every loop (the timing summary printed when the vehicle stops)
    assert re.search(r"^Pilot\s+100\s", out, re.MULTILINE), out
