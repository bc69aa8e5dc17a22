"""Single views of boxes as a table scene's depth camera sees them (3 mm grid, 2-3 mm
depth noise, from 0.72 m and 56 deg up): a block seen on its top and one side, a
domino standing on its end, are boxes -- not the cylinder or cone the paper's rule base
decides first when the L of two faces spreads little about an axis (robust mode's
challenge of a rotational part by the box, graspsim.perception.decompose)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from graspsim.perception import IdentifyConfig, identify
from graspsim.planning.scene_config import SCENE_FIT_POINTS, SCENE_MAX_NOISE_RATIO
from graspsim.primitives import Cylinder, synthetic_cloud
from graspsim.primitives.box import Box
from graspsim.transforms import make_transform

EYE = np.array([0.0, -0.4, 0.6])  # E10's camera over the table's origin [m]


def _view(box: Box, seed: int, noise: float):
    """``box`` standing on the table at a seeded yaw, seen from EYE."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(0.0, np.pi)
    c, s = np.cos(yaw), np.sin(yaw)
    T = make_transform(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), [0.0, 0.0, box.z / 2])
    cam = (np.linalg.inv(T) @ np.r_[EYE, 1.0])[:3]
    return synthetic_cloud(box, rng, resolution=0.003, noise=noise, camera=cam, T_world_obj=T).points


SCENE = IdentifyConfig(fit_points=SCENE_FIT_POINTS, max_noise_ratio=SCENE_MAX_NOISE_RATIO)  # the scene planner's
DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize("seed", range(6))
def test_block_seen_on_two_faces_is_one_box(seed):
    # seed 3: the paper's rules alone decide a cylinder of radius 2.6 cm
    res = identify(_view(Box(0.15, 0.05, 0.03), seed, 0.003), rng=np.random.default_rng(seed), config=SCENE)
    assert [p.shape.value for p in res.parts] == ["box"]
    x, y, z = sorted(res.parts[0].dims.values())
    assert 0.02 <= x <= 0.045 and 0.04 <= y <= 0.06 and 0.135 <= z <= 0.165


@pytest.mark.parametrize("seed", range(3))
def test_standing_domino_is_a_box(seed):
    # a segment of E10's (tests/data): by the paper's rules alone a cone (seed 1) or a cylinder (seed 2)
    pts = np.array(json.loads((DATA / "domino_standing_segment.json").read_text())["points"])
    res = identify(pts, rng=np.random.default_rng(seed), config=SCENE)
    assert [p.shape.value for p in res.parts] == ["box"]


@pytest.mark.parametrize("seed", range(4))
def test_standing_can_stays_a_cylinder(seed):
    # the box challenges a rotational part but does not win where the part is round
    rng = np.random.default_rng([seed, 1])
    cam = (EYE - [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 0.0465])
    pts = synthetic_cloud(Cylinder(0.033, 0.093), rng, resolution=0.003, noise=0.0025, camera=cam).points
    res = identify(pts, rng=np.random.default_rng(seed), config=SCENE)
    assert [p.shape.value for p in res.parts] == ["cylinder"]


@pytest.mark.parametrize("seed", range(4))
def test_lying_bottle_stays_a_cylinder(seed):
    # a thin plate behind the curved strip a camera sees scores well on distances alone (its small area, its hidden
    # back face catching the noise); its faces do not face as the points do (decompose._facing)
    rng = np.random.default_rng([seed, 2])
    yaw = rng.uniform(0.0, np.pi)
    c, s = np.cos(yaw), np.sin(yaw)
    T = make_transform(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]), [0.0, 0.0, 0.026])
    cam = (np.linalg.inv(T) @ np.r_[EYE, 1.0])[:3]
    pts = synthetic_cloud(Cylinder(0.026, 0.15), rng, resolution=0.003, noise=0.0025, camera=cam, T_world_obj=T).points
    res = identify(pts, rng=np.random.default_rng(seed), config=SCENE)
    assert "box" not in [p.shape.value for p in res.parts]
