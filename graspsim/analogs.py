"""Synthetic analogs of the paper's case-study objects (section 3.4, RGB-D database).

The paper tested five real objects; we have no scans of them, so the demo, the case
study experiment and the validation build stand-ins from primitives with the same
structure and a plausible size. Object frames follow DESIGN.md (origin at the centre
of mass, +z up when standing).
"""

from __future__ import annotations

import numpy as np

from graspsim.primitives import Box, Compound, Cone, Cylinder, Sphere
from graspsim.transforms import make_transform

__all__ = ["glue_bottle", "pencil_cup", "duck_toy", "ball_with_tab", "bottle_brush_cloud",
           "ANALOGS"]


def glue_bottle() -> Compound:
    """Elmer's washable glue analog: a bottle body (r 2.6 cm, h 6.5 cm) with a long
    applicator (r 0.9 cm, h 12 cm) -- two cylinders, the paper's 'unknown object'. The
    applicator is long so that the MVBB split criterion of eq. (1) separates the parts
    at the paper's theta_th = 0.5 (theta* ~ 0.46 on noisy clouds); a short cap gives
    theta* ~ 0.7 and the cloud would not be split at 0.5."""
    return Compound.from_parts([Cylinder(0.026, 0.065), Cylinder(0.009, 0.12)],
                               [make_transform(np.eye(3), [0, 0, 0.0325]),
                                make_transform(np.eye(3), [0, 0, 0.125])])


def pencil_cup() -> Cone:
    """Rolodex jumbo pencil cup analog: a frustum wider at the top (familiar cone)."""
    return Cone(0.036, 0.044, 0.11)


def duck_toy() -> Cylinder:
    """Kong duck dog toy analog: a squat cylinder (familiar cylinder)."""
    return Cylinder(0.032, 0.085)


def ball_with_tab() -> Compound:
    """Kong AirDog squeakair ball analog: a ball (r 3.2 cm) with a thin box tab."""
    return Compound.from_parts([Sphere(0.032), Box(0.012, 0.06, 0.07)],
                               [np.eye(4), make_transform(np.eye(3), [0.036, 0, 0])])


def bottle_brush_cloud(rng: np.random.Generator, T_world_obj: np.ndarray | None = None) -> np.ndarray:
    """Dr. Brown's bottle brush analog as a cloud (N, 3) [m]: a handle seen only in a
    few sparse patches plus scattered bristle tips -- sparse and non-continuous, so
    clustering must fail (paper 4.3)."""
    handle = np.column_stack([rng.normal(0, 0.002, 40), rng.normal(0, 0.002, 40),
                              rng.choice([-0.08, -0.05, 0.0, 0.06], 40) + rng.normal(0, 0.003, 40)])
    tips = rng.normal(size=(90, 3))
    tips = 0.025 * tips / np.linalg.norm(tips, axis=1, keepdims=True)
    tips[:, 2] = rng.uniform(0.03, 0.1, 90)
    pts = np.vstack([handle, tips])
    T = np.eye(4) if T_world_obj is None else np.asarray(T_world_obj, float)
    return pts @ T[:3, :3].T + T[:3, 3]


ANALOGS = {"glue_bottle": glue_bottle, "pencil_cup": pencil_cup, "duck_toy": duck_toy,
           "ball_with_tab": ball_with_tab}
