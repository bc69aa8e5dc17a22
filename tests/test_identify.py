"""Identification: primitives recovered in random poses, compound objects split into
their parts, failure is a result, same seed same answer; rules and match decisions."""

from __future__ import annotations

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError, PointCloudError
from graspsim.maps.match import MatchKind, classify_match
from graspsim.perception import (
    IdentificationStatus,
    IdentifyConfig,
    Shape,
    ShapeFeatures,
    classify,
    identify,
)
from graspsim.primitives import Cone, Cylinder, synthetic_cloud
from graspsim.transforms import invert_transform, make_transform, random_rotation, transform_points
from tests.conftest import PAPER_SHAPES
from tests.test_mvbb import ball_on_plate, bottle


def _cloud(shape, seed, **kw):
    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), rng.uniform(-0.5, 0.5, 3))
    kw = {"resolution": 0.005, "noise": 0.001, "outliers": 0.01} | kw
    return synthetic_cloud(shape, rng, T_world_obj=T, **kw)


@pytest.mark.parametrize("seed", [0, 1])
def test_each_primitive_is_recovered_in_random_poses(shape, seed):
    cloud = _cloud(shape, seed)
    res = identify(cloud.points, rng=np.random.default_rng(seed))
    assert res.status is IdentificationStatus.IDENTIFIED and len(res.parts) == 1
    part = res.parts[0]
    assert part.shape.value == shape.kind
    # dims within 3 mm or 5 % (box edges sorted, z the longest)
    want = sorted(shape.dims.values()) if shape.kind == "box" else list(shape.dims.values())
    np.testing.assert_allclose(list(part.dims.values()), want, atol=0.003, rtol=0.05)
    # the primitive placed at T_world_obj reproduces the cloud (object frame, COM origin)
    inl = ~cloud.is_outlier
    d = part.primitive().sdf(transform_points(invert_transform(part.T_world_obj), cloud.points[inl]))
    assert np.median(np.abs(d)) < 0.0015
    if shape.kind != "sphere":  # a sphere has no orientation to agree on
        z_true, z_found = cloud.T_world_obj[:3, 2], part.T_world_obj[:3, 2]
        assert abs(z_true @ z_found) > 0.99 or shape.kind == "box"
    assert res.n_points == len(cloud.points) and part.n_points <= len(cloud.points)


def _single_view(shape, seed, *, resolution=0.001, noise=0.0015):
    """A depth camera 0.6 m away, 35 deg up, at a seeded azimuth; noise along the ray."""
    az = np.random.default_rng([seed, 7]).uniform(0, 2 * np.pi)
    cam = 0.6 * np.array([np.cos(0.61) * np.cos(az), np.cos(0.61) * np.sin(az), np.sin(0.61)])
    return synthetic_cloud(shape, np.random.default_rng(seed), resolution=resolution, noise=noise,
                           outliers=0.005, camera=cam)


NOISE = 0.0015  # depth noise of _single_view [m]


@pytest.fixture(scope="module")
def dense_single_views():
    """A cylinder r 3 cm, h 10 cm, standing, seen from 35 deg above (top cap and one side
    visible, the bottom cap never) by _single_view, seeds 0-5: (cloud, identification)."""
    out = []
    for seed in range(6):
        cloud = _single_view(Cylinder(0.03, 0.10), seed)
        out.append((cloud, identify(cloud.points, rng=np.random.default_rng(seed))))
    return out


def _ends(cloud, part) -> tuple[float, float]:
    """Bottom and top of the fitted cylinder along the true axis, true frame [m]."""
    T = cloud.T_world_obj
    c = float((part.T_world_obj[:3, 3] - T[:3, 3]) @ T[:3, 2])
    h = part.dims["height"]
    return c - 0.5 * h, c + 0.5 * h


