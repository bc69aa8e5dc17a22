"""Acceptance that scales with the data, and the score that chooses decompositions.

The paper's rules count a point as explained when MLESAC's inlier posterior exceeds 1/2
under a Gaussian of the sensor's sigma, and a model as fitting when 85 % of the points
are explained. On a real object the primitive is only an approximation of the surface
(rounded edges, slight tapers), so the residuals of a correct primitive spread wider
than the sensor noise. Here the scale of the data is the noise combined with half the
point spacing (a surface sampled at spacing s cannot pin a model closer than about
s / 2), and:

* :func:`inlier_band`: a point is explained by a model when its distance to the model's
  surface is at most ``factor`` times that scale;
* :func:`band_rate`: the fraction of a cluster's points so explained;
* :func:`decomposition_score`: a BIC-like score of a set of models for a cloud -- minus
  twice the log-likelihood of the points under the mixture of the models and a uniform
  outlier density over the points' box, mixing weights by EM, plus ``ln n`` per free
  parameter. Lower is better. Each model is the density of points drawn uniformly over
  its surface (1 / its area) with a Gaussian shell across it (sigma the band over
  ``factor``): a proper density, so a part is worth adding when it explains enough
  more points to pay for its parameters, and a model pays for surface no point lies
  on (one box across two crossing slabs, a body fitted over the gap beside it). Were
  the shells not normalised by area, the mixing weights would charge every split
  (a weight of 10 % costs each of its points ln 10) while nothing charged a large
  model for its empty surface.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from graspsim.primitives.sdf import model_sdf

__all__ = ["N_PARAMS", "surface_area", "data_scale", "inlier_band", "band_rate", "decomposition_score",
           "model_distance", "FitQuality", "fit_quality"]

#: free parameters of each model kind (pose up to its symmetry + dims)
N_PARAMS: dict[str, int] = {"sphere": 4, "cylinder": 7, "box": 9, "cone": 8, "half_toroid": 8}


def surface_area(kind: str, dims) -> float:
    """Surface area [m^2] of a model of ``kind`` with fit dims (see
    :data:`~graspsim.primitives.sdf.DIM_NAMES`), its end faces included; the
    half-toroid's is half a torus and its two end discs."""
    d = [float(v) for v in dims]
    if kind == "sphere":
        return 4.0 * math.pi * d[0] ** 2
    if kind == "cylinder":
        return 2.0 * math.pi * d[0] * (d[0] + d[1])
    if kind == "box":
        return 2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
    if kind == "cone":
        r0, r1, h = d
        return math.pi * ((r0 + r1) * math.hypot(r0 - r1, h) + r0 * r0 + r1 * r1)
    if kind == "half_toroid":
        return 2.0 * math.pi**2 * d[0] * d[1] + 2.0 * math.pi * d[1] ** 2
    raise ValueError(f"unknown model kind {kind!r}")


def data_scale(noise: float, spacing: float) -> float:
    """The cloud's length scale [m]: the noise sigma combined with half the spacing."""
    return math.sqrt(noise * noise + 0.25 * spacing * spacing)


def inlier_band(noise: float, spacing: float, factor: float = 3.0) -> float:
    """Largest distance [m] of an explained point from a model's surface."""
    return factor * data_scale(noise, spacing)


def model_distance(models, points: np.ndarray) -> np.ndarray:
    """(N,) distance [m] of each point to the nearest surface of ``models`` (fits with
    kind, R, t, dims); inf without models."""
    out = np.full(len(points), np.inf)
    for m in models:
        d = np.abs(model_sdf(m.kind, m.R[None], m.t[None], m.dims[None], points)[0])
        out = np.minimum(out, np.nan_to_num(d, nan=np.inf))
    return out


def band_rate(model, points: np.ndarray, band: float) -> float:
    """Fraction of the points (N, 3) within ``band`` [m] of the model's surface."""
    if not len(points):
        return 0.0
    return float(np.mean(model_distance([model], points) <= band))


def decomposition_score(models, points: np.ndarray, band: float, factor: float = 3.0, *,
                        em_iters: int = 8) -> float:
    """BIC-like score (lower is better) of the models (fits) for the points (N, 3): the
    log-likelihood of the points under the mixture of one density per model (uniform
    over its surface, a Gaussian shell of sigma = band / factor across it) and a uniform
    outlier density over the points' box padded by 5 sigma, with the mixing weights
    estimated by EM; one parameter per weight besides the models'."""
    n = len(points)
    sigma = band / factor
    span = np.ptp(points, axis=0) + 10.0 * sigma
    comps = [np.full(n, 1.0 / float(np.prod(span)))]
    far = float(np.linalg.norm(span))
    for m in models:
        d = np.nan_to_num(np.abs(model_sdf(m.kind, m.R[None], m.t[None], m.dims[None], points)[0]), nan=far)
        area = max(surface_area(m.kind, m.dims), 1e-12)
        comps.append(np.exp(-0.5 * (d / sigma) ** 2) / (area * sigma * math.sqrt(2.0 * math.pi)))
    like = np.stack(comps)  # (K + 1, N)
    w = np.full(len(comps), 1.0 / len(comps))
    for _ in range(em_iters):
        joint = w[:, None] * like
        post = joint / np.maximum(joint.sum(axis=0), 1e-300)
        w = np.clip(post.mean(axis=1), 1e-9, 1.0)
        w /= w.sum()
    ll = float(np.sum(np.log(np.maximum((w[:, None] * like).sum(axis=0), 1e-300))))
    k = sum(N_PARAMS[m.kind] + 1 for m in models)
    return -2.0 * ll + k * math.log(max(n, 2))


