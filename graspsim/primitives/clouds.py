"""Synthetic point clouds of primitives and compounds, for perception work and tests.

A cloud is drawn uniformly over the surface by area (mesh triangles, then projected
onto the exact surface with the SDF), optionally restricted to what one camera sees,
perturbed by Gaussian sensor noise, salted with uniform outliers and posed in the
world. Every random draw comes from the caller's ``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.transforms import normalize, transform_points

__all__ = ["SyntheticCloud", "synthetic_cloud", "sample_surface", "visible_mask", "table_scene_cloud"]


@dataclass(frozen=True)
class SyntheticCloud:
    """points: (N, 3) world frame [m]; normals: (N, 3) world-frame outward normals of the
    true surface (garbage for outliers); is_outlier: (N,) bool; T_world_obj: (4, 4)."""

    points: np.ndarray
    normals: np.ndarray
    is_outlier: np.ndarray
    T_world_obj: np.ndarray


def sample_surface(shape, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniform by area on the surface of ``shape`` (object frame) and their
    outward normals."""
    mesh = shape.mesh(sections=96)
    tri = mesh.triangles
    area = mesh.area_faces
    face = rng.choice(len(tri), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    bary = np.column_stack([1.0 - s, s * (1.0 - r2), s * r2])
    p = np.einsum("ni,nij->nj", bary, tri[face])
    # project onto the exact surface (two Newton steps on the SDF)
    for _ in range(2):
        p = p - shape.sdf(p)[:, None] * shape.normals(p)
    return p, shape.normals(p)


def visible_mask(shape, points: np.ndarray, normals: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """(N,) bool: surface points a pinhole camera at ``camera`` (object frame) sees,
    i.e. facing it and not occluded (sphere tracing on the SDF towards each point)."""
    camera = np.asarray(camera, float)
    to_cam = camera - points
    dist = np.linalg.norm(to_cam, axis=1)
    facing = np.sum(normals * to_cam, axis=1) > 0.0
    d = -to_cam / np.maximum(dist[:, None], 1e-300)
    t = np.zeros(len(points))
    hit = np.full(len(points), np.inf)
    active = np.flatnonzero(facing)
    tol = 1e-5
    for _ in range(400):
        if active.size == 0:
            break
        s = shape.sdf(camera + t[active, None] * d[active])
        done = (s < tol) | (t[active] > dist[active])
        hit[active[done]] = t[active[done]]
        active = active[~done]
        t[active] += np.maximum(s[~done], tol)
    return facing & (hit >= dist - 10 * tol)


def synthetic_cloud(
    shape,
    rng: np.random.Generator,
    *,
    resolution: float = 0.005,
    noise: float = 0.0,
    outliers: float = 0.0,
    camera: np.ndarray | None = None,
    T_world_obj: np.ndarray | None = None,
) -> SyntheticCloud:
    """A synthetic sensor cloud of ``shape`` (a Primitive or Compound).

    resolution: mean point spacing on the surface [m] (count = area / resolution^2).
    noise: standard deviation of Gaussian noise [m] (along the viewing ray when a
        camera is given, like a depth sensor; isotropic otherwise).
    outliers: fraction of extra points drawn uniformly in the padded bounding box.
    camera: camera position in the object frame for a single-view partial cloud.
    T_world_obj: pose of the object in the world (identity if None).
    """
    if not resolution > 0:
        raise InvalidParameterError(f"resolution must be > 0 m, got {resolution!r}")
    if not noise >= 0:
        raise InvalidParameterError(f"noise must be >= 0 m, got {noise!r}")
    if not 0 <= outliers < 1:
        raise InvalidParameterError(f"outliers must be a fraction in [0, 1), got {outliers!r}")
    area = shape.mesh(sections=96).area
    n = max(8, int(round(area / resolution**2)))
    p, nrm = sample_surface(shape, n, rng)
    if camera is not None:
        keep = visible_mask(shape, p, nrm, camera)
        p, nrm = p[keep], nrm[keep]
    if noise > 0:
        if camera is not None:
            ray = normalize(p - np.asarray(camera, float))
            p = p + rng.normal(0.0, noise, size=(len(p), 1)) * ray
        else:
            p = p + rng.normal(0.0, noise, size=p.shape)
    n_out = int(round(outliers * len(p) / (1.0 - outliers))) if outliers > 0 else 0
    if n_out:
        b = shape.aabb
        pad = 0.1 * (b[1] - b[0])
        q = rng.uniform(b[0] - pad, b[1] + pad, size=(n_out, 3))
        p = np.vstack([p, q])
        nrm = np.vstack([nrm, normalize(rng.normal(size=(n_out, 3)))])
    is_out = np.zeros(len(p), bool)
    is_out[len(p) - n_out :] = True
    T = np.eye(4) if T_world_obj is None else np.asarray(T_world_obj, float)
    return SyntheticCloud(transform_points(T, p), nrm @ T[:3, :3].T, is_out, T)


def table_scene_cloud(
    shapes,
    xy: np.ndarray,
    rng: np.random.Generator,
    *,
    yaw: np.ndarray | None = None,
    resolution: float = 0.003,
    noise: float = 0.0,
    camera: tuple[float, float, float] = (0.0, -0.45, 0.55),
    table_size: float = 0.5,
    T_world_table: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A table-top scene seen by one camera: ``shapes`` (K primitives or compounds)
    standing upright (object +z up) on a square table of side ``table_size`` [m] at
    ``xy`` (K, 2) [m] in the table's frame (z up, top at z = 0) with yaws ``yaw`` (K,)
    [rad] (default 0), each seen from ``camera`` (table frame) as by
    :func:`synthetic_cloud`; the table sampled on a grid of step ``resolution``, less
    the objects' footprints, with the same noise along z. The whole scene is posed at
    ``T_world_table`` (identity: level table).

    Returns (points (N, 3) world [m], labels (N,): object index, -1 the table,
    T_world_obj (K, 4, 4))."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    yaw = np.zeros(len(xy)) if yaw is None else np.asarray(yaw, float)
    T_table = np.eye(4) if T_world_table is None else np.asarray(T_world_table, float)
    cam = np.asarray(camera, float)
    pts, labels, poses = [], [], []
    g = np.arange(-table_size / 2, table_size / 2, resolution)
    table = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    table = np.column_stack([table, np.zeros(len(table))])
    under = np.zeros(len(table), bool)
    for k, (shape, (x, y), a) in enumerate(zip(shapes, xy, yaw)):
        c, s = np.cos(a), np.sin(a)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = (x, y, -shape.aabb[0, 2])
        cloud = synthetic_cloud(shape, rng, resolution=resolution, noise=noise,
                                camera=transform_points(np.linalg.inv(T), cam[None])[0], T_world_obj=T)
        pts.append(cloud.points)
        labels.append(np.full(len(cloud.points), k))
        under |= shape.sdf(transform_points(np.linalg.inv(T), table + (0.0, 0.0, 1e-3))) < 0
        poses.append(T_table @ T)
    table = table[~under]
    if noise > 0:
        table[:, 2] += rng.normal(0.0, noise, len(table))
    pts.append(table)
    labels.append(np.full(len(table), -1))
    return (transform_points(T_table, np.concatenate(pts)), np.concatenate(labels),
            np.array(poses).reshape(-1, 4, 4))
