"""How a tub and its catalogs come into being, so that a kill at any instant leaves each whole or
absent, and what repair does with what a kill at birth left (issue 27).

- A new tub grows in a hidden folder beside it (``.NAME.partial-PID``: manifest.json, the first
  catalog and its ``.catalog_manifest``, ``images/``) and is renamed into place once its first
  record is durable: a kill leaves no tub or one with records, never one whose catalog is empty
  (DonkeyCar 5.3 cannot open that: its read-only open mmaps the catalog). A tub closed without a
  record leaves nothing. The hidden folders of killed runs are removed by the next creation in
  the same folder (:func:`parts.tub.format.remove_stale_partials`).
- A new catalog (a roll-over every max_len records) is written with its first lines to a hidden
  ``.catalog_N.catalog.new``, then its ``.catalog_manifest``, then manifest.json, which lists it,
  and only then renamed into place. DonkeyCar reads the catalogs manifest.json lists: it never
  reads fewer records than the folder holds without saying so (in the instant between the last
  two steps it finds the listed file missing and says so); the next writable open or ``tub check
  --repair`` completes the rename (:func:`complete_staged`).
- Older versions created the first catalog before manifest.json: a folder killed then holds at
  most an empty ``images/``, an empty ``catalog_0.catalog`` and its (temporary) catalog manifest.
  It held no record; :func:`stillborn` recognises it and ``tub check --repair`` removes it.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Callable
from pathlib import Path

from parts.tub.format import CATALOG_RE, IMAGES, MANIFEST, fsync_dir, remove_stale_partials

logger = logging.getLogger(__name__)

#: what a folder killed at birth by an older version may hold besides an empty images/
_STILLBORN_FILES = frozenset({"catalog_0.catalog", "catalog_0.catalog_manifest", ".catalog_0.catalog_manifest.tmp",
                              ".manifest.json.tmp"})


def absent_or_empty(path: Path) -> bool:
    """Whether ``path`` does not exist or is an empty folder (a tub may be created there)."""
    if not path.exists():
        return True
    return path.is_dir() and not any(path.iterdir())


def start_nursery(path: Path, build: Callable[[Path], None], durable: bool = True) -> Path:
    """Where a new tub for the folder ``path`` (absent or empty) grows until its first record:
    ``build(tmp)`` fills a hidden folder beside it, returned; :func:`put_in_place` later renames it
    to ``path``. A kill before leaves ``path`` as it was (the hidden folder goes with the next
    creation in that folder).

    Where no hidden folder can be made (``path``'s parent is read-only) the tub is built in place,
    as before, and ``path`` is returned."""
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(path.parent)
    tmp = path.parent / f".{path.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir()
    except OSError:  # a read-only parent
        build(path)
        return path
    try:
        build(tmp)
        if durable:
            fsync_dir(tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return tmp


def put_in_place(tmp: Path, path: Path, durable: bool = True) -> None:
    """Rename the nursery ``tmp`` (:func:`start_nursery`), whose records are durable, to ``path``:
    the tub appears whole, with its records.

    Where ``path`` cannot be replaced by a rename (an empty mount point, such as a USB stick's root)
    the files are moved into it one by one, manifest.json last: a kill in between leaves catalogs
    with records that the next writable open or ``tub check --repair`` completes."""
    if os.name == "nt" and path.is_dir():
        path.rmdir()  # Windows renames onto no folder, even an empty one
    try:
        os.replace(tmp, path)  # POSIX: replaces an empty folder atomically
    except OSError as exc:  # EBUSY (a mount point), EXDEV
        logger.debug("%s: moved in file by file (%s)", path, exc)
        path.mkdir(exist_ok=True)
        names = sorted(os.listdir(tmp), key=lambda n: n == MANIFEST)
        for name in names:
            os.replace(tmp / name, path / name)
        if durable:
            fsync_dir(path)
        tmp.rmdir()
    if durable:
        fsync_dir(path.parent)


def staged_catalog(catalog: Path) -> Path:
    """Where a new catalog's first lines wait until manifest.json lists it."""
    return catalog.with_name(f".{catalog.name}.new")


def complete_staged(tub: Path, listed: list[str]) -> list[str]:
    """Put in place the staged catalogs that manifest.json lists (a kill between listing one and
    renaming it); remove those it does not list (a kill before: their records were never
    committed). Returns what was done, for the recovery report."""
    done = []
    try:
        names = [n for n in os.listdir(tub) if n.startswith(".catalog_") and n.endswith(".catalog.new")]
    except OSError:
        return done
    for name in names:
        final = name[1:-len(".new")]
        if not CATALOG_RE.match(final):
            continue
        if final in listed and not (tub / final).exists():
            os.replace(tub / name, tub / final)
            fsync_dir(tub)
            done.append(f"{final} was being put in place when the writer was killed: completed")
        else:
            (tub / name).unlink(missing_ok=True)
    return done


def stillborn(path: Path) -> bool:
    """Whether ``path`` is a tub an older version was killed while creating: no manifest.json, at
    most an empty ``images/``, an empty ``catalog_0.catalog`` and its catalog manifest."""
    try:
        entries = list(os.scandir(path))
    except OSError:
        return False
    for entry in entries:
        if entry.name == IMAGES:
            if not entry.is_dir(follow_symlinks=False) or any(os.scandir(entry.path)):
                return False
        elif entry.name not in _STILLBORN_FILES or not entry.is_file(follow_symlinks=False) \
                or (entry.name == "catalog_0.catalog" and entry.stat().st_size):
            return False
    return True


def remove_stillborn(path: Path) -> None:
    """Remove a :func:`stillborn` tub folder (it holds no record)."""
    if not stillborn(path):
        raise ValueError(f"{path} is not a tub killed at its creation")
    shutil.rmtree(path)
    logger.info("%s: removed a tub killed while it was created (it held no records)", path)


def set_aside(path: Path) -> Path:
    """Rename the tub folder ``path`` to a hidden sibling ``.NAME.empty`` (``-2``, ``-3`` ... when
    taken), which tub readers and DonkeyCar's ``data/*`` skip; returns it. Used for a tub without
    records, which DonkeyCar cannot open; ``mv`` brings it back."""
    aside = path.with_name(f".{path.name}.empty")
    n = 1
    while aside.exists():
        n += 1
        aside = path.with_name(f".{path.name}.empty-{n}")
    os.rename(path, aside)
    fsync_dir(path.parent)
    logger.info("%s: holds no records; moved aside to %s", path, aside)
    return aside
