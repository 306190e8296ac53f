"""The car's model manager: the trained models in its database, with the datasets they were trained
on, their parameters, metrics and comments (:class:`ModelDB`, which also holds the car's datasets
and evaluations: :mod:`training.dataset_db`, :mod:`training.evaluation_db`).

Track Driver AI's "model manager" on the command line (``vehicle models``) and the database of the
trainer console (``vehicle console``): both read and write one file, so a change in either shows
in the other. Training registers each model it writes. The schema and its migrations are in
:mod:`training.db_store`.
"""

from __future__ import annotations

import difflib
import json
import logging
import re
import sqlite3
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from parts.pilots.export_files import file_sha256
from training.dataset_db import DatasetEntry, DatasetTable
from training.db_store import DB_FILENAME, ModelDBError, Store, _json
from training.evaluation_db import Evaluation, EvaluationTable

logger = logging.getLogger(__name__)

__all__ = ["DB_FILENAME", "DatasetEntry", "Evaluation", "ModelChanged", "ModelDB", "ModelDBError", "ModelEntry",
           "check_model_name", "check_registered", "register_model"]

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
# Files that training or export write next to a model and that `remove(delete_files=True)` removes.
SIDECAR_SUFFIXES: tuple[str, ...] = (".onnx", ".int8.onnx", ".ts", ".loss.png", ".metrics.json")


