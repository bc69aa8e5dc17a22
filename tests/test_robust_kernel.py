"""The robust kernel's shared pass over the points (graspsim/maps/_robust_kernel.py):
the points it keeps for the openings are every point some opening needs."""

import numpy as np
import pytest

from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps._robust_geometry import merged_boxes
from graspsim.maps._robust_kernel import _shared_pass


def _distances(q, centers, half, sign, ho):
    """(M,) signed distance of points q (M, 3) to the union of the boxes at half gap ho."""
    c = centers.copy()
    c[:, 0] += sign * ho
    e = np.abs(q[:, None, :] - c[None]) - half[None]
    return (np.linalg.norm(np.maximum(e, 0.0), axis=-1) + np.minimum(e.max(axis=-1), 0.0)).min(axis=1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_shared_pass_keeps_every_point_an_opening_needs(seed):
    rng = np.random.default_rng(seed)
    centers, half, sign = merged_boxes(HGPL_25_60_A)
    M, n_cloud = 20000, 12000
    q = (rng.uniform([-0.12, -0.06, -0.04], [0.12, 0.06, 0.25], (M, 3))).astype(np.float32)
    reach = rng.uniform(0.002, 0.012, M).astype(np.float32)
    ho_lo, ho_hi = 0.012, 0.022  # the map's opening and 10 mm wider per side
    sd0, lb = np.empty(M, np.float32), np.empty(M, np.float32)
    bits0, keep = np.empty(M, np.int32), np.empty(M, np.int32)
    _shared_pass(q[:, 0].copy(), q[:, 1].copy(), q[:, 2].copy(), M, np.arange(M) < n_cloud, reach, centers, half, sign,
                 ho_lo, ho_hi, sd0, bits0, lb, keep)
    kept = keep.astype(bool)
    q64 = q.astype(float)
    for ho in np.linspace(ho_lo, ho_hi, 6):
        d = _distances(q64, centers, half, sign, ho)
        within = d <= reach - 1e-6  # within reach of a box at this opening (float32 rounding aside)
        assert np.all(kept[within]), f"{np.sum(within & ~kept)} points within reach dropped at {ho}"
        closest = np.argmin(d[:n_cloud])  # the cloud's clearance at this opening
        assert kept[closest]
    assert 0.01 < kept.mean() < 0.5  # the pass culls (else it would test nothing)
    # the boxes that do not move are measured exactly, with their reach bits
    fixed = sign == 0
    d_fixed = _distances(q64, centers[fixed], half[fixed], sign[fixed], 0.0)
    np.testing.assert_allclose(sd0, d_fixed, atol=1e-6)
    assert np.array_equal(bits0 != 0, sd0 <= reach)


def test_the_clouds_clearance_survives_when_no_point_is_within_reach():
    # every point farther than any reach: only the clearance keeps points, at every opening.
    # Points along the fingers, between and outside them: the closest lies between the
    # fingers at the widest opening and outside them at the narrowest
    rng = np.random.default_rng(3)
    centers, half, sign = merged_boxes(HGPL_25_60_A)
    cz, hz = centers[-1, 2], half[-1, 2]  # a finger's box
    q = rng.uniform([-0.06, -0.005, cz - hz], [0.06, 0.005, cz + hz], (40000, 3))
    ho_lo, ho_hi = 0.012, 0.022
    near = np.min([_distances(q, centers, half, sign, ho) for ho in (ho_lo, ho_hi)], axis=0)
    q = q[near > 0.004].astype(np.float32)
    M = len(q)
    reach = np.full(M, 0.001, np.float32)
    sd0, lb = np.empty(M, np.float32), np.empty(M, np.float32)
    bits0, keep = np.empty(M, np.int32), np.empty(M, np.int32)
    _shared_pass(q[:, 0].copy(), q[:, 1].copy(), q[:, 2].copy(), M, np.ones(M, bool), reach, centers, half, sign,
                 ho_lo, ho_hi, sd0, bits0, lb, keep)
    kept = keep.astype(bool)
    for ho in np.linspace(ho_lo, ho_hi, 11):
        d = _distances(q.astype(float), centers, half, sign, ho)
        assert kept[np.argmin(d)], ho
    assert not kept.all()
