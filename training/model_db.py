"""The car's registry of trained models, datasets and evaluations: one SQLite database per car.

Track Driver AI's "model manager" on the command line (``vehicle models``) and the database of the
trainer console (``vehicle console``): both read and write this one file, so a change in either
shows in the other. Training registers each model it writes; the registry keeps what the file
name does not say: the model type, the datasets (tubs) it was trained on, the training parameters,
the metrics, a free comment and the closed-loop evaluations in the simulator.

Schema (normalised as in Track Driver AI's database, but many-to-many because a model trains on several tubs)::

    models(id, name UNIQUE, path, type, parameters JSON, metrics JSON, comment, transfer, created)
    datasets(id, path UNIQUE, label, comment, added, origin, deleted, kept_deleted JSON)
    model_datasets(model_id -> models.id, dataset_id -> datasets.id)
    evaluations(id, model_id -> models.id, tracks JSON, laps, created, overall JSON,
                per_track JSON, settings JSON, picture PNG)

``path`` is stored relative to the database's folder when the model lies inside it, so a car
folder can be moved or copied. Times are ISO 8601 UTC. Re-registering a name (retraining to the
same file) replaces its entry and drops its evaluations (they judged other weights).

A dataset row with ``origin`` NULL only records what a model was trained on; the console manages
the others (``found`` in the data folder, ``registered`` by path, ``created`` empty, ``udacity``
imported). ``deleted`` marks a soft delete (the tub's own record deletes, ``kept_deleted`` holding
the records that were deleted before, so a restore gives back exactly what was there).

The schema version is SQLite's ``user_version``; :data:`MIGRATIONS` upgrades older files in place
(version 1 had no dataset details and no evaluations).
"""

from __future__ import annotations

import difflib
import json
import logging
import re
import sqlite3
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

