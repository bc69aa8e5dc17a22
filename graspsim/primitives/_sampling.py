"""Deterministic cell-centre sampling of flat faces, disks and surfaces of revolution.

Each sample stands for one parameter cell; its ``area`` is the cell's area and the
returned ``cover_radius`` is the largest distance from a cell's sample to the cell's
corners and edge midpoints, i.e. every surface point is that close to some sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from graspsim.primitives.samples import PatchGrid, SurfaceSamples, cells, grid_cover_radius

__all__ = ["rect_samples", "disk_samples", "revolution_samples"]


def rect_samples(
    center: np.ndarray, u: np.ndarray, v: np.ndarray, lu: float, lv: float, step: float
) -> SurfaceSamples:
    """Flat rectangle ``center + a u + b v``, |a| <= lu/2, |b| <= lv/2; normal u x v."""
    nu, nv = cells(lu, step), cells(lv, step)
    du, dv = lu / nu, lv / nv
    a = (np.arange(nu) + 0.5) * du - lu / 2
    b = (np.arange(nv) + 0.5) * dv - lv / 2
    A, B = np.meshgrid(a, b, indexing="ij")
    u, v = np.asarray(u, float), np.asarray(v, float)
    pts = center + A.reshape(-1, 1) * u + B.reshape(-1, 1) * v
    n = np.cross(u, v)
    return SurfaceSamples(
        points=pts,
        normals=np.broadcast_to(n, pts.shape).copy(),
        areas=np.full(len(pts), du * dv),
        cover_radius=grid_cover_radius(du, dv),
        patch=np.zeros(len(pts), np.int64),
        uv=np.column_stack([A.ravel(), B.ravel()]),
        grids=(PatchGrid("rect", 0, nu=nu, nv=nv, lu=lu, lv=lv),),
    )


def disk_samples(
    center: np.ndarray, u: np.ndarray, v: np.ndarray, radius: float, step: float
) -> SurfaceSamples:
    """Flat disk in the plane spanned by unit ``u``, ``v``; normal u x v; polar rings.
    (The rings' sizes are worked out one by one, their samples in one pass.)"""
    nr = cells(radius, step)
    dr = radius / nr
    rhos, counts, dts, areas, tang, cover = [], [], [], [], [], 0.0
    u, v = np.asarray(u, float), np.asarray(v, float)
    for k in range(nr):
        rho = (k + 0.5) * dr
        # size the cells by their outer arc so no cell side exceeds the step
        nt = max(3, math.ceil(2.0 * math.pi * (rho + dr / 2) / step - 1e-9))
        dt = 2.0 * math.pi / nt
        ring = 0.0
        for rc in (rho - dr / 2, rho + dr / 2):
            for half in (dt / 2, 0.0):
                d2 = rho**2 + rc**2 - 2.0 * rho * rc * math.cos(half)
                ring = max(ring, math.sqrt(max(d2, 0.0)))
        ring = max(ring, 2.0 * rho * math.sin(dt / 4) if nt > 1 else rho)
        rhos.append(rho)
        counts.append(nt)
        dts.append(dt)
        areas.append(2.0 * math.pi * rho * dr / nt)
        tang.append(ring)
        cover = max(cover, ring)
    nts = np.asarray(counts, np.int64)
    which = np.repeat(np.arange(nr), nts)
    k = np.arange(len(which)) - np.repeat(np.cumsum(nts) - nts, nts)  # index within its ring
    th = (k + 0.5) * np.asarray(dts)[which]
    rho = np.asarray(rhos)[which]
    pts = center + rho[:, None] * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v)
    n = np.cross(u, v)
    return SurfaceSamples(pts, np.broadcast_to(n, pts.shape).copy(), np.asarray(areas)[which], cover,
                          tangent_radius=np.asarray(tang)[which], normal_height=np.zeros(len(pts)),
                          patch=np.zeros(len(pts), np.int64), uv=np.column_stack([rho, th]),
                          grids=(PatchGrid("rings", 0, width=dr, counts=tuple(counts)),))


def revolution_samples(
    profile: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    length: float,
    step: float,
    sweep: float = 2.0 * math.pi,
) -> SurfaceSamples:
    """Surface of revolution about z.

    ``profile(s)`` maps arc length s in [0, length] to (rho, z, n_rho, n_z): the
    distance from the axis, the height and the outward unit normal in the (rho, z)
    half-plane. The profile is swept over azimuth [0, sweep] (counter-clockwise
    from +x). Rings of cells along s; each ring has enough azimuth cells that no cell
    side exceeds ``step``.
    """
    ns = cells(length, step)
    ds = length / ns
    s = (np.arange(ns) + 0.5) * ds
    rho, z, nr, nz = (np.broadcast_to(np.asarray(a, float), s.shape) for a in profile(s))
    edges = np.asarray(profile(np.linspace(0.0, length, ns + 1))[0], float)
    widest = np.maximum(rho, np.maximum(edges[:-1], edges[1:]))
    nt = np.maximum(3, np.ceil(sweep * widest / step - 1e-9).astype(np.int64))
    dt = sweep / nt
    ring = np.repeat(np.arange(ns), nt)
    k = np.arange(len(ring)) - np.repeat(np.cumsum(nt) - nt, nt)
    th = (k + 0.5) * dt[ring]
    c, si = np.cos(th), np.sin(th)
    pts = np.column_stack([rho[ring] * c, rho[ring] * si, z[ring]])
    nrm = np.column_stack([nr[ring] * c, nr[ring] * si, nz[ring]])
    areas = (rho * dt * ds)[ring]
    # offsets of each ring cell's corners and edge midpoints from its sample (azimuth
    # 0 by symmetry), split along the sample's normal and its tangent plane
    sc = s[:, None] + np.array([-0.5, 0.0, 0.5]) * ds
    rc, zc, _, _ = (np.broadcast_to(np.asarray(a, float), sc.shape) for a in profile(sc))
    half = np.array([-0.5, 0.0, 0.5])[None, None, :] * dt[:, None, None]
    dx = rc[:, :, None] * np.cos(half) - rho[:, None, None]
    dy = rc[:, :, None] * np.sin(half)
    dz = np.broadcast_to((zc - z[:, None])[:, :, None], dx.shape)
    h = dx * nr[:, None, None] + dz * nz[:, None, None]
    d2 = dx**2 + dy**2 + dz**2
    cell_h = np.abs(h).reshape(ns, -1).max(axis=1)
    cell_t = np.sqrt(np.maximum(d2 - h**2, 0.0)).reshape(ns, -1).max(axis=1)
    cover = float(np.sqrt(d2).max())
    return SurfaceSamples(pts, nrm, areas, cover, tangent_radius=cell_t[ring],
                          normal_height=cell_h[ring], patch=np.zeros(len(pts), np.int64),
                          uv=np.column_stack([s[ring], th]),
                          grids=(PatchGrid("rings", 0, width=ds, counts=tuple(int(c) for c in nt),
                                           sweep=sweep),))
