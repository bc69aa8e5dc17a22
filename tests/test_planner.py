"""The run-time planner: cloud -> identification -> known / familiar / combined map."""

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.geometry.table import TablePlane
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.collide import boxes_clear_sdf
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.match import MatchKind
from graspsim.maps.robust import RobustConfig
from graspsim.perception import IdentifyConfig
from graspsim.planning.planner import GraspBatch, PlannerConfig, PlanResult, PlanStatus, plan, plan_stream
from graspsim.primitives import Box, Compound, Cylinder, Sphere, synthetic_cloud
from graspsim.transforms import invert_transform, make_transform, random_rotation

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Cylinder(0.02, 0.2), Cylinder(0.01, 0.12), Sphere(0.03), Box(0.02, 0.12, 0.12)])
    return d


def _bottle() -> Compound:
    """A body and a neck: two cylinders stacked."""
    return Compound.from_parts([Cylinder(0.03, 0.08), Cylinder(0.01, 0.12)],
                               [make_transform(np.eye(3), [0, 0, 0.04]), make_transform(np.eye(3), [0, 0, 0.14])])


def _cloud(shape, seed, **kw):
    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), [0.4, -0.1, 0.25])
    return synthetic_cloud(shape, rng, resolution=kw.pop("resolution", 0.004), noise=0.0005,
                           T_world_obj=T, **kw)


def _in_true_frame(result: PlanResult, cloud) -> np.ndarray:
    """The plan's contacts expressed in the true object's frame."""
    T = invert_transform(cloud.T_world_obj) @ result.T_cloud_obj
    c = result.map.contacts.reshape(-1, 3).astype(float)
    return c @ T[:3, :3].T + T[:3, 3]


def test_familiar_cylinder_is_scaled_and_fits_the_real_object(db):
    truth = Cylinder(0.025, 0.16)
    cloud = _cloud(truth, 1)
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0))
    assert r.status is PlanStatus.COMPLETE and [p.match for p in r.parts] == [MatchKind.FAMILIAR]
    assert r.parts[0].to_dict()["match"] == "familiar"
    assert len(r.map) > 100 and np.all(r.map.grade > 0.7)
    assert np.allclose(r.map.meta.extra["T_cloud_obj"], r.T_cloud_obj)
    # grasp contacts lie on the true surface, within the perception error
    assert np.median(np.abs(truth.sdf(_in_true_frame(r, cloud)))) < 0.001


def test_known_cylinder_uses_the_stored_map(db):
    """As is in paper mode; in robust mode less any grasps the cloud does not bear out
    (here none or few: the cylinder fits the cloud)."""
    cloud = _cloud(Cylinder(0.0202, 0.198), 2)  # within known's 3 % of the stored one
    stored = db.lookup("cylinder", {"radius": 0.02, "height": 0.2}).entry["accepted"]
    paper = plan(cloud.points, db=db, rng=np.random.default_rng(0),
                 config=PlannerConfig(identify=IdentifyConfig.preset("paper")))
    assert [p.match for p in paper.parts] == ["known"] and len(paper.map) == stored
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0))
    assert [p.match for p in r.parts] == ["known"] and 0.95 * stored <= len(r.map) <= stored


def test_compound_is_combined_without_collisions(db):
    bottle = _bottle()
    cloud = _cloud(bottle, 3, resolution=0.003)
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0))
    assert r.status is PlanStatus.COMPLETE and len(r.parts) == 2
    assert set(np.unique(r.map.part)) == {0, 1}
    assert r.map.meta.method == "adapted/combined"
    T = invert_transform(cloud.T_world_obj) @ r.T_cloud_obj
    idx = np.random.default_rng(0).choice(len(r.map), 80, replace=False)
    poses = T @ r.map.T_obj_wrist[idx]
    # collision-free against the true compound (up to the identification error)
    assert boxes_clear_sdf(bottle, G, poses, r.map.width[idx] + 2 * G.approach_clearance,
                           tolerance=0.002).mean() > 0.9


def test_adapted_grasps_are_checked_at_the_planners_collision_tolerance(db, collision_checks):
    """A scaled part and the combination of a compound's parts check collisions at
    PlannerConfig.collision_tolerance, None: the stored maps' own; a larger tolerance
    keeps fewer grasps (here: a part's fingers come near the other part)."""
    bottle = _bottle()
    cloud = _cloud(bottle, 3, resolution=0.003)
    seen = collision_checks
    kept = {}
    for tol, want in ((None, FAST.collision_tolerance), (0.003, 0.003)):
        seen.clear()
        r = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=PlannerConfig(collision_tolerance=tol))
        assert r.status is PlanStatus.COMPLETE and "familiar" in [p.match for p in r.parts]
        assert {name for name, _ in seen} == {"scaling", "combine"}
        assert {t for _, t in seen} == {want}
        kept[tol] = len(r.map)
    assert 0 < kept[0.003] < kept[None]


@pytest.mark.parametrize("bad", [0.0, -0.001, float("nan"), float("inf"), True, "1mm"])
def test_collision_tolerance_is_a_positive_length_or_none(bad):
    with pytest.raises(InvalidParameterError, match="collision_tolerance"):
        PlannerConfig(collision_tolerance=bad)


