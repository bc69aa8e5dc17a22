"""The table filter: which map poses keep the gripper above the support plane."""

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import GraspsimError
from graspsim.geometry.table import TablePlane, table_frame
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.collide_fcl import FclChecker
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.table_clearance import clears_table
from graspsim.primitives import Box, Cylinder
from graspsim.transforms import make_transform, matrix_to_quat

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
    approach_z = (T_table_obj[:3, :3] @ m.approach.T).T[:, 2]
    assert np.all(clear[approach_z < -0.99])  # straight down from above: always clear
    assert not np.any(clear[approach_z > 0.5])  # from below the table: never
    assert 0 < clear.mean() < 1
    assert np.array_equal(clears_table(m, T_table_obj, G, 0.002, chunk=997), clear)


def test_clearance_agrees_with_fcl_distances_to_a_table_slab():
    """Independent geometry: FCL's distance from the gripper's boxes (arm keep-out
    included, jaws at the pre-grasp opening) to a 10 m x 10 m x 1 m slab whose top is the
    table decides the same poses as ``clears_table``."""
    m = generate_fs_map(Cylinder(0.02, 0.12), config=FAST)
    rng = np.random.default_rng(2)
    T_table_obj = make_transform(_yaw(rng.uniform(0, 2 * math.pi)), [0.1, 0.3, 0.06])
    rows = rng.choice(len(m), 400, replace=False)
    sub = m.select(rows)
    slab = FclChecker(Box(10.0, 10.0, 1.0), G)
    T_slab_table = make_transform(np.eye(3), [0.0, 0.0, 0.5])  # the slab's top face is z = 0
    T = T_slab_table @ T_table_obj @ sub.T_obj_wrist
    dist = np.array([slab.distance(t, o) for t, o in zip(T, G.pregrasp_opening(sub.width))])
    for c in (0.0, 0.002, 0.02):
        decided = np.abs(dist - c) > 1e-6
        got = clears_table(sub, T_table_obj, G, c)
        assert np.array_equal(got[decided], dist[decided] >= c), c
        assert 0.05 < got.mean() < 0.95
    assert decided.mean() > 0.95


@pytest.mark.parametrize("c", [0.0, 0.002])
def test_hand_computed_poses(c):
    """Wrist straight above the table pointing down: the fingertips, fingertip_z =
    60 (housing) + 15 (jaw) + 80 (finger) = 155 mm below the wrist, are the lowest point.
    Approach horizontal, fingers closing horizontally: the housing, jaws, fingers and
    the arm keep-out are all 50 mm wide, so their lower faces are 25 mm below the wrist."""
    assert G.fingertip_z == pytest.approx(0.155)
    down = make_transform(np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 0.0])
    side = make_transform(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), [0.0, 0.0, 0.0])
    for R0, low in ((down, 0.155), (side, 0.025)):
        for dz, want in ((-1e-4, False), (1e-4, True)):
            gmap = _one_pose_map(R0[:3, :3], width=0.03)
            T_table_obj = make_transform(np.eye(3), [0.3, -0.2, low + c + dz])
            assert clears_table(gmap, T_table_obj, G, c)[0] == want, (low, dz)


def _one_pose_map(R, width):
    m = generate_fs_map(Cylinder(0.02, 0.05), config=FAST).select([0])
    return replace(m, wrist_quat=matrix_to_quat(R)[None].astype(m.wrist_quat.dtype),
                   wrist_position=np.zeros((1, 3), m.wrist_position.dtype),
                   width=np.array([width], m.width.dtype))


