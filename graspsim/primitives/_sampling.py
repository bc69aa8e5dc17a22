"""Deterministic cell-centre sampling of flat faces, disks and surfaces of revolution.

Each sample stands for one parameter cell; its ``area`` is the cell's area and the
returned ``cover_radius`` is the largest distance from a cell's sample to the cell's
corners and edge midpoints, i.e. every surface point is that close to some sample.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from graspsim.primitives.base import SurfaceSamples, cells, grid_cover_radius

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
    )


def disk_samples(
    center: np.ndarray, u: np.ndarray, v: np.ndarray, radius: float, step: float
) -> SurfaceSamples:
    """Flat disk in the plane spanned by unit ``u``, ``v``; normal u x v; polar rings."""
    nr = cells(radius, step)
    dr = radius / nr
    pts, areas, tang, cover = [], [], [], 0.0
    u, v = np.asarray(u, float), np.asarray(v, float)
    for k in range(nr):
        rho = (k + 0.5) * dr
        # size the cells by their outer arc so no cell side exceeds the step
        nt = max(3, math.ceil(2.0 * math.pi * (rho + dr / 2) / step - 1e-9))
        dt = 2.0 * math.pi / nt
        th = (np.arange(nt) + 0.5) * dt
        pts.append(center + rho * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v))
        areas.append(np.full(nt, 2.0 * math.pi * rho * dr / nt))
        ring = 0.0
        for rc in (rho - dr / 2, rho + dr / 2):
            for half in (dt / 2, 0.0):
                d2 = rho**2 + rc**2 - 2.0 * rho * rc * math.cos(half)
                ring = max(ring, math.sqrt(max(d2, 0.0)))
        ring = max(ring, 2.0 * rho * math.sin(dt / 4) if nt > 1 else rho)
        tang.append(np.full(nt, ring))
        cover = max(cover, ring)
    pts = np.concatenate(pts)
    n = np.cross(u, v)
    return SurfaceSamples(pts, np.broadcast_to(n, pts.shape).copy(), np.concatenate(areas), cover,
                          tangent_radius=np.concatenate(tang), normal_height=np.zeros(len(pts)))


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
    from +x).
    """
    ns = cells(length, step)
    ds = length / ns
    s = (np.arange(ns) + 0.5) * ds
    rho, z, nr, nz = (np.asarray(a, float) for a in profile(s))
    pts, nrm, areas, tang, height = [], [], [], [], []
    cover = 0.0
    edges = np.asarray(profile(np.linspace(0.0, length, ns + 1))[0], float)
    for j in range(ns):
        # size the cells by their widest arc so no cell side exceeds the step
        nt = max(3, math.ceil(sweep * max(rho[j], edges[j], edges[j + 1]) / step - 1e-9))
        dt = sweep / nt
        th = (np.arange(nt) + 0.5) * dt
        c, si = np.cos(th), np.sin(th)
        pts.append(np.column_stack([rho[j] * c, rho[j] * si, np.full(nt, z[j])]))
        nrm.append(np.column_stack([nr[j] * c, nr[j] * si, np.full(nt, nz[j])]))
        areas.append(np.full(nt, rho[j] * dt * ds))
        # offsets of the cell's corners and edge midpoints from its sample (azimuth 0 by
        # symmetry), split along the sample's normal and its tangent plane
        sc = np.array([s[j] - ds / 2, s[j], s[j] + ds / 2])
        rc, zc, _, _ = (np.asarray(a, float) for a in profile(sc))
        cell_t, cell_h = 0.0, 0.0
        for half in (-dt / 2, 0.0, dt / 2):
            d = np.stack([rc * math.cos(half) - rho[j], rc * math.sin(half), zc - z[j]], axis=1)
            h = d[:, 0] * nr[j] + d[:, 2] * nz[j]
            cell_h = max(cell_h, float(np.abs(h).max()))
            cell_t = max(cell_t, float(np.sqrt(np.maximum((d**2).sum(1) - h**2, 0.0)).max()))
            cover = max(cover, float(np.sqrt((d**2).sum(1)).max()))
        tang.append(np.full(nt, cell_t))
        height.append(np.full(nt, cell_h))
    return SurfaceSamples(np.concatenate(pts), np.concatenate(nrm), np.concatenate(areas), cover,
                          tangent_radius=np.concatenate(tang), normal_height=np.concatenate(height))
