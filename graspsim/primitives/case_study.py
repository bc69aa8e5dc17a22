"""Synthetic analogs of the paper's case-study objects (section 3.4, RGB-D database).

The paper tested five real objects; we have no scans of them, so the demo, the case
study experiment (E03) and the validation build stand-ins from primitives with the same
structure and a plausible size. Object frames follow docs/design.md §3 (origin at the centre
of mass, +z up when standing).

How the paper's split criterion (eq. (1), theta_th = 0.5) treats them is a property of
their proportions, measured with ``graspsim.perception`` at 1.5 mm depth noise (E03):

* :func:`glue_bottle` (the demo's): a long applicator, theta* ~ 0.43-0.50 complete,
  0.46-0.48 seen from one side: split into its two cylinders at 0.5;
* :func:`glue_bottle_capped`: Elmer's proportions (a short cap), theta* ~ 0.8 complete,
  0.6-0.65 from one side: *not* split at 0.5, although the paper split the real bottle;
* :func:`ball_with_tab`: theta* ~ 0.9 complete, but 0.48-0.59 from one side (the visible
  half of the ball has a thin box): split from some views only.
"""

from __future__ import annotations

import numpy as np

from graspsim.primitives import Box, Compound, Cone, Cylinder, Sphere, synthetic_cloud
from graspsim.transforms import make_transform

__all__ = ["glue_bottle", "glue_bottle_capped", "pencil_cup", "duck_toy", "ball_with_tab", "bottle_brush",
           "bottle_brush_cloud", "ANALOGS"]


def _at(z: float, x: float = 0.0) -> np.ndarray:
    return make_transform(np.eye(3), [x, 0.0, z])


def glue_bottle() -> Compound:
    """Elmer's washable glue analog: a bottle body (r 2.6 cm, h 6.5 cm) with a long
    applicator (r 0.9 cm, h 12 cm) -- two cylinders, the paper's 'unknown object'. The
    applicator is long so that the MVBB split criterion of eq. (1) separates the parts
    at the paper's theta_th = 0.5 (theta* ~ 0.46 on noisy clouds); a short cap gives
    theta* ~ 0.7 and the cloud would not be split at 0.5 (see
    :func:`glue_bottle_capped`)."""
    return Compound.from_parts([Cylinder(0.026, 0.065), Cylinder(0.009, 0.12)], [_at(0.0325), _at(0.125)])


def glue_bottle_capped() -> Compound:
    """A glue bottle with Elmer's proportions: body r 2.5 cm, h 10 cm with a neck and
    cap r 1.1 cm, h 3.5 cm. Eq. (1) gains little volume by cutting the cap off: theta*
    ~ 0.8 on complete clouds, 0.55-0.65 seen from one side, so at theta_th = 0.5 the
    cloud is not split and stays unidentified."""
    return Compound.from_parts([Cylinder(0.025, 0.10), Cylinder(0.011, 0.035)], [_at(0.05), _at(0.1175)])


def pencil_cup() -> Cone:
    """Rolodex jumbo pencil cup analog: a (solid) frustum wider at the top, r 3.6 cm
    at the bottom and 4.4 cm at the top, h 11 cm (familiar cone)."""
    return Cone(0.036, 0.044, 0.11)


def duck_toy() -> Compound:
    """Kong duck dog toy analog: a round body cylinder (r 3 cm, h 10 cm) with a head
    sphere (r 1.8 cm) bulging 2.4 cm over its top, off-axis (paper: familiar
    cylinder). Seen from one side the head holds 10-20 % of the points."""
    return Compound.from_parts([Cylinder(0.03, 0.10), Sphere(0.018)], [_at(0.05), _at(0.106, 0.012)])


def ball_with_tab() -> Compound:
    """Kong AirDog squeakair ball analog: a ball (r 3.2 cm) with a thin box tab
    (1.2 x 6 x 7 cm) against its side (paper: sphere + box)."""
    return Compound.from_parts([Sphere(0.032), Box(0.012, 0.06, 0.07)], [np.eye(4), _at(0.0, 0.036)])


def bottle_brush() -> Compound:
    """Dr. Brown's bottle brush analog, as a shape: a thin handle (r 0.4 cm, h 16 cm) and
    a bristle head (r 1.8 cm, h 9 cm). Its *cloud* is what matters: see
    :func:`bottle_brush_cloud`."""
    return Compound.from_parts([Cylinder(0.004, 0.16), Cylinder(0.018, 0.09)], [_at(0.08), _at(0.205)])


def bottle_brush_cloud(rng: np.random.Generator, T_world_obj: np.ndarray | None = None, *,
                       camera: np.ndarray | None = None, resolution: float = 0.001, noise: float = 0.0015,
                       outliers: float = 0.005, handle_returns: float = 0.25, spots: int = 15,
                       spot_radius: float = 0.005, spot_returns: float = 0.30) -> np.ndarray:
    """What a depth camera returns from a bristle brush (paper 4.3: sparse and not
    continuous, so clustering must fail), as a cloud (N, 3) [m] in the world frame.

    The :func:`bottle_brush` seen like any analog (``camera`` position in the object
    frame, None: all around; depth noise, outliers as ``synthetic_cloud``), then thinned:
    ``handle_returns`` of the handle's points are kept, and on the bristle head only
    ``spot_returns`` of the points within ``spot_radius`` [m] of ``spots`` random spots."""
    shape = bottle_brush()
    T = np.eye(4) if T_world_obj is None else np.asarray(T_world_obj, float)
    c = synthetic_cloud(shape, rng, resolution=resolution, noise=noise, outliers=outliers, camera=camera,
                        T_world_obj=T)
    local = (c.points - T[:3, 3]) @ T[:3, :3]
    head = np.abs(shape.part_sdfs(local)[1]) < 0.004
    keep = ~head & ~c.is_outlier & (rng.random(len(local)) < handle_returns)
    hp = np.flatnonzero(head)
    centres = local[rng.choice(hp, size=min(spots, len(hp)), replace=False)]
    near = np.min(np.linalg.norm(local[hp, None, :] - centres[None], axis=2), axis=1) < spot_radius
    keep[hp[near & (rng.random(len(hp)) < spot_returns)]] = True
    return c.points[keep | c.is_outlier]


#: The shape analogs by name (the brush is a cloud: :func:`bottle_brush_cloud`).
ANALOGS = {"glue_bottle": glue_bottle, "pencil_cup": pencil_cup, "duck_toy": duck_toy,
           "ball_with_tab": ball_with_tab}
