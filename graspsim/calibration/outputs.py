"""Writing study outputs: JSON with the config and library versions, markdown."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from graspsim._atomic import atomic_write_text
from graspsim._jsonable import to_jsonable
from graspsim.errors import GraspsimError

__all__ = ["library_versions", "to_jsonable", "write_json", "write_text"]


def library_versions() -> dict:
    """Versions of the libraries results depend on, the git commit (and whether the
    code under graspsim/ and experiments/ differs from it), the host and the BLAS kernels
    it ran (:func:`graspsim._blas.blas_cores`)."""
    import importlib.metadata as md

    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in ("graspsim", "numpy", "scipy", "mujoco", "numba", "trimesh", "h5py", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = None
    out.update(git_state(Path(__file__).resolve().parents[2]))
    from graspsim._blas import blas_cores

    out["blas"] = blas_cores()  # the BLAS kernels: results repeat to the bit only on the same ones (graspsim._blas)
    out["date"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    return out


def git_state(root: Path) -> dict:
    """``{"git_commit": HEAD or None, "git_dirty": bool or None}`` of the checkout at
    ``root``: dirty when the code that produces results (``graspsim/``, ``experiments/``)
    differs from the commit; the published summaries in ``experiments/reported/`` are
    results, which ``--publish`` itself writes, not code (as ``experiments/_common.provenance``
    counts them). None where there is no git."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                                timeout=5).stdout.strip() or None
        st = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "graspsim",
                             "experiments", ":(exclude)experiments/reported"], cwd=root, capture_output=True,
                            text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return {"git_commit": None, "git_dirty": None}
    return {"git_commit": commit, "git_dirty": bool(st.stdout.strip()) if st.returncode == 0 and commit else None}


def write_json(path: str | os.PathLike, obj) -> Path:
    atomic_write_text(path, json.dumps(to_jsonable(obj), indent=1) + "\n", GraspsimError)
    return Path(path)


def write_text(path: str | os.PathLike, text: str) -> Path:
    atomic_write_text(path, text.rstrip("\n") + "\n", GraspsimError)
    return Path(path)