def test_stream_yields_grasps_before_the_result(db):
    cloud = _cloud(Cylinder(0.024, 0.17), 4)
    items = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0)))
    assert isinstance(items[-1], PlanResult) and all(isinstance(i, GraspBatch) for i in items[:-1])
    assert len(items) > 3
    assert items[0].seconds <= items[-2].seconds
    assert sum(len(i.map) for i in items[:-1]) == len(items[-1].map)


def test_sparse_gappy_cloud_fails_cleanly(db):
    r = plan(_gappy_ball(), db=db, rng=np.random.default_rng(0))
    assert r.status is PlanStatus.FAILED and len(r.map) == 0


def _gappy_ball() -> np.ndarray:
    rng = np.random.default_rng(6)  # six separate 1 cm patches of a 5 cm ball, 15 points each
    centres = rng.normal(size=(6, 3))
    d = centres[:, None, :] + 0.2 * rng.normal(size=(6, 15, 3))
    return 0.05 * (d / np.linalg.norm(d, axis=2, keepdims=True)).reshape(-1, 3)


def test_a_map_without_an_accepted_grasp_is_planned_again_from_the_same_generator(db, monkeypatch):
    """PlannerConfig.restarts: the first identification made to fail (as a decomposition
    with no accepted grasp would), robust planning identifies again and keeps the first map
    with an accepted grasp, recording the attempts; with restarts=0, or in paper mode, the
    failed attempt is the answer; when every attempt fails, restarts + 1 are made."""
    import graspsim.planning.planner as planner

    real, calls = planner.identify, []

    def failing(first: int):
        def identify(points, *, rng, config):
            calls.append(len(points))
            return real(_gappy_ball() if len(calls) <= first else points, rng=rng, config=config)
        return identify

    cloud = _cloud(Cylinder(0.025, 0.16), 1)
    monkeypatch.setattr(planner, "identify", failing(1))
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0))
    assert len(calls) == 2 and r.status is PlanStatus.COMPLETE and r.map.accepted.any()
    assert r.map.meta.extra["identification"]["attempts"] == r.attempts == 2
    assert r.summary()["identification"]["attempts"] == 2
    calls.clear()
    again = plan(cloud.points, db=db, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(again.map.wrist_position, r.map.wrist_position)  # the same seed, the same answer
    for cfg in (PlannerConfig(restarts=0), PlannerConfig(identify=IdentifyConfig.preset("paper"))):
        calls.clear()
        r = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg)
        assert len(calls) == 1 and r.status is PlanStatus.FAILED and len(r.map) == 0
    monkeypatch.setattr(planner, "identify", failing(99))
    calls.clear()
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=PlannerConfig(restarts=3))
    assert len(calls) == 4 and r.status is PlanStatus.FAILED and r.attempts == 4


@pytest.mark.parametrize("bad", [-1, 11, 1.5, True, "2"])
def test_restarts_are_a_small_whole_number(bad):
    with pytest.raises(InvalidParameterError, match="restarts must be an integer in"):
        PlannerConfig(restarts=bad)


@pytest.mark.parametrize("obstacles,seen,match", [
    (None, np.ones(3, bool), "obstacles_seen needs obstacles"),
    (np.zeros((3, 3)), np.ones(2, bool), r"obstacles_seen must be \(3,\) bool"),
    (np.zeros((3, 3)), np.ones(3), r"obstacles_seen must be \(3,\) bool")])
def test_which_obstacles_were_seen_is_one_bool_per_obstacle_point(db, obstacles, seen, match):
    cloud = _cloud(Sphere(0.03), 1)
    with pytest.raises(InvalidParameterError, match=match):
        next(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0), obstacles=obstacles,
                         obstacles_seen=seen))


def test_same_seed_same_plan(db):
    cloud = _cloud(Cylinder(0.023, 0.15), 6)
    a = plan(cloud.points, db=db, rng=np.random.default_rng(9))
    b = plan(cloud.points, db=db, rng=np.random.default_rng(9))
    np.testing.assert_array_equal(a.map.wrist_position, b.map.wrist_position)
    np.testing.assert_array_equal(a.T_cloud_obj, b.T_cloud_obj)


def test_a_robust_budget_of_zero_scores_nothing_and_orders_by_grade(db):
    cloud = _cloud(Cylinder(0.023, 0.15), 6)
    cfg = PlannerConfig(robust=RobustConfig(top=0))
    res = plan(cloud.points, db=db, rng=np.random.default_rng(9), config=cfg)
    assert len(res.map) and res.map.meta.extra["robust"]["scored"] == 0
    assert res.map.robust is None or not np.isfinite(res.map.robust).any()
    assert np.all(np.diff(res.map.grade) <= 0)