@pytest.mark.parametrize("seed", range(6))
def test_dense_single_view_cylinder_with_depth_noise(dense_single_views, seed):
    """1 mm spacing, 1.5 mm depth noise (noise above the spacing): one cylinder. What one
    view fixes: the radius (the whole visible side) and the seen top end (its cap) to
    within the noise sigma. The bottom end is unseen: only side points within a few sigma
    of the rim hold it, so the refined fit may stop short of it by up to ~2 sigma (on
    AVX2-only numpy, seed 2 stops 2.8 mm short: 96.8 mm tall, the failure reported on a
    fresh clone; with AVX-512, 1.5 mm at most) -- allowed 3 sigma; it may not reach past
    it by more than sigma (the fit is cut back to its inliers' extent). Seen through the
    ends, the height is within 6 mm, and across the seeds typically within 1.5 mm (the
    next test). With plain 16-neighbour normals this was 6 of 10 seeds."""
    cloud, res = dense_single_views[seed]
    assert res.status is IdentificationStatus.IDENTIFIED and len(res.parts) == 1
    part = res.parts[0]
    assert part.shape is Shape.CYLINDER
    assert abs(part.dims["radius"] - 0.03) <= NOISE
    bottom, top = _ends(cloud, part)
    assert abs(top - 0.05) <= NOISE, f"top end {top * 1e3:.2f} mm, true 50 mm"
    assert -NOISE <= bottom + 0.05 <= 3 * NOISE, f"bottom end {bottom * 1e3:.2f} mm, true -50 mm"


def test_dense_single_view_cylinder_heights_across_seeds(dense_single_views):
    """The single-view height errors over six seeds: median within the noise sigma (the
    unseen end's occasional shortfall above is not the rule: on AVX-512 numpy the errors
    are 0.1-1.3 mm, with AVX2-only numpy and Haswell BLAS two seeds fall 2.0 and 3.2 mm
    short and the median is 0.9 mm)."""
    err = np.array([abs(r.parts[0].dims["height"] - 0.10) for _, r in dense_single_views])
    assert np.median(err) <= NOISE, err


@pytest.mark.parametrize("seed", range(3))
def test_weakly_tapered_frustum_is_a_cone(seed):
    """A pencil cup (r 3.5 -> 4.2 cm over 11 cm) seen from one side with 1.5 mm depth
    noise: four-point cone samples are ill-posed for a 3.6 deg taper; the cone refined
    from the cylinder fit finds it, and its unseen bottom is cut back to its points."""
    cloud = _single_view(Cone(0.035, 0.042, 0.11), seed)
    res = identify(cloud.points, rng=np.random.default_rng(seed))
    assert res.status is IdentificationStatus.IDENTIFIED and len(res.parts) == 1
    part = res.parts[0]
    assert part.shape is Shape.CONE
    np.testing.assert_allclose([part.dims[k] for k in ("bottom_radius", "top_radius", "height")],
                               [0.042, 0.035, 0.11], atol=0.003)


def test_frustum_seen_with_its_base_disc_is_a_cone():
    """A wide frustum (r 5 -> 2 cm, h 8 cm) seen from below: about half the points lie
    on the base disc, so four-point samples that mix in disc points give no cone; cone
    samples are drawn off the largest flat face. With plain sampling 5 of these 12 views
    were identified; now at least 10 must be, with dims within 5 mm."""
    shape = Cone(0.05, 0.02, 0.08)
    ok = 0
    for seed in range(12):
        rng = np.random.default_rng(seed)
        az = rng.uniform(0, 2 * np.pi)
        cam = 0.6 * np.array([0.8 * np.cos(az), 0.8 * np.sin(az), -0.6])  # from below the base
        cloud = synthetic_cloud(shape, rng, resolution=0.005, noise=0.001, outliers=0.01, camera=cam)
        assert 0.4 < np.mean(np.abs(shape.normals(cloud.points)[:, 2]) > 0.95) < 0.75
        res = identify(cloud.points, rng=np.random.default_rng(seed))
        if res.status is IdentificationStatus.IDENTIFIED and [p.shape for p in res.parts] == [Shape.CONE]:
            d = res.parts[0].dims
            ok += bool(np.allclose([d["bottom_radius"], d["top_radius"], d["height"]], [0.05, 0.02, 0.08],
                                   atol=0.005))
    assert ok >= 10


