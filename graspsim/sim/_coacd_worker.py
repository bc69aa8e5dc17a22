"""The bounded half of mesh preparation, run as a separate process by
:func:`graspsim.sim.meshes.prepare_mesh`: decimate (fast-simplification) and decompose
(CoACD) one mesh, then write the convex parts.

CoACD has no time limit of its own, and neither has quadric decimation on a pathological
mesh (a fan of slivers), so the caller runs this file as a script with a wall-clock limit
and kills it when the limit passes. It imports only numpy, fast_simplification and coacd
(never graspsim: a fresh interpreter starts in a fraction of a second).

    python _coacd_worker.py IN.npz OUT.npz

IN.npz: ``vertices`` (V, 3), ``faces`` (F, 3), ``params`` (a JSON string: threshold,
max_parts, preprocess_resolution, mcts_iterations, mcts_nodes, mcts_max_depth, resolution,
seed, max_faces, closed). ``closed``: the caller found the mesh closed and consistently
wound, so CoACD's manifold remeshing is skipped -- unless decimation (which promises no
manifold result) left it open. OUT.npz: ``count`` and ``part0``
... (convex vertex arrays), ``faces_used``.
Each stage is announced on stdout as ``stage NAME`` for the caller's progress display.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np


def _stage(name: str) -> None:
    print(f"stage {name}", flush=True)


def decimate(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with at most about ``max_faces`` faces (quadric decimation; unchanged if
    it has no more)."""
    if len(faces) <= max_faces:
        return vertices, faces
    import fast_simplification

    return fast_simplification.simplify(np.ascontiguousarray(vertices, np.float64),
                                        np.ascontiguousarray(faces, np.int64), target_count=int(max_faces))


def closed_surface(faces: np.ndarray) -> bool:
    """Whether triangles ``faces`` form closed, consistently wound surfaces: every directed
    edge appears once and its reverse once (what trimesh calls watertight and consistently
    wound, without importing trimesh here)."""
    f = np.asarray(faces, np.int64)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(directed.max()) + 1
    code = directed[:, 0] * n + directed[:, 1]
    if len(np.unique(code)) != len(code):
        return False
    return bool(np.isin(directed[:, 1] * n + directed[:, 0], code).all())


def run(vertices: np.ndarray, faces: np.ndarray, params: dict) -> tuple[list[np.ndarray], int]:
    closed = bool(params.get("closed", False))
    if len(faces) > params["max_faces"]:
        _stage("decimating")
        vertices, faces = decimate(vertices, faces, params["max_faces"])
        closed = closed and closed_surface(faces)
    _stage("decomposing")
    import coacd

    coacd.set_log_level("error")
    result = coacd.run_coacd(
        coacd.Mesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int32)),
        threshold=params["threshold"], max_convex_hull=params["max_parts"],
        preprocess_mode="off" if closed else "auto",
        preprocess_resolution=params["preprocess_resolution"], resolution=params["resolution"],
        mcts_iterations=params["mcts_iterations"], mcts_nodes=params["mcts_nodes"],
        mcts_max_depth=params["mcts_max_depth"], seed=params["seed"])
    return [np.asarray(v, np.float64) for v, _ in result if len(v) >= 4], len(faces)


def main(argv: list[str]) -> int:
    src, dst = argv
    with np.load(src) as z:
        vertices, faces, params = z["vertices"], z["faces"], json.loads(str(z["params"]))
    parts, used = run(vertices, faces, params)
    tmp = f"{dst}.{os.getpid()}.part.npz"
    with open(tmp, "wb") as f:
        np.savez(f, count=len(parts), faces_used=used, **{f"part{i}": p for i, p in enumerate(parts)})
    os.replace(tmp, dst)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
