"""Rule-based shape classification from the four features (paper 2.3).

The rules, in order (a *candidate* is a model whose fit rate is at least
``min_fit_rate`` and within ``fit_margin`` of the best fit rate of the cluster):

1. no model fits well (best fit rate < ``min_fit_rate``)        -> unidentified
2. the sphere is a candidate (feature 1)                        -> sphere
3. rotationally symmetric (feature 3 <= ``symmetry_tol`` noise):
   tapered halves (feature 4) and the cone is a candidate       -> cone;
   equal halves and the cylinder or the cone is a candidate     -> cylinder
4. the box is a candidate                                       -> box
5. the half-toroid is a candidate                               -> half-toroid
6. a rotational model is still a candidate (the symmetry features were spoiled,
   e.g. by a partial view): the cylinder if the halves are equal, else the cone
7. otherwise                                                    -> unidentified

Ties between equally good fits go to the simpler model by construction: a cone with
equal radii *is* a cylinder, so the half-symmetry feature, not the fit rate, decides.
A cylinder decided from a cone candidate alone takes its fit from the cone's axis
(see :func:`graspsim.perception.identify.identify_cluster`).
"""

from __future__ import annotations

import math
from enum import Enum

from graspsim.perception.shape_features import ShapeFeatures

__all__ = ["Shape", "classify"]


class Shape(str, Enum):
    """Outcome of identifying one cluster; values are the primitive kinds."""

    BOX = "box"
    CYLINDER = "cylinder"
    SPHERE = "sphere"
    CONE = "cone"
    HALF_TOROID = "half_toroid"
    UNIDENTIFIED = "unidentified"


def classify(features: ShapeFeatures, noise: float, *, min_fit_rate: float = 0.85,
             fit_margin: float = 0.03, symmetry_tol: float = 2.5,
             taper_tol: float = 3.0, taper_rel: float = 0.05) -> Shape:
    """Apply the rule base. noise: sensor noise sigma [m]; symmetry_tol / taper_tol in
    multiples of it; taper_rel: least radius difference of the halves relative to the
    mean radius that counts as a taper."""
    rates = features.fit_rates
    if not rates:
        return Shape.UNIDENTIFIED
    best = max(rates.values())
    if best < min_fit_rate:
        return Shape.UNIDENTIFIED
    cand = {k for k, v in rates.items() if v >= min_fit_rate and v >= best - fit_margin}
    if "sphere" in cand:
        return Shape.SPHERE
    sym, half, r = features.cylindrical_symmetry, features.half_symmetry, features.mean_radius
    tapered = (not math.isnan(half)) and half > max(taper_tol * noise, taper_rel * r)
    if not math.isnan(sym) and sym <= symmetry_tol * noise:
        if tapered and "cone" in cand:
            return Shape.CONE
        if not tapered and cand & {"cylinder", "cone"}:
            return Shape.CYLINDER
    if "box" in cand:
        return Shape.BOX
    if "half_toroid" in cand:
        return Shape.HALF_TOROID
    if "cylinder" in cand and not tapered:
        return Shape.CYLINDER
    if "cone" in cand and not tapered and not math.isnan(half):
        return Shape.CYLINDER
    if "cone" in cand:
        return Shape.CONE
    if "cylinder" in cand:
        return Shape.CYLINDER
    return Shape.UNIDENTIFIED
