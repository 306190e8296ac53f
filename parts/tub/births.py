"""How a tub and its catalogs come into being, so that a kill at any instant leaves each whole or
absent, and what repair does with what a kill at birth left (issue 27).

- A new tub is built in a hidden folder beside it (``.NAME.partial-PID``: manifest.json, the first
  catalog and its ``.catalog_manifest``, ``images/``) and renamed into place: a kill leaves no tub
  or a complete one; the hidden folders of killed runs are removed by the next creation in the
  same folder (:func:`parts.tub.format.remove_stale_partials`).
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

from parts.tub.format import CATALOG_RE, IMAGES, fsync_dir, remove_stale_partials

logger = logging.getLogger(__name__)

#: what a folder killed at birth by an older version may hold besides an empty images/
_STILLBORN_FILES = frozenset({"catalog_0.catalog", "catalog_0.catalog_manifest", ".catalog_0.catalog_manifest.tmp",
                              ".manifest.json.tmp"})


def absent_or_empty(path: Path) -> bool:
    """Whether ``path`` does not exist or is an empty folder (a tub may be created there)."""
    if not path.exists():
        return True
    return path.is_dir() and not any(path.iterdir())


def create_whole(path: Path, build: Callable[[Path], None], durable: bool = True) -> None:
    """Create the folder ``path`` (absent or empty) all at once: ``build(tmp)`` fills a hidden
    folder beside it, which is then renamed to ``path``. A kill leaves ``path`` as it was.

    Where that cannot be done (``path`` is an empty mount point, such as a USB stick's root, or its
    parent is read-only) the folder is built in place, as before."""
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(path.parent)
    tmp = path.parent / f".{path.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir()
    except OSError:  # a read-only parent
        build(path)
        return
    try:
        build(tmp)
        if durable:
            fsync_dir(tmp)
        if os.name == "nt" and path.is_dir():
            path.rmdir()  # Windows renames onto no folder, even an empty one
        try:
            os.replace(tmp, path)  # POSIX: replaces an empty folder atomically
        except OSError as exc:  # EBUSY (a mount point), EXDEV
            logger.debug("%s: built in place (%s)", path, exc)
            shutil.rmtree(tmp, ignore_errors=True)
            build(path)
            return
        if durable:
            fsync_dir(path.parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


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
