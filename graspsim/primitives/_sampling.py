"""Deterministic cell-centre sampling of flat faces, disks and surfaces of revolution.

Each sample stands for one parameter cell; its ``area`` is the cell's area and the
returned ``cover_radius`` is the largest distance from a cell's sample to the cell's
corners and edge midpoints, i.e. every surface point is that close to some sample.

A shape made of several patches sizes each first (:func:`rect_part`, :func:`disk_part`,
:func:`revolution_part`) and :func:`assemble` makes their samples straight into one set
of arrays: what :meth:`SurfaceSamples.concat` of the patches' own samples gives, without
making them apart first (the finest collision samples run to hundreds of thousands).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graspsim.primitives.samples import PatchGrid, SurfaceSamples, cells, grid_cover_radius

__all__ = ["disk_samples", "rect_part", "disk_part", "revolution_part",
           "assemble"]


@dataclass(frozen=True)
class Part:
    """One patch's samples, sized before they are made: ``fill(out, a)`` writes its ``n``
    rows of ``points``, ``normals``, ``areas``, ``tangent_radius``, ``normal_height`` and
    ``uv`` into the arrays of ``out`` (a dict) from row ``a``."""

    n: int
    cover: float
    grid: PatchGrid
    fill: Callable[[dict, int], None]


def assemble(parts: list[Part]) -> SurfaceSamples:
    """The samples of the patches ``parts`` in order, patch k's ``patch`` index k and its
    cell layout moved to its rows (as :meth:`SurfaceSamples.concat` lays them out)."""
    n = sum(p.n for p in parts)
    out = {"points": np.empty((n, 3)), "normals": np.empty((n, 3)), "areas": np.empty(n),
           "tangent_radius": np.empty(n), "normal_height": np.empty(n), "uv": np.empty((n, 2))}
    patch = np.empty(n, np.int64)
    grids, a = [], 0
    for k, p in enumerate(parts):
        p.fill(out, a)
        patch[a:a + p.n] = k
        grids.append(p.grid.shifted(a))
        a += p.n
    return SurfaceSamples(out["points"], out["normals"], out["areas"], max(p.cover for p in parts),
                          tangent_radius=out["tangent_radius"], normal_height=out["normal_height"], patch=patch,
                          uv=out["uv"], grids=tuple(grids))


def rect_part(center: np.ndarray, u: np.ndarray, v: np.ndarray, lu: float, lv: float, step: float) -> Part:
    """Flat rectangle ``center + a u + b v``, |a| <= lu/2, |b| <= lv/2; normal u x v."""
    nu, nv = cells(lu, step), cells(lv, step)
    du, dv = lu / nu, lv / nv
    cover = grid_cover_radius(du, dv)

    def fill(out: dict, a0: int) -> None:
        a = (np.arange(nu) + 0.5) * du - lu / 2
        b = (np.arange(nv) + 0.5) * dv - lv / 2
        A, B = np.meshgrid(a, b, indexing="ij")
        uu, vv = np.asarray(u, float), np.asarray(v, float)
        rows = slice(a0, a0 + nu * nv)
        pts = out["points"][rows]
        np.multiply(A.reshape(-1, 1), uu, out=pts)
        np.add(center, pts, out=pts)  # center + a u, then + b v: the order of the sum
        pts += B.reshape(-1, 1) * vv
        out["normals"][rows] = np.cross(uu, vv)
        out["areas"][rows] = du * dv
        out["tangent_radius"][rows] = cover
        out["normal_height"][rows] = 0.0
        out["uv"][rows, 0] = A.ravel()
        out["uv"][rows, 1] = B.ravel()

    return Part(nu * nv, cover, PatchGrid("rect", 0, nu=nu, nv=nv, lu=lu, lv=lv), fill)


def disk_part(center: np.ndarray, u: np.ndarray, v: np.ndarray, radius: float, step: float) -> Part:
    """Flat disk in the plane spanned by unit ``u``, ``v``; normal u x v; polar rings.
    (The rings' sizes are worked out one by one, their samples in one pass.)"""
    nr = cells(radius, step)
    dr = radius / nr
    rhos, counts, dts, areas, tang, cover = [], [], [], [], [], 0.0
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

    def fill(out: dict, a0: int) -> None:
        uu, vv = np.asarray(u, float), np.asarray(v, float)
        nts = np.asarray(counts, np.int64)
        per_ring = lambda a: np.repeat(np.asarray(a), nts)  # noqa: E731 -- each ring's value on its cells
        n = int(nts.sum())
        k = np.arange(n) - per_ring(np.cumsum(nts) - nts)  # index within its ring
        th = (k + 0.5) * per_ring(dts)
        rho = per_ring(rhos)
        rows = slice(a0, a0 + n)
        pts = out["points"][rows]  # center + rho (cos u + sin v)
        np.multiply(np.cos(th)[:, None], uu, out=pts)
        pts += np.sin(th)[:, None] * vv
        pts *= rho[:, None]
        pts += center
        out["normals"][rows] = np.cross(uu, vv)
        out["areas"][rows] = per_ring(areas)
        out["tangent_radius"][rows] = per_ring(tang)
        out["normal_height"][rows] = 0.0
        out["uv"][rows, 0] = rho
        out["uv"][rows, 1] = th

    return Part(int(sum(counts)), cover, PatchGrid("rings", 0, width=dr, counts=tuple(counts)), fill)


def disk_samples(
    center: np.ndarray, u: np.ndarray, v: np.ndarray, radius: float, step: float
) -> SurfaceSamples:
    """Flat disk in the plane spanned by unit ``u``, ``v``; normal u x v; polar rings."""
    return assemble([disk_part(center, u, v, radius, step)])


def revolution_part(
    profile: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    length: float,
    step: float,
    sweep: float = 2.0 * math.pi,
) -> Part:
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

    def fill(out: dict, a0: int) -> None:
        n = int(nt.sum())
        per_ring = lambda a: np.repeat(a, nt)  # noqa: E731 -- each ring's value on its cells
        k = np.arange(n) - per_ring(np.cumsum(nt) - nt)
        th = (k + 0.5) * per_ring(dt)
        c, si = np.cos(th), np.sin(th)
        rows = slice(a0, a0 + n)
        pts, nrm = out["points"][rows], out["normals"][rows]
        rho_r, nr_r = per_ring(rho), per_ring(nr)
        np.multiply(rho_r, c, out=pts[:, 0])
        np.multiply(rho_r, si, out=pts[:, 1])
        pts[:, 2] = per_ring(z)
        np.multiply(nr_r, c, out=nrm[:, 0])
        np.multiply(nr_r, si, out=nrm[:, 1])
        nrm[:, 2] = per_ring(nz)
        out["areas"][rows] = per_ring(rho * dt * ds)
        out["tangent_radius"][rows] = per_ring(cell_t)
        out["normal_height"][rows] = per_ring(cell_h)
        out["uv"][rows, 0] = per_ring(s)
        out["uv"][rows, 1] = th

    return Part(int(nt.sum()), cover, PatchGrid("rings", 0, width=ds, counts=tuple(int(c) for c in nt), sweep=sweep),
                fill)
