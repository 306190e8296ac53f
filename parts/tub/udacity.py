"""Udacity self-driving-car simulator recordings (driving_log.csv + IMG/): import into a tub, export
from tubs (``export_udacity``, for behavioural-cloning scripts written for the simulator).

Both forms of driving_log.csv are read:

- the simulator's own: no header, absolute paths (``C:\\Users\\me\\data\\IMG\\center_2016_12_01_13_30_48_287.jpg``
  or ``/home/me/data/IMG/center_...jpg``);
- the sample data's: a header ``center,left,right,steering,throttle,brake,speed`` and relative
  paths (``IMG/center_...jpg``, often with a leading space).

Numbers written with a decimal comma (a simulator run under a German or French locale) are read
too: quoted (``"0,5"``), with ``;`` as the separator, or unquoted, where ``0,5`` splits into two
fields; such rows are put back together by choosing the split whose values are in range (and
where throttle and brake are not both on); a row that can be read in two ways is an error.
Images are copied as they are (no re-encoding). Each record holds ``cam/image_array`` (center),
``cam/image_array_left``, ``cam/image_array_right``, ``user/angle`` (steering), ``user/throttle``,
``user/brake``, ``enc/speed`` (m/s, converted from the simulator's mph) and ``user/mode`` = user;
``_timestamp_ms`` comes from the image file name.
"""

from __future__ import annotations

import csv
import io
import itertools
import logging
import os
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

from parts.tub.errors import TubError
from parts.tub.tub import Tub

logger = logging.getLogger(__name__)

MPH_TO_MS = 0.44704
COLUMNS = ("center", "left", "right", "steering", "throttle", "brake", "speed")
_STAMP = re.compile(r"(\d{4})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{3})")
# Plausible ranges of steering, throttle, brake, speed (mph): used to rebuild comma-decimal rows.
_RANGES = ((-1.0, 1.0), (-1.0, 1.0), (0.0, 1.0), (0.0, 200.0))


@dataclass
class UdacityRow:
    """One line of driving_log.csv."""

    line: int
    center: str
    left: str
    right: str
    steering: float
    throttle: float
    brake: float
    speed: float


@dataclass
class ImportReport:
    """What ``import_udacity`` did."""

    tub: Path
    imported: int = 0
    skipped: list[str] = field(default_factory=list)  # "line N: reason"


def _number(text: str) -> float:
    t = text.strip().replace(",", ".")
    return float(t)


def _rebuild(tokens: list[str], line: int) -> list[float]:
    """Turn the numeric fields of a row into (steering, throttle, brake, speed).

    With decimal commas and ',' as separator, ``-0,25`` arrives as two tokens; try every way of
    joining a token with the next all-digit token and keep the one whose values are in range.
    """
    tokens = [t.strip() for t in tokens]
    if len(tokens) == 4:
        return [_number(t) for t in tokens]
    extra = len(tokens) - 4
    if extra < 0:
        raise ValueError(f"line {line}: expected 4 numbers (steering, throttle, brake, speed), "
                         f"got {len(tokens)}")
    found: list[list[float]] = []
    for joins in itertools.combinations(range(len(tokens) - 1), extra):
        if any(b - a < 2 for a, b in itertools.pairwise(joins)):
            continue  # a token joins at most one neighbour
        # the fraction is all digits and never ends in 0 (.NET writes the shortest form: 0,5 not 0,50)
        if any(not tokens[j + 1].isdigit() or tokens[j + 1].endswith("0") for j in joins):
            continue
        vals, i = [], 0
        try:
            while i < len(tokens):
                if i in joins:
                    vals.append(float(f"{tokens[i]}.{tokens[i + 1]}"))
                    i += 2
                else:
                    vals.append(_number(tokens[i]))
                    i += 1
        except ValueError:
            continue
        if all(lo <= v <= hi for v, (lo, hi) in zip(vals, _RANGES, strict=True)):
            found.append(vals)
    # the simulator never reports throttle and brake at once: prefer readings where one is 0
    exclusive = [v for v in found if v[1] == 0 or v[2] == 0]
    unique = {tuple(v) for v in (exclusive or found)}
    if len(unique) != 1:
        why = "no" if not unique else "more than one"
        raise ValueError(f"line {line}: {why} way to read the numbers {','.join(tokens)} (decimal commas "
                         "without quotes); re-export the log with '.' as the decimal point")
    return list(unique.pop())


