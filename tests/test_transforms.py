import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from graspsim.transforms import (
    angle_between,
    cross3,
    frame_from_axes,
    invert_transform,
    make_transform,
    matrix_to_quat,
    normalize,
    quat_to_matrix,
    random_rotation,
    transform_points,
)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_quaternion_round_trip_is_wxyz(seed):
    rng = np.random.default_rng(seed)
    R = random_rotation(rng, 5)
    q = matrix_to_quat(R)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-12)


def test_quaternion_order_matches_mujoco():
    # 90 degrees about z: w = cos(45), z = sin(45)
    q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    np.testing.assert_allclose(quat_to_matrix(q) @ [1, 0, 0], [0, 1, 0], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_inverse_transform_round_trip(seed):
    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng, 4), rng.normal(size=(4, 3)))
    I = T @ invert_transform(T)
    np.testing.assert_allclose(I, np.broadcast_to(np.eye(4), I.shape), atol=1e-12)
    p = rng.normal(size=(4, 3))
    np.testing.assert_allclose(transform_points(invert_transform(T), transform_points(T, p)), p, atol=1e-12)


def test_frame_from_axes_is_right_handed(rng):
    z = rng.normal(size=(10, 3))
    x = rng.normal(size=(10, 3))
    R = frame_from_axes(x, z)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_allclose(R[:, :, 2], z / np.linalg.norm(z, axis=1, keepdims=True), atol=1e-12)


def test_angle_between_extremes():
    a = np.array([[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    b = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 3.0, 0]])
    np.testing.assert_allclose(angle_between(a, b), [0, np.pi, np.pi / 2], atol=1e-12)


def test_quaternion_product_composes_rotations(rng):
    from graspsim.transforms import quat_multiply

    Ra, Rb = random_rotation(rng, 6), random_rotation(rng, 6)
    q = quat_multiply(matrix_to_quat(Ra), matrix_to_quat(Rb))
    np.testing.assert_allclose(quat_to_matrix(q), Ra @ Rb, atol=1e-12)
    assert np.all(q[:, 0] >= 0)


def test_cross3_and_normalize_are_numpys_to_the_bit():
    rng = np.random.default_rng(5)
    for sa, sb in (((7, 3), (7, 3)), ((4, 5, 1, 3), (4, 5, 6, 3)), ((3,), (9, 3))):
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        assert cross3(a, b).tobytes() == np.cross(a, b).tobytes()
        assert cross3(a, b).shape == np.cross(a, b).shape
    v = np.concatenate([rng.normal(size=(50, 3)), np.zeros((2, 3))])
    want = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
    assert normalize(v).tobytes() == want.tobytes()
    assert normalize(v.T, axis=0).tobytes() == (v.T / np.maximum(np.linalg.norm(v.T, axis=0, keepdims=True),
                                                                    1e-12)).tobytes()
