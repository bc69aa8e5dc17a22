"""The four shape features of paper section 2.3.

* sphere fit rate and cylinder fit rate (eq. 2): fraction of the cluster's points that
  MLESAC classifies as inliers of the best sphere / cylinder;
* overall cylindrical symmetry: spread of the points' radii about the main axis, taken
  slice by slice along the axis (median over slices of the robust standard deviation
  of the radii, in metres) -- about the noise level for cylinders, cones and spheres,
  much larger for boxes and half-toroids;
* half-cylindrical symmetry: difference of the median radius of the lower and the
  upper half along the main axis [m] -- about zero for cylinders, large for cones
  (medians: a minority of points off the surface, a duck's head on its body, does
  not make a taper).

The main axis is the axis of the better of the cylinder and cone fits. Points within 10 % of the axial
extent of either end are left out of the symmetry features (they are cap points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graspsim.perception.mlesac import ModelFit

__all__ = ["ShapeFeatures", "shape_features"]


@dataclass(frozen=True)
class ShapeFeatures:
    """sphere_fit_rate, cylinder_fit_rate: in [0, 1]; cylindrical_symmetry,
    half_symmetry: [m] (NaN without a cylinder or cone fit); mean_radius [m];
    fit_rates: fit rate of every model kind that was fitted."""

    sphere_fit_rate: float
    cylinder_fit_rate: float
    cylindrical_symmetry: float
    half_symmetry: float
    mean_radius: float
    fit_rates: dict[str, float]


def _robust_std(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def shape_features(points: np.ndarray, fits: dict[str, ModelFit | None], *,
                   n_slices: int = 8) -> ShapeFeatures:
    """Features of a cluster (N, 3) [m] from its model fits (by kind; None = failed)."""
    rates = {k: (f.fit_rate if f is not None else 0.0) for k, f in fits.items()}
    axis_fit = fits.get("cylinder")
    cone = fits.get("cone")
    if cone is not None and (axis_fit is None or cone.fit_rate > axis_fit.fit_rate):
        axis_fit = cone
    sym = half = mean_r = float("nan")
    if axis_fit is not None:
        a, c = axis_fit.R[:, 2], axis_fit.t
        rel = points - c
        z = rel[:, 0] * a[0] + rel[:, 1] * a[1] + rel[:, 2] * a[2]
        rho = np.linalg.norm(rel - z[:, None] * a, axis=1)
        lo, hi = np.quantile(z, [0.02, 0.98])
        span = hi - lo
        body = (z > lo + 0.1 * span) & (z < hi - 0.1 * span)
        if body.sum() >= 2 * n_slices:
            zb, rb = z[body], rho[body]
            edges = np.linspace(zb.min(), zb.max(), n_slices + 1)
            sl = np.clip(np.searchsorted(edges, zb, side="right") - 1, 0, n_slices - 1)
            spreads = [_robust_std(rb[sl == s]) for s in range(n_slices) if np.sum(sl == s) >= 4]
            sym = float(np.median(spreads)) if spreads else float("nan")
            mid = 0.5 * (zb.min() + zb.max())
            low, up = rb[zb < mid], rb[zb >= mid]
            if len(low) and len(up):
                half = float(abs(np.median(low) - np.median(up)))
            mean_r = float(rb.mean())
    return ShapeFeatures(rates.get("sphere", 0.0), rates.get("cylinder", 0.0), sym, half,
                         mean_r, rates)
