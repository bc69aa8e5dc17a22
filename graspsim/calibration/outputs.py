"""Writing study outputs: JSON with the config and library versions, markdown, cases."""

from __future__ import annotations

import json
import logging
import os
import platform
import subprocess
import sys
import time
from pathlib import Path


from graspsim._atomic import atomic_write_text
from graspsim._jsonable import to_jsonable
from graspsim.errors import GraspsimError

__all__ = ["library_versions", "to_jsonable", "write_json", "write_text", "fs_cases"]

log = logging.getLogger(__name__)


def library_versions() -> dict:
    """Versions of the libraries results depend on, the git commit (and whether the
    code under graspsim/ and experiments/ differs from it) and the host."""
    import importlib.metadata as md

    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in ("graspsim", "numpy", "scipy", "mujoco", "numba", "trimesh", "h5py", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = None
    root = Path(__file__).resolve().parents[2]
    try:
        out["git_commit"] = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                                           text=True, timeout=5).stdout.strip() or None
        # uncommitted changes to the code that produced the results (None: no git)
        st = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "graspsim",
                             "experiments"], cwd=root, capture_output=True, text=True, timeout=10)
        out["git_dirty"] = bool(st.stdout.strip()) if st.returncode == 0 and out["git_commit"] else None
    except (OSError, subprocess.SubprocessError):
        out["git_commit"] = out["git_dirty"] = None
    out["date"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    return out


def write_json(path: str | os.PathLike, obj) -> Path:
    atomic_write_text(path, json.dumps(to_jsonable(obj), indent=1) + "\n", GraspsimError)
    return Path(path)


def write_text(path: str | os.PathLike, text: str) -> Path:
    atomic_write_text(path, text.rstrip("\n") + "\n", GraspsimError)
    return Path(path)


def fs_cases(shapes: dict, *, config=None, quality=None, gripper=None, kind: str = "fs",
             threads: int | None = None) -> list:
    """One :class:`CalibrationCase` per named shape with its FS map (a compound gets
    the combined map of its parts' FS maps, as the planner builds it)."""
    from graspsim.calibration.trials import CalibrationCase
    from graspsim.gripper import HGPL_25_60_A
    from graspsim.maps.combine import combine_maps
    from graspsim.maps.generate import generate_fs_map
    from graspsim.primitives import Compound

    gripper = gripper or HGPL_25_60_A
    cases = []
    for name, shape in shapes.items():
        t = time.perf_counter()
        if isinstance(shape, Compound):
            parts = [generate_fs_map(p, gripper, quality, config, threads=threads) for p in shape.parts]
            gmap = combine_maps(parts, shape, quality=quality, config=config)
            k = "combined"
        else:
            gmap = generate_fs_map(shape, gripper, quality, config, threads=threads)
            k = kind
        log.info("map of %s: %d grasps in %.1f s", name, len(gmap), time.perf_counter() - t)
        cases.append(CalibrationCase(f"{name}/{k}", gmap, group=name, kind=k))
    return cases
