"""The closed-loop evaluations the car's database keeps per model, and the leaderboard over them
(:class:`EvaluationTable`, part of :class:`training.model_db.ModelDB`)."""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from training.db_store import ModelDBError, Store, _json, _now

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Evaluation:
    """One closed-loop evaluation of a model in the simulator."""

    id: int
    model: str
    tracks: tuple[int, ...]
    laps: int
    created: str
    overall: dict[str, Any]
    per_track: list[dict[str, Any]]
    settings: dict[str, Any]
    has_picture: bool = False

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly view (without the picture's bytes)."""
        return {"id": self.id, "model": self.model, "tracks": list(self.tracks), "laps": self.laps,
                "created": self.created, "overall": self.overall, "per_track": self.per_track,
                "settings": self.settings, "has_picture": self.has_picture}


class EvaluationTable(Store):
    """The ``evaluations`` table of the database (a model's evaluations go with it)."""

    def add_evaluation(self, name: str, report: Mapping[str, Any], picture: bytes | None = None) -> Evaluation:
        """Store an evaluation report (``vehicle.app.evaluate.evaluate``'s) of the model ``name``.

        Trajectories are not stored (the picture shows them); per-track metrics and the overall
        figures are.
        """
        entry = self.get(name)
        tracks = sorted(int(s) for s in report["seeds"])
        per_track = [{k: v for k, v in t.items() if k not in ("trajectory", "off_track_at")}
                     for t in report.get("tracks", [])]
        with self._connect(write=True) as conn:
            cur = conn.execute(
                "INSERT INTO evaluations (model_id, tracks, laps, created, overall, per_track, settings, picture) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (entry.id, json.dumps(tracks), int(report["laps"]), _now(), _json(report.get("overall"), "overall"),
                 json.dumps(per_track, default=str), _json(report.get("settings"), "settings"), picture))
            eid = cur.lastrowid
        logger.info("stored evaluation %d of %s on tracks %s", eid, entry.name, tracks)
        return self.evaluation(eid)

    _ECOLUMNS = ("e.id, m.name, e.tracks, e.laps, e.created, e.overall, e.per_track, e.settings, "
                 "e.picture IS NOT NULL")

    @staticmethod
    def _evaluation(row: tuple[Any, ...]) -> Evaluation:
        eid, name, tracks, laps, created, overall, per_track, settings, pic = row
        return Evaluation(eid, name, tuple(json.loads(tracks)), laps, created, json.loads(overall),
                          json.loads(per_track), json.loads(settings), bool(pic))

    def evaluation(self, evaluation_id: int) -> Evaluation:
        """One evaluation by id (ModelDBError if none)."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {self._ECOLUMNS} FROM evaluations e JOIN models m ON m.id = e.model_id "
                               "WHERE e.id = ?", (int(evaluation_id),)).fetchone()
        if row is None:
            raise ModelDBError(f"no evaluation {evaluation_id} in {self.db_path}")
        return self._evaluation(row)

    def evaluations(self, name: str | None = None) -> list[Evaluation]:
        """Evaluations of the model ``name`` (every model's when None), newest first."""
        where, args = ("WHERE m.name = ?", (self.get(name).name,)) if name is not None else ("", ())
        with self._connect() as conn:
            rows = conn.execute(f"SELECT {self._ECOLUMNS} FROM evaluations e JOIN models m ON m.id = e.model_id "
                                f"{where} ORDER BY e.created DESC, e.id DESC", args).fetchall()
        return [self._evaluation(r) for r in rows]

    def evaluation_picture(self, evaluation_id: int) -> bytes | None:
        """The PNG of an evaluation's trajectories (None if it has none)."""
        with self._connect() as conn:
            row = conn.execute("SELECT picture FROM evaluations WHERE id = ?", (int(evaluation_id),)).fetchone()
        if row is None:
            raise ModelDBError(f"no evaluation {evaluation_id} in {self.db_path}")
        return row[0]

    def remove_evaluation(self, evaluation_id: int) -> None:
        """Delete one evaluation."""
        with self._connect(write=True) as conn:
            conn.execute("DELETE FROM evaluations WHERE id = ?", (int(evaluation_id),))

    def leaderboard(self, tracks: Iterable[int], laps: int | None = None) -> list[Evaluation]:
        """Each model's latest evaluation on exactly ``tracks`` (and ``laps`` when given), best first:
        by :func:`parts.sim.metrics.rank_key` (autonomy times the share of the laps driven, then laps
        completed, then mean |CTE|, then mean speed)."""
        key = json.dumps(sorted(int(t) for t in tracks))
        latest: dict[str, Evaluation] = {}
        for ev in self.evaluations():  # newest first: the first seen per model is its latest
            if json.dumps(list(ev.tracks)) == key and (laps is None or ev.laps == laps):
                latest.setdefault(ev.model, ev)

        from parts.sim.metrics import rank_key

        return sorted(latest.values(), key=lambda ev: rank_key(ev.overall))

    def track_sets(self) -> list[tuple[tuple[int, ...], int, int]]:
        """(tracks, laps, number of models) of every track set evaluated, most models first."""
        seen: dict[tuple[tuple[int, ...], int], set[str]] = {}
        for ev in self.evaluations():
            seen.setdefault((ev.tracks, ev.laps), set()).add(ev.model)
        return sorted(((t, lp, len(m)) for (t, lp), m in seen.items()), key=lambda x: (-x[2], x[0], x[1]))
