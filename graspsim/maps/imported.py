"""A third-party grasp file's graspsim map, written beside it (never into it).

``graspsim trial`` simulates a dataset file (ACRONYM, GraspGen, GraspNet:
:mod:`graspsim.maps.formats`) through the map :func:`import_beside` writes next to it,
``<stem>.graspsim.h5``: the converted poses, the dataset's own labels under
:data:`SOURCE_GROUP` (with the simulator or method that produced them), and the MuJoCo
results the trials add. The dataset file is only read.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from graspsim.errors import MapFileError
from graspsim.maps.formats import is_foreign, read_grasp_file
from graspsim.maps.graspmap import GraspabilityMap

__all__ = ["import_beside", "imported_path", "load_any", "SOURCE_GROUP"]

#: where an imported map file keeps the dataset's own labels (never named after a simulator
#: path a reader hard-codes: ``info`` says which simulator produced them)
SOURCE_GROUP = "grasps/qualities/source"


def imported_path(path: str | os.PathLike) -> Path:
    """Where :func:`import_beside` writes the map of a third-party file: beside it,
    ``<stem>.graspsim.h5``."""
    path = Path(path)
    return path.with_name(path.stem + ".graspsim.h5")


def import_beside(path: str | os.PathLike, target: str | os.PathLike | None = None, *,
                  require_mesh: bool = True, **read_kw) -> Path:
    """The graspsim map of a third-party grasp file, written once beside it
    (:func:`imported_path`; the dataset file itself is never written), its labels in
    :data:`SOURCE_GROUP`; ``target`` names another place for it. An existing one made
    from the same file and arguments is reused, so trial results accumulate in it;
    returns its path. ``require_mesh``: refuse (before writing anything) a file whose
    object mesh is not found -- nothing could simulate it."""
    from graspsim.maps.io import load_map, save_map, write_sim_results

    path = Path(path)
    target = imported_path(path) if target is None else Path(target)
    key = {"file": str(path.resolve()), "size": path.stat().st_size, "mtime_ns": path.stat().st_mtime_ns,
           "args": {k: (np.asarray(v).tolist() if v is not None and not isinstance(v, (str, int, float))
                        else v) for k, v in sorted(read_kw.items()) if k != "gripper" or v is not None}}
    key["args"] = json.loads(json.dumps(key["args"], default=str))
    if target.is_file():
        try:
            old = load_map(target, rows=slice(0, 0)).meta.extra.get("import", {}).get("key")
        except MapFileError:
            old = None
        if old == key:
            return target
    gf = read_grasp_file(path, **read_kw)
    gmap = gf.gmap
    if require_mesh:
        _check_mesh(gmap.meta.object, path)
    gmap = gmap.with_meta(extra={"import": {**gmap.meta.extra["import"], "key": key}})
    save_map(gmap, target)
    if gf.labels:
        write_sim_results(target, {k: np.asarray(v) for k, v in gf.labels.items()}, group=SOURCE_GROUP,
                          attrs_json={"label_source": gf.label_source, "format": gf.format,
                                      "file": str(path)})
    return target


def _check_mesh(obj: dict, path: Path) -> None:
    name = obj.get("file")
    if not name:
        raise MapFileError(f"{path} names no object mesh (object/file): give the mesh (--mesh FILE)")
    if not Path(name).is_file():
        raise MapFileError(f"{path}: its object mesh {name} was not found (looked beside the file and in "
                           "its two parent folders); give it with --mesh FILE [--mesh-scale S]")


def load_any(path: str | os.PathLike, **read_kw) -> GraspabilityMap:
    """A graspsim map file (:func:`~graspsim.maps.io.load_map`) or a third-party grasp
    file read as one (:func:`~graspsim.maps.formats.read_grasp_file`)."""
    from graspsim.maps.io import load_map

    if not is_foreign(path):
        return load_map(path)
    return read_grasp_file(path, **read_kw).gmap
