"""Atomic file writes: write temporary files beside the targets, fsync, rename.

A crash or a full disk leaves the old file (or none) in place, never half a file. Several
outputs of one command (a map and its plot) are committed together: every temporary is
written first, and only then are they renamed onto their targets.

A temporary is named ``.<target name>.<writer pid>.<random>.tmp<target suffix>`` (the
suffix keeps format-by-extension writers such as matplotlib working). A process killed
with SIGKILL cannot clean up its temporary; the next write to the same target removes
such leftovers when their writer is no longer running or they have not been touched for
:data:`STALE_SECONDS`.

:func:`check_output` and :func:`check_folder` say before any work starts whether an
output can be written (the one check every command uses). :func:`staged_folder` does for a folder of outputs
written while a command runs (per-step figures, saved scenes) what :func:`atomic_paths`
does for files: nothing reaches the folder unless the command succeeds.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from graspsim.errors import MapFileError, OutputPathError

__all__ = ["atomic_path", "atomic_paths", "atomic_write_text", "check_output", "check_folder",
           "staged_folder", "STALE_SECONDS"]

STALE_SECONDS = 3600.0  # a temporary untouched this long is a leftover, whoever wrote it


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _checked_path(path, what: str, error) -> Path:
    text = os.fspath(path)
    if not str(text).strip():
        raise error(f"cannot write {what}: no path given")
    if "\0" in str(text):
        raise error(f"cannot write {what} {text!r}: the path contains a NUL byte")
    return Path(text)


def check_output(path: str | os.PathLike, what: str = "output", error=OutputPathError, *,
                 others: dict[str, str | os.PathLike] | None = None) -> Path:
    """Raise ``error`` unless ``path`` can be written as a file: it is not a directory
    (or other non-file), its folder exists, a file can be created there (tried, not
    guessed from permission bits), and it is none of ``others`` (name -> path: the
    command's inputs and other outputs, which writing it would destroy). Returns
    ``path`` as a Path."""
    path = _checked_path(path, what, error)
    folder = _folder(path)
    try:
        for name, other in (others or {}).items():
            if other is not None and "\0" not in str(other) and os.path.realpath(path) == os.path.realpath(other):
                raise error(f"cannot write {what} {path}: it is also the {name}")
        if path.is_dir():
            raise error(f"cannot write {what} {path}: it is a directory (give a file name)")
        if path.exists() and not path.is_file():
            raise error(f"cannot write {what} {path}: it exists and is not a regular file")
        if not folder.is_dir():
            raise error(f"cannot write {what} {path}: folder {folder} does not exist")
        _new_temp(path).unlink()
    except OSError as err:  # a name too long, a folder we may not enter, ...
        if isinstance(err, error):
            raise
        raise error(f"cannot write {what} {path}: {err.strerror or err}") from err
    return path


def check_folder(path: str | os.PathLike, what: str = "output folder", error=OutputPathError) -> Path:
    """Raise ``error`` unless ``path`` is (or can be created as) a folder files can be
    written into. Nothing is created. Returns ``path`` as a Path."""
    path = _checked_path(path, what, error)
    try:
        if path.exists() and not path.is_dir():
            raise error(f"cannot write {what} {path}: it exists and is not a folder")
        if path.is_symlink() and not path.exists():
            raise error(f"cannot write {what} {path}: it is a broken symbolic link")
        existing = path
        while not existing.exists() and existing != existing.parent:  # the nearest existing
            existing = existing.parent  # ancestor must take new entries
        if not existing.is_dir():
            raise error(f"cannot write {what} {path}: {existing} is not a folder")
        fd, probe = tempfile.mkstemp(prefix=".graspsim-probe.", dir=existing)
    except OSError as err:
        if isinstance(err, error):
            raise
        raise error(f"cannot write {what} {path}: {err.strerror or err}") from err
    os.close(fd)
    os.unlink(probe)
    return path


def _temp_pattern(path: Path) -> re.Pattern:
    """Temporaries of ``path``: ours (``.NAME.PID.RANDOM.tmpSUFFIX``) and those of earlier
    versions (``.NAME.RANDOM.tmp``)."""
    return re.compile(rf"^\.{re.escape(path.name)}\.(?:(\d+)\.)?[a-z0-9_]+\.tmp"
                      rf"(?:{re.escape(path.suffix)})?$")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, but another user's
        return True
    return True


def remove_stale_temps(path: str | os.PathLike, max_age: float = STALE_SECONDS) -> list[Path]:
    """Remove leftover temporaries of ``path`` (see the module docstring); returns them."""
    path = Path(path)
    pat = _temp_pattern(path)
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(_folder(path)))
    except OSError:
        return removed
    for e in entries:
        m = pat.match(e.name)
        if m is None:
            continue
        pid = int(m.group(1)) if m.group(1) else None
        try:
            old = now - e.stat(follow_symlinks=False).st_mtime > max_age
        except OSError:
            continue
        dead = pid is not None and pid != os.getpid() and not _alive(pid)
        if dead or old:
            with contextlib.suppress(OSError):
                os.unlink(e.path)
                removed.append(Path(e.path))
    return removed


def _own_temp(path: Path) -> bool:
    """``path`` is a temporary this process made (``.NAME.<our pid>.RANDOM.tmp...``)."""
    m = re.match(r"^\..+\.(\d+)\.[a-z0-9_]+\.tmp[^/]*$", path.name)
    return m is not None and int(m.group(1)) == os.getpid() and path.is_file()


def _new_temp(path: Path) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp" + path.suffix,
                               dir=_folder(path))
    os.close(fd)
    return Path(tmp)


def _file_mode(path: Path) -> int:
    """The mode the target gets: the existing file's, else 0o666 less the umask (as
    ``open`` would give; mkstemp's own 0o600 would hide maps from other users)."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


@contextlib.contextmanager
def atomic_paths(paths, error=MapFileError) -> Iterator[list[Path]]:
    """Yield temporary paths, one per target of ``paths``, in the targets' folders; when
    the block succeeds they are all renamed onto their targets, otherwise all removed.

    The folders must exist: a missing folder is an error, not silently created.
    """
    paths = [Path(p) for p in paths]
    for p in paths:
        if not _folder(p).is_dir():
            raise error(f"cannot write {p}: folder {_folder(p)} does not exist")
        if p.is_dir():
            raise error(f"cannot write {p}: it is a directory")
    # a target that is already one of this process's temporaries (a writer called inside
    # an enclosing atomic block) is written directly: the enclosing block commits it
    direct = [_own_temp(p) for p in paths]
    tmps: list[Path] = []
    try:
        for p, d in zip(paths, direct):
            if d:
                tmps.append(p)
                continue
            remove_stale_temps(p)
            try:
                tmps.append(_new_temp(p))
            except OSError as err:
                raise error(f"cannot write {p}: {err.strerror or err}") from err
        yield list(tmps)
        todo = [(p, t) for p, t, d in zip(paths, tmps, direct) if not d]
        try:
            for p, t in todo:
                with open(t, "rb+") as f:
                    os.fsync(f.fileno())
                os.chmod(t, _file_mode(p))
            for p, t in todo:
                os.replace(t, p)
        except OSError as err:
            raise error(f"cannot write {p}: {err.strerror or err}") from err
    except BaseException:
        for t, d in zip(tmps, direct):
            if not d:
                with contextlib.suppress(FileNotFoundError):
                    t.unlink()
        raise


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, error=MapFileError) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success."""
    with atomic_paths([path], error) as (tmp,):
        yield tmp


def atomic_write_text(path: str | os.PathLike, text: str, error=MapFileError) -> None:
    with atomic_path(path, error) as tmp:
        tmp.write_text(text)


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike, error=OutputPathError) -> Iterator[Path]:
    """Yield a staging folder for the outputs meant for folder ``path``; when the block
    succeeds its files are moved into ``path`` (created with its parents if missing; a
    file of the same name replaced), otherwise the staging folder is removed and ``path``
    is left as it was -- not created, no file added or replaced. The staging folder
    (``.<name>.<pid>.<random>.tmp``) lies in the nearest existing ancestor of ``path``, so
    the moves are renames on one file system."""
    import shutil

    path = Path(path)
    existing = path.parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=existing))
    except OSError as err:
        raise error(f"cannot write {path}: {err.strerror or err}") from err
    try:
        yield stage
        try:
            path.mkdir(parents=True, exist_ok=True)
            for f in sorted(stage.rglob("*")):
                target = path / f.relative_to(stage)
                if f.is_dir():
                    target.mkdir(exist_ok=True)
                else:
                    os.replace(f, target)
        except OSError as err:
            raise error(f"cannot write {path}: {err.strerror or err}") from err
    finally:
        shutil.rmtree(stage, ignore_errors=True)
