import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel, force_closure_angle, stability_distance
from graspsim.transforms import random_rotation


def test_antipodal_sphere_grasp_through_centre_is_perfect():
    r = 0.03
    p1, p2 = np.array([[-r, 0, 0]]), np.array([[r, 0, 0]])
    n1, n2 = p1 / r, p2 / r
    q = QualityModel().evaluate(p1, p2, n1, n2, com=np.zeros(3), d_ref=r)
    assert q.fc_angle[0] == pytest.approx(0.0, abs=1e-12)
    assert q.grade[0] == pytest.approx(1.0)


def test_force_closure_cut_at_friction_cone():
    m = QualityModel(friction=0.5)
    a = np.array([0.0, 0.5, 1.0, 1.2]) * m.friction_angle
    # contact 1 normal tilted by a, contact 2 antipodal
    n1 = np.stack([-np.cos(a), np.sin(a), 0 * a], axis=1)
    p1 = np.tile([0.0, 0, 0], (4, 1))
    p2 = np.tile([1.0, 0, 0], (4, 1))
    n2 = np.tile([1.0, 0, 0], (4, 1))
    q = m.evaluate(p1, p2, n1, n2, com=np.array([0.5, 0, 0]), d_ref=1.0)
    np.testing.assert_allclose(q.fc_angle, a, atol=1e-12)
    np.testing.assert_allclose(q.q_fc, [1.0, 0.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(q.grade, 0.5 * q.q_fc + 0.5, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_quality_is_invariant_under_rigid_transforms(seed):
    rng = np.random.default_rng(seed)
    n = 20
    p1, p2, com = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=3)
    n1 = rng.normal(size=(n, 3))
    n2 = rng.normal(size=(n, 3))
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    n2 /= np.linalg.norm(n2, axis=1, keepdims=True)
    R, t = random_rotation(rng), rng.normal(size=3)
    m = QualityModel(stability_mode="closing_line")
    a = m.evaluate(p1, p2, n1, n2, com, 2.0)
    b = m.evaluate(p1 @ R.T + t, p2 @ R.T + t, n1 @ R.T, n2 @ R.T, R @ com + t, 2.0)
    for f in ("fc_angle", "q_fc", "stability_distance", "q_st", "grade"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), atol=1e-9)
    assert np.all((a.grade >= 0) & (a.grade <= 1))


def test_contact_order_does_not_matter(rng):
    p1, p2 = rng.normal(size=(10, 3)), rng.normal(size=(10, 3))
    n1, n2 = rng.normal(size=(10, 3)), rng.normal(size=(10, 3))
    np.testing.assert_allclose(force_closure_angle(p1, p2, n1, n2), force_closure_angle(p2, p1, n2, n1))


def test_stability_modes():
    p1, p2 = np.array([[0.0, -1, 0]]), np.array([[0.0, 1, 0]])
    com = np.array([0.3, 0.5, 0.0])
    assert stability_distance(p1, p2, com)[0] == pytest.approx(math.hypot(0.3, 0.5))
    assert stability_distance(p1, p2, com, "closing_line")[0] == pytest.approx(0.3)


@pytest.mark.parametrize(
    "kw", [{"friction": 0}, {"fc_weight": 1.5}, {"stability_mode": "x"}, {"threshold": 2},
           {"stability_reference": -1.0}]
)
def test_bad_parameters(kw):
    with pytest.raises(InvalidParameterError):
        QualityModel(**kw)


def test_model_from_map_metadata():
    m = QualityModel(friction=0.6)
    meta = {**m.to_dict(), "d_ref": 0.1}
    assert QualityModel.from_meta(meta) == m
    regraded = {"name": "pad_contact", "threshold": 0.88, "grade_model": {}, "base_quality": m.to_dict()}
    assert QualityModel.from_meta(regraded) == m