def test_table_plane_drops_exactly_the_poses_below_the_table(db):
    """An object standing on a table (z = 0), seen from one side: with the table given,
    no kept pose takes the gripper below it; the dropped poses are the difference to the
    table-free plan, and the estimated table height is where the table is."""
    from graspsim.geometry.table import TablePlane
    from graspsim.planning.planner import PlannerConfig

    truth = Cylinder(0.024, 0.16)
    T = make_transform(np.eye(3), [0.45, 0.05, 0.08])
    eye = np.array([0.6, 0.0, 0.45])
    cloud = synthetic_cloud(truth, np.random.default_rng(5), resolution=0.003, noise=0.0005,
                            camera=eye, T_world_obj=T)
    # the table's drop alone (the cloud filter drops other poses in each plan); a single view, planned as one
    free = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=PlannerConfig(clear_observed=False),
                viewpoint=eye)
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0),
             config=PlannerConfig(table=TablePlane(), clear_observed=False), viewpoint=eye)
    t = r.map.meta.extra["table"]
    assert abs(t["height"]) < 0.003 and r.summary()["table"]["dropped"] == t["dropped"]
    assert len(r.map) + t["dropped"] == len(free.map) and 0 < t["dropped"] < len(free.map)
    low = G.lowest_point(r.T_cloud_obj @ r.map.T_obj_wrist, G.pregrasp_opening(r.map.width))
    assert low.min() >= 0.002 - 0.003  # the clearance, up to the height estimate's error
    low_free = G.lowest_point(free.T_cloud_obj @ free.map.T_obj_wrist, G.pregrasp_opening(free.map.width))
    assert np.sum(low_free < -0.003) <= t["dropped"]
    # a given height is used as is
    r2 = plan(cloud.points, db=db, rng=np.random.default_rng(0),
              config=PlannerConfig(table=TablePlane(height=-0.05), clear_observed=False), viewpoint=eye)
    assert r2.map.meta.extra["table"]["height"] == -0.05 and len(r2.map) > len(r.map)


def test_known_shapes_are_planned_without_a_cloud(db):
    """plan_shape: the same retrieval / scaling / combination for a given primitive or
    compound; a known cylinder gives the stored map, a compound a combined map whose
    poses are collision-free against it exactly."""
    from graspsim.errors import GraspsimError
    from graspsim.planning.planner import plan_shape, plan_shape_stream

    T = make_transform(random_rotation(np.random.default_rng(3)), [0.3, 0.1, 0.2])
    r = plan_shape(Cylinder(0.02, 0.2), T, db=db)
    assert r.identification is None and [p.match for p in r.parts] == ["known"]
    assert len(r.map) == db.lookup("cylinder", {"radius": 0.02, "height": 0.2}).entry["accepted"]
    np.testing.assert_allclose(r.T_cloud_obj, T)
    bottle = _bottle()
    items = list(plan_shape_stream(bottle, T, db=db))
    res = items[-1]
    assert isinstance(res, PlanResult) and res.status is PlanStatus.COMPLETE and len(res.parts) == 2
    assert len(items) > 2 and set(np.unique(res.map.part)) == {0, 1}
    poses = invert_transform(T) @ res.T_cloud_obj @ res.map.T_obj_wrist
    assert boxes_clear_sdf(bottle, G, poses, res.map.width + 2 * G.approach_clearance).all()
    with pytest.raises(GraspsimError):
        plan_shape("cylinder", db=db)
    with pytest.raises(GraspsimError):
        plan_shape(Sphere(0.03), np.full((4, 4), np.nan), db=db)


def test_a_flat_box_gets_top_down_grasps_when_the_nearest_stored_box_is_a_plate(tmp_path):
    """Issue 15: a sugar-box-size box (17.6 x 9.3 x 4.5 cm) lying on its largest face was
    scaled from the nearest stored box, a 2 x 12 x 12 cm plate whose map has no grasp
    approaching its faces (both chords across them exceed the opening): every grasp
    approached horizontally and ``--table auto`` dropped them all."""
    from graspsim.transforms import quat_to_matrix

    db = MapDatabase(tmp_path / "db", config=FAST)
    db.build([Box(0.02, 0.12, 0.12)])
    box = Box(0.045, 0.093, 0.176)
    T = make_transform(np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]), [0.0, 0.0, 0.0225])
    cloud = synthetic_cloud(box, np.random.default_rng(3), resolution=0.006, noise=0.001, T_world_obj=T)
    r = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=PlannerConfig(table=TablePlane()))
    assert r.parts[0].match == MatchKind.BUILD  # the plate's map cannot serve it
    approach_z = (quat_to_matrix(r.map.wrist_quat)[:, :, 2] @ r.T_cloud_obj[:3, :3].T)[:, 2]
    assert len(r.map) and np.sum(approach_z < -0.9) > 0  # top-down grasps, above the table


def test_a_stored_box_in_another_edge_order_is_matched_as_it_is_scaled(tmp_path):
    """A box map stored as 10 x 6 x 4 cm (edges descending) was called *known* for a
    4 x 6 x 10 cm query -- matching compared sorted edges -- and served as is, in its own
    frame; a 3 x 6 x 10 cm query was called familiar and scaling, which pairs edges by
    name, raised. Both now plan, with every contact on the queried box."""
    from graspsim.planning.planner import plan_shape

    db = MapDatabase(tmp_path / "db", config=FAST)
    db.build([Box(0.10, 0.06, 0.04)])
    for box in (Box(0.04, 0.06, 0.10), Box(0.03, 0.06, 0.10)):
        r = plan_shape(box, db=db)
        assert r.parts[0].match is not MatchKind.KNOWN and len(r.map)
        c = r.map.contacts.reshape(-1, 3).astype(float)
        assert np.abs(box.sdf(c)).max() < 1e-3  # on the queried box, not the stored one


