"""Where graspsim keeps what it computes once and reuses (prepared meshes, capability
maps, measured gripper models): ``$GRASPSIM_CACHE_DIR/<kind>``, else
``$XDG_CACHE_HOME/graspsim/<kind>`` (an absolute ``XDG_CACHE_HOME`` only, as the XDG
base-directory rule says), else ``~/.cache/graspsim/<kind>``. The map database has its own
setting (``$GRASPSIM_DB``, :func:`graspsim.maps.database.default_root`)."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["user_cache"]


def user_cache(kind: str) -> Path:
    """The folder the cache ``kind`` (``"coacd"``, ``"reach"``, ``"grippers"``) lives in
    (module doc); not created here."""
    root = os.environ.get("GRASPSIM_CACHE_DIR")
    if root:
        return Path(root) / kind
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"
    return base / "graspsim" / kind
