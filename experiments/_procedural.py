"""Procedural objects that no primitive decomposition explains (issue 33, item 6): a
thin-walled bowl, flat tools lying down (a clamp, scissors, a hammer), a rounded box, a
curved banana-like tube and a tall box. Each is one watertight trimesh in metres,
resting on the table (z = 0) as it would lie, centred on the z axis; no boolean engine is
needed: the bowl is a revolved profile, the flat tools are a rasterised 2D outline
extruded (1 mm pixels), the tube is swept rings with capped ends.

    from _procedural import PROCEDURAL, make
    mesh = make("bowl")
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import math

import numpy as np
import trimesh

__all__ = ["PROCEDURAL", "make", "bowl", "flat_tool", "rounded_box", "banana"]


def bowl(radius: float = 0.075, wall: float = 0.002, segments: int = 64) -> trimesh.Trimesh:
    """A hemispherical shell ``wall`` thick, outer ``radius``, opening up, its bottom on
    the table."""
    a = np.linspace(0.0, 0.5 * math.pi, 24)
    outer = np.column_stack([radius * np.sin(a), -radius * np.cos(a)])  # bottom -> rim
    inner = np.column_stack([(radius - wall) * np.sin(a), -(radius - wall) * np.cos(a)])[::-1]
    profile = np.vstack([outer, inner, outer[:1]])
    mesh = trimesh.creation.revolve(profile, sections=segments)
    mesh.merge_vertices()
    mesh.apply_translation([0.0, 0.0, radius])
    return mesh


def flat_tool(inside, extent: tuple[float, float], thickness: float, pixel: float = 0.001) -> trimesh.Trimesh:
    """The 2D region where ``inside(x, y)`` (vectorised, metres) holds, within
    ``extent`` (half-widths in x, y), rasterised at ``pixel`` and extruded
    ``thickness`` up from the table: one watertight mesh."""
    nx, ny = (int(math.ceil(e / pixel)) for e in extent)
    xs = (np.arange(-nx, nx) + 0.5) * pixel
    ys = (np.arange(-ny, ny) + 0.5) * pixel
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    fill = inside(X, Y)
    i, j = np.nonzero(fill)
    W = 2 * ny + 1  # corner (a, b) of the (2nx + 1) x (2ny + 1) grid -> a * W + b
    c00, c10, c01, c11 = i * W + j, (i + 1) * W + j, i * W + j + 1, (i + 1) * W + j + 1
    faces = np.concatenate([np.column_stack([c00, c10, c11]), np.column_stack([c00, c11, c01])])
    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    a, b = np.divmod(used, W)
    verts = np.column_stack([(a - nx) * pixel, (b - ny) * pixel])
    mesh = trimesh.creation.extrude_triangulation(verts, faces, thickness)
    mesh.merge_vertices()
    return mesh


def _bar(X, Y, p, q, half_width):
    """Inside a bar of half-width ``half_width`` from p to q (2D)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = q - p
    t = np.clip(((X - p[0]) * d[0] + (Y - p[1]) * d[1]) / (d @ d), 0.0, 1.0)
    return np.hypot(X - p[0] - t * d[0], Y - p[1] - t * d[1]) <= half_width


def _ring(X, Y, c, r_in, r_out):
    r = np.hypot(X - c[0], Y - c[1])
    return (r >= r_in) & (r <= r_out)


def scissors() -> trimesh.Trimesh:
    """Two 5 mm-thick blades crossing at a pivot, each with a finger ring: 190 mm long."""
    def inside(X, Y):
        blades = _bar(X, Y, (-0.02, -0.012), (0.10, 0.006), 0.005) | _bar(X, Y, (-0.02, 0.012), (0.10, -0.006), 0.005)
        rings = _ring(X, Y, (-0.055, -0.022), 0.011, 0.016) | _ring(X, Y, (-0.055, 0.022), 0.011, 0.016)
        necks = _bar(X, Y, (-0.04, -0.018), (-0.02, -0.012), 0.004) | _bar(X, Y, (-0.04, 0.018), (-0.02, 0.012), 0.004)
        return blades | rings | necks
    return flat_tool(inside, (0.11, 0.04), 0.005)


