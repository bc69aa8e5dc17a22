"""The k best grasps at least a pose apart (non-maximum suppression)."""

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps.separation import separated_rows
from graspsim.transforms import matrix_to_quat

D, A = 0.01, math.radians(20)


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _grasps(rows):
    """(grasp points, quaternions) from (point, rotation matrix) pairs."""
    p = np.array([r[0] for r in rows], float)
    q = matrix_to_quat(np.stack([r[1] for r in rows]))
    return p, q


def test_near_duplicates_are_suppressed_and_distinct_grasps_kept_in_order():
    I3 = np.eye(3)
    p, q = _grasps([
        ([0, 0, 0], I3),                      # 0: the best
        ([0.004, 0, 0], _rz(5)),              # 1: 4 mm, 5 deg from 0: a duplicate
        ([0, 0.002, 0], _rz(180)),            # 2: the jaws swapped: the same grasp
        ([0, 0, 0], _rz(90)),                 # 3: same point, closing across: distinct
        ([0.03, 0, 0], I3),                   # 4: 3 cm along: distinct
        ([0.031, 0, 0], _rz(185)),            # 5: a duplicate of 4, jaws swapped
        ([0.06, 0, 0], I3),                   # 6
    ])
    order = np.arange(7)
    assert separated_rows(p, q, order, 10, distance=D, angle=A).tolist() == [0, 3, 4, 6]
    assert separated_rows(p, q, order, 2, distance=D, angle=A).tolist() == [0, 3]
    # the order decides which of two duplicates stays
    assert separated_rows(p, q, order[::-1], 10, distance=D, angle=A).tolist() == [6, 5, 3, 2]
    # no separation: the first k of the order
    assert separated_rows(p, q, order, 3, distance=0.0, angle=A).tolist() == [0, 1, 2]
    assert separated_rows(p, q, order, 0, distance=D, angle=A).tolist() == []


def test_kept_grasps_of_a_real_map_are_pairwise_separated():
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.map_config import MapConfig
    from graspsim.primitives import Box
    from graspsim.transforms import quat_to_matrix

    gmap = generate_fs_map(Box(0.04, 0.06, 0.10), config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
    plain = gmap.top_k(10, rank="paper")
    top = gmap.top_k(10, rank="paper", separation=(D, A))
    assert len(top) == 10 and top.grade[0] == plain.grade[0]
    R = quat_to_matrix(top.wrist_quat)
    for i in range(10):
        for j in range(i):
            near = np.linalg.norm(top.grasp_point[i] - top.grasp_point[j]) < D
            ang = min(np.arccos(np.clip((np.trace(R[j].T @ R[i] * s) - 1) / 2, -1, 1))
                      for s in (np.ones(3), np.array([-1.0, -1.0, 1.0])))
            assert not (near and ang < A)
    # the plain ten best hold near-duplicates (why the option exists)
    assert len(np.unique(np.round(plain.grasp_point / D), axis=0)) < 10


def test_bad_separation_is_refused():
    p, q = _grasps([([0, 0, 0], np.eye(3))])
    with pytest.raises(InvalidParameterError, match="separation"):
        separated_rows(p, q, np.arange(1), 1, distance=-0.01, angle=A)
    with pytest.raises(InvalidParameterError, match="k must"):
        separated_rows(p, q, np.arange(1), -1, distance=D, angle=A)
