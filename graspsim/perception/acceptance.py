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
  twice the log-likelihood of the points under the mixture of the models (a Gaussian
  shell about each surface, sigma the band over ``factor``) and a uniform outlier
  density, mixing weights by EM, plus ``ln n`` per free parameter. Lower is better; a
  part is only worth adding when it explains enough more points to pay for its
  parameters and for its share of the points (a weight of 10 % costs each of its points
  ln 10).
"""

from __future__ import annotations

import math

import numpy as np

from graspsim.perception.shapes import model_sdf

__all__ = ["N_PARAMS", "data_scale", "inlier_band", "band_rate", "decomposition_score", "model_distance"]

#: free parameters of each model kind (pose up to its symmetry + dims)
N_PARAMS: dict[str, int] = {"sphere": 4, "cylinder": 7, "box": 9, "cone": 8, "half_toroid": 8}


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
    log-likelihood of the points under the mixture of one Gaussian shell per model
    (sigma = band / factor about its surface) and a uniform outlier density, with the
    mixing weights estimated by EM; one parameter per weight besides the models'."""
    n = len(points)
    sigma = band / factor
    nu = float(np.linalg.norm(np.ptp(points, axis=0))) + 10.0 * sigma
    comps = [np.full(n, 1.0 / nu)]
    for m in models:
        d = np.nan_to_num(np.abs(model_sdf(m.kind, m.R[None], m.t[None], m.dims[None], points)[0]), nan=nu)
        comps.append(np.exp(-0.5 * (d / sigma) ** 2) / (sigma * math.sqrt(2.0 * math.pi)))
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