def _yaw(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_bad_table_pose_is_refused():
    m = generate_fs_map(Cylinder(0.02, 0.05), config=FAST)
    with pytest.raises(GraspsimError):
        clears_table(m, np.full((4, 4), np.nan), G)


def test_lowest_point_equals_the_lowest_of_all_box_corners():
    """The closed form (a box's lowest corner: centre height - sum |up_i| x half extent_i)
    against enumerating all eight corners of every box, jaws opened along x."""
    rng = np.random.default_rng(3)
    n = 500
    from graspsim.transforms import random_rotation

    T = np.stack([make_transform(random_rotation(rng), rng.normal(scale=0.1, size=3)) for _ in range(n)])
    opening = rng.uniform(G.min_opening, G.max_opening, n)
    b = G.collision_boxes()
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    corners = b.centers[None, :, None, :] + b.half_extents[None, :, None, :] * signs[None, None]
    corners = np.repeat(corners, n, axis=0)
    corners[..., 0] += b.x_sign[None, :, None] * 0.5 * opening[:, None, None]
    z = np.einsum("nj,nbcj->nbc", T[:, 2, :3], corners) + T[:, 2, 3, None, None]
    np.testing.assert_allclose(G.lowest_point(T, opening), z.reshape(n, -1).min(axis=1), atol=1e-12)


def test_heights_above_match_the_lowest_point_in_the_table_frame():
    from graspsim.maps.table_clearance import heights_above
    from graspsim.transforms import quat_to_matrix, random_rotation

    rng = np.random.default_rng(4)
    q = rng.normal(size=(300, 4)) * rng.uniform(0.5, 2.0, (300, 1))  # any length: normalised
    p = rng.normal(scale=0.05, size=(300, 3))
    width = rng.uniform(0.0, 0.05, 300)
    T_table_obj = make_transform(random_rotation(rng), [0.01, -0.02, 0.07])
    T = T_table_obj @ make_transform(quat_to_matrix(q), p)
    np.testing.assert_allclose(heights_above(G, T_table_obj, q, p, width),
                               G.lowest_point(T, G.pregrasp_opening(width)), atol=1e-12)


@pytest.mark.parametrize("n,first,growth", [(0, 1, 4.0), (1, 1, 4.0), (1000, 1, 4.0), (999, 48, 1.0), (10000, 7, 2.5)])
def test_stream_order_yields_every_position_once_preferred_first(n, first, growth):
    from graspsim.maps.table_clearance import stream_order

    plain = list(stream_order(n, first, growth))
    assert np.array_equal(np.concatenate(plain) if plain else np.zeros(0), np.arange(n))
    liked = np.random.default_rng(n).random(n) < 0.1
    calls = []

    def prefer(pos):
        calls.append(len(pos))
        return liked[pos]

    batches = list(stream_order(n, first, growth, prefer, chunk=500))
    out = np.concatenate(batches) if batches else np.zeros(0, int)
    assert np.array_equal(np.sort(out), np.arange(n))  # each exactly once
    k = int(liked.sum())
    assert np.all(liked[out[:k]]) and not np.any(liked[out[k:]])  # the preferred ones first, in order
    assert np.all(np.diff(out[:k]) > 0) and np.all(np.diff(out[k:]) > 0)
    assert all(np.all(np.diff(b) > 0) for b in batches)
    assert len(batches) == 0 or len(batches[0]) <= max(first, 1)
    assert max(calls, default=0) <= 500  # evaluated lazily, a chunk at a time


@pytest.mark.parametrize("n", [0, 1, 300, 1000, 4097, 9000])
def test_stream_order_batches_do_not_depend_on_the_chunks_and_an_early_stop_asks_little(n):
    """The preference is asked about chunks that grow from 256 positions: the batches
    are those of one chunk of everything, and a consumer that stops after its first
    batches has asked about a few hundred positions, not thousands."""
    from graspsim.maps.table_clearance import _chunks, stream_order

    liked = np.random.default_rng(n).random(n) < 0.5
    asked = []

    def prefer(pos):
        asked.append(len(pos))
        return liked[pos]

    whole = [b.tolist() for b in stream_order(n, 1, 4.0, lambda pos: liked[pos], chunk=max(n, 1))]
    assert [b.tolist() for b in stream_order(n, 1, 4.0, prefer)] == whole
    edges = _chunks(n, 4096)
    assert [a for a, _ in edges[1:]] == [b for _, b in edges[:-1]] and (not n or edges[-1][1] == n)
    assert all(b - a >= min(256, n) for a, b in edges[:-1]) and all(b - a <= 4096 for a, b in edges)
    asked.clear()
    stream = stream_order(n, 1, 4.0, prefer)
    for _, _ in zip(range(3), stream):  # 1 + 4 + 16 preferred positions
        pass
    assert sum(asked) <= 256 or n <= 511
