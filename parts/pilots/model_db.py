"""The car's registry of trained models: an SQLite database next to the models.

Track Driver AI's "model manager" on the command line (``vehicle models``). Training registers
each model it writes; the registry keeps what the file name does not say: the model type, the
datasets (tubs) it was trained on, the training parameters, the metrics and a free comment.

Schema (normalised as in Track Driver AI's database, but many-to-many because a model trains on several tubs)::

    models(id, name UNIQUE, path, type, parameters JSON, metrics JSON, comment, transfer, created)
    datasets(id, path UNIQUE)
    model_datasets(model_id -> models.id, dataset_id -> datasets.id)

``path`` is stored relative to the database's folder when the model lies inside it, so a car
folder can be moved or copied. ``created`` is ISO 8601 UTC. Re-registering a name (retraining to
the same file) replaces its entry.
"""

from __future__ import annotations

import difflib
import json
import logging
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

DB_FILENAME = "models.sqlite3"
SCHEMA_VERSION = 1
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


class RegistryError(VehicleError):
    """A model is not in the registry, or the registry file is not a model registry."""


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
                conn.executescript(_SCHEMA)
                version = conn.execute("PRAGMA user_version").fetchone()[0]
            except sqlite3.DatabaseError as exc:
                raise RegistryError(f"{self.db_path} is not a model registry ({exc}); move it away and "
                                    "train again to start a new one") from exc
            if version == 0:
                conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            elif version > SCHEMA_VERSION:
                raise RegistryError(f"{self.db_path} was written by a newer version (schema {version}); "
                                    "upgrade the package")
            with conn:  # one transaction per call, committed on success
                yield conn
        finally:
            conn.close()

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
            conn.execute("DELETE FROM datasets WHERE id NOT IN (SELECT dataset_id FROM model_datasets)")
        if delete_files:
            sidecars = (entry.path.with_name(entry.path.stem + s) for s in SIDECAR_SUFFIXES)
            for path in (entry.path, *sidecars):
                if path.is_file():
                    path.unlink()
                    deleted.append(path)
        logger.info("removed model %s from %s (%d files deleted)", entry.name, self.db_path, len(deleted))
        return deleted


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
