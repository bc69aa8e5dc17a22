"""The table filter: which map poses keep the gripper above the support plane."""

import math

import numpy as np
import pytest

from graspsim.errors import GraspsimError
from graspsim.gripper import HGPL_25_60_A as G
from graspsim.maps.generate import MapConfig, generate_fs_map
from graspsim.maps.table import TablePlane, clears_table, table_frame
from graspsim.primitives import Cylinder
from graspsim.transforms import make_transform

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.mark.parametrize("kw", [{"normal": (0, 0, 0)}, {"normal": (0, np.nan, 1)}, {"normal": (1, 2)},
                                {"height": math.inf}, {"clearance": -0.001}, {"clearance": math.nan},
                                {"normal": "up"}, {"height": "low"}, {"clearance": None}])
def test_bad_planes_are_refused(kw):
    with pytest.raises(GraspsimError):
        TablePlane(**kw)


def test_plane_normal_is_normalised_and_serialisable():
    t = TablePlane(normal=(0, 0, 2), height=0.1)
    assert t.normal == (0.0, 0.0, 1.0) and t.to_dict() == {"normal": [0.0, 0.0, 1.0], "height": 0.1,
                                                            "clearance": 0.002}


def test_table_frame_measures_height_above_the_plane():
    rng = np.random.default_rng(0)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    T = table_frame(n, 0.3)
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and np.linalg.det(T[:3, :3]) > 0
    p = rng.normal(size=(50, 3))
    z = (p @ T[:3, :3].T + T[:3, 3])[:, 2]
    assert np.allclose(z, p @ n - 0.3)


def test_standing_cylinder_keeps_top_and_side_grasps_and_loses_those_from_below():
    cyl = Cylinder(0.02, 0.12)
    m = generate_fs_map(cyl, config=FAST)
    rng = np.random.default_rng(1)
    # the cylinder stands on a table (z = 0) in a random yaw and place; the map's poses
    # in the table frame decide
    T_table_obj = make_transform(_yaw(rng.uniform(0, 2 * math.pi)), [0.2, -0.1, 0.06])
    clear = clears_table(m, T_table_obj, G, 0.002)
    low = G.lowest_point(T_table_obj @ m.T_obj_wrist, G.pregrasp_opening(m.width))
    assert np.array_equal(clear, low >= 0.002)
    approach_z = (T_table_obj[:3, :3] @ m.approach.T).T[:, 2]
    assert np.all(clear[approach_z < -0.99])  # straight down from above: always clear
    assert not np.any(clear[approach_z > 0.5])  # from below the table: never
    assert 0 < clear.mean() < 1
    assert np.array_equal(clears_table(m, T_table_obj, G, 0.002, chunk=997), clear)


def _yaw(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_bad_table_pose_is_refused():
    m = generate_fs_map(Cylinder(0.02, 0.05), config=FAST)
    with pytest.raises(GraspsimError):
        clears_table(m, np.full((4, 4), np.nan), G)
