"""Reading a small JSON input file (a gripper spec, a scene description) that a user names:
a regular file of bounded size, or one error line -- never a read that blocks on a FIFO
or runs on for ever from a device."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["read_small_text"]

#: The largest small input file read [bytes] (a spec or scene JSON is a few kB).
MAX_SMALL_BYTES = 1 << 20


def read_small_text(path: str | os.PathLike, what: str, error, max_bytes: int = MAX_SMALL_BYTES) -> str:
    """The text of ``path``, or ``error`` naming ``what`` it should be: a missing file, a
    folder, a FIFO or device, a loop of links, a NUL byte in the name, more than
    ``max_bytes`` or text that is not UTF-8."""
    p = Path(path)
    try:
        if not p.is_file():  # a folder, a FIFO, a device: opening one to read may block or never end
            raise OSError("no such file" if not os.path.lexists(p) else "not a regular file")
        size = p.stat().st_size
        if size > max_bytes:
            raise OSError(f"{size} bytes; a {what} is a small JSON file (<= {max_bytes})")
        return p.read_text()
    except (OSError, UnicodeDecodeError, ValueError) as err:  # ValueError: a NUL byte in the path
        raise error(f"cannot read {what} {str(p)!r}: {getattr(err, 'strerror', None) or err}") from err