def test_an_approximate_parts_grasps_are_kept_only_where_the_cloud_agrees(db):
    from scipy.spatial import cKDTree

    from graspsim.maps.agreement import ObservedSurface
    from graspsim.planning.planner import plan_shape

    box = Box(0.02, 0.12, 0.12)  # edges ascending: the map's frame is the box's
    gmap = plan_shape(box, db=db).map
    # the cloud covers the box's surface only where y < 0: grasps touching y > 0 disagree
    pts = box.surface_samples(0.003).points
    pts = pts[pts[:, 1] < 0.0]
    keep = ObservedSurface(pts).borne_out(gmap.contacts.astype(float), tol=0.004, max_angle=math.atan(0.5),
                                          min_observed=2)
    assert 0 < keep.sum() < len(gmap)
    d = cKDTree(pts).query(gmap.contacts[keep].reshape(-1, 3))[0]
    assert d.max() <= 0.004
    assert not ObservedSurface(pts + [0.0, 0.0, 0.5]).borne_out(
        gmap.contacts.astype(float), tol=0.004, max_angle=1.5, min_observed=1).any()


def test_an_approximate_part_seen_from_one_side_keeps_grasps_whose_far_contact_is_unobserved(db):
    """A single view shows one side of a part; the far contact of most grasps lies where
    no point was seen. That is no evidence against the grasp, on an approximate part as
    on any other: one contact borne out is enough (E09's single views lost every grasp
    of their approximate parts when both had to be). The same points seen all round (no
    viewpoint) are all there is of the object: a finger whose closing path meets none of
    them closes on air, so both contacts must be borne out (E09's mug: a half-toroid
    laid over the rim put one contact 9-11 mm above it, and 8 of its 10 best dropped)."""
    from dataclasses import replace

    from graspsim.geometry.spacing import median_spacing
    from graspsim.maps.agreement import ObservedSurface
    from graspsim.perception import identify
    from graspsim.transforms import transform_points

    cfg = PlannerConfig(identify=IdentifyConfig.preset("robust"))
    full = _cloud(Cylinder(0.02, 0.2), 5)
    local = transform_points(invert_transform(full.T_world_obj), full.points)
    pts = full.points[local[:, 0] < 0.004]  # the half a camera on the part's -x side sees
    eye = transform_points(full.T_world_obj, np.array([[-0.5, 0.0, 0.0]]))[0]
    ident = identify(pts, rng=np.random.default_rng(0), config=cfg.identify)
    assert ident.parts
    ident = replace(ident, parts=tuple(replace(p, approximate=True) for p in ident.parts))
    got = {}
    for name, view in (("single", eye), ("all round", None)):
        r = [x for x in plan_stream(pts, db=db, rng=np.random.default_rng(0), config=cfg, identification=ident,
                                    viewpoint=view)][-1]
        c = (r.map.contacts.astype(float) @ r.T_cloud_obj[:3, :3].T + r.T_cloud_obj[:3, 3])
        s = ObservedSurface(pts, viewpoint=view)
        tol = r.map.meta.extra["observed"]["contact_tolerance"]  # the planner's: at least 3 spacings all round
        spaced = max(cfg.contact_tolerance, 3 * median_spacing(pts))
        assert tol == (cfg.contact_tolerance if view is not None else spaced)
        got[name] = [s.borne_out(c, tol=tol, max_angle=db.quality.friction_angle,
                                 min_observed=k) for k in (1, 2)]
    one, both = got["single"]
    assert one.all() and (~both).sum() > 0.2 * len(one)
    one, both = got["all round"]
    assert len(both) and both.all()  # no grasp with a contact the cloud does not bear out
    assert len(both) < 0.8 * len(got["single"][0])


def test_the_summary_and_the_map_record_the_identification_mode(db):
    cloud = _cloud(Sphere(0.03), 2)
    for mode in ("paper", "robust"):
        r = plan(cloud.points, db=db, rng=np.random.default_rng(0),
                 config=PlannerConfig(identify=IdentifyConfig.preset(mode)))
        assert r.summary()["identification"]["mode"] == mode
        assert r.map.meta.extra["identification"]["mode"] == mode


