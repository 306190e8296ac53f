"""The datasets (tubs) the car's database knows: found, registered, created or imported ones, soft
deletes and the models trained on each (:class:`DatasetTable`, part of :class:`training.model_db.ModelDB`)."""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from training.db_store import ModelDBError, Store, _now

DATASET_ORIGINS = ("found", "registered", "created", "udacity")


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


class DatasetTable(Store):
    """The ``datasets`` table of the database."""

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
        """The dataset with this id (ModelDBError if none)."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {self._DCOLUMNS} FROM datasets WHERE id = ? AND origin IS NOT NULL",
                               (int(dataset_id),)).fetchone()
        if row is None:
            raise ModelDBError(f"no dataset {dataset_id} in {self.db_path}")
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
                raise ModelDBError(f"another dataset already uses {values.get('path')}") from exc
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