DB_FILENAME = "models.sqlite3"
SCHEMA_VERSION = 2
# Files that training or export write next to a model and that `remove(delete_files=True)` removes.
SIDECAR_SUFFIXES: tuple[str, ...] = (".onnx", ".int8.onnx", ".ts", ".loss.png", ".metrics.json")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS models (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    name TEXT NOT NULL UNIQUE,
    path TEXT NOT NULL,
    type TEXT NOT NULL,
    parameters TEXT NOT NULL DEFAULT '{}',
    metrics TEXT NOT NULL DEFAULT '{}',
    comment TEXT,
    transfer TEXT,
    created TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS datasets (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    path TEXT NOT NULL UNIQUE
);
CREATE TABLE IF NOT EXISTS model_datasets (
    model_id INTEGER NOT NULL REFERENCES models(id) ON DELETE CASCADE,
    dataset_id INTEGER NOT NULL REFERENCES datasets(id) ON DELETE CASCADE,
    PRIMARY KEY (model_id, dataset_id)
);
"""

#: statements that bring a file of version N-1 to version N, applied in order in one transaction
MIGRATIONS: dict[int, tuple[str, ...]] = {
    2: (
        "ALTER TABLE datasets ADD COLUMN label TEXT",
        "ALTER TABLE datasets ADD COLUMN comment TEXT",
        "ALTER TABLE datasets ADD COLUMN added TEXT",
        "ALTER TABLE datasets ADD COLUMN origin TEXT",
        "ALTER TABLE datasets ADD COLUMN deleted TEXT",
        "ALTER TABLE datasets ADD COLUMN kept_deleted TEXT",
        """CREATE TABLE evaluations (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            model_id INTEGER NOT NULL REFERENCES models(id) ON DELETE CASCADE,
            tracks TEXT NOT NULL,
            laps INTEGER NOT NULL,
            created TEXT NOT NULL,
            overall TEXT NOT NULL DEFAULT '{}',
            per_track TEXT NOT NULL DEFAULT '[]',
            settings TEXT NOT NULL DEFAULT '{}',
            picture BLOB
        )""",
        "CREATE INDEX evaluations_model ON evaluations(model_id)",
    ),
}

DATASET_ORIGINS = ("found", "registered", "created", "udacity")


class RegistryError(VehicleError):
    """A model is not in the registry, or the registry file is not a model registry."""


@dataclass(frozen=True)
class DatasetEntry:
    """One dataset (tub folder) the console manages."""

    id: int
    path: Path
    label: str | None = None
    comment: str | None = None
    added: str | None = None
    origin: str | None = None
    deleted: str | None = None
    kept_deleted: tuple[int, ...] = ()

    @property
    def name(self) -> str:
        """The folder name."""
        return self.path.name

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly view."""
        return {"id": self.id, "name": self.name, "path": str(self.path), "label": self.label,
                "comment": self.comment, "added": self.added, "origin": self.origin,
                "deleted": self.deleted, "exists": self.path.is_dir()}


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


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def check_model_name(name: str) -> str:
    """A model name as a file stem: letters, digits, ``.``, ``_``, ``-``; ValueError otherwise.

    A trailing ``.pt`` is dropped (``pilot.pt`` names the model ``pilot``).
    """
    name = (name or "").strip()
    if name.endswith(".pt"):
        name = name[:-3]
    if not name:
        raise ValueError("must not be empty: the name is the model's file name")
    if len(name) > 100 or not _NAME_RE.match(name):
        raise ValueError(f"{name!r} must be letters, digits, '.', '_' or '-' (at most 100, starting with a "
                         "letter or digit): it becomes the file name")
    return name


@dataclass(frozen=True)
class ModelEntry:
    """One registered model."""

    name: str
    path: Path  # absolute
    type: str
    datasets: tuple[str, ...] = ()
    parameters: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    comment: str | None = None
    transfer: str | None = None
    created: str = ""
    id: int | None = None

    @property
    def exists(self) -> bool:
        """Whether the model file is still on disk."""
        return self.path.is_file()

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly view (paths as strings)."""
        return {"name": self.name, "path": str(self.path), "type": self.type,
                "datasets": list(self.datasets), "parameters": self.parameters,
                "metrics": self.metrics, "comment": self.comment, "transfer": self.transfer,
                "created": self.created, "exists": self.exists}


def _json(value: Mapping[str, Any] | None, what: str) -> str:
    try:
        return json.dumps(dict(value or {}), sort_keys=True, default=str)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"register: {what} must be a JSON-like mapping: {exc}") from exc


class ModelRegistry:
    """The models database at ``db_path`` (created on first write).

    >>> reg = ModelRegistry("models/models.sqlite3")          # doctest: +SKIP
    >>> reg.register("models/pilot.pt", model_type="linear")   # doctest: +SKIP
    """

    def __init__(self, db_path: str | Path) -> None:
        self.db_path = Path(db_path).resolve()
        self.root = self.db_path.parent

    @classmethod
    def for_models_dir(cls, models_dir: str | Path) -> ModelRegistry:
        """The registry of a car's models folder (``MODELS_PATH``)."""
        return cls(Path(models_dir) / DB_FILENAME)

    # -- connection ---------------------------------------------------------------------------
    @contextmanager
    def _connect(self, write: bool = False) -> Iterator[sqlite3.Connection]:
        if not write and not self.db_path.is_file():
            # Reading an absent registry: behave as an empty one without creating files.
            conn = sqlite3.connect(":memory:")
        else:
            self.db_path.parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.db_path, timeout=10.0)  # 10 s: another process may write
        try:
            conn.execute("PRAGMA foreign_keys = ON")
            try:
                self._migrate(conn)
            except sqlite3.DatabaseError as exc:
                raise RegistryError(f"{self.db_path} is not a model registry ({exc}); move it away and "
                                    "train again to start a new one") from exc
            with conn:  # one transaction per call, committed on success
                yield conn
        finally:
            conn.close()

    def _migrate(self, conn: sqlite3.Connection) -> None:
        """Create the tables or bring an older file up to :data:`SCHEMA_VERSION`, atomically (another
        process may open the same file at the same moment: the version is re-read under the lock)."""
        if conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION:
            return
        conn.isolation_level = None  # explicit transaction: DDL and the version change commit together
        try:
            conn.execute("BEGIN IMMEDIATE")
            try:
                fresh = conn.execute("SELECT count(*) FROM sqlite_master WHERE name = 'models'").fetchone()[0] == 0
                for statement in _SCHEMA.split(";"):
                    if statement.strip():
                        conn.execute(statement)
                version = conn.execute("PRAGMA user_version").fetchone()[0]
                if version > SCHEMA_VERSION:
                    raise RegistryError(f"{self.db_path} was written by a newer version (schema {version}); "
                                        "upgrade the package")
                version = max(version, 1)  # files of version 1 were created with user_version 1
                for target in range(version + 1, SCHEMA_VERSION + 1):
                    for statement in MIGRATIONS[target]:
                        conn.execute(statement)
                    if not fresh:
                        logger.info("%s: registry upgraded to schema %d", self.db_path, target)
                conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
        finally:
            conn.isolation_level = ""

    def _stored_path(self, path: Path) -> str:
        path = path.resolve()
        try:
            return path.relative_to(self.root).as_posix()
        except ValueError:
            return str(path)

    def _entry(self, conn: sqlite3.Connection, row: sqlite3.Row | tuple[Any, ...]) -> ModelEntry:
        mid, name, path, mtype, params, metrics, comment, transfer, created = row
        datasets = tuple(r[0] for r in conn.execute(
            "SELECT d.path FROM datasets d JOIN model_datasets md ON md.dataset_id = d.id "
            "WHERE md.model_id = ? ORDER BY d.path", (mid,)))
        stored = Path(path)
        return ModelEntry(name=name, path=stored if stored.is_absolute() else self.root / stored,
                          type=mtype, datasets=datasets, parameters=json.loads(params),
                          metrics=json.loads(metrics), comment=comment, transfer=transfer,
                          created=created, id=mid)

    _COLUMNS = "id, name, path, type, parameters, metrics, comment, transfer, created"

    # -- API ----------------------------------------------------------------------------------
    def register(self, model_path: str | Path, *, model_type: str, datasets: Sequence[str | Path] = (),
                 parameters: Mapping[str, Any] | None = None, metrics: Mapping[str, Any] | None = None,
                 comment: str | None = None, transfer: str | Path | None = None,
                 name: str | None = None, created: datetime | None = None) -> ModelEntry:
        """Add (or replace) the entry of the model file ``model_path``; returns the stored entry.

        Args:
            model_path: the model file (need not exist yet, e.g. registered just before saving).
            model_type: registry name of the architecture ("linear", "pilotnet", ...).
            datasets: the tubs / data folders it was trained on.
            parameters: training parameters (learning rate, epochs, augmentations ...).
            metrics: results (best validation loss, epochs run ...).
            comment: free text; kept from the previous entry when None on re-registration.
            transfer: the model it was fine-tuned from, if any.
            name: entry name; default the file name without its extension.
        """
        model_path = Path(model_path)
        if not isinstance(model_type, str) or not model_type:
            raise ValueError(f"register: model_type must be a non-empty string, got {model_type!r}")
        name = name or model_path.stem
        if not name:
            raise ValueError(f"register: cannot derive a name from {model_path!s}; pass name=")
        when = (created or datetime.now(UTC)).astimezone(UTC).isoformat(timespec="seconds")
        params_json, metrics_json = _json(parameters, "parameters"), _json(metrics, "metrics")
        dataset_paths = sorted({str(Path(d).resolve()) for d in datasets})
        with self._connect(write=True) as conn:
            old = conn.execute("SELECT id, comment FROM models WHERE name = ?", (name,)).fetchone()
            if old is not None:
                if comment is None:
                    comment = old[1]
                conn.execute("DELETE FROM models WHERE id = ?", (old[0],))
            cur = conn.execute(
                "INSERT INTO models (name, path, type, parameters, metrics, comment, transfer, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (name, self._stored_path(model_path), model_type, params_json, metrics_json, comment,
                 None if transfer is None else str(transfer), when))
            mid = cur.lastrowid
            for dpath in dataset_paths:
                conn.execute("INSERT OR IGNORE INTO datasets (path) VALUES (?)", (dpath,))
                conn.execute("INSERT INTO model_datasets (model_id, dataset_id) "
                             "SELECT ?, id FROM datasets WHERE path = ?", (mid, dpath))
            row = conn.execute(f"SELECT {self._COLUMNS} FROM models WHERE id = ?", (mid,)).fetchone()
            entry = self._entry(conn, row)
        logger.info("registered model %s (%s) in %s", name, model_type, self.db_path)
        return entry

    def list(self) -> list[ModelEntry]:
        """Every entry, oldest first."""
        with self._connect() as conn:
            rows = conn.execute(f"SELECT {self._COLUMNS} FROM models ORDER BY created, id").fetchall()
            return [self._entry(conn, row) for row in rows]

    def names(self) -> list[str]:
        """Entry names, oldest first."""
        return [e.name for e in self.list()]

    def get(self, name_or_path: str | Path) -> ModelEntry:
        """The entry named ``name_or_path`` (a name, ``NAME.pt`` or the model's path).

        Raises:
            RegistryError: no such entry; the message lists the closest names.
        """
        key = str(name_or_path)
        with self._connect() as conn:
            rows = conn.execute(f"SELECT {self._COLUMNS} FROM models").fetchall()
            entries = [self._entry(conn, row) for row in rows]
        for entry in entries:
            if key in (entry.name, entry.path.name):
                return entry
        resolved = Path(key).resolve()
        for entry in entries:
            if entry.path.resolve() == resolved:
                return entry
        names = [e.name for e in entries]
        close = difflib.get_close_matches(Path(key).stem, names, n=3)
        hint = f" Did you mean {', '.join(close)}?" if close else (
            f" Registered: {', '.join(names)}." if names else " The registry is empty: train a model first.")
        raise RegistryError(f"no model {key!r} in {self.db_path}.{hint}")

    def set_comment(self, name: str, comment: str | None) -> ModelEntry:
        """Replace the comment of an entry (None or "" clears it)."""
        entry = self.get(name)
        with self._connect(write=True) as conn:
            conn.execute("UPDATE models SET comment = ? WHERE id = ?", (comment or None, entry.id))
        return self.get(entry.name)

    def remove(self, name: str, delete_files: bool = False) -> list[Path]:
        """Remove an entry; with ``delete_files`` also the model file and its exports/plots.

        Returns the files deleted.
        """
        entry = self.get(name)
        deleted: list[Path] = []
        with self._connect(write=True) as conn:
            conn.execute("DELETE FROM models WHERE id = ?", (entry.id,))
            conn.execute("DELETE FROM datasets WHERE origin IS NULL AND id NOT IN "
                         "(SELECT dataset_id FROM model_datasets)")
        if delete_files:
            sidecars = (entry.path.with_name(entry.path.stem + s) for s in SIDECAR_SUFFIXES)
            for path in (entry.path, *sidecars):
                if path.is_file():
                    path.unlink()
                    deleted.append(path)
        logger.info("removed model %s from %s (%d files deleted)", entry.name, self.db_path, len(deleted))
        return deleted

    def rename(self, name: str, new_name: str, move_files: bool = True) -> ModelEntry:
        """Rename an entry and (``move_files``) its model file and side files to ``NEW_NAME.pt``...

        Raises:
            ValueError: ``new_name`` is not a usable file name.
            RegistryError: no such entry, the name is taken, or a target file exists.
        """
        entry = self.get(name)
        try:
            new_name = check_model_name(new_name)
        except ValueError as exc:
            raise RegistryError(f"new name {exc}") from exc
        if new_name == entry.name:
            return entry
        if new_name in self.names():
            raise RegistryError(f"a model named {new_name!r} is already registered; pick another name")
        moves: list[tuple[Path, Path]] = []
        if move_files:
            suffixes = (".pt", *SIDECAR_SUFFIXES) if entry.path.suffix == ".pt" else ("",)
            stem = entry.path.name[:-3] if entry.path.suffix == ".pt" else entry.path.name
            for suffix in suffixes:
                src = entry.path.with_name(stem + suffix) if suffix else entry.path
                dst = entry.path.with_name(new_name + (suffix or entry.path.suffix))
                if src.exists():
                    if dst.exists():
                        raise RegistryError(f"cannot rename {entry.name} to {new_name}: {dst} exists")
                    moves.append((src, dst))
        new_path = entry.path.with_name(new_name + entry.path.suffix) if move_files else entry.path
        done: list[tuple[Path, Path]] = []
        try:
            for src, dst in moves:
                src.rename(dst)
                done.append((src, dst))
            with self._connect(write=True) as conn:
                conn.execute("UPDATE models SET name = ?, path = ? WHERE id = ?",
                             (new_name, self._stored_path(new_path), entry.id))
        except BaseException:
            for src, dst in reversed(done):  # put the files back: registry and disk stay in step
                dst.rename(src)
            raise
        logger.info("renamed model %s to %s", entry.name, new_name)
        return self.get(new_name)

    # -- datasets -----------------------------------------------------------------------------
    _DCOLUMNS = "id, path, label, comment, added, origin, deleted, kept_deleted"

    @staticmethod
    def _dataset(row: tuple[Any, ...]) -> DatasetEntry:
        did, path, label, comment, added, origin, deleted, kept = row
        return DatasetEntry(did, Path(path), label, comment, added, origin, deleted,
                            tuple(json.loads(kept)) if kept else ())

    def datasets(self, include_deleted: bool = True) -> list[DatasetEntry]:
        """The datasets the console manages (not the bare training references), oldest first."""
        where = "origin IS NOT NULL" + ("" if include_deleted else " AND deleted IS NULL")
        with self._connect() as conn:
            rows = conn.execute(f"SELECT {self._DCOLUMNS} FROM datasets WHERE {where} ORDER BY id").fetchall()
        return [self._dataset(r) for r in rows]

    def dataset(self, dataset_id: int) -> DatasetEntry:
        """The dataset with this id (RegistryError if none)."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {self._DCOLUMNS} FROM datasets WHERE id = ? AND origin IS NOT NULL",
                               (int(dataset_id),)).fetchone()
        if row is None:
            raise RegistryError(f"no dataset {dataset_id} in {self.db_path}")
        return self._dataset(row)

    def add_dataset(self, path: str | Path, origin: str, label: str | None = None,
                    comment: str | None = None) -> DatasetEntry:
        """Start managing the folder ``path`` (or return its entry when it is managed already; a
        bare training reference to the same folder becomes managed)."""
        if origin not in DATASET_ORIGINS:
            raise ValueError(f"origin must be one of {DATASET_ORIGINS}, got {origin!r}")
        key = str(Path(path).resolve())
        with self._connect(write=True) as conn:
            row = conn.execute("SELECT id, origin FROM datasets WHERE path = ?", (key,)).fetchone()
            if row is None:
                conn.execute("INSERT INTO datasets (path, label, comment, added, origin) VALUES (?, ?, ?, ?, ?)",
                             (key, label, comment, _now(), origin))
            elif row[1] is None:
                conn.execute("UPDATE datasets SET origin = ?, added = ?, label = ?, comment = ? WHERE id = ?",
                             (origin, _now(), label, comment, row[0]))
            did = conn.execute("SELECT id FROM datasets WHERE path = ?", (key,)).fetchone()[0]
        return self.dataset(did)

    def update_dataset(self, dataset_id: int, **fields: Any) -> DatasetEntry:
        """Change ``path``, ``label``, ``comment``, ``deleted`` or ``kept_deleted`` of a dataset."""
        allowed = {"path", "label", "comment", "deleted", "kept_deleted"}
        unknown = set(fields) - allowed
        if unknown:
            raise ValueError(f"update_dataset: unknown fields {sorted(unknown)}")
        entry = self.dataset(dataset_id)
        values = dict(fields)
        if "path" in values:
            values["path"] = str(Path(values["path"]).resolve())
        if "kept_deleted" in values:
            values["kept_deleted"] = json.dumps(sorted(int(i) for i in values["kept_deleted"] or ()))
        if values:
            sets = ", ".join(f"{k} = ?" for k in values)
            try:
                with self._connect(write=True) as conn:
                    conn.execute(f"UPDATE datasets SET {sets} WHERE id = ?", (*values.values(), entry.id))
            except sqlite3.IntegrityError as exc:
                raise RegistryError(f"another dataset already uses {values.get('path')}") from exc
        return self.dataset(entry.id)

    def forget_dataset(self, dataset_id: int) -> None:
        """Stop managing a dataset (its folder is left alone; models keep their reference)."""
        entry = self.dataset(dataset_id)
        with self._connect(write=True) as conn:
            conn.execute("UPDATE datasets SET origin = NULL, label = NULL, comment = NULL, deleted = NULL, "
                         "kept_deleted = NULL WHERE id = ?", (entry.id,))
            conn.execute("DELETE FROM datasets WHERE id = ? AND id NOT IN (SELECT dataset_id FROM model_datasets)",
                         (entry.id,))

    def models_of_dataset(self, dataset_id: int) -> list[str]:
        """Names of the models trained on this dataset."""
        with self._connect() as conn:
            return [r[0] for r in conn.execute(
                "SELECT m.name FROM models m JOIN model_datasets md ON md.model_id = m.id "
                "WHERE md.dataset_id = ? ORDER BY m.created", (int(dataset_id),))]

    # -- evaluations --------------------------------------------------------------------------
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
        """One evaluation by id (RegistryError if none)."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {self._ECOLUMNS} FROM evaluations e JOIN models m ON m.id = e.model_id "
                               "WHERE e.id = ?", (int(evaluation_id),)).fetchone()
        if row is None:
            raise RegistryError(f"no evaluation {evaluation_id} in {self.db_path}")
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
            raise RegistryError(f"no evaluation {evaluation_id} in {self.db_path}")
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


