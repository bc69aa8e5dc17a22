"""Maps adapted to another gripper (paper section 5): identity, opening limits, B's limits."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A as A
from graspsim.maps.collide import boxes_clear_sdf
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.regrip import adapt_to_gripper, pad_depth
from graspsim.primitives import Cylinder

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def cyl_fs():
    return generate_fs_map(Cylinder(0.02, 0.10), config=FAST)


def _rows(m) -> np.ndarray:
    """Each row as (contacts, orientation, wrist position): (N, 13)."""
    return np.column_stack([m.contacts.reshape(-1, 6), m.wrist_quat, m.wrist_position]).astype(float)


def _within(a, b, tol: float = 2e-6) -> np.ndarray:
    """(len(a),) bool: the row of map ``a`` is a row of map ``b`` (to ``tol``)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(len(a), bool)
    return cKDTree(_rows(b)).query(_rows(a), distance_upper_bound=tol)[0] <= tol


def _same_rows(a, b) -> bool:
    return len(a) == len(b) and _within(a, b).all() and _within(b, a).all()


def test_adapting_to_the_same_gripper_is_the_identity(cyl_fs):
    same = adapt_to_gripper(cyl_fs, A, source_min_grade=0.0, keep_min_grade=0.0)
    # the re-check of A's own poses may only differ at the collision tolerance's edge
    assert len(same) >= 0.999 * len(cyl_fs)
    assert _within(same, cyl_fs).all()
    acc = adapt_to_gripper(cyl_fs, A)  # the paper's default: the accepted grasps
    assert len(acc) >= 0.999 * int(cyl_fs.accepted.sum()) and np.all(acc.grade > 0.7)
    assert acc.meta.gripper == A.to_dict() and acc.meta.extra["source_gripper"] == A.to_dict()


def test_a_smaller_stroke_drops_exactly_the_grasps_wider_than_its_opening(cyl_fs):
    small = replace(A, stroke_per_jaw=0.025)  # largest opening 5 cm: chords up to 4 cm
    same = adapt_to_gripper(cyl_fs, A, source_min_grade=0.0, keep_min_grade=0.0)
    got = adapt_to_gripper(cyl_fs, small, source_min_grade=0.0, keep_min_grade=0.0)
    fits = same.width + 2 * small.approach_clearance <= small.max_opening + 1e-9
    assert 0 < fits.sum() < len(same)  # the case drops some grasps and keeps some
    assert _same_rows(got, same.select(fits))
    assert got.meta.extra["gripper_adaptation"]["fit_opening"] == int(
        (cyl_fs.width + 2 * small.approach_clearance <= small.max_opening + 1e-9).sum())


def test_pad_depth_maps_the_usable_pad_onto_the_usable_pad():
    b = replace(A, pad_length=0.03, contact_depth_margin=0.004)
    d = np.array([A.contact_depth_margin, A.pad_length / 2, A.pad_length - A.contact_depth_margin])
    np.testing.assert_allclose(pad_depth(d, A, b), [0.004, 0.015, 0.026])
    np.testing.assert_allclose(pad_depth(d, A, A), d)


_variant = st.builds(
    lambda finger, pad_frac, stroke: replace(
        A, finger_size=(0.01, 0.02, finger), pad_length=round(max(0.015, pad_frac * finger), 4),
        stroke_per_jaw=stroke, housing_size=(max(0.18, 2 * (stroke + 0.03)), 0.05, 0.06)),
    st.sampled_from([0.04, 0.06, 0.08, 0.11]), st.sampled_from([0.3, 0.5, 0.8]),
    st.sampled_from([0.02, 0.03, 0.06, 0.08]))


@settings(max_examples=12, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(b=_variant)
def test_adapted_grasps_respect_the_new_grippers_limits(cyl_fs, b):
    m = adapt_to_gripper(cyl_fs, b)
    assert m.meta.gripper_spec == b and m.meta.method == "gripper/combined"
    assert np.all(m.grade > m.threshold)
    assert np.all(m.width + 2 * b.approach_clearance <= b.max_opening + 1e-6)
    assert np.all(m.width >= b.min_opening)
    depth = b.contact_depth(m.grasp_point.astype(float), m.wrist_position.astype(float), m.approach)
    grid = b.contact_depths(FAST.depth_step)
    assert np.all(np.min(np.abs(depth[:, None] - grid[None]), axis=1) < 1e-5)  # on B's pad grid
    src = set(map(tuple, np.round(cyl_fs.contacts.reshape(-1, 6), 6)))
    assert set(map(tuple, np.round(m.contacts.reshape(-1, 6), 6))) <= src  # only A's grasps move
    # collision-free for B by the independent branch-and-bound check (a sample of rows)
    rows = np.random.default_rng(0).choice(len(m), min(40, len(m)), replace=False) if len(m) else []
    if len(rows):
        sub = m.select(rows)
        opening = sub.width.astype(float) + 2 * b.approach_clearance
        assert boxes_clear_sdf(Cylinder(0.02, 0.10), b, sub.T_obj_wrist, opening).all()


def test_a_mesh_map_cannot_be_adapted(cyl_fs):
    mesh_map = cyl_fs.with_meta(object={"file": "duck.obj", "scale": 1.0, "com": [0, 0, 0]})
    with pytest.raises(InvalidParameterError, match="object geometry"):
        adapt_to_gripper(mesh_map, A)