def test_robust_ranking_streams_first_and_never_offers_a_pose_into_the_cloud(db):
    from graspsim.maps.robust import RobustConfig, ranking
    from graspsim.planning.planner import PlannerConfig

    cloud = _cloud(Cylinder(0.024, 0.17), 4)
    cfg = PlannerConfig(robust=RobustConfig(top=300, samples=8))
    items = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg))
    r = items[-1]
    # every batch is scored (best-graded first) and ordered by the robust score
    assert items[0].map.has_robust and r.timing["first_robust"] is not None
    assert r.timing["first_robust"] <= r.timing["total"]
    # the calling thread's CPU from the end of identification: never more than the wall time
    assert 0 <= r.timing["first_robust_cpu"] <= r.timing["first_robust"] - r.timing["identify"] + 1e-3
    for b in items[:-1]:
        np.testing.assert_array_equal(ranking(b.map), np.arange(len(b.map)))
    m = r.map
    # 300 scored; the cloud filter drops those that hold observed points at every opening
    scored = int(np.isfinite(m.robust).sum())
    assert scored == m.meta.extra["robust"]["scored"] and 300 - m.meta.extra["observed"]["dropped"] <= scored <= 300
    top = m.top_k(20)
    assert np.all(top.robust > 0)
    # no top pose touches an observed point at its nominal pose (independent check)
    T_obj_cloud = invert_transform(r.T_cloud_obj)
    pts = cloud.points @ T_obj_cloud[:3, :3].T + T_obj_cloud[:3, 3]
    for T, w in zip(top.T_obj_wrist, top.width):
        c, h = G.boxes_at(float(G.pregrasp_opening(w)))
        q = (pts - T[:3, 3]) @ T[:3, :3]
        assert not np.any(np.all(np.abs(q[:, None, :] - c[None]) < h[None], axis=-1))
    # the paper's order is still there, and plan(rank="paper") scores nothing
    np.testing.assert_array_equal(m.ranked("paper").grade, np.sort(m.grade)[::-1])
    p = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=PlannerConfig(rank="paper"))
    assert not p.map.has_robust and p.timing["first_robust"] is None


@pytest.mark.parametrize("rank", ["robust", "paper"])
def test_every_streamed_batch_is_best_first_on_a_compound(db, rank):
    """A two-part bottle spends a part's robust budget and streams that part's later maps
    unscored: those batches too come best-graded first, and the final map is the same
    rows in the ranking's order."""
    from graspsim.maps.robust import ranking

    cfg = PlannerConfig(rank=rank, robust=RobustConfig(top=300, samples=8))
    items = list(plan_stream(_cloud(_bottle(), 4).points, db=db, rng=np.random.default_rng(0), config=cfg))
    batches = [i.map for i in items[:-1]]
    assert {int(b.part[0]) for b in batches} == {0, 1}
    if rank == "robust":  # the case that matters: unscored batches after scored ones
        assert any(not np.isfinite(b.robust).any() for b in batches)
    for b in batches:
        np.testing.assert_array_equal(ranking(b, rank), np.arange(len(b)))
    final = items[-1].map
    assert len(final) == sum(len(b) for b in batches)
    np.testing.assert_array_equal(ranking(final, rank), np.arange(len(final)))


def test_scored_only_skips_a_parts_unscored_batches_and_keeps_every_scored_one(db):
    """scored_only (a scene's planning): once a part's robust budget is spent, the rest
    of its maps are skipped -- the batches streamed are exactly the plain stream's
    batches that hold a scored row, in the same order, each part's included."""
    from graspsim.maps.robust import RobustConfig
    from graspsim.planning.planner import plan_shape_stream

    bottle = _bottle()
    T = make_transform(random_rotation(np.random.default_rng(5)), [0.3, 0.1, 0.2])
    cfg = PlannerConfig(robust=RobustConfig(top=40, samples=8))
    plain = [i.map for i in plan_shape_stream(bottle, T, db=db, config=cfg) if isinstance(i, GraspBatch)]
    items = list(plan_shape_stream(bottle, T, db=db, config=cfg, scored_only=True))
    only = [i.map for i in items if isinstance(i, GraspBatch)]
    scored = [m for m in plain if np.isfinite(m.robust).any()]
    assert len(scored) < len(plain)  # the plain stream goes on unscored: something to skip
    assert len(only) == len(scored) and {int(m.part[0]) for m in only} == {0, 1}
    for a, b in zip(only, scored):
        np.testing.assert_array_equal(a.robust, b.robust)
        np.testing.assert_array_equal(a.T_obj_wrist, b.T_obj_wrist)
    r = items[-1]  # the final map: what streamed, each part's budget scored
    assert isinstance(r, PlanResult) and len(r.map) == sum(len(m) for m in only)
    assert np.isfinite(r.map.robust).sum() == 2 * 40
    # a budget of 0 scores nothing: nothing to stream
    none = PlannerConfig(robust=RobustConfig(top=0, samples=8))
    assert not [i for i in plan_shape_stream(bottle, T, db=db, config=none, scored_only=True)
                if isinstance(i, GraspBatch)]


def test_the_occlusion_terms_depth_image_is_made_once_per_plan(db, monkeypatch):
    """Every batch of a plan is scored against the same cloud from the same viewpoint:
    the occlusion term's depth image (``view_of``) is made once, not per batch (a bottle:
    two parts, so two batches at least, each scored). The single-view rules' image of the
    cloud in its own frame is another, made once too."""
    import graspsim.planning.planner as planner
    from graspsim.maps import occlusion
    from graspsim.maps.robust import RobustConfig

    made, views = [], []
    real, real_view_of = occlusion.ViewDepth.__init__, planner.view_of
    monkeypatch.setattr(occlusion.ViewDepth, "__init__", lambda self, *a, **k: made.append(1) or real(self, *a, **k))
    monkeypatch.setattr(planner, "view_of", lambda *a, **k: views.append(1) or real_view_of(*a, **k))
    cloud = _cloud(_bottle(), 4)
    cfg = PlannerConfig(robust=RobustConfig(top=300, samples=8))
    items = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg,
                             viewpoint=cloud.points.mean(axis=0) + [0, 0, 0.5]))
    scored = [i for i in items[:-1] if np.isfinite(i.map.robust).any()]
    assert len(scored) >= 2 and len(views) == 1 and len(made) <= 2