def test_single_view_half_toroids_find_where_their_half_starts():
    """Single views of a half-toroid (R 5 cm, r 1.2 cm) from random directions: the
    hypothesis aims the half at the mean direction of the points it sees, which one view
    biases; the most likely turn about the ring's axis is searched. Without the search
    14 of these 16 views were identified; now at least 15 must be, dims within 5 / 3 mm."""
    from graspsim.primitives import HalfToroid
    from graspsim.transforms import normalize

    shape, ok = HalfToroid(0.05, 0.012), 0
    for seed in range(16):
        rng = np.random.default_rng(seed)
        T = make_transform(random_rotation(rng), [0, 0, 0])
        cloud = synthetic_cloud(shape, rng, resolution=0.005, noise=0.001, outliers=0.01,
                                camera=0.6 * normalize(rng.normal(size=3)), T_world_obj=T)
        res = identify(cloud.points, rng=np.random.default_rng(seed))
        if res.status is IdentificationStatus.IDENTIFIED and [p.shape for p in res.parts] == [Shape.HALF_TOROID]:
            d = res.parts[0].dims
            ok += abs(d["major_radius"] - 0.05) < 0.005 and abs(d["minor_radius"] - 0.012) < 0.003
    assert ok >= 15


def test_same_seed_same_result():
    cloud = _cloud(PAPER_SHAPES["half_toroid"], 3)
    a = identify(cloud.points, rng=np.random.default_rng(11)).to_dict()
    b = identify(cloud.points, rng=np.random.default_rng(11)).to_dict()
    a.pop("seconds"), b.pop("seconds")
    assert a == b


@pytest.mark.slow
@pytest.mark.parametrize("make, kinds", [(bottle, ["cylinder", "cylinder"]),
                                         (ball_on_plate, ["box", "sphere"])])
def test_compound_objects_split_into_their_parts(make, kinds):
    """At the paper's theta_th = 0.5: both objects gain > 50 % volume by one split."""
    obj = make()
    cloud = _cloud(obj, 4, outliers=0.0)
    res = identify(cloud.points, rng=np.random.default_rng(4), config=IdentifyConfig(theta=0.5))
    assert res.status is IdentificationStatus.IDENTIFIED and res.n_splits == 1
    assert sorted(p.shape.value for p in res.parts) == kinds
    want = sorted((p.kind, tuple(sorted(p.dims.values()))) for p in obj.parts)
    got = sorted((p.shape.value, tuple(sorted(p.dims.values()))) for p in res.parts)
    for (k1, d1), (k2, d2) in zip(want, got):
        assert k1 == k2
        np.testing.assert_allclose(d2, d1, atol=0.006)


def test_the_bottle_fails_in_paper_mode_when_splitting_is_not_allowed():
    cloud = _cloud(bottle(), 5, outliers=0.0)
    res = identify(cloud.points, rng=np.random.default_rng(5), config=IdentifyConfig.preset("paper", theta=0.2))
    assert res.status is IdentificationStatus.FAILED and res.parts == ()
    assert len(res.unidentified) == 1 and res.unidentified[0].shape is Shape.UNIDENTIFIED
    assert res.unidentified[0].n_points == len(cloud.points)


@pytest.mark.parametrize("case", ["patches", "scatter"])
def test_sparse_non_continuous_cloud_fails_without_an_exception(case):
    rng = np.random.default_rng(6)
    if case == "patches":  # six separate 1 cm patches of a 5 cm sphere, 15 points each
        centres = rng.normal(size=(6, 3))
        d = centres[:, None, :] + 0.2 * rng.normal(size=(6, 15, 3))
        pts = 0.05 * (d / np.linalg.norm(d, axis=2, keepdims=True)).reshape(-1, 3)
    else:  # points scattered through a 10 cm cube
        pts = rng.uniform(-0.05, 0.05, size=(150, 3))
    res = identify(pts, rng=rng)
    assert res.status is IdentificationStatus.FAILED and res.unidentified
    assert all(p.reason for p in res.unidentified)
    assert sum(p.n_points for p in res.parts + res.unidentified) + res.n_removed == len(pts)


