"""Touching objects parted along the concave crease between them (SceneConfig.crease_angle),
without splitting one object: rendered by the scene camera with its depth noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspsim.geometry.camera import backproject, rig
from graspsim.planning.scene import perceive_scene
from graspsim.planning.scene_config import SceneConfig
from graspsim.primitives import Box, Cylinder
from graspsim.tabletop.clutter import one_cluster_objects
from graspsim.tabletop.depth_noise import DepthNoise
from graspsim.tabletop.scene_objects import ObjectSpec
from graspsim.tabletop.scene_sim import SceneSim
from graspsim.transforms import make_transform


def _spec(shape) -> ObjectSpec:
    return ObjectSpec("primitive", shape.kind, shape.to_dict())


def _yaw(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def _segments(objects, seeds=(0, 1), **cfg):
    """(objects seen, one cluster, segments) per depth-noise draw of E10's camera."""
    cam = rig(1)[0]
    sim = SceneSim(objects)
    out = []
    try:
        for seed in seeds:
            view = backproject(sim.render(cam, noise=DepthNoise(), rng=np.random.default_rng(seed)))
            per = perceive_scene(view.world(), np.random.default_rng(0), SceneConfig(**cfg),
                                 viewpoint=cam.T_world_camera[:3, 3])
            out.append((*one_cluster_objects(view.labels[per.indices], per.segment), per.n_segments))
    finally:
        sim.close()
    return out


def _touching_boxes():
    """A tall box behind a low one, touching: the low box's top meets the tall box's front
    face (towards the camera) in a concave crease; no gap anywhere between them."""
    R = _yaw(10)
    return [(_spec(Box(0.05, 0.06, 0.07)), make_transform(R, R @ [0.0, 0.03, 0.035])),
            (_spec(Box(0.05, 0.06, 0.04)), make_transform(R, R @ [0.01, -0.03, 0.02]))]


def test_two_touching_boxes_come_apart_along_their_crease():
    assert all(r == (2, 2, 2) for r in _segments(_touching_boxes()))
    # the spacing rule alone sees one object (what the crease cut adds)
    assert all(r[1] == 0 for r in _segments(_touching_boxes(), crease_angle=None))


def test_one_object_is_not_split_by_its_own_edges():
    R = _yaw(25)
    lying = make_transform(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]) @ _yaw(0), [0.09, 0.0, 0.03])
    objs = [(_spec(Box(0.06, 0.05, 0.09)), make_transform(R, [-0.08, 0.0, 0.045])),
            (_spec(Cylinder(0.03, 0.1)), lying)]  # apart: each alone, convex edges only
    assert all(r == (2, 2, 2) for r in _segments(objs))


def test_known_gaps_leave_the_clustering_as_it_was():
    """With a known least gap (packed scenes) objects do not touch: no crease cut."""
    a = _segments(_touching_boxes(), seeds=(0,), min_gap=0.01)
    b = _segments(_touching_boxes(), seeds=(0,), min_gap=0.01, crease_angle=None)
    assert a == b


@pytest.mark.parametrize("bad", [0, 180, -5, "15"])
def test_a_bad_crease_angle_is_refused(bad):
    from graspsim.errors import InvalidParameterError

    with pytest.raises(InvalidParameterError, match="crease_angle"):
        SceneConfig(crease_angle=bad)