@pytest.mark.parametrize("truth,match", [(Sphere(0.0305), "known"), (Cylinder(0.024, 0.16), "familiar")])
def test_grasps_likely_to_clear_the_table_stream_first(db, monkeypatch, truth, match):
    """An object resting on a table (a sphere; a cylinder lying): many of its best-graded
    grasps reach below the table. The planner streams the poses predicted to clear it
    first (stored poses as they are, scaled ones predicted), so its first batch is the
    first (one-grasp) batch, not one found after thousands of dropped poses; the
    finished map holds the same grasps as without that order."""
    import graspsim.planning.planner as planner

    R = np.eye(3) if isinstance(truth, Sphere) else np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)
    T = make_transform(R, [0.4, 0.0, 0.035 if isinstance(truth, Sphere) else 0.024])
    cloud = synthetic_cloud(truth, np.random.default_rng(2), resolution=0.004, noise=0.0005, T_world_obj=T)
    # paper identification: robust mode's cloud-agreement filter (graspsim.maps.agreement)
    # also thins the batches, so a batch's size would no longer tell what the table did
    cfg = PlannerConfig(table=TablePlane(height=0.0), identify=IdentifyConfig.preset("paper"))
    items = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg))
    first, result = items[0], items[-1]
    assert [p.match.value for p in result.parts] == [match]
    assert isinstance(first, GraspBatch) and len(first.map) == cfg.scaling.first_batch
    assert result.map.meta.extra["table"]["dropped"] > 10 * len(first.map)
    monkeypatch.setattr(planner, "_TABLE_TOLERANCE", math.inf)  # nothing preferred: the stored order
    plain = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg))
    assert len(plain[0].map) > cfg.scaling.first_batch  # the table emptied the first batches

    def rows(m):
        return np.unique(np.column_stack([m.wrist_position, m.wrist_quat]).round(9), axis=0)

    np.testing.assert_array_equal(rows(result.map), rows(plain[-1].map))
    assert result.map.meta.extra["table"]["dropped"] == plain[-1].map.meta.extra["table"]["dropped"]


def test_a_single_view_of_one_face_gives_no_grasp_across_the_depth_it_did_not_show(db):
    """A carton standing on a table, seen from the front and above, shows its front face and
    its top: robust identification fits the face as a plate a few mm thick. Its depth was not
    measured, so no grasp may close across it where its far finger goes into what the view
    did not see (the carton behind the face); what is left across it holds the carton's seen
    top or goes under the table -- nothing across the depth is offered. Across the face's
    width it may close. The same face with nothing behind it -- a domino standing on its edge,
    the camera seeing past it -- keeps the grasps across its thickness whose fingers stay in
    space the view saw (at most ``SEEN_FINGER_SHARE`` of them unseen). A view that also shows
    the plate's top edge measures its thickness: nothing is dropped. No viewpoint (a cloud
    seen all round) or ``seen_depth`` off: nothing is dropped."""
    from graspsim.geometry.table import table_frame
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.table_clearance import clears_table
    from graspsim.planning.observed import ObservedChecks, clear_of_cloud

    plate = Box(0.002, 0.044, 0.06)
    m = generate_fs_map(plate, G, config=FAST)
    closing = np.abs(m.wrist_transforms()[:, :3, 0])
    assert (closing[:, 0] > 0.9).any() and (closing[:, 1] > 0.9).any()
    rng = np.random.default_rng(3)
    front = np.column_stack([np.full(800, 0.001), rng.uniform([-0.022, -0.03], [0.022, 0.03], (800, 2))])
    top = np.column_stack([rng.uniform(-0.001, 0.001, 300), rng.uniform(-0.022, 0.022, 300), np.full(300, 0.03)])
    # the carton's top, 44 mm deep behind the front face (another part: the plate is fitted to the face)
    carton = np.column_stack([rng.uniform(-0.045, -0.005, 800), rng.uniform(-0.022, 0.022, 800), np.full(800, 0.03)])
    eye, I = np.array([0.6, 0.05, 0.3]), np.eye(4)
    on_table = clears_table(m, table_frame((0.0, 0.0, 1.0), -0.03), G)  # the plate stands on it
    cos45 = math.cos(math.radians(45))

    def kept(points, viewpoint=eye, seen=True):
        """The rows of ``m`` unseen_depth keeps, with the plate's points ``points``."""
        checks = ObservedChecks(points + rng.normal(0, 0.0005, points.shape), None, I, viewpoint=viewpoint,
                                noise=0.0005, gripper=G, quality=db.quality, cfg=PlannerConfig(seen_depth=seen))
        out = checks.unseen_depth(replace(m, part=np.arange(len(m))), plate, I, I)  # part: the row
        return out.part.astype(int)

    def offered_across(rows, cloud):  # kept, across the depth, on the table and holding no seen point
        rows = rows[(closing[rows, 0] >= cos45) & on_table[rows]]
        return rows[clear_of_cloud(m, rows, cloud, gripper=G)[0]]

    seen = np.concatenate([front, carton])
    carton_rows = kept(seen)
    assert (closing[carton_rows, 1] > 0.9).any()
    assert len(offered_across(carton_rows, seen)) == 0
    assert len(offered_across(np.arange(len(m)), seen)) > 0  # seen_depth's doing, not the other checks'
    domino_rows = kept(front)
    assert len(offered_across(domino_rows, front)) > 0
    assert (closing[domino_rows, 0] >= cos45).sum() < (closing[:, 0] >= cos45).sum()  # not every one
    for other in (kept(np.concatenate([front, top])), kept(front, viewpoint=None), kept(front, seen=False)):
        assert len(other) == len(m)


