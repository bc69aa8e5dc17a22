"""Verify (and repair) an FS map database: ``graspsim db check [--repair]``.

Every record of the index is checked against its file: present, readable, a valid
map (:func:`~graspsim.maps.validate.map_problems`) and consistent with the record
(primitive, dimensions, grasp counts). Map files no record lists and temporary files
left by killed writers are found too; files younger than ``stale_after`` seconds are
left alone (a build may be writing them).

Repair makes the index match the valid files: a record whose file is a valid map is
rewritten from the file; a record whose file is missing, unreadable or invalid is
removed with its file; valid unlisted maps are indexed, invalid ones deleted; stale
temporary files are deleted; a damaged index is rebuilt from the valid files.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

from graspsim.errors import GraspsimError, MapDatabaseError
from graspsim.maps.database import MapDatabase, index_record
from graspsim.maps.io import load_map
from graspsim.maps.validate import map_problems

__all__ = ["DatabaseReport", "check_database"]

log = logging.getLogger(__name__)

_RECORD_FIELDS = ("key", "primitive", "dims", "file", "grasps", "accepted")


@dataclass(frozen=True)
class DatabaseReport:
    """root; maps: index records checked; valid: records whose file is a valid,
    consistent map; problems: (file, problem) pairs; removed: files deleted and
    reindexed: files (re)indexed by the repair; repaired: whether --repair ran and
    fixed every problem."""

    root: str
    maps: int
    valid: int
    problems: tuple[tuple[str, str], ...]
    removed: tuple[str, ...] = ()
    reindexed: tuple[str, ...] = ()
    repaired: bool = False

    @property
    def ok(self) -> bool:
        """Nothing wrong, or everything wrong was repaired."""
        return not self.problems or self.repaired

    def to_dict(self) -> dict:
        return {"root": self.root, "maps": self.maps, "valid": self.valid, "ok": self.ok,
                "problems": [{"file": f, "problem": p} for f, p in self.problems],
                "removed": list(self.removed), "reindexed": list(self.reindexed),
                "repaired": self.repaired}


def _read(path: Path):
    """(map, None) or (None, why the file is not a usable map)."""
    try:
        gmap = load_map(path)
    except (GraspsimError, OSError, ValueError, KeyError, TypeError) as err:
        return None, f"unreadable: {err}"
    problems = map_problems(gmap)
    return (None, "; ".join(problems)) if problems else (gmap, None)


def _record_problem(rec: dict, gmap) -> str | None:
    """Why the record does not describe the (valid) map in its file, or None."""
    obj = gmap.meta.object
    if rec.get("primitive") != obj.get("primitive") or rec.get("dims") != obj.get("dims"):
        return (f"record says {rec.get('primitive')} {rec.get('dims')}, the file holds "
                f"{obj.get('primitive')} {obj.get('dims')}")
    if rec.get("grasps") != len(gmap) or rec.get("accepted") != int(gmap.accepted.sum()):
        return (f"record counts {rec.get('grasps')} grasps / {rec.get('accepted')} accepted, the file "
                f"{len(gmap)} / {int(gmap.accepted.sum())}")
    if Path(rec["file"]).stem != rec.get("key"):
        return f"record key {rec.get('key')!r} does not name its file"
    return None


def _file_of(root: Path, rec: dict) -> Path | None:
    """The record's map file, if it names one inside the database folder (a loop of
    symbolic links: the link itself, which the check then finds unreadable)."""
    try:
        name = root / rec["file"]
        try:
            path = name.resolve()
        except (RuntimeError, OSError):  # a loop of symbolic links (RuntimeError before Python 3.13)
            path = name.parent.resolve() / name.name
        path.relative_to(root.resolve())
    except (KeyError, TypeError, ValueError, OSError, RuntimeError):
        return None
    return path


def _unreadable(path: Path) -> str | None:
    """Why ``path`` cannot be read as a file at all (a loop of symbolic links, a
    dangling link, a folder), or None."""
    try:
        path.stat()
    except OSError as err:
        return f"not a readable file: {err.strerror or err}"
    return None if path.is_file() else "not a regular file"


def check_database(db: MapDatabase, *, repair: bool = False, stale_after: float = 600.0) -> DatabaseReport:
    """Check every map the index of ``db`` lists (any settings); see the module text."""
    root, now = db.root.resolve(), time.time()
    problems: list[tuple[str, str]] = []
    try:
        records = db.records()
    except MapDatabaseError as err:
        problems.append(("index.json", str(err)))
        records = []
    keep: dict[str, dict] = {}  # file -> the record the repaired index holds
    doomed: set[Path] = set()
    valid = 0
    for rec in records:
        ok = isinstance(rec, dict) and all(k in rec for k in _RECORD_FIELDS)
        path = _file_of(root, rec) if ok else None
        name = str(rec.get("file", "?")) if isinstance(rec, dict) else "?"
        if path is None:
            problems.append((name, f"index record is incomplete or points outside the database: {rec!r}"))
            continue
        rel = str(path.relative_to(root))
        if rel in keep or path in doomed:
            problems.append((name, "listed twice in the index"))
            continue
        if not path.is_file() and not path.is_symlink():
            problems.append((name, "listed in the index but the file is missing"))
            continue
        why = _unreadable(path)
        if why:
            problems.append((name, why))
            doomed.add(path)
            continue
        gmap, why = _read(path)
        if gmap is None:
            problems.append((name, why))
            doomed.add(path)
            continue
        why = _record_problem(rec, gmap)
        if why:
            problems.append((name, why))
            rec = index_record(root, path, gmap, rec.get("seconds"), path.stat().st_mtime)
        else:
            valid += 1
        keep[rel] = rec
    reindexed: list[str] = []
    for path in sorted(root.glob("*/*.h5")):
        rel = str(path.relative_to(root))
        if rel in keep or path in doomed:
            continue
        why = _unreadable(path)
        if why:
            problems.append((rel, f"not listed in the index and {why}"))
            doomed.add(path)
            continue
        if _age(path, now) < stale_after:
            continue
        gmap, why = _read(path)
        problems.append((rel, "not listed in the index" + (f" and invalid: {why}" if why else "")))
        if gmap is None:
            doomed.add(path)
        else:
            keep[rel] = index_record(root, path, gmap, gmap.meta.timing.get("total"), path.stat().st_mtime)
            reindexed.append(rel)
    stale = [p for p in (*root.glob(".*.tmp"), *root.glob("*/.*.tmp")) if _age(p, now) >= stale_after]
    problems += [(str(p.relative_to(root)), "stale temporary file of an interrupted write") for p in stale]
    if not repair or not problems:
        return DatabaseReport(str(db.root), len(records), valid, tuple(problems))
    removed, failed = _remove(root, doomed | set(stale))
    seen = {_identity(r) for r in records}

    def edit(current: list[dict]) -> list[dict]:
        # records a concurrent build added since the check are kept as they are
        fresh = {r.get("file"): r for r in current if isinstance(r, dict) and _identity(r) not in seen}
        return list({**keep, **fresh}.values())

    try:
        db.edit_index(edit, damaged_ok=True)
    except GraspsimError as err:
        failed.append(("index.json", f"could not rewrite: {err}"))
    log.info("database %s repaired: %d files removed, %d reindexed", root, len(removed), len(reindexed))
    return DatabaseReport(str(db.root), len(records), valid, tuple(problems + failed), tuple(removed),
                          tuple(reindexed), repaired=not failed)


def _age(path: Path, now: float) -> float:
    """Seconds since ``path`` was written; -inf if it vanished meanwhile (someone else's)."""
    try:
        return now - path.stat().st_mtime
    except FileNotFoundError:
        return -float("inf")
    except OSError:  # a loop of links: not a fresh write of anyone's
        return float("inf")


def _identity(record) -> str:
    return json.dumps(record, sort_keys=True, default=str)


def _remove(root: Path, paths: set[Path]) -> tuple[list[str], list[tuple[str, str]]]:
    removed, failed = [], []
    for path in sorted(paths):
        rel = str(path.relative_to(root))
        try:
            path.unlink(missing_ok=True)
            removed.append(rel)
        except OSError as err:
            failed.append((rel, f"could not remove: {err}"))
    return removed, failed