def test_bad_input_raises_point_cloud_errors():
    with pytest.raises(PointCloudError, match="empty"):
        identify(np.zeros((0, 3)), rng=np.random.default_rng(0))
    with pytest.raises(PointCloudError, match="at least 30"):
        identify(np.random.default_rng(0).normal(size=(12, 3)), rng=np.random.default_rng(0))
    with pytest.raises(InvalidParameterError, match="theta must be in"):
        IdentifyConfig(theta=1.5)
    with pytest.raises(InvalidParameterError, match="repetitions"):
        IdentifyConfig(repetitions=0)
    with pytest.raises(InvalidParameterError, match="max_extent_ratio must be >= 1"):
        IdentifyConfig(max_extent_ratio=0.5)
    with pytest.raises(InvalidParameterError, match="min_coverage"):
        IdentifyConfig(min_coverage=1.0)


def _features(**rates):
    base = dict(sphere=0.2, cylinder=0.3, box=0.3, cone=0.3, half_toroid=0.2) | rates
    return lambda sym=float("nan"), half=float("nan"), r=0.02: ShapeFeatures(
        base["sphere"], base["cylinder"], sym, half, r, base)


def test_rule_base():
    s = 0.001
    assert classify(_features()(), s) is Shape.UNIDENTIFIED
    assert classify(_features(sphere=0.99, cone=0.99)(), s) is Shape.SPHERE
    cyl = _features(cylinder=0.99, cone=0.995)
    assert classify(cyl(sym=0.001, half=0.0002), s) is Shape.CYLINDER
    assert classify(cyl(sym=0.001, half=0.01), s) is Shape.CONE  # tapered halves
    assert classify(_features(cone=0.99)(sym=0.001, half=0.01), s) is Shape.CONE
    # an untapered cone is a cylinder, even when only the cone fit well enough
    assert classify(_features(cone=0.99)(sym=0.001, half=0.0002), s) is Shape.CYLINDER
    assert classify(_features(cone=0.99)(sym=0.01, half=0.0002), s) is Shape.CYLINDER  # spoiled symmetry
    assert classify(_features(cone=0.99)(), s) is Shape.CONE  # no feature to tell: the fit decides
    assert classify(_features(box=0.99, cylinder=0.98)(sym=0.004, half=0.0), s) is Shape.BOX
    assert classify(_features(half_toroid=0.99, box=0.9)(sym=0.006), s) is Shape.HALF_TOROID
    # a box and a half-toroid fitting equally well: the box (simpler, rule 4) wins
    assert classify(_features(half_toroid=0.99, box=0.98)(sym=0.006), s) is Shape.BOX


def test_known_familiar_decision():
    stored = [{"primitive": "cylinder", "dims": {"radius": 0.02, "height": 0.20}, "key": "c1"},
              {"primitive": "cylinder", "dims": {"radius": 0.04, "height": 0.10}, "key": "c2"},
              {"primitive": "box", "dims": {"x": 0.06, "y": 0.04, "z": 0.10}, "key": "b1"}]
    d = classify_match("cylinder", {"radius": 0.0203, "height": 0.205}, stored)  # within 3 %: known
    assert d.match is MatchKind.KNOWN and d.match == "known" and d.entry["key"] == "c1"
    d = classify_match("cylinder", {"radius": 0.025, "height": 0.205}, stored)  # within 1 cm, 25 % wider
    assert d.match is MatchKind.FAMILIAR and d.entry["key"] == "c1"
    d = classify_match("cylinder", {"radius": 0.02, "height": 0.22}, stored)
    assert d.match is MatchKind.FAMILIAR and d.entry["key"] == "c1"
    assert d.max_diff == pytest.approx(0.02)
    assert classify_match("sphere", {"radius": 0.02}, stored).match is MatchKind.BUILD
    # boxes compare sorted edges
    assert classify_match("box", {"x": 0.06, "y": 0.04, "z": 0.1}, stored).match is MatchKind.KNOWN
    with pytest.raises(InvalidParameterError, match="dims"):
        classify_match("cylinder", {"radius": 0.02}, stored)
