"""The compiled nearest-other-location distances behind ``median_spacing``
(graspsim/geometry/spacing_kernel.py) against a KD-tree over the distinct rows."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from graspsim.errors import PointCloudError
from graspsim.geometry.spacing import median_spacing
from graspsim.geometry.spacing_kernel import nearest_other
from graspsim.perception.prepare import distinct_rows


def _reference(P):
    u = distinct_rows(P)
    return np.sort(cKDTree(u).query(u, k=2)[0][:, 1]) if len(u) >= 2 else np.full(len(u), np.inf)


def _clouds(rng):
    yield rng.normal(size=(2000, 3)) * 0.05  # a blob
    s = rng.normal(size=(3000, 3))
    yield s / np.linalg.norm(s, axis=1, keepdims=True) * 0.04  # a sphere's surface
    yield np.round(rng.uniform(-0.05, 0.05, (1500, 3)), 2)  # on a coarse lattice: many repeated points
    yield np.column_stack([rng.uniform(0, 0.3, 800), np.zeros(800), np.zeros(800)])  # a line
    yield np.concatenate([rng.normal(size=(500, 3)) * 0.01, rng.normal(size=(5, 3)) * 3.0])  # far outliers
    yield np.array([[0.0, 0.0, 0.0], [0.003, 0.0, 0.0]])


def test_the_distances_are_the_kd_trees():
    for P in _clouds(np.random.default_rng(0)):
        d = np.sort(nearest_other(np.ascontiguousarray(P, float)))
        ref = _reference(P)
        assert len(d) == len(ref)  # one per distinct location: repeated points count once
        np.testing.assert_allclose(d, ref, rtol=1e-12, atol=0)


@pytest.mark.parametrize("P, expected", [(np.zeros((5, 3)), 0.0), (np.zeros((1, 3)), 0.0), (np.zeros((0, 3)), 0.0)])
def test_a_single_location_has_no_spacing(P, expected):
    assert median_spacing(P) == expected


def test_non_finite_points_are_refused_by_name():
    P = np.concatenate([np.random.default_rng(1).normal(size=(50, 3)), [[np.inf, 0.0, 0.0]]])
    with pytest.raises(PointCloudError, match="1 of 51 points have NaN or inf"):
        median_spacing(P)


def test_a_remembered_spacing_is_the_spacing_of_the_same_points():
    """median_spacing keeps its last answers keyed by the points' bytes: asked again about
    equal points it answers as measured; about points changed in place, or others of the
    same shape, it measures afresh."""
    from graspsim.geometry import spacing

    rng = np.random.default_rng(3)
    P = rng.normal(size=(600, 3)) * 0.02
    first = median_spacing(P)
    assert median_spacing(P.copy()) == first == float(np.median(_reference(P)))
    P *= 2.0  # the same array, other points
    assert median_spacing(P) == pytest.approx(2.0 * first, rel=1e-12)
    assert median_spacing(P.astype(np.float32)) == float(np.median(_reference(P.astype(np.float32).astype(float))))
    for _ in range(spacing.REMEMBERED + 5):  # bounded: the oldest answers go
        median_spacing(rng.normal(size=(20, 3)))
    assert len(spacing._memo) <= spacing.REMEMBERED
