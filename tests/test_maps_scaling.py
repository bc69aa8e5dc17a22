"""Map scaling (paper 2.4): invariants of the three algorithms."""

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.collide import boxes_clear_sdf
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.scaling import ScalingConfig, ScalingMethod, scale_factors, scale_map, scale_stream
from graspsim.primitives import Box, Cone, Cylinder, HalfToroid, Sphere

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def cyl_fs():
    return generate_fs_map(Cylinder(0.02, 0.12), config=FAST)


@pytest.mark.parametrize("method", list(ScalingMethod))
def test_factor_one_returns_the_accepted_fs_map(cyl_fs, method):
    m = scale_map(cyl_fs, Cylinder(0.02, 0.12), scaling=ScalingConfig(method=method))
    acc = cyl_fs.filter(accepted=True)
    assert len(m) == len(acc)
    # one wrist pose can hold several chords (different widths along the approach axis)
    key = lambda g: np.lexsort(np.column_stack(  # noqa: E731
        [np.round(g.wrist_position, 5), np.round(g.wrist_quat, 5), np.round(g.contacts.reshape(-1, 6), 5)]).T)
    a, b = acc.select(key(acc)), m.select(key(m))
    np.testing.assert_allclose(b.wrist_position, a.wrist_position, atol=2e-6)
    np.testing.assert_allclose(b.contacts, a.contacts, atol=2e-6)
    np.testing.assert_allclose(b.grade, a.grade, atol=1e-5)


def test_up_then_down_returns_the_original_poses(cyl_fs):
    big = Cylinder(0.026, 0.15)
    up = scale_map(cyl_fs, big, scaling=ScalingConfig(method="quality", keep_min_grade=0.0))
    fs_big = up.with_meta(object={**up.meta.object}, quality=cyl_fs.meta.quality)
    down = scale_map(fs_big, Cylinder(0.02, 0.12),
                     scaling=ScalingConfig(method="quality", source_min_grade=0.0, keep_min_grade=0.0))
    orig = cyl_fs.filter(accepted=True)
    okey = {tuple(np.round(np.r_[w, q], 4)) for w, q in zip(orig.wrist_position, orig.wrist_quat)}
    dkey = {tuple(np.round(np.r_[w, q], 4)) for w, q in zip(down.wrist_position, down.wrist_quat)}
    assert len(dkey) > 0.8 * len(okey)
    assert dkey <= okey  # every pose that survives the round trip is an original one


@pytest.mark.parametrize("target", [Cylinder(0.024, 0.15), Cylinder(0.016, 0.1)])
@pytest.mark.parametrize("method", list(ScalingMethod))
def test_scaled_grasps_are_valid_and_regraded(cyl_fs, target, method):
    m = scale_map(cyl_fs, target, scaling=ScalingConfig(method=method))
    assert len(m) > 0 and m.meta.method == f"scaled/{method.value}"
    c = m.contacts.astype(float)
    assert np.abs(target.sdf(c.reshape(-1, 3))).max() < 2e-6
    assert np.all(m.width + 2 * G.approach_clearance <= G.max_opening + 1e-6)
    q = QualityModel().evaluate(c[:, 0], c[:, 1], m.normals[:, 0], m.normals[:, 1], np.zeros(3),
                                target.circumradius)
    np.testing.assert_allclose(m.grade, q.grade, atol=1e-5)
    assert np.all(m.grade > 0.7)
    idx = np.random.default_rng(0).choice(len(m), min(60, len(m)), replace=False)
    assert boxes_clear_sdf(target, G, m.T_obj_wrist[idx], m.width[idx] + 2 * G.approach_clearance).all()


def test_combined_keeps_at_least_quality(cyl_fs):
    t = Cylinder(0.024, 0.16)
    q = scale_map(cyl_fs, t, scaling=ScalingConfig(method="quality"))
    c = scale_map(cyl_fs, t, scaling=ScalingConfig(method="combined"))
    assert len(c) >= len(q)


@pytest.mark.parametrize("shape,target", [
    (Box(0.04, 0.05, 0.06), Box(0.05, 0.04, 0.07)),
    (Sphere(0.03), Sphere(0.04)),
    (Cone(0.035, 0.015, 0.08), Cone(0.04, 0.02, 0.09)),
    (HalfToroid(0.04, 0.01), HalfToroid(0.045, 0.012)),
])
def test_every_primitive_scales(shape, target):
    fs = generate_fs_map(shape, config=FAST)
    m = scale_map(fs, target)
    assert len(m) > 0
    assert np.abs(target.sdf(m.contacts.reshape(-1, 3).astype(float))).max() < 2e-6


