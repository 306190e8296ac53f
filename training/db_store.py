"""The car's database of trained models, datasets and evaluations (one SQLite file per car): the
connection, the schema and its migrations. What it stores is in :mod:`training.model_db` (models),
:mod:`training.dataset_db` and :mod:`training.evaluation_db`.

Track Driver AI's "model manager" on the command line (``vehicle models``) and the database of the
trainer console (``vehicle console``): both read and write this one file, so a change in either
shows in the other. Training registers each model it writes; the db keeps what the file
name does not say: the model type, the datasets (tubs) it was trained on, the training parameters,
the metrics, a free comment and the closed-loop evaluations in the simulator.

Schema (normalised as in Track Driver AI's database, but many-to-many because a model trains on several tubs)::

    models(id, name UNIQUE, path, type, parameters JSON, metrics JSON, comment, transfer, created, sha256)
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

``sha256`` is the hex SHA-256 of the model file's bytes when it was registered (NULL when the file
did not exist yet, or for entries of schema 2 and older): a registered file that no longer has it
is refused before it drives (:meth:`training.model_db.ModelDB.check_file`): its zip CRC-32s only
catch damage, not another intact model put under the same name.

The schema version is SQLite's ``user_version``; :data:`MIGRATIONS` upgrades older files in place
(version 1 had no dataset details and no evaluations, version 2 no model hashes).
"""

from __future__ import annotations

import json
import logging
import sqlite3
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

DB_FILENAME = "models.sqlite3"
SCHEMA_VERSION = 3
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
    # existing entries keep NULL: hashing their files now would vouch for whatever lies there today
    3: ("ALTER TABLE models ADD COLUMN sha256 TEXT",),
}


class ModelDBError(VehicleError):
    """A model is not in the db, or the db file is not a model db."""


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")




def _json(value: Mapping[str, Any] | None, what: str) -> str:
    try:
        return json.dumps(dict(value or {}), sort_keys=True, default=str)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"register: {what} must be a JSON-like mapping: {exc}") from exc


class Store:
    """The car's database file at ``db_path`` (created on first write): the connection, the schema
    and its migrations, shared by the models, datasets and evaluations stored in it."""

    def __init__(self, db_path: str | Path) -> None:
        self.db_path = Path(db_path).resolve()
        self.root = self.db_path.parent

    @classmethod
    def for_models_dir(cls, models_dir: str | Path) -> Self:
        """The database of a car's models folder (``MODELS_PATH``)."""
        return cls(Path(models_dir) / DB_FILENAME)

    # -- connection ---------------------------------------------------------------------------
    @contextmanager
    def _connect(self, write: bool = False) -> Iterator[sqlite3.Connection]:
        if not write and not self.db_path.is_file():
            # Reading an absent db: behave as an empty one without creating files.
            conn = sqlite3.connect(":memory:")
        else:
            self.db_path.parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.db_path, timeout=10.0)  # 10 s: another process may write
        try:
            conn.execute("PRAGMA foreign_keys = ON")
            try:
                self._migrate(conn)
            except sqlite3.DatabaseError as exc:
                raise ModelDBError(f"{self.db_path} is not a model database ({exc}); move it away and "
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
                    raise ModelDBError(f"{self.db_path} was written by a newer version (schema {version}); "
                                        "upgrade the package")
                version = max(version, 1)  # files of version 1 were created with user_version 1
                for target in range(version + 1, SCHEMA_VERSION + 1):
                    for statement in MIGRATIONS[target]:
                        conn.execute(statement)
                    if not fresh:
                        logger.info("%s: db upgraded to schema %d", self.db_path, target)
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