def read_driving_log(csv_path: str | os.PathLike[str]) -> list[UdacityRow]:
    """Parse driving_log.csv (either form); ValueError naming the line for a row that cannot be read."""
    text = Path(csv_path).read_bytes().decode("utf-8-sig", errors="replace")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    delimiter = ";" if first.count(";") >= 6 else ","
    rows: list[UdacityRow] = []
    order = list(range(7))
    for n, fields in enumerate(csv.reader(io.StringIO(text), delimiter=delimiter), 1):
        if not fields or not "".join(fields).strip():
            continue
        if n == 1 and fields[0].strip().lower() == "center":
            names = [f.strip().lower() for f in fields]
            missing = [c for c in COLUMNS if c not in names]
            if missing:
                raise ValueError(f"{csv_path}: header lacks columns {missing}; expected {','.join(COLUMNS)}")
            order = [names.index(c) for c in COLUMNS]
            continue
        if len(fields) < 7:
            raise ValueError(f"{csv_path}, line {n}: {len(fields)} fields, expected 7 "
                             f"({','.join(COLUMNS)})")
        if order != list(range(7)):
            fields = [fields[i] for i in order]
        nums = _rebuild(fields[3:], n)
        rows.append(UdacityRow(n, fields[0].strip(), fields[1].strip(), fields[2].strip(), *nums))
    return rows


def resolve_image(recorded: str, base: Path) -> Path | None:
    """Find an image named in the log: ``<base>/IMG/<file name>`` first (the recording may have
    moved, and Windows paths do not exist elsewhere), then the path as written."""
    if not recorded:
        return None
    name = re.split(r"[\\/]", recorded)[-1]
    candidates = [base / "IMG" / name, base / recorded.replace("\\", "/"), Path(recorded)]
    for c in candidates:
        if c.is_file():
            return c
    return None


def timestamp_from_name(name: str) -> int | None:
    """``center_2016_12_01_13_30_48_287.jpg`` -> epoch milliseconds (local time), else None."""
    m = _STAMP.search(name)
    if not m:
        return None
    y, mo, d, h, mi, s, ms = (int(x) for x in m.groups())
    try:
        return int(time.mktime((y, mo, d, h, mi, s, 0, 0, -1)) * 1000) + ms
    except (OverflowError, ValueError):
        return None


def import_udacity(source: str | os.PathLike[str], tub_path: str | os.PathLike[str], *,
                   max_catalog_len: int = 1000, progress: bool = False) -> ImportReport:
    """Import a recording (driving_log.csv, or the folder holding it) into ``tub_path``."""
    from tqdm import tqdm

    src = Path(source)
    csv_path = src / "driving_log.csv" if src.is_dir() else src
    if not csv_path.is_file():
        raise TubError(f"{csv_path}: no such file; give driving_log.csv or the folder that holds it")
    rows = read_driving_log(csv_path)
    if not rows:
        raise TubError(f"{csv_path}: no rows to import")
    base = csv_path.parent
    has_left = any(r.left for r in rows)
    has_right = any(r.right for r in rows)
    inputs = ["cam/image_array"] + (["cam/image_array_left"] if has_left else []) \
        + (["cam/image_array_right"] if has_right else []) \
        + ["user/angle", "user/throttle", "user/brake", "enc/speed", "user/mode"]
    types = ["image_array"] * (1 + has_left + has_right) + ["float"] * 4 + ["str"]
    report = ImportReport(Path(tub_path))
    with Tub(tub_path, inputs, types, {"source": "udacity", "driving_log": str(csv_path.resolve())},
             max_catalog_len, fsync_records=200, fsync_ms=5000) as tub:
        report.tub = tub.path
        for row in tqdm(rows, desc="import", unit="rec", disable=not progress, leave=False):
            record: dict[str, object] = {"user/angle": row.steering, "user/throttle": row.throttle,
                                         "user/brake": row.brake, "enc/speed": row.speed * MPH_TO_MS,
                                         "user/mode": "user"}
            problem = None
            for key, recorded, wanted in (("cam/image_array", row.center, True),
                                          ("cam/image_array_left", row.left, has_left),
                                          ("cam/image_array_right", row.right, has_right)):
                if not wanted or (not recorded and key != "cam/image_array"):
                    continue
                path = resolve_image(recorded, base)
                data = path.read_bytes() if path is not None else b""
                if not data:
                    problem = f"line {row.line}: image {recorded!r} " + ("is empty" if path else "not found")
                    break
                record[key] = data
            if problem:
                report.skipped.append(problem)
                continue
            tub.write_record(record, timestamp_ms=timestamp_from_name(row.center))
            report.imported += 1
    if report.skipped:
        logger.warning("%s: %d rows skipped, first: %s", csv_path, len(report.skipped), report.skipped[0])
    return report


# -- export ----------------------------------------------------------------------------------------

#: driving_log.csv layouts: (header, separator, image paths absolute)
STYLES: dict[str, tuple[bool, str, bool]] = {
    "simulator": (False, ",", True),   # what the simulator writes: no header, absolute paths
    "sample": (True, ", ", False),     # Udacity's sample data.zip: header, ", ", IMG/... paths
    "semicolon": (True, ";", False),   # header, ";" (spreadsheet exports; read by behavioural-cloning scripts)
}
SIDES = (("center", "cam/image_array"), ("left", "cam/image_array_left"), ("right", "cam/image_array_right"))
SPEED_KEYS = ("enc/speed", "sim/speed")


@dataclass
class UdacityExportReport:
    """What ``export_udacity`` wrote."""

    out: Path
    rows: int = 0
    cameras: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # "tub: record N: reason"


def _stamp(ms: int, images: Path) -> str:
    """The simulator's file-name time ``yyyy_MM_dd_HH_mm_ss_fff`` (local time); a millisecond
    whose frame is already written is moved on by 1 ms, so that no two frames share a name."""
    while True:
        stamp = time.strftime("%Y_%m_%d_%H_%M_%S", time.localtime(ms // 1000)) + f"_{ms % 1000:03d}"
        if not (images / f"center_{stamp}.jpg").exists():
            return stamp
        ms += 1


def _csv_field(text: str, sep: str) -> str:
    if sep.strip() in text or '"' in text:
        return '"' + text.replace('"', '""') + '"'
    return text


def export_udacity(tubs: list[str | os.PathLike[str]] | str | os.PathLike[str], out: str | os.PathLike[str], *,
                   style: str = "simulator", progress: bool = False) -> UdacityExportReport:
    """Write the live records of ``tubs`` as a Udacity recording: ``out/driving_log.csv`` + ``out/IMG/``.

    Each record gives one row ``center,left,right,steering,throttle,brake,speed``: the JPEGs of
    ``cam/image_array`` (and ``cam/image_array_left``/``_right`` where the tub has them; empty
    columns otherwise) copied as ``IMG/{center|left|right}_<capture time>.jpg``, ``user/angle``,
    ``user/throttle`` (negative = reverse, as the tub has it), ``user/brake`` (0 without it) and
    the speed in mph from ``enc/speed`` or ``sim/speed`` (m/s; 0 without either). ``style``: one of
    :data:`STYLES`. ``import-udacity`` reads every style back.
    """
    from tqdm import tqdm

    from parts.tub.format import check_new_folder, new_folder_tmp, replace_folder
    from parts.tub.reader import find_tubs, iter_records

    if style not in STYLES:
        raise TubError(f"unknown driving_log style {style!r}; choose one of {', '.join(STYLES)}")
    header, sep, absolute = STYLES[style]
    final = Path(os.path.expanduser(os.fspath(out))).absolute()
    check_new_folder(final)
    paths = find_tubs(tubs)
    report = UdacityExportReport(final)
    tmp = new_folder_tmp(final)
    errors: list = []
    try:
        (tmp / "IMG").mkdir()
        lines = [sep.strip().join(COLUMNS)] if header else []  # the sample's header has no spaces
        for rec in tqdm(iter_records(paths, errors=errors), desc="export", unit="rec", disable=not progress,
                        leave=False):
            angle, throttle = rec.angle, rec.throttle
            if not isinstance(angle, int | float) or not isinstance(throttle, int | float):
                report.skipped.append(f"{rec.tub}: record {rec.index}: no user/angle or user/throttle value")
                continue
            ts = rec.timestamp_ms
            stamp = _stamp(int(ts) if isinstance(ts, int | float) else int(time.time() * 1000), tmp / "IMG")
            images = []
            for side, key in SIDES:
                if rec.get(key) is None:
                    images.append("")
                    continue
                name = f"{side}_{stamp}.jpg"
                (tmp / "IMG" / name).write_bytes(rec.image_bytes(key))
                images.append(str(final / "IMG" / name) if absolute else f"IMG/{name}")
                if side not in report.cameras:
                    report.cameras.append(side)
            speed = next((rec.get(k) for k in SPEED_KEYS if isinstance(rec.get(k), int | float)), 0.0)
            brake = rec.get("user/brake")
            numbers = [float(angle), float(throttle), float(brake) if isinstance(brake, int | float) else 0.0,
                       float(speed) / MPH_TO_MS]
            lines.append(sep.join([_csv_field(p, sep) for p in images] + [repr(v) for v in numbers]))
            report.rows += 1
        report.skipped.extend(str(e) for e in errors)
        if not report.rows:
            raise TubError(f"{', '.join(map(str, paths))}: no records to export")
        (tmp / "driving_log.csv").write_text("".join(line + "\n" for line in lines), encoding="utf-8")
        replace_folder(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return report
