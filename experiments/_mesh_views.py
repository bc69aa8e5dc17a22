"""E09's view of a mesh: resting on the table (settled by physics, as the simulator rests it,
or on trimesh's most probable stable face), at a random yaw,
seen as a full cloud (uniform over the surface) and as a single view (the points one
camera sees, z-buffered; noise along the ray). World frame, table at z = 0, metres."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import math

import numpy as np
from _scenes import camera_position

from graspsim.sim.trial_scene import resting_pose
from graspsim.transforms import make_transform

__all__ = ["rest_on_table", "rest_physics", "rest_stable", "surface_points", "visible", "clouds"]


def rest_on_table(mesh, obj, rng: np.random.Generator):
    """The mesh (a copy) as the simulator rests its object ``obj`` on the table (upright
    when stable, else on the hull face nearest the centre of mass: :func:`resting_pose`),
    turned by a random yaw about the vertical through its centre of mass; and
    T_world_mesh."""
    a = rng.uniform(0.0, 2.0 * math.pi)
    Rz = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    T = make_transform(Rz, np.zeros(3)) @ resting_pose(obj)
    out = mesh.copy()
    out.apply_transform(T)
    return out, T


def rest_physics(mesh, obj, rng: np.random.Generator, *, max_time: float = 3.0):
    """The mesh (a copy) as it comes to rest in MuJoCo: its simulated object ``obj`` put
    on the table as :func:`rest_on_table` puts it and stepped until at rest (``SceneSim.settle``;
    at most ``max_time`` s), so a pose that only looks stable (a centre of mass over the
    edge of its support, within the support rule's 2 mm tolerance) tips over first; then
    lowest point at z = 0, centre of mass over the origin, turned by a random yaw about the
    vertical. Returns the mesh and T_world_mesh."""
    from graspsim.tabletop.scene_sim import SceneSim

    # no rolling resistance (the trial scene's table has none: with the clutter scenes' 3 mm an object
    # balanced on an edge stays there, then tips in the trial), and settled twice (a slow start of a
    # topple reads as at rest for 0.1 s)
    sim = SceneSim([(obj, resting_pose(obj))], table_rolling=0.0)
    try:
        sim.settle(max_time=max_time)
        sim.settle(max_time=max_time)
        R = sim.pose(0)[:3, :3]
    finally:
        sim.close()
    v = np.asarray(obj.surface.vertices, float) @ R.T
    c = R @ obj.com
    T = make_transform(R, np.array([-c[0], -c[1], -v[:, 2].min()]))
    a = rng.uniform(0.0, 2.0 * math.pi)
    Rz = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    T = make_transform(Rz, np.zeros(3)) @ T
    out = mesh.copy()
    out.apply_transform(T)
    return out, T


def surface_points(mesh, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniform over the mesh's surface by area."""
    f = rng.choice(len(mesh.faces), size=n, p=mesh.area_faces / mesh.area)
    tri = mesh.triangles[f]
    u, v = rng.random((2, n))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])


def visible(mesh, p: np.ndarray, cam: np.ndarray, rng: np.random.Generator, *, pixel: float = 0.0025,
            tol: float = 0.002) -> np.ndarray:
    """(N,) bool: which points p (N, 3) on the mesh the camera at ``cam`` sees -- a
    z-buffer of dense surface samples (pixels of ``pixel`` m at the object), a point
    visible when it is within ``tol`` of the nearest surface along its pixel's ray."""
    target = np.asarray(mesh.bounds, float).mean(axis=0)
    f = (target - cam) / np.linalg.norm(target - cam)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    scale = pixel / np.linalg.norm(target - cam)

    def project(q):
        d = q - cam
        depth = d @ f
        return np.floor((d @ r) / depth / scale).astype(np.int64), np.floor((d @ u) / depth / scale).astype(
            np.int64), depth

    dense = surface_points(mesh, int(np.clip(mesh.area / (0.4 * pixel) ** 2, 20000, 400000)), rng)
    i, j, depth = project(dense)
    key = (i - i.min()) * (j.max() - j.min() + 1) + (j - j.min())
    order = np.lexsort((depth, key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    zbuf = dict(zip(key[order][first].tolist(), depth[order][first].tolist()))
    pi, pj, pd = project(p)
    pk = (pi - i.min()) * (j.max() - j.min() + 1) + (pj - j.min())
    ok = (pi >= i.min()) & (pi <= i.max()) & (pj >= j.min()) & (pj <= j.max())
    near = np.array([zbuf.get(k, -np.inf) for k in pk.tolist()])  # no surface sampled there: unseen
    return ok & (pd <= near + tol)


def clouds(mesh, cfg, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The full cloud and the single view of the posed mesh (world frame, table z = 0),
    and the single view's camera position ("camera", (3,));
    ``cfg`` (E09's ``Config``) gives resolution, max_points, noise, camera_distance and
    camera_elevation_deg."""
    n = int(np.clip(mesh.area / cfg.resolution**2, 400, cfg.max_points))
    full = surface_points(mesh, n, rng) + rng.normal(0.0, cfg.noise, (n, 3))
    cam = camera_position(cfg.camera_distance, cfg.camera_elevation_deg, rng.uniform(0, 2 * math.pi))
    p = surface_points(mesh, n, rng)
    p = p[(p[:, 2] > 0.002) & visible(mesh, p, cam, rng)]  # the table hides the base
    ray = (p - cam) / np.linalg.norm(p - cam, axis=1, keepdims=True)
    single = p + rng.normal(0.0, cfg.noise, len(p))[:, None] * ray
    return {"full": full, "single": single, "camera": cam}


def rest_stable(mesh, obj, rng: np.random.Generator):
    """The mesh (a copy) on its most probable stable face (trimesh's
    ``compute_stable_poses``: the quasi-static topple graph over the hull's faces),
    lowest point at z = 0, turned by a random yaw about the vertical through its centre
    of mass; and T_world_mesh. ``obj`` is unused (the signature of :func:`rest_on_table`)."""
    import trimesh

    poses, prob = trimesh.poses.compute_stable_poses(mesh)
    T = poses[int(np.argmax(prob))]
    a = rng.uniform(0.0, 2.0 * math.pi)
    Rz = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    out = mesh.copy()
    out.apply_transform(T)
    c = np.asarray(out.center_mass if out.is_watertight else out.bounds.mean(axis=0), float)
    T2 = make_transform(Rz, np.zeros(3)) @ make_transform(np.eye(3), [-c[0], -c[1], -out.bounds[0, 2]])
    out.apply_transform(T2)
    return out, T2 @ T