def test_a_block_whose_sides_the_camera_cannot_see_is_grasped_across_its_seen_width(db):
    """A block lying with its long axis towards the camera shows its top and its near end;
    its long sides are edge-on to the camera, so no contact of a grasp across its width can
    be borne out by the cloud. Its width was measured (the top face spans it), so such
    grasps are kept where no contact is contradicted (``PlannerConfig.hidden_faces``);
    with the option off, seen from a side that faces the camera but shows no points
    (evidence against), or with its top alone seen (its height, the hidden sides'
    extent, a guess), there are none across the width. Box frame: x up, y across, z
    along the block."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.observed import ObservedChecks

    block = Box(0.02, 0.04, 0.09)
    m = generate_fs_map(block, G, config=FAST)
    rng = np.random.default_rng(5)
    top = np.column_stack([np.full(900, 0.01), rng.uniform([-0.02, -0.045], [0.02, 0.045], (900, 2))])
    end = np.column_stack([rng.uniform(-0.01, 0.01, 200), rng.uniform(-0.02, 0.02, 200), np.full(200, -0.045)])
    cloud = np.concatenate([top, end]) + rng.normal(0, 0.0005, (1100, 3))
    I = np.eye(4)
    across = np.abs(m.wrist_transforms()[:, :3, 0] @ np.array([0.0, 1.0, 0.0])) >= math.cos(math.radians(45))
    assert across.sum() > 0

    def kept_across(eye, hidden=True, prim=block, points=cloud):
        checks = ObservedChecks(points, None, I, viewpoint=np.asarray(eye, float), noise=0.0005, gripper=G,
                                quality=db.quality, cfg=PlannerConfig(hidden_faces=hidden))
        out = checks.borne_out(replace(m, part=np.arange(len(m))), I, prim, I if prim is not None else None)
        return int(across[out.part.astype(int)].sum())

    front = (0.6, 0.0, -0.4)  # above and in front of the near end: both long sides edge-on
    assert kept_across(front) > 0
    assert kept_across(front, hidden=False) == 0
    assert kept_across(front, prim=None) == 0
    assert kept_across((0.6, 0.5, -0.4)) == 0  # the +y side faces the camera and shows nothing: not hidden
    assert kept_across(front, points=cloud[:900]) == 0  # the top alone: the sides' height is a guess


def test_a_single_view_of_a_curved_part_gives_no_grasp_closing_along_the_line_of_sight(db):
    """A cylinder seen from one side shows the camera its near half: the fit's back is the
    extrapolation of that side's curvature, and a real object's back (a duck's body fitted
    as a cylinder) goes on beyond it. So no grasp may close within 45 deg of the line of
    sight through its grasp point (its far finger on the unseen back) unless its fingers
    stay in space the view saw; grasps closing across it (on the silhouette's edges) stay.
    No viewpoint or ``seen_depth`` off:
    nothing is dropped."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.observed import ObservedChecks

    can = Cylinder(0.03, 0.08)
    m = generate_fs_map(can, G, config=FAST)
    eye, I = np.array([0.5, 0.0, 0.4]), np.eye(4)
    rng = np.random.default_rng(5)
    a, z = rng.uniform(-math.pi / 2, math.pi / 2, 1500), rng.uniform(-0.04, 0.04, 1500)
    seen = np.column_stack([0.03 * np.cos(a), 0.03 * np.sin(a), z])  # the half turned to the camera (+x)

    def sight_cos(k):
        at = k.grasp_point.astype(float)
        s = (at - eye) / np.linalg.norm(at - eye, axis=1, keepdims=True)
        return np.abs(np.einsum("ni,ni->n", k.wrist_transforms()[:, :3, 0], s))

    def kept(viewpoint=eye, seen_depth=True):
        checks = ObservedChecks(seen + rng.normal(0, 0.0005, seen.shape), None, I, viewpoint=viewpoint, noise=0.0005,
                                gripper=G, quality=db.quality, cfg=PlannerConfig(seen_depth=seen_depth))
        return checks.unseen_depth(m, can, I, I), checks

    assert (sight_cos(m) > 0.9).any() and (sight_cos(m) < 0.3).any()
    k, checks = kept()
    cone = math.cos(math.radians(45))
    across, along = int(np.sum(sight_cos(m) < cone)), int(np.sum(sight_cos(m) >= cone))
    assert checks.unseen == len(m) - len(k)
    # every grasp across the line of sight stays; of those along it, only the few whose fingers
    # stay in space the view saw (SEEN_FINGER_SHARE) -- not those with a finger on the unseen back
    assert int(np.sum(sight_cos(k) < cone)) == across
    from graspsim.maps.occlusion import finger_occlusion
    from graspsim.planning.observed import SEEN_FINGER_SHARE

    on_sight = sight_cos(m) >= cone
    w = m.wrist_transforms()[on_sight]
    f = finger_occlusion(checks._view, w[:, :3, :3], w[:, :3, 3], G.pregrasp_opening(m.width[on_sight]), G)
    assert len(k) - across == int(np.sum(f <= SEEN_FINGER_SHARE)) < along / 2
    assert (sight_cos(k) < 0.3).any()  # closing across the line of sight: kept
    assert len(kept(viewpoint=None)[0]) == len(kept(seen_depth=False)[0]) == len(m)


def test_unseen_depth_is_found_per_part_and_the_same_for_every_batch(db):
    """ObservedChecks finds a box part's unmeasured axes once per part and plan (a part
    streams many batches): a second batch of the same part is judged as the first, and
    a part of the same size elsewhere (no points on it: nothing measured, nothing
    dropped) gets its own answer, not the first part's."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.observed import ObservedChecks

    plate = Box(0.002, 0.044, 0.06)
    m = generate_fs_map(plate, G, config=FAST)
    rng = np.random.default_rng(3)
    front = np.column_stack([np.full(800, 0.001), rng.uniform([-0.022, -0.03], [0.022, 0.03], (800, 2))])
    I, away = np.eye(4), np.eye(4)
    away[:3, 3] = [0.0, 0.3, 0.0]
    checks = ObservedChecks(front + rng.normal(0, 0.0005, front.shape), None, I, viewpoint=np.array([0.6, 0.05, 0.3]),
                            noise=0.0005, gripper=G, quality=db.quality, cfg=PlannerConfig())
    first = checks.unseen_depth(m, plate, I, I)
    assert 0 < len(first) < len(m)
    assert len(checks.unseen_depth(m, plate, away, away)) == len(m)
    again = checks.unseen_depth(m, plate, I, I)
    np.testing.assert_array_equal(again.wrist_transforms(), first.wrist_transforms())
    assert checks.unseen == 2 * (len(m) - len(first))


def test_stored_grasps_predicted_far_under_the_table_are_not_scaled_and_no_kept_grasp_is_lost(db):
    """``PlannerConfig.table_skip`` (scene planning's :data:`SCENE_TABLE_SKIP`): a sphere
    resting on a table, scaled from a stored one -- the stored grasps predicted more than
    3 cm under the table's clearance are not scaled, and the finished map holds exactly the
    grasps of the plan that scaled them all (the table filter dropped every one of them);
    fewer poses reach the table filter."""
    from graspsim.planning.planner import SCENE_TABLE_SKIP
    from graspsim.planning.scene_config import SceneConfig

    assert SceneConfig().planner.table_skip == SCENE_TABLE_SKIP
    with pytest.raises(InvalidParameterError):
        PlannerConfig(table_skip=-0.01)
    truth = Sphere(0.036)
    T = make_transform(np.eye(3), [0.4, 0.0, 0.036])
    cloud = synthetic_cloud(truth, np.random.default_rng(2), resolution=0.004, noise=0.0005, T_world_obj=T)
    cfg = PlannerConfig(table=TablePlane(height=0.0), identify=IdentifyConfig.preset("paper"))
    every = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg)
    skip = plan(cloud.points, db=db, rng=np.random.default_rng(0), config=replace(cfg, table_skip=SCENE_TABLE_SKIP))
    assert [p.match.value for p in skip.parts] == ["familiar"]

    def rows(m):
        return np.column_stack([m.wrist_position, m.wrist_quat, m.grade])

    assert len(skip.map) > 0
    np.testing.assert_array_equal(rows(skip.map), rows(every.map))
    dropped = [r.map.meta.extra["table"]["dropped"] for r in (every, skip)]
    assert dropped[1] < dropped[0] / 2  # most of the poses the table dropped were never scaled


def test_a_part_no_chord_of_which_fits_the_gripper_gives_no_grasps_and_the_others_are_planned(db):
    """A part identified a millimetre thick (a disc a cone was fitted to, in an E10 packed
    scene) has no chord the gripper can close on, so no FS map can be built for it: that
    part gives no grasps, no map is stored for it, and the object's other parts are
    planned as ever (it ended a whole clutter run with NoFeasibleGraspError)."""
    from graspsim.errors import NoFeasibleGraspError
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.planner import plan_shape
    from graspsim.primitives import Cone

    disc = Cone(0.0393, 0.0343, 0.00111)
    with pytest.raises(NoFeasibleGraspError):
        generate_fs_map(disc, G, config=FAST)
    shape = Compound.from_parts([Cylinder(0.02, 0.2), disc],
                                [make_transform(np.eye(3), [0, 0, 0.1]), make_transform(np.eye(3), [0, 0, 0.2006])])
    before = len(db.entries())
    r = plan_shape(shape, make_transform(np.eye(3), [0.3, 0.1, 0.2]), db=db)
    assert len(r.parts) == 2 and len(r.map) and set(np.unique(r.map.part)) == {0}
    assert r.parts[0].match == "known" and r.parts[1].match == "build"
    assert len(db.entries()) == before  # nothing stored for the disc
