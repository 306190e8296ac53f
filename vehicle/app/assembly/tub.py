"""Recording: ``add_tub_writer`` adds the tub writer (and the erase-button wiper) to a vehicle."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

from vehicle.errors import UserError

TIMESTAMP_KEY = "cam/timestamp"
ERASE_KEY = "tub/erase"
#: what a car in correction mode (CORRECTION_MODE) records besides TUB_INPUTS
CORRECTION_FIELDS = (("user/correction", "boolean"), ("pilot/angle", "float"), ("pilot/throttle", "float"))


def new_tub_path(data_path: Path) -> Path:
    """``data_path/tub_<N>_<YY-MM-DD>`` with N one above the highest existing tub number."""
    numbers = [int(m.group(1)) for p in (data_path.iterdir() if data_path.is_dir() else [])
               if (m := re.match(r"^tub_(\d+)_", p.name))]
    n = max(numbers, default=0) + 1
    return data_path / f"tub_{n}_{time.strftime('%y-%m-%d')}"


def tub_path(cfg: Any) -> Path:
    """Where this drive records: a new tub under DATA_PATH (AUTO_CREATE_NEW_TUB) or DATA_PATH."""
    data = cfg.path("DATA_PATH")
    return new_tub_path(data) if cfg.AUTO_CREATE_NEW_TUB else data


def _produced(V: Any, key: str) -> bool:
    """Whether a part already added outputs ``key`` or the user seeded it in memory."""
    return V.produces(key) or key in V.mem


def recorded_extras(V: Any, cfg: Any, inputs: list[str]) -> list[tuple[str, str]]:
    """What a drive records beside ``inputs``, as (key, tub type), for the parts ``V`` holds.

    What the car's parts declare (:meth:`vehicle.Vehicle.recorded`: a sensor's readings, the side
    cameras' frames, the behaviour); pilot/angle and pilot/throttle with RECORD_DURING_AI (when a
    pilot part was added); the correction fields with CORRECTION_MODE. Each only while a part
    writes it. ``manage.py drive``, the expert recording and the console's recordings all record
    through this, so a part present is recorded by each.
    """
    wanted: list[tuple[str, str]] = []
    if getattr(cfg, "RECORD_DURING_AI", False):  # a drive without a model has no pilot
        wanted += [("pilot/angle", "float"), ("pilot/throttle", "float")]
    wanted += list(V.recorded().items())
    if getattr(cfg, "CORRECTION_MODE", False):  # the flag, and what the pilot wanted beside the label
        wanted += CORRECTION_FIELDS
    seen = set(inputs)
    extras = []
    for key, tp in wanted:
        if key not in seen and _produced(V, key):
            extras.append((key, tp))
            seen.add(key)
    return extras


def add_tub_writer(V: Any, cfg: Any, inputs: list[str] | None = None, types: list[str] | None = None) -> Any:
    """Add a TubWriter (run_condition ``recording``, output ``tub/num_records``) and return it.

    ``inputs``/``types`` default to TUB_INPUTS/TUB_TYPES plus :func:`recorded_extras`.
    When a part produces ``cam/timestamp`` it is recorded as ``_timestamp_ms``. When a part
    produces ``tub/erase``, a TubWiper deletes the last ERASE_LAST_N_RECORDS records on each press.
    """
    from parts.tub.errors import TubError
    from parts.tub.writer import TubWiper, TubWriter

    if (inputs is None) != (types is None):
        raise UserError("add_tub_writer: give both inputs and types (one type per input), or neither")
    if inputs is None:
        inputs, types = list(cfg.TUB_INPUTS), list(cfg.TUB_TYPES)
        for key, tp in recorded_extras(V, cfg, inputs):
            inputs.append(key)
            types.append(tp)
    inputs, types = list(inputs), list(types or [])
    if len(inputs) != len(types):
        raise UserError(f"add_tub_writer: {len(inputs)} inputs {inputs} but {len(types)} types {types}; "
                        "check TUB_INPUTS and TUB_TYPES")
    if TIMESTAMP_KEY not in inputs and _produced(V, TIMESTAMP_KEY):
        inputs.append(TIMESTAMP_KEY)
        types.append("float")
    path = tub_path(cfg)
    try:
        writer = TubWriter(path, inputs, types, metadata=list(cfg.METADATA),
                           max_catalog_len=cfg.TUB_MAX_CATALOG_LEN, queue_size=cfg.TUB_QUEUE_SIZE,
                           fsync=cfg.TUB_FSYNC, fsync_records=cfg.TUB_FSYNC_RECORDS,
                           fsync_ms=cfg.TUB_FSYNC_MS, jpeg_quality=cfg.TUB_JPEG_QUALITY)
    except (TubError, ValueError) as exc:
        raise UserError(f"cannot record into {path}: {exc}") from exc
    V.add(writer, run_condition="recording")
    if _produced(V, ERASE_KEY):
        V.add(TubWiper(writer, cfg.ERASE_LAST_N_RECORDS))
    return writer
