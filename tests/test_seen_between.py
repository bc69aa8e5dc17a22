"""Grasps must close on what was seen of the object (``PlannerConfig.seen_between``): the
closing region's point count (:meth:`GripperSpec.points_between`) and the planner's
scoring budget going only to grasps with enough of the object's own points between the
pads (:func:`graspsim.planning.observed.first_clear`'s ``also``)."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import RobustConfig
from graspsim.planning.observed import SEEN_BETWEEN, first_clear
from graspsim.planning.planner import PlannerConfig, plan_stream
from graspsim.planning.scene_config import SceneConfig
from graspsim.primitives import Cylinder, synthetic_cloud
from graspsim.transforms import make_transform

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))
ROBUST = RobustConfig(samples=8, top=60)


def _posed(local: np.ndarray, T: np.ndarray) -> np.ndarray:
    return local @ T[:3, :3].T + T[:3, 3]


def test_points_between_counts_the_closing_region_only():
    """Points placed in a wrist frame: inside the region between the pads (|x| < opening / 2,
    |y| < half the finger width, z along the pad) count; just outside each face does not,
    whatever the pose."""
    z_mid = G.fingertip_z - 0.5 * G.pad_length
    opening = 0.04
    inside = np.array([[0.0, 0.0, z_mid], [0.019, 0.009, z_mid], [-0.019, -0.009, G.fingertip_z - 0.001],
                       [0.0, 0.0, G.fingertip_z - G.pad_length + 0.001]])
    outside = np.array([[0.021, 0.0, z_mid], [0.0, 0.011, z_mid], [0.0, 0.0, G.fingertip_z + 0.001],
                        [0.0, 0.0, G.fingertip_z - G.pad_length - 0.001], [-0.021, 0.0, z_mid]])
    rng = np.random.default_rng(3)
    poses = np.stack([make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(0, 0.2, 3))
                      for _ in range(5)])
    for T in poses:
        pts = _posed(np.concatenate([inside, outside]), T)
        assert G.points_between(T[None], [opening], pts).tolist() == [len(inside)]
    # a wider opening takes in the points beside the pads, a narrower one drops the off-centre ones
    T = poses[0]
    pts = _posed(np.concatenate([inside, outside]), T)
    assert G.points_between(np.stack([T, T, T]), [0.05, 0.04, 0.01], pts).tolist() == [6, 4, 2]


def test_points_between_is_the_same_in_chunks():
    """Many poses against many points (so the count runs in chunks): each pose's count is
    the one it gets alone."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-0.1, 0.1, (40_000, 3)) + [0, 0, 0.2]
    T = np.stack([make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(0, 0.02, 3))
                  for _ in range(120)])
    opening = rng.uniform(0.01, 0.1, len(T))
    together = G.points_between(T, opening, pts)
    alone = [int(G.points_between(T[i:i + 1], opening[i:i + 1], pts)[0]) for i in range(0, len(T), 17)]
    assert together[::17].tolist() == alone and together.max() > 0
    assert G.points_between(T, opening, np.empty((0, 3))).tolist() == [0] * len(T)


def _between_numpy(g, T, opening, P):
    """The count as numpy made it before the compiled kernel: every point in every wrist frame."""
    local = np.einsum("nji,nmj->nmi", T[:, :3, :3], P[None] - T[:, None, :3, 3])
    half = 0.5 * np.asarray(opening, float)[:, None]
    return ((np.abs(local[..., 0]) < half) & (np.abs(local[..., 1]) < 0.5 * g.finger_size[1])
            & (local[..., 2] > g.fingertip_z - g.pad_length) & (local[..., 2] < g.fingertip_z)).sum(axis=1)