@dataclass(frozen=True)
class FitQuality:
    """How well a set of posed primitives explains a whole cloud (every point, not one
    part's cluster). explained: share of the points within ``band`` [m] of some part's
    surface; outside: share lying farther than ``band`` outside every part (shape the
    primitives miss: where a finger sized for them meets the object); mean, p95, max:
    the points' distances [m] to the nearest part surface; covered: share of the parts'
    outer surface (area; surface inside another part left out) with a point within
    ``band`` + the point spacing -- a full cloud covers a primitive that is the object
    almost wholly, and a part claiming matter where none was seen (a sphere over a
    bowl's opening, a box over a flat tool's gaps) lowers it; with a viewpoint only the
    surface facing it counts; points: how many were measured; band: the inlier band
    (:func:`inlier_band`) of the cloud's noise and spacing. :attr:`score`, explained x
    covered, is the one number: near 1 where the primitives are the object, low where
    they miss it either way."""

    explained: float
    outside: float
    mean: float
    p95: float
    max: float
    covered: float
    points: int
    band: float

    @property
    def score(self) -> float:
        """explained x covered: how well the primitives explain the cloud, in [0, 1]."""
        return self.explained * self.covered

    def to_dict(self) -> dict:
        return {**asdict(self), "score": self.score}

    @classmethod
    def from_dict(cls, d: dict) -> FitQuality:
        """Back from :meth:`to_dict` (NaN residuals may have been written as null)."""
        return cls(**{k: math.nan if d.get(k) is None else d[k] for k in cls.__dataclass_fields__})

    def text(self) -> str:
        """One line for a terminal."""
        return (f"fit {self.score:.2f}: {100 * self.explained:.1f} % of {self.points} points within "
                f"{1e3 * self.band:.1f} mm of a part, {100 * self.outside:.1f} % outside every part "
                f"(residual mean {1e3 * self.mean:.1f} mm, "
                f"95th percentile {1e3 * self.p95:.1f} mm); {100 * self.covered:.0f} % of the parts' surface "
                "has points on it")


def fit_quality(points: np.ndarray, shapes, poses, band: float, spacing: float = 0.0,
                viewpoint: np.ndarray | None = None) -> FitQuality:
    """:class:`FitQuality` of ``points`` (N, 3) [m] for the primitives ``shapes`` (each
    with ``sdf`` and ``surface_samples`` in its own frame) posed at ``poses`` (4x4, their
    frames in the points' frame), with the inlier band ``band`` [m] and the cloud's
    point ``spacing`` [m]; ``viewpoint`` (3,): where a single view was seen from (None:
    all round). No shape: nothing is explained or covered."""
    from scipy.spatial import cKDTree

    P = np.asarray(points, float).reshape(-1, 3)
    poses = [np.asarray(T, float) for T in poses]
    if not len(P) or not len(shapes):
        return FitQuality(0.0, 1.0 if len(P) else 0.0, math.nan, math.nan, math.nan, 0.0, len(P), float(band))

    def union_sdf(Q, skip=-1):
        d = np.full(len(Q), np.inf)
        for k, (shape, T) in enumerate(zip(shapes, poses)):
            if k != skip:
                d = np.minimum(d, shape.sdf((Q - T[:3, 3]) @ T[:3, :3]))
        return d

    d = union_sdf(P)  # signed distance to the union of the parts
    r = np.abs(d)
    reach = band + spacing
    tree, area, seen = cKDTree(P), 0.0, 0.0
    for k, (shape, T) in enumerate(zip(shapes, poses)):
        s = shape.surface_samples(min(max(reach, 0.002), 0.5 * shape.size_scale))  # a part smaller than the reach
        q = s.points @ T[:3, :3].T + T[:3, 3]
        outer = union_sdf(q, skip=k) > -band  # surface buried in another part is never seen
        if viewpoint is not None:  # one view: the surface facing the camera
            outer &= np.einsum("ij,ij->i", s.normals @ T[:3, :3].T, np.asarray(viewpoint, float) - q) > 0
        near = tree.query(q[outer], k=1, distance_upper_bound=reach)[0] <= reach
        area += float(s.areas[outer].sum())
        seen += float(s.areas[outer][near].sum())
    return FitQuality(float(np.mean(r <= band)), float(np.mean(d > band)), float(r.mean()),
                      float(np.quantile(r, 0.95)), float(r.max()), seen / area if area > 0 else 0.0, len(P),
                      float(band))