def clamp() -> trimesh.Trimesh:
    """An F-clamp lying flat, 12 mm thick: a 200 mm rail, a fixed and a sliding jaw, a
    screw and a handle."""
    def inside(X, Y):
        rail = _bar(X, Y, (-0.10, 0.0), (0.10, 0.0), 0.006)
        fixed = _bar(X, Y, (0.095, 0.0), (0.095, 0.08), 0.007)
        slide = _bar(X, Y, (0.0, 0.0), (0.0, 0.07), 0.008)
        screw = _bar(X, Y, (0.0, 0.07), (0.06, 0.07), 0.003)
        handle = _bar(X, Y, (-0.05, 0.075), (0.0, 0.075), 0.011)
        return rail | fixed | slide | screw | handle
    mesh = flat_tool(inside, (0.11, 0.1), 0.012)
    mesh.apply_translation([0.0, -0.04, 0.0])
    return mesh


def hammer() -> trimesh.Trimesh:
    """A hammer lying on its side, 22 mm thick: a 280 mm handle and a 110 x 30 mm head."""
    def inside(X, Y):
        return _bar(X, Y, (-0.14, 0.0), (0.12, 0.0), 0.014) | ((np.abs(X - 0.12) <= 0.015) & (np.abs(Y) <= 0.055))
    return flat_tool(inside, (0.15, 0.06), 0.022, pixel=0.002)


def rounded_box(size=(0.07, 0.10, 0.16), radius: float = 0.015) -> trimesh.Trimesh:
    """A box with every edge and corner rounded by ``radius`` (the hull of 8 spheres),
    standing on its smallest face."""
    half = np.asarray(size, float) / 2.0 - radius
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    pts = np.concatenate([sphere.vertices + half * np.array(s) for s in np.ndindex(2, 2, 2)
                          for s in [np.array(s) * 2 - 1]])
    mesh = trimesh.convex.convex_hull(pts)
    mesh.apply_translation([0.0, 0.0, size[2] / 2.0])
    return mesh


def banana(length: float = 0.19, bend: float = 1.0, radius: float = 0.018, rings: int = 40,
           segments: int = 24) -> trimesh.Trimesh:
    """A curved tube lying flat: its centre line an arc of ``length`` bent by ``bend``
    [rad], its radius tapering from ``radius`` at the middle to a third of it at the
    tips, both ends capped."""
    s = np.linspace(-0.5, 0.5, rings)
    R = length / bend
    ang = s * bend
    centre = np.column_stack([R * np.sin(ang), R * (1 - np.cos(ang)), np.zeros(rings)])
    normal = np.column_stack([-np.sin(ang), np.cos(ang), np.zeros(rings)])
    up = np.array([0.0, 0.0, 1.0])
    r = radius * (1.0 / 3.0 + (2.0 / 3.0) * np.cos(math.pi * s) ** 0.5)
    phi = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    ring = centre[:, None] + r[:, None, None] * (np.cos(phi)[None, :, None] * normal[:, None]
                                                   + np.sin(phi)[None, :, None] * up)
    verts = np.concatenate([ring.reshape(-1, 3), centre[[0, -1]]])
    faces = []
    for k in range(rings - 1):
        for m in range(segments):
            a, b = k * segments + m, k * segments + (m + 1) % segments
            faces += [[a, b, b + segments], [a, b + segments, a + segments]]
    tip0, tip1 = rings * segments, rings * segments + 1
    for m in range(segments):
        faces.append([tip0, (m + 1) % segments, m])
        faces.append([tip1, (rings - 1) * segments + m, (rings - 1) * segments + (m + 1) % segments])
    mesh = trimesh.Trimesh(verts, np.asarray(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    mesh.apply_translation([-mesh.centroid[0], -mesh.centroid[1], -mesh.bounds[0, 2]])
    return mesh


def tall_box() -> trimesh.Trimesh:
    """A 60 x 80 x 220 mm box standing on end (a primitive: the control)."""
    mesh = trimesh.creation.box((0.06, 0.08, 0.22))
    mesh.apply_translation([0.0, 0.0, 0.11])
    return mesh


PROCEDURAL = {"bowl": bowl, "clamp": clamp, "scissors": scissors, "hammer": hammer,
              "rounded_box": rounded_box, "banana": banana, "tall_box": tall_box}


def make(name: str) -> trimesh.Trimesh:
    """The procedural object ``name`` (a key of :data:`PROCEDURAL`), resting on z = 0."""
    mesh = PROCEDURAL[name]()
    mesh.apply_translation([-mesh.bounds[:, 0].mean(), -mesh.bounds[:, 1].mean(), -mesh.bounds[0, 2]])
    return mesh