class ModelChanged(ModelDBError):
    """A registered model file's bytes are not those it had when it was registered."""


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
    sha256: str | None = None  # of the file when registered; None: unknown (not written yet, or an old entry)

    @property
    def exists(self) -> bool:
        """Whether the model file is still on disk."""
        return self.path.is_file()

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly view (paths as strings)."""
        return {"name": self.name, "path": str(self.path), "type": self.type,
                "datasets": list(self.datasets), "parameters": self.parameters,
                "metrics": self.metrics, "comment": self.comment, "transfer": self.transfer,
                "created": self.created, "exists": self.exists, "sha256": self.sha256}


class ModelDB(EvaluationTable, DatasetTable, Store):
    """The models database at ``db_path`` (created on first write).

    >>> db = ModelDB("models/models.sqlite3")                 # doctest: +SKIP
    >>> db.register("models/pilot.pt", model_type="linear")   # doctest: +SKIP
    """

    def _entry(self, conn: sqlite3.Connection, row: sqlite3.Row | tuple[Any, ...]) -> ModelEntry:
        mid, name, path, mtype, params, metrics, comment, transfer, created, sha256 = row
        datasets = tuple(r[0] for r in conn.execute(
            "SELECT d.path FROM datasets d JOIN model_datasets md ON md.dataset_id = d.id "
            "WHERE md.model_id = ? ORDER BY d.path", (mid,)))
        stored = Path(path)
        return ModelEntry(name=name, path=stored if stored.is_absolute() else self.root / stored,
                          type=mtype, datasets=datasets, parameters=json.loads(params),
                          metrics=json.loads(metrics), comment=comment, transfer=transfer,
                          created=created, id=mid, sha256=sha256)

    _COLUMNS = "id, name, path, type, parameters, metrics, comment, transfer, created, sha256"

    def register(self, model_path: str | Path, *, model_type: str, datasets: Sequence[str | Path] = (),
                 parameters: Mapping[str, Any] | None = None, metrics: Mapping[str, Any] | None = None,
                 comment: str | None = None, transfer: str | Path | None = None,
                 name: str | None = None, created: datetime | None = None) -> ModelEntry:
        """Add (or replace) the entry of the model file ``model_path``; returns the stored entry.

        Args:
            model_path: the model file (need not exist yet, e.g. registered just before saving).
            model_type: type name of the architecture ("linear", "pilotnet", ...).
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
        digest = file_sha256(model_path) if model_path.is_file() else None  # what check_file compares
        with self._connect(write=True) as conn:
            old = conn.execute("SELECT id, comment FROM models WHERE name = ?", (name,)).fetchone()
            if old is not None:
                if comment is None:
                    comment = old[1]
                conn.execute("DELETE FROM models WHERE id = ?", (old[0],))
            cur = conn.execute(
                "INSERT INTO models (name, path, type, parameters, metrics, comment, transfer, created, sha256) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (name, self._stored_path(model_path), model_type, params_json, metrics_json, comment,
                 None if transfer is None else str(transfer), when, digest))
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
            ModelDBError: no such entry; the message lists the closest names.
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
            f" Registered: {', '.join(names)}." if names else " The model database is empty: train a model first.")
        raise ModelDBError(f"no model {key!r} in {self.db_path}.{hint}")

    def entry_for_file(self, path: str | Path) -> ModelEntry | None:
        """The entry whose model file is ``path`` (the same file, not just the same name), or None."""
        resolved = Path(path).resolve()
        return next((e for e in self.list() if e.path.resolve() == resolved), None)

    def check_file(self, path: str | Path, digest: str | None = None) -> ModelEntry | None:
        """The entry of the model file ``path`` (None: not registered here), after checking that the
        file still has the bytes it was registered with (``digest``: its SHA-256, if already known).

        Raises:
            ModelChanged: the file changed since it was registered (another model under its name,
                or a copy over it); the one-line message says how to accept it or what to redo.
        """
        entry = self.entry_for_file(path)
        if entry is None or entry.sha256 is None:
            return entry
        if (digest or file_sha256(path)) != entry.sha256:
            raise ModelChanged(f"{Path(path).resolve()}: changed since it was registered as model {entry.name!r} "
                               f"in {self.db_path} (its SHA-256 differs: another file was put under its name); "
                               f"retrain it, or accept this file with `vehicle models rehash {entry.name}`")
        return entry

    def rehash(self, name: str) -> ModelEntry:
        """Record the SHA-256 of an entry's file as it is now (the user vouches for it).

        Raises:
            ModelDBError: no such entry, or its file is missing.
        """
        entry = self.get(name)
        if not entry.exists:
            raise ModelDBError(f"model {entry.name}: its file {entry.path} is missing")
        digest = file_sha256(entry.path)
        with self._connect(write=True) as conn:
            conn.execute("UPDATE models SET sha256 = ? WHERE id = ?", (digest, entry.id))
        logger.info("model %s: recorded the SHA-256 of %s", entry.name, entry.path)
        return self.get(entry.name)

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
            ModelDBError: no such entry, the name is taken, or a target file exists.
        """
        entry = self.get(name)
        try:
            new_name = check_model_name(new_name)
        except ValueError as exc:
            raise ModelDBError(f"new name {exc}") from exc
        if new_name == entry.name:
            return entry
        if new_name in self.names():
            raise ModelDBError(f"a model named {new_name!r} is already registered; pick another name")
        moves: list[tuple[Path, Path]] = []
        if move_files:
            suffixes = (".pt", *SIDECAR_SUFFIXES) if entry.path.suffix == ".pt" else ("",)
            stem = entry.path.name[:-3] if entry.path.suffix == ".pt" else entry.path.name
            for suffix in suffixes:
                src = entry.path.with_name(stem + suffix) if suffix else entry.path
                dst = entry.path.with_name(new_name + (suffix or entry.path.suffix))
                if src.exists():
                    if dst.exists():
                        raise ModelDBError(f"cannot rename {entry.name} to {new_name}: {dst} exists")
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
            for src, dst in reversed(done):  # put the files back: db and disk stay in step
                dst.rename(src)
            raise
        logger.info("renamed model %s to %s", entry.name, new_name)
        return self.get(new_name)


def register_model(model_path: str | Path, meta: Mapping[str, Any] | None = None, *,
                   db_path: str | Path | None = None, comment: str | None = None,
                   **fields: Any) -> ModelEntry:
    """Register a model file written by training; the call training makes after saving.

    Fields are read from the model file's metadata ``meta`` (keys ``type`` or ``model.type``, ``datasets``,
    ``training`` or ``parameters``, ``metrics``, ``transfer``, ``comment``) and may be given or
    overridden as keywords of :meth:`ModelDB.register` (``model_type=``, ``datasets=`` ...).

    Args:
        model_path: the saved model file.
        meta: the metadata saved in the model file.
        db_path: the db; default ``models.sqlite3`` next to the model file.
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
    db = ModelDB(db_path) if db_path is not None else \
        ModelDB.for_models_dir(Path(model_path).resolve().parent)
    return db.register(model_path, **values)


def check_registered(path: str | Path, *models_dirs: str | Path) -> None:
    """Refuse a model file that changed since it was registered: in the database next to it (where
    training registers it) or in those of ``models_dirs`` (the car's MODELS_PATH). The file is
    hashed once, and only when an entry has a hash to compare with.

    Raises:
        ModelChanged: the one-line refusal (see :meth:`ModelDB.check_file`).
    """
    path = Path(path)
    if not path.is_file():
        return  # the loader says what is wrong with the path
    dbs = {(Path(d).resolve() / DB_FILENAME) for d in (path.resolve().parent, *models_dirs)}
    digest: str | None = None
    for db_path in sorted(dbs):
        if not db_path.is_file():
            continue
        db = ModelDB(db_path)
        try:
            entry = db.entry_for_file(path)
        except ModelDBError as exc:  # a broken database must not keep the car from driving
            logger.warning("cannot check %s against %s: %s", path, db_path, exc)
            continue
        if entry is not None and entry.sha256 is not None:
            digest = digest or file_sha256(path)
            db.check_file(path, digest)
