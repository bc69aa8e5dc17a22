"""The objects of the calibration studies: a training set and a held-out set.

The calibrated grade is fitted on ``TRAIN_SHAPES`` only; ``HELD_OUT_SHAPES`` -- other
sizes and proportions of the five primitives and two compounds (a bottle and the
case study's ball with a tab, ``graspsim.primitives.case_study.ball_with_tab``) -- are never used in
fitting, so scores on them are scores on unseen objects. Sizes are chosen so that most
chords fit the HGPL-25-60 (opening <= 120 mm).
"""

from __future__ import annotations

import math

import numpy as np

from graspsim.maps.database import PAPER_SHAPES, size_grid
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Sphere
from graspsim.primitives.case_study import ball_with_tab
from graspsim.transforms import make_transform

__all__ = ["TRAIN_SHAPES", "HELD_OUT_SHAPES", "SIZE_SCALES", "paper_size_grid", "bottle", "CALIBRATION_CONE"]

SIZE_SCALES = (0.8, 1.0, 1.25)
# closing directions up to 44 deg from the inward normal: grasps well outside the
# planner's friction cone (26.6 deg at mu = 0.5) are in the maps, so calibration sees them
CALIBRATION_CONE = math.radians(44.0)


def paper_size_grid(scales=SIZE_SCALES) -> dict:
    """The five paper primitives at several sizes: {"cylinder@1.25": Cylinder, ...}."""
    out = {}
    for name, base in PAPER_SHAPES.items():
        for s, shape in zip(scales, size_grid(base, scales)):
            out[f"{name}@{s:g}"] = shape
    return out


def bottle() -> Compound:
    """A bottle: body cylinder r 3 cm, h 9 cm, with a neck r 1.1 cm, h 4 cm on top."""
    return Compound.from_parts([Cylinder(0.03, 0.09), Cylinder(0.011, 0.04)],
                               [make_transform(np.eye(3), [0, 0, 0.045]),
                                make_transform(np.eye(3), [0, 0, 0.11])])


TRAIN_SHAPES: dict = {
    **paper_size_grid(),
    "box_4x6x10": Box(0.04, 0.06, 0.10),
    "box_3x5x12": Box(0.03, 0.05, 0.12),
    "cylinder_r30_h120": Cylinder(0.03, 0.12),
    "cylinder_r40_h70": Cylinder(0.04, 0.07),
    "cone_full_r35_h80": Cone(0.035, 0.0, 0.08),
    "cone_inverted_30_45_90": Cone(0.03, 0.045, 0.09),
    "sphere_r25": Sphere(0.025),
    "half_toroid_R50_r12": HalfToroid(0.05, 0.012),
}

HELD_OUT_SHAPES: dict = {
    "box_5x7x9": Box(0.05, 0.07, 0.09),
    "cylinder_r25_h160": Cylinder(0.025, 0.16),
    "cylinder_r35_h100": Cylinder(0.035, 0.10),
    "sphere_r40": Sphere(0.04),
    "cone_45_25_120": Cone(0.045, 0.025, 0.12),
    "half_toroid_R35_r9": HalfToroid(0.035, 0.009),
    "bottle": bottle(),
    "ball_with_tab": ball_with_tab(),
}
