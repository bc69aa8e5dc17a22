"""Shared fixtures: seeded generators, the paper's reference primitives, a spy on the
planner's collision checks."""

from __future__ import annotations

import numpy as np
import pytest

from graspsim._gl import default_gl
from graspsim.primitives import Box, Cone, Cylinder, HalfToroid, Sphere

# Test modules import mujoco directly; the backend must be chosen before the first of them
# is collected, or the render tests skip (or GLFW aborts) depending on the order they run in.
default_gl()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


PAPER_SHAPES = {
    "box": Box(0.06, 0.06, 0.06),
    "cylinder": Cylinder(0.02, 0.20),
    "sphere": Sphere(0.035),
    "cone": Cone(0.04, 0.02, 0.10),
    "half_toroid": HalfToroid(0.04, 0.01),
}


@pytest.fixture(params=sorted(PAPER_SHAPES))
def shape(request):
    return PAPER_SHAPES[request.param]


@pytest.fixture
def collision_checks(monkeypatch) -> list:
    """(module, tolerance [m]) of every collision check of adapted grasps made in this
    process from now on: the scaled maps' ("scaling") and a compound's combination's
    ("combine")."""
    import graspsim.maps.combine as combine
    import graspsim.maps.scaling as scaling

    seen = []
    for mod in (scaling, combine):
        def spy(*args, _real=mod.grasps_collision_free, _name=mod.__name__.rsplit(".", 1)[1], **kw):
            seen.append((_name, args[6].collision_tolerance))
            return _real(*args, **kw)
        monkeypatch.setattr(mod, "grasps_collision_free", spy)
    return seen
