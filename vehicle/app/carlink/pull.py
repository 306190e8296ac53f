"""Pulling a car's tubs into a folder of the laptop: only what it does not have, resumably.

Each car tub ``T`` of the car ``C`` becomes the tub ``DEST/C_T`` (its indexes kept: see
:mod:`parts.tub.transfer`). A pull asks for the records from the laptop copy's next index; the
car answers with a snapshot taken at that moment, so a tub being recorded is copied as it was
then, and the next pull takes the rest.
"""

from __future__ import annotations

import http.client
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from parts.tub.transfer import FrameReader, PullReport, TransferError, TubMirror, resume_index
from vehicle.app.carlink.client import CarClient

logger = logging.getLogger(__name__)


def local_name(car: str, tub: str) -> str:
    """The laptop folder name of the car ``car``'s tub ``tub``: ``CAR_TUB`` (a folder name)."""
    return re.sub(r"[^A-Za-z0-9._-]", "-", f"{car}_{tub}").lstrip(".-_")[:100] or "car_tub"


@dataclass
class Planned:
    """One car tub and what the laptop has of it."""

    name: str  # on the car
    target: Path  # on the laptop
    have: int  # the laptop's next index
    end: int  # the car's next index (manifest: may lag a recording by a second)
    records: int  # live records on the car
    bytes: int  # on the car's disk

    @property
    def new(self) -> int:
        """Indexes the laptop lacks (deleted ones included)."""
        return max(0, self.end - self.have)


def plan(client: CarClient, dest: Path, car: str, only: list[str] | None = None) -> list[Planned]:
    """The car's tubs (or ``only`` those) and what ``dest`` has of each."""
    tubs = client.tubs()
    names = {t["name"] for t in tubs}
    missing = [n for n in (only or []) if n not in names]
    if missing:
        raise TransferError(f"the car has no tub {missing[0]!r}; its tubs: {', '.join(sorted(names)) or 'none'}")
    out = []
    for t in tubs:
        if only and t["name"] not in only:
            continue
        target = dest / local_name(car, t["name"])
        out.append(Planned(t["name"], target, resume_index(target), int(t["current_index"]), int(t["records"]),
                           int(t["bytes"])))
    return out


def pull_tub(client: CarClient, item: Planned, source: str, progress: Callable[[int, int], None] | None = None,
             fsync: bool = True) -> PullReport:
    """Pull the records of ``item`` the laptop lacks; TransferError (resumable) when cut."""
    start = resume_index(item.target)
    conn, resp = client.open_records(item.name, start)
    try:
        return TubMirror(item.target, source, fsync=fsync).receive(FrameReader(resp), progress)
    except (OSError, http.client.HTTPException) as exc:
        raise TransferError(f"the connection to the car broke during the pull of {item.name} "
                            f"({exc or type(exc).__name__}): run the pull again to resume") from exc
    finally:
        conn.close()


def pull_all(client: CarClient, dest: Path, only: list[str] | None = None,
             progress: Callable[[dict[str, Any]], None] | None = None, fsync: bool = True) -> list[PullReport]:
    """Pull every tub of the car (or ``only`` those) with new records into ``dest``.

    ``progress`` gets ``{"tub", "done", "total", "tub_done", "tub_total"}`` (records) as it goes."""
    status = client.status()
    car = str(status.get("name") or client.address.host)
    items = [p for p in plan(client, dest, car, only) if p.new]
    total = sum(p.new for p in items)
    dest.mkdir(parents=True, exist_ok=True)
    reports, before = [], 0
    for item in items:
        def step(done: int, tub_total: int, item: Planned = item, before: int = before) -> None:
            if progress is not None:
                progress({"tub": item.name, "done": before + done, "total": max(total, before + tub_total),
                          "tub_done": done, "tub_total": tub_total})

        report = pull_tub(client, item, car, step, fsync)
        reports.append(report)
        before += report.end - report.start
        logger.debug("pulled %d records of %s into %s", report.received, item.name, report.tub)
    return reports
