"""Minimum-volume bounding boxes and the hierarchical fit-and-split."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from graspsim.perception.mvbb import min_volume_box, pca_box
from graspsim.perception.split import _chain_areas, best_split, theta_star
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Sphere, synthetic_cloud
from graspsim.transforms import make_transform, random_rotation, transform_points


def _posed_cloud(shape, rng, noise=0.0005):
    T = make_transform(random_rotation(rng), rng.uniform(-0.5, 0.5, 3))
    return synthetic_cloud(shape, rng, resolution=0.005, noise=noise, T_world_obj=T), T


def test_box_cloud_gives_the_box(rng):
    for _ in range(3):
        cloud, T = _posed_cloud(Box(0.04, 0.06, 0.10), rng)
        box = min_volume_box(cloud.points)
        # the box bounds the noisy points: each side grows by ~3.5 sigma of 0.5 mm
        assert np.all(box.extents >= [0.04, 0.06, 0.10])
        np.testing.assert_allclose(box.extents, [0.04, 0.06, 0.10], atol=0.005)
        # the box axes are the object's axes (up to sign), sorted by extent
        assert np.allclose(np.abs(np.sum(box.axes * T[:3, :3], axis=0)), 1.0, atol=0.01)
        local = box.local(cloud.points)
        assert np.all(np.abs(local) <= box.extents / 2 + 1e-9)


@pytest.mark.parametrize("shape", [Cylinder(0.02, 0.2), Cone(0.04, 0.02, 0.1), HalfToroid(0.04, 0.01),
                                   Sphere(0.035), Box(0.02, 0.1, 0.15)])
def test_never_worse_than_trimesh_or_pca(rng, shape):
    cloud, _ = _posed_cloud(shape, rng)
    box = min_volume_box(cloud.points)
    _, ext = trimesh.bounds.oriented_bounds(cloud.points)
    assert box.volume <= np.prod(ext) * (1 + 1e-6)
    assert box.volume <= pca_box(cloud.points).volume * (1 + 1e-6)
    assert np.all(np.abs(box.local(cloud.points)) <= box.extents / 2 + 1e-9)


def test_volume_is_invariant_to_rigid_motion(rng):
    cloud, _ = _posed_cloud(Cone(0.04, 0.02, 0.1), rng)
    T = make_transform(random_rotation(rng), [1.0, -2.0, 0.5])
    v1 = min_volume_box(cloud.points).volume
    v2 = min_volume_box(transform_points(T, cloud.points)).volume
    assert v2 == pytest.approx(v1, rel=1e-6)


def test_flat_points_do_not_crash(rng):
    p = np.column_stack([rng.uniform(size=(50, 2)), np.zeros(50)])
    box = min_volume_box(p)
    assert box.volume == pytest.approx(0.0, abs=1e-12) and box.extents[2] > 0.5


def test_theta_star_is_eq_1():
    assert theta_star(10.0, (2.0, 3.0), 5.0) == pytest.approx((2 + 3 + 5) / (10 + 5))


def test_chain_areas_match_exact_hulls(rng):
    # with at most two points per slab the slab extremes are all points: areas are exact
    u = np.sort(rng.uniform(0, 1, 40))
    b = rng.uniform(0, 1, 40)
    group = np.arange(40) // 2
    areas = _chain_areas(u, b, group, 20)
    for g in range(2, 20):
        sel = group <= g
        assert areas[g] == pytest.approx(ConvexHull(np.column_stack([u[sel], b[sel]])).volume, rel=1e-9)


def _split_purity(obj, rng):
    cloud, T = _posed_cloud(obj, rng, noise=0.001)
    truth = obj.part_index(transform_points(np.linalg.inv(T), cloud.points))
    box = min_volume_box(cloud.points)
    split = best_split(cloud.points, box, min_points=30)
    assert split is not None
    theta = theta_star(box.volume, tuple(b.volume for b in split.boxes), 0.0)
    purity = [np.bincount(truth[m], minlength=2).max() / m.sum() for m in (split.mask, ~split.mask)]
    return theta, purity


def bottle():
    """Body r 3 cm h 8 cm with a neck r 1 cm h 12 cm: eq. (1) gives theta* ~ 0.47."""
    return Compound.from_parts([Cylinder(0.03, 0.08), Cylinder(0.01, 0.12)],
                               [make_transform(np.eye(3), [0, 0, 0.04]),
                                make_transform(np.eye(3), [0, 0, 0.14])])


def ball_on_plate():
    """A 3 cm ball resting on a 12 x 12 x 2 cm plate: theta* ~ 0.45."""
    return Compound.from_parts([Box(0.12, 0.12, 0.02), Sphere(0.03)],
                               [make_transform(np.eye(3), [0, 0, 0.01]),
                                make_transform(np.eye(3), [0, 0, 0.05])])


@pytest.mark.parametrize("make", [bottle, ball_on_plate])
def test_split_separates_the_parts(rng, make):
    theta, purity = _split_purity(make(), rng)
    assert theta < 0.5
    assert min(purity) > 0.95


def test_no_split_when_clusters_would_be_too_small(rng):
    cloud, _ = _posed_cloud(Sphere(0.02), rng)
    assert best_split(cloud.points, min_volume_box(cloud.points), min_points=len(cloud.points)) is None


def test_dense_noise_free_convex_clouds_stay_fast(rng):
    """Every point of a clean sphere is a hull vertex: the frame is searched on a
    thinned hull (this took minutes before), the box still bounds every point and
    is within 3 % of the box found on the full hull."""
    import time

    cloud = synthetic_cloud(Sphere(0.03), rng, resolution=0.0015)
    t0 = time.process_time()
    box = min_volume_box(cloud.points)
    assert time.process_time() - t0 < 5.0
    assert np.all(np.abs(box.local(cloud.points)) <= box.extents / 2 + 1e-9)
    small = cloud.points[::6]
    assert len(ConvexHull(small).vertices) > 400
    full = min_volume_box(small, max_hull_points=10**9)
    assert min_volume_box(small).volume <= full.volume * 1.03