def test_points_between_counts_as_the_numpy_reference_does():
    """The compiled count gives numpy's counts, pose by pose, for poses around a cloud
    (rotations and openings at random, the cloud dense enough that many counts are large)."""
    rng = np.random.default_rng(11)
    pts = rng.normal(0.0, 0.03, (5000, 3))
    T = np.stack([make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(0, 0.01, 3))
                  for _ in range(300)])
    T[:, :3, 3] -= np.einsum("nij,j->ni", T[:, :3, :3], [0.0, 0.0, G.fingertip_z - 0.5 * G.pad_length])
    opening = rng.uniform(0.005, 0.1, len(T))
    got = G.points_between(T, opening, pts)
    assert got.dtype == np.int64 and got.tolist() == _between_numpy(G, T, opening, pts).tolist()
    assert (got > 100).sum() > 50  # the pads' region sits in the cloud for most poses


def test_first_clear_also_passes_over_the_rows_a_further_test_rejects():
    """``also`` is asked of the clear rows only, and the budget is filled further down the
    order with rows that pass it."""
    from graspsim.maps.generate import generate_fs_map

    m = generate_fs_map(Cylinder(0.025, 0.1), G, config=FAST)
    order = np.argsort(-m.grade, kind="stable")
    far = np.array([[1.0, 1.0, 1.0]])  # nothing near: every row is clear
    asked: list[np.ndarray] = []

    def odd(rows):
        asked.append(rows)
        return rows % 2 == 1

    rows, checked = first_clear(m, order, 20, far, ROBUST, G, also=odd)
    want = order[order % 2 == 1][:20]
    assert np.array_equal(rows, want)
    assert checked == int(np.flatnonzero(order == want[-1])[0]) + 1  # checked down to the 20th that passes
    assert np.array_equal(np.concatenate(asked)[:checked], order[:checked])


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Cylinder(0.025, 0.1)])
    return d


def test_no_grasp_is_scored_that_closes_on_too_few_seen_points(db):
    """A cylinder seen with a 40 mm band of its side missing (hidden by something the
    plan is not told of): the fitted cylinder spans the band, and grasps at its edge
    close on a few of the object's points only. With ``seen_between`` every grasp scored
    has at least that many of them between its pads, and the ones passed over are
    counted; without it some scored grasp has fewer. Points of other things (obstacles)
    between the pads do not count. (The count asked here is well above
    the scene planner's, so that the ordinary grasps of this clean cloud meet it and the
    band's edge does not.)"""
    T = make_transform(np.eye(3), [0.4, -0.1, 0.25])
    rng = np.random.default_rng(1)
    cloud = synthetic_cloud(Cylinder(0.025, 0.1), rng, resolution=0.003, noise=0.0002)
    P = cloud.points
    band = (P[:, 2] >= 0.0) & (P[:, 2] <= 0.04)
    pts = _posed(P[~band], T)
    # points of something else in the band, inside the fitted cylinder (clear of every finger): not the object's
    filler = _posed(P[band] * [0.5, 0.5, 1.0], T)
    base = PlannerConfig(robust=replace(ROBUST, top=200), features=None, clear_observed=False, clear_first=True)
    need = 60

    def plan(k: int):
        res = list(plan_stream(pts, db=db, rng=np.random.default_rng(2), obstacles=filler,
                               config=replace(base, seen_between=k), scored_only=True))[-1]
        m = res.map
        scored = np.flatnonzero(np.isfinite(m.robust))
        own = (pts - res.T_cloud_obj[:3, 3]) @ res.T_cloud_obj[:3, :3]
        counts = G.points_between(m.select(scored).wrist_transforms(), G.pregrasp_opening(m.width[scored]), own)
        return counts, m.meta.extra["observed"]

    off, rec_off = plan(0)
    on, rec_on = plan(need)
    assert len(off) == len(on) == 200  # the budget is spent in full either way
    assert off.min() < need <= np.median(off)
    assert on.min() >= need
    assert rec_on["seen_between"] == need and rec_on["on_nothing"] > 0
    assert rec_off["on_nothing"] == 0


