#!/usr/bin/env bash
# Create .bench/donkey-venv: DonkeyCar 5.3.0 without TensorFlow, for the benchmarks that compare
# against it (bench/tub.py, the loop benchmark). Safe to re-run: an existing venv is reused.
#
# DonkeyCar pins Python >=3.11,<3.12 and numpy<2; `--no-deps` skips its heavy requirements
# (tensorflow extras, kivy, pandas ...). The modules below are what `import donkeycar`,
# donkeycar.vehicle, donkeycar.parts.tub_v2/datastore_v2 and donkeycar.pipeline.types import,
# plus a few small pure-Python modules other common parts import (docopt, pyyaml, simple_pid).
#
# WITH_TENSORFLOW=1 adds DonkeyCar's Keras trainer: tensorflow-cpu 2.15 (its last release with
# Keras 2, which donkeycar.parts.keras is written for), for bench/donkey_train.py; about 600 MB
# more. (donkeycar.pipeline.training also imports pandas and albumentations, which the benchmark's
# worker does not use: bench/donkey_keras_worker.py stands in for them.)
#   WITH_TENSORFLOW=1 DONKEY_VENV=/path/to/venv bench/setup_donkey_venv.sh
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${DONKEY_VENV:-$ROOT/.bench/donkey-venv}"
PYTHON="${PYTHON:-$(command -v python3.11 || command -v python3)}"

if ! "$PYTHON" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)'; then
    echo "DonkeyCar 5.3 needs Python 3.11; set PYTHON=/path/to/python3.11" >&2
    exit 1
fi

if [ ! -x "$VENV/bin/python" ]; then
    mkdir -p "$(dirname "$VENV")"
    "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet --no-deps donkeycar==5.3.0
"$VENV/bin/python" -m pip install --quiet --no-warn-conflicts \
    "numpy>=1.23,<2" pillow pyfiglet prettytable typing_extensions \
    docopt pyyaml simple_pid psutil opencv-python-headless
if [ "${WITH_TENSORFLOW:-0}" = "1" ]; then
    "$VENV/bin/python" -m pip install --quiet --no-warn-conflicts tensorflow-cpu==2.15.0
    "$VENV/bin/python" - <<'PY'
import os
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
import contextlib, io
with contextlib.redirect_stdout(io.StringIO()):
    import tensorflow as tf
    from donkeycar.parts.keras import KerasLinear  # noqa: F401
print("tf", tf.__version__)
PY
fi
# Smoke test: the modules the benchmarks use import without TensorFlow.
"$VENV/bin/python" - <<'PY'
import contextlib, io
with contextlib.redirect_stdout(io.StringIO()):  # donkeycar prints a banner on import
    import donkeycar
    from donkeycar.parts.tub_v2 import Tub, TubWriter  # noqa: F401
    from donkeycar.pipeline.types import TubRecord  # noqa: F401
    from donkeycar.vehicle import Vehicle  # noqa: F401
print("donkeycar", donkeycar.__version__, "ready")
PY
echo "DonkeyCar venv: $VENV"