def register_model(model_path: str | Path, meta: Mapping[str, Any] | None = None, *,
                   db_path: str | Path | None = None, comment: str | None = None,
                   **fields: Any) -> ModelEntry:
    """Register a model file written by training; the call training makes after saving.

    Fields are read from the model file's metadata ``meta`` (keys ``type`` or ``model.type``, ``datasets``,
    ``training`` or ``parameters``, ``metrics``, ``transfer``, ``comment``) and may be given or
    overridden as keywords of :meth:`ModelRegistry.register` (``model_type=``, ``datasets=`` ...).

    Args:
        model_path: the saved model file.
        meta: the metadata saved in the model file.
        db_path: the registry; default ``models.sqlite3`` next to the model file.
    """
    meta = dict(meta or {})
    values: dict[str, Any] = {
        "model_type": meta.get("type") or meta.get("model_type") or (meta.get("model") or {}).get("type"),
        "datasets": meta.get("datasets") or (),
        "parameters": meta.get("training") or meta.get("parameters") or {},
        "metrics": meta.get("metrics") or {},
        "transfer": meta.get("transfer"),
        "comment": comment if comment is not None else meta.get("comment"),
    }
    values.update(fields)
    if not values["model_type"]:
        raise ValueError("register_model: the model type is unknown: pass model_type= or meta['type']")
    registry = ModelRegistry(db_path) if db_path is not None else \
        ModelRegistry.for_models_dir(Path(model_path).resolve().parent)
    return registry.register(model_path, **values)