def test_the_scene_planner_asks_for_seen_points_and_bad_values_are_refused():
    assert SceneConfig().planner.seen_between == SEEN_BETWEEN > 0
    assert PlannerConfig().seen_between == 0  # a plan of its own is as it was
    for bad in (-1, 2.5, True, "5"):
        with pytest.raises(InvalidParameterError, match="seen_between"):
            PlannerConfig(seen_between=bad)


def test_sparse_grasps_keep_a_share_of_their_score(db):
    """``discount_sparse``: the grasps whose closing region (at the opening they execute)
    holds fewer of the segment's points than asked keep :data:`SPARSE_SHARE` of their robust
    score, the others keep theirs, and 0 asks nothing. The cylinder seen with a band missing
    (above): grasps at the band's edge close on few points."""
    from graspsim.maps.robust import executed_width
    from graspsim.planning.scene_config import SPARSE_BETWEEN, SPARSE_SHARE
    from graspsim.planning.scene_segments import discount_sparse

    T = make_transform(np.eye(3), [0.4, -0.1, 0.25])
    cloud = synthetic_cloud(Cylinder(0.025, 0.1), np.random.default_rng(1), resolution=0.003, noise=0.0002)
    P = cloud.points
    pts = _posed(P[(P[:, 2] < 0.0) | (P[:, 2] > 0.04)], T)
    cfg = PlannerConfig(robust=replace(ROBUST, top=200), features=None, clear_observed=False, clear_first=True)
    m = list(plan_stream(pts, db=db, rng=np.random.default_rng(2), config=cfg, scored_only=True))[-1].map
    m = m.select(np.isfinite(m.robust))
    Tw = m.meta.placement.T_cloud_obj @ m.T_obj_wrist
    counts = G.points_between(Tw, G.pregrasp_opening(executed_width(m)), pts)
    need = int(np.median(counts))
    assert counts.min() < need <= counts.max()
    out = discount_sparse(m, pts, G, need)
    sparse = counts < need
    assert np.allclose(out.robust[sparse], SPARSE_SHARE * m.robust[sparse], rtol=1e-6)
    assert np.array_equal(out.robust[~sparse], m.robust[~sparse])
    assert len(out) == len(m) and np.array_equal(out.grade, m.grade)
    assert discount_sparse(m, pts, G, 0) is m
    assert 0 < SPARSE_SHARE < 1 and SceneConfig().sparse_between == SPARSE_BETWEEN > SEEN_BETWEEN
    for bad in (-1, 2.5, True, "30", None):
        with pytest.raises(InvalidParameterError, match="sparse_between"):
            SceneConfig(sparse_between=bad)


def test_the_scene_planner_discounts_sparse_grasps(db):
    """Through ``plan_scene``: asked for more points than any grasp closes on, every grasp of
    the scene keeps :data:`SPARSE_SHARE` of the score it has with the discount off, in the
    same order; asked for none, the scores are the off ones."""
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SPARSE_SHARE

    rng = np.random.default_rng(4)
    T = make_transform(np.eye(3), [0.0, 0.0, 0.05])
    cyl = _posed(synthetic_cloud(Cylinder(0.025, 0.1), rng, resolution=0.003, noise=0.0002).points, T)
    table = np.c_[rng.uniform(-0.2, 0.2, (5000, 2)), rng.normal(0, 0.0005, 5000)]
    pts = np.r_[table[np.linalg.norm(table[:, :2], axis=1) > 0.035], cyl[cyl[:, 2] > 0.008]]
    scores = {}
    for need in (0, 10**6):
        sp = plan_scene(pts, db=db, rng=np.random.default_rng(5), config=SceneConfig(workers=1, sparse_between=need))
        scores[need] = [g.score for g in sp.grasps]
    assert scores[0] and max(scores[0]) > 0
    assert np.allclose(scores[10**6], SPARSE_SHARE * np.array(scores[0]), rtol=1e-6)
