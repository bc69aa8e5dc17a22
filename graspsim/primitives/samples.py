"""Surface samples of a primitive: points with normals and tangent frames, the patch
and cell layout they were drawn on (:class:`PatchGrid`), and the cell arithmetic the
primitives' samplers share."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["SurfaceSamples", "PatchGrid", "grid_cover_radius", "cells"]


@dataclass(frozen=True)
class PatchGrid:
    """The cell layout of one sampled surface patch, to find the cell that holds a
    point given its patch parameters (u, v). ``kind`` "rect": nu x nv cells over
    [-lu/2, lu/2] x [-lv/2, lv/2]; "rings": rings of width ``width`` along u, ring k
    split into ``counts[k]`` equal cells of v over [0, sweep). ``offset``: index of the
    patch's first sample in the concatenated samples."""

    kind: str
    offset: int
    nu: int = 0
    nv: int = 0
    lu: float = 0.0
    lv: float = 0.0
    width: float = 0.0
    counts: tuple[int, ...] = ()
    sweep: float = 2.0 * math.pi

    def locate(self, uv: np.ndarray) -> np.ndarray:
        """Global sample index (N,) of the cell containing each (u, v) (N, 2)."""
        u, v = uv[:, 0], uv[:, 1]
        if self.kind == "rect":
            i = np.clip(np.floor((u + self.lu / 2) / (self.lu / self.nu)), 0, self.nu - 1).astype(np.int64)
            j = np.clip(np.floor((v + self.lv / 2) / (self.lv / self.nv)), 0, self.nv - 1).astype(np.int64)
            return self.offset + i * self.nv + j
        counts = np.asarray(self.counts, np.int64)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        k = np.clip(np.floor(u / self.width), 0, len(counts) - 1).astype(np.int64)
        j = np.floor(np.mod(v, self.sweep) / (self.sweep / counts[k])).astype(np.int64)
        return self.offset + starts[k] + np.clip(j, 0, counts[k] - 1)

    def shifted(self, by: int) -> PatchGrid:
        return replace(self, offset=self.offset + by)


@dataclass(frozen=True)
class SurfaceSamples:
    """A deterministic sampling of a surface.

    points, normals: (N, 3) object frame [m], outward unit normals.
    areas: (N,) surface area each sample stands for [m^2].
    cover_radius: every surface point lies within this distance of a sample [m].
    tangent_radius, normal_height: (N,) extent of each sample's cell (the surface patch
        it stands for) along its tangent plane and along its normal [m]; every point of
        the cell lies within them (flat cells have normal_height 0).
    patch, uv: (N,) patch index and (N, 2) patch parameters of each sample, and
        ``grids`` the patches' cell layouts: another sampling of the same shape finds
        the cell holding each of its samples with :meth:`locate` (None/() when unknown,
        e.g. after filtering).
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    cover_radius: float
    tangent_radius: np.ndarray | None = None
    normal_height: np.ndarray | None = None
    patch: np.ndarray | None = None
    uv: np.ndarray | None = None
    grids: tuple[PatchGrid, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.points)
        if self.tangent_radius is None:
            object.__setattr__(self, "tangent_radius", np.full(n, float(self.cover_radius)))
        if self.normal_height is None:
            object.__setattr__(self, "normal_height", np.zeros(n))

    def __len__(self) -> int:
        return len(self.points)

    def shifted(self, offset: np.ndarray) -> SurfaceSamples:
        offset = np.asarray(offset, float)
        if not np.any(offset) and np.all(np.signbit(offset)):
            return self  # x + (-0.0) is x, bit for bit (a centred shape's -com_geo)
        return replace(self, points=self.points + offset)

    def select(self, mask) -> SurfaceSamples:
        return replace(self, points=self.points[mask], normals=self.normals[mask],
                       areas=self.areas[mask], tangent_radius=self.tangent_radius[mask],
                       normal_height=self.normal_height[mask], patch=None, uv=None, grids=())

    def locate(self, other: SurfaceSamples) -> np.ndarray | None:
        """Index (M,) of this sampling's cell that holds each sample of ``other`` (a
        sampling of the same shape), or None if either lacks its cell layout."""
        if not self.grids or other.patch is None or other.uv is None:
            return None
        if len(other.grids) != len(self.grids) or any(
                a.kind != b.kind for a, b in zip(self.grids, other.grids)):
            return None
        out = np.empty(len(other), np.int64)
        spans = other._patch_spans()
        for p, g in enumerate(self.grids):
            if spans is None:
                m = other.patch == p
                out[m] = g.locate(other.uv[m])
            else:  # the same cells, found on the patch's slice (no mask, no copies)
                out[spans[p]:spans[p + 1]] = g.locate(other.uv[spans[p]:spans[p + 1]])
        return out

    def _patch_spans(self) -> list[int] | None:
        """Where each patch's samples start (and the end), when every patch is one
        contiguous run in patch order starting at its grid's offset (as the samplers and
        :meth:`concat` lay them out); else None."""
        n = len(self)
        spans = [g.offset for g in self.grids] + [n]
        if spans[0] != 0 or any(b < a for a, b in zip(spans, spans[1:])):
            return None
        for p in range(len(self.grids)):
            if not np.all(self.patch[spans[p]:spans[p + 1]] == p):
                return None
        return spans

    @staticmethod
    def concat(parts: list[SurfaceSamples]) -> SurfaceSamples:
        layout = all(p.patch is not None and p.uv is not None and p.grids for p in parts)
        patch, uv, grids = None, None, ()
        if layout:
            offs = np.concatenate([[0], np.cumsum([len(p) for p in parts])[:-1]])
            pids = np.concatenate([[0], np.cumsum([len(p.grids) for p in parts])[:-1]])
            patch = np.concatenate([p.patch + k for p, k in zip(parts, pids)])
            uv = np.concatenate([p.uv for p in parts])
            grids = tuple(g.shifted(int(o)) for p, o in zip(parts, offs) for g in p.grids)
        return SurfaceSamples(
            points=np.concatenate([p.points for p in parts]),
            normals=np.concatenate([p.normals for p in parts]),
            areas=np.concatenate([p.areas for p in parts]),
            cover_radius=max(p.cover_radius for p in parts),
            tangent_radius=np.concatenate([p.tangent_radius for p in parts]),
            normal_height=np.concatenate([p.normal_height for p in parts]),
            patch=patch, uv=uv, grids=grids,
        )


def grid_cover_radius(du: float, dv: float) -> float:
    """Cover radius of cell-centre samples on a flat grid with cell sizes du x dv."""
    return 0.5 * math.hypot(du, dv)


def cells(length: float, step: float, minimum: int = 1) -> int:
    """Number of equal cells of size <= step covering ``length``."""
    return max(minimum, math.ceil(length / step - 1e-9))
