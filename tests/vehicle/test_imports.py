"""The core imports no hardware library and no torch; the CLI loads command modules lazily."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("torch", "cv2", "pygame", "smbus2", "socketio", "aiohttp", "onnxruntime", "matplotlib", "gpiozero",
         "serial", "gymnasium", "stable_baselines3")


def test_core_and_cli_import_light():
    code = (
        "import sys, json, vehicle, vehicle.app.assembly, vehicle.config, vehicle.app.cli;"
        "vehicle.app.cli.build_parser();"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r})))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []
