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
import math
import os
import re
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from parts.tub.errors import CorruptRecord, TubError
from parts.tub.format import MANIFEST, building_folder, check_new_folder
from parts.tub.manifest import parse_manifest
from parts.tub.reader import IMAGE_KEY, SPEED_KEYS, TubRecord, find_tubs, iter_records
from parts.tub.tub import Tub
from vehicle.keys import key_names

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
class UdacityImportReport:
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
                   max_catalog_len: int = 1000, progress: bool = False) -> UdacityImportReport:
    """Import a recording (driving_log.csv, or the folder holding it) into ``tub_path``."""
    from tqdm import tqdm

    src = Path(source)
    csv_path = src / "driving_log.csv" if src.is_dir() else src
    if not csv_path.is_file():
        raise TubError(f"{csv_path}: no such file; give driving_log.csv or the folder that holds it")
    check_new_folder(Path(tub_path))  # a second import would append every row again
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
    report = UdacityImportReport(Path(tub_path))
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
SIDES = (("center", IMAGE_KEY), ("left", "cam/image_array_left"), ("right", "cam/image_array_right"))


@dataclass
class UdacityExportReport:
    """What ``export_udacity`` wrote, and what it left out and why."""

    out: Path
    rows: int = 0
    cameras: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # "tub: record N: reason"
    why_skipped: Counter[str] = field(default_factory=Counter)  # reason -> records

    def skip(self, what: str, why: str, detail: str = "") -> None:
        """Count a record left out: ``what`` names it (tub: record N), ``why`` is its category."""
        self.why_skipped[why] += 1
        self.skipped.append(f"{what}: {detail or why}")

    def skipped_summary(self) -> str:
        """``skipped 3: 2 without a cam/image_array image, 1 with a non-finite number``."""
        if not self.skipped:
            return "skipped 0"
        return f"skipped {len(self.skipped)}: " + ", ".join(f"{n} {why}" for why, n in self.why_skipped.items())


def _stamp(ms: int, images: Path) -> str:
    """The simulator's file-name time ``yyyy_MM_dd_HH_mm_ss_fff`` (local time); a millisecond
    for which any camera's frame is already written is moved on by 1 ms, so that no two frames
    share a name."""
    while True:
        stamp = time.strftime("%Y_%m_%d_%H_%M_%S", time.localtime(ms // 1000)) + f"_{ms % 1000:03d}"
        if not any((images / f"{side}_{stamp}.jpg").exists() for side, _ in SIDES):
            return stamp
        ms += 1


def _csv_field(text: str, sep: str) -> str:
    if sep.strip() in text or '"' in text:
        return '"' + text.replace('"', '""') + '"'
    return text


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _numbers(rec: TubRecord) -> tuple[list[float] | None, str, str]:
    """(steering, throttle, brake, speed in mph) of a record, or (None, why, detail)."""
    angle, throttle = rec.angle, rec.throttle
    if not _is_number(angle) or not _is_number(throttle):
        return None, "without user/angle or user/throttle", ""
    brake = rec.get("user/brake")
    speed_key = next((k for k in SPEED_KEYS if _is_number(rec.get(k))), None)
    named = (("steering", angle), ("user/throttle", throttle), ("user/brake", brake if _is_number(brake) else 0.0),
             (speed_key or "speed", rec[speed_key] if speed_key else 0.0))
    for name, value in named:
        if not math.isfinite(value):
            return None, "with a non-finite number", f"{name} is {value} (NaN or infinity)"
    steering, throttle, brake, speed = (float(v) for _, v in named)
    return [steering, throttle, brake, speed / MPH_TO_MS], "", ""


def export_udacity(tubs: list[str | os.PathLike[str]] | str | os.PathLike[str], out: str | os.PathLike[str], *,
                   style: str = "simulator", progress: bool = False) -> UdacityExportReport:
    """Write the live records of ``tubs`` as a Udacity recording: ``out/driving_log.csv`` + ``out/IMG/``.

    Each record gives one row ``center,left,right,steering,throttle,brake,speed``: the JPEGs of
    ``cam/image_array`` (and ``cam/image_array_left``/``_right`` where its tub has them; empty
    columns for a tub without) copied as ``IMG/{center|left|right}_<capture time>.jpg``,
    ``user/angle``, ``user/throttle`` (negative = reverse, as the tub has it), ``user/brake`` (0
    without it) and the speed in mph from ``enc/speed`` or ``sim/speed`` (m/s; 0 without either).
    Records without a centre image (or without an image their tub's other cameras should have),
    without steering or throttle, or with a NaN or infinite number are left out and counted in
    the report. The CSV is written as the records stream by, into a hidden folder renamed to
    ``out`` when complete. ``style``: one of :data:`STYLES`. ``import-udacity`` reads every style back.
    """
    from tqdm import tqdm

    if style not in STYLES:
        raise TubError(f"unknown driving_log style {style!r}; choose one of {', '.join(STYLES)}")
    header, sep, absolute = STYLES[style]
    final = Path(os.path.expanduser(os.fspath(out))).absolute()
    paths = find_tubs(tubs)
    report = UdacityExportReport(final)
    errors: list[CorruptRecord] = []
    sides_of: dict[Path, list[tuple[str, str]]] = {}  # tub -> the cameras its records must have
    with building_folder(final) as tmp, open(tmp / "driving_log.csv", "w", encoding="utf-8", newline="") as log:
        images_dir = tmp / "IMG"
        images_dir.mkdir()
        if header:
            log.write(sep.strip().join(COLUMNS) + "\n")  # the sample's header has no spaces
        for rec in tqdm(iter_records(paths, errors=errors, check_images=False), desc="export", unit="rec",
                        disable=not progress, leave=False):
            what = f"{rec.tub}: record {rec.index}"
            numbers, why, detail = _numbers(rec)
            if numbers is None:
                report.skip(what, why, detail)
                continue
            if rec.tub not in sides_of:
                inputs = parse_manifest(rec.tub / MANIFEST).manifest.inputs
                sides_of[rec.tub] = [(side, key) for side, key in SIDES  # a side camera under either name
                                     if key == IMAGE_KEY or any(k in inputs for k in key_names(key))]
            images: dict[str, bytes] = {}
            for side, key in sides_of[rec.tub]:
                if not rec.has_image(key):
                    report.skip(what, f"without a {key} image")
                    break
                try:
                    images[side] = rec.image_bytes(key)
                except CorruptRecord as exc:
                    report.skip(what, "with a missing or empty image file", f"{key}: {exc.reason}")
                    break
            else:
                ts = rec.timestamp_ms
                stamp = _stamp(int(ts) if _is_number(ts) else int(time.time() * 1000), images_dir)
                columns = []
                for side, _ in SIDES:
                    if side not in images:
                        columns.append("")
                        continue
                    name = f"{side}_{stamp}.jpg"
                    (images_dir / name).write_bytes(images[side])
                    columns.append(str(final / "IMG" / name) if absolute else f"IMG/{name}")
                    if side not in report.cameras:
                        report.cameras.append(side)
                log.write(sep.join([_csv_field(c, sep) for c in columns] + [repr(v) for v in numbers]) + "\n")
                report.rows += 1
        for e in errors:
            report.skip(f"{e.tub}: record {e.index}", "that cannot be read", f"{e.file.name}: {e.reason}")
        if not report.rows:
            raise TubError(f"{', '.join(map(str, paths))}: no records to export ({report.skipped_summary()}"
                           + (f", first: {report.skipped[0]}" if report.skipped else "") + ")")
    if report.skipped:
        logger.warning("%s; first: %s", report.skipped_summary(), report.skipped[0])
    return report