def test_a_pointed_cone_scales_from_and_to_a_sub_millimetre_top():
    """Matching takes a top below MIN_DIM as a point (maps/match.py), so the grid's 0.4 mm
    tops serve identified tops of 0 and the other way round: scaled, with finite factors
    (the top's counted as 1), contacts on the target, and no more grasps than the source's
    or the target's own map offers (a pointed tip has no grasp across it)."""
    tip = generate_fs_map(Cone(0.03, 0.0004, 0.05), config=FAST)
    m = scale_map(tip, Cone(0.035, 0.0008, 0.06))
    assert len(m) > 0 and m.meta.extra["factors"]["top_radius"] == 1.0
    assert np.abs(Cone(0.035, 0.0008, 0.06).sdf(m.contacts.reshape(-1, 3).astype(float))).max() < 2e-6
    for source, target in ((tip, Cone(0.035, 0.0, 0.06)),
                           (generate_fs_map(Cone(0.03, 0.0, 0.05), config=FAST), Cone(0.035, 0.0008, 0.06))):
        assert scale_factors(source.meta.shape, target) == pytest.approx(
            {"bottom_radius": 3.5 / 3, "top_radius": 1.0, "height": 1.2})
        m = scale_map(source, target)  # within the range: no error
        own = generate_fs_map(target, config=FAST)
        assert len(m) <= max(int(own.accepted.sum()), int(source.accepted.sum()))
        if len(m):
            assert np.abs(target.sdf(m.contacts.reshape(-1, 3).astype(float))).max() < 2e-6


def test_stream_is_best_first_and_matches_the_whole(cyl_fs):
    t = Cylinder(0.022, 0.13)
    batches = list(scale_stream(cyl_fs, t))
    assert len(batches) > 2 and len(batches[0]) <= 2
    whole = scale_map(cyl_fs, t)
    assert sum(len(b) for b in batches) == len(whole)
    assert batches[0].grade.max() >= whole.grade.max() - 1e-6


def test_a_scaled_map_records_the_collision_tolerance_it_was_checked_to(cyl_fs):
    """The map's own generation tolerance unless the caller's config says otherwise (the
    planner's PlannerConfig.collision_tolerance; tests/test_planner.py)."""
    from dataclasses import replace

    t = Cylinder(0.022, 0.13)
    own = scale_map(cyl_fs, t)
    coarse = scale_map(cyl_fs, t, config=replace(cyl_fs.meta.map_config, collision_tolerance=0.003))
    assert own.meta.extra["collision_tolerance"] == cyl_fs.meta.map_config.collision_tolerance
    assert coarse.meta.extra["collision_tolerance"] == 0.003 and len(coarse) > 0


def test_limits_and_wrong_primitive(cyl_fs):
    with pytest.raises(InvalidParameterError, match="factor"):
        scale_map(cyl_fs, Cylinder(0.08, 0.12))
    with pytest.raises(InvalidParameterError, match="cylinder"):
        scale_map(cyl_fs, Sphere(0.02))


def test_a_skip_with_a_preference_drops_the_same_grasps_predicting_each_once(cyl_fs):
    """With a preference (stream order) and a skip (not scaled), each stored grasp's pose
    is predicted once and asked about once by each; the preference changes only the order:
    the grasps kept are those of the skip alone, and of a skip told nothing of the first."""
    t = Cylinder(0.022, 0.13)
    asked = {"prefer": 0, "skip": 0}
    predicted = []  # the predictions the preference was given

    def prefer(q, p, w):
        asked["prefer"] += len(q)
        predicted.append(p)
        return p[:, 2] > 0.0  # e.g. poses above the object's middle first

    def skip(q, p, w):
        asked["skip"] += len(q)
        assert any(p is x for x in predicted)  # the same prediction, not made again
        return p[:, 0] > 0.0  # poses on one side not scaled

    def rows(batches):
        g = GraspabilityMap_concat(batches)
        return np.unique(np.round(np.column_stack([g.wrist_position, g.wrist_quat, g.width]), 9), axis=0)

    both = list(scale_stream(cyl_fs, t, prefer=prefer, skip=skip))
    assert asked["prefer"] == asked["skip"] > 0  # one prediction: each asked about every row once
    alone = list(scale_stream(cyl_fs, t, skip=lambda q, p, w: p[:, 0] > 0.0))
    assert 0 < sum(len(b) for b in both) < len(scale_map(cyl_fs, t))
    np.testing.assert_array_equal(rows(both), rows(alone))


def GraspabilityMap_concat(batches):  # noqa: N802 -- the class's own concat, by name
    from graspsim.maps.graspmap import GraspabilityMap

    return GraspabilityMap.concat(batches, meta=batches[0].meta)
