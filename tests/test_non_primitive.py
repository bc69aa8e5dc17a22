"""Objects that are not primitives (issue 33, item 6): how well the parts explain a cloud,
and no offered grasp whose gripper holds observed points -- a thin-walled bowl (one
sphere wider than the gripper) and a flat tool lying down (one box over its bars)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graspsim.geometry.table import TablePlane
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import cloud_in_object, executed_width
from graspsim.perception.acceptance import fit_quality
from graspsim.planning.planner import PlannerConfig, plan
from graspsim.primitives import Box, Sphere
from graspsim.transforms import make_transform, quat_to_matrix

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


def _hemisphere(rng, n, r):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = -np.abs(d[:, 2])
    return r * d


def _bowl(rng, n=2500, radius=0.075, wall=0.002, noise=0.0005):
    """A hemispherical shell ``wall`` thick, opening up, its bottom on z = 0: outer and
    inner surfaces by area, and the rim."""
    ri = radius - wall
    k = rng.multinomial(n, np.array([radius**2, ri**2, radius * wall / math.pi]) / (radius**2 + ri**2
                                                                                      + radius * wall / math.pi))
    a = rng.uniform(0, 2 * math.pi, k[2])
    rim = np.column_stack([rng.uniform(ri, radius, k[2]) * np.cos(a), rng.uniform(ri, radius, k[2]) * np.sin(a),
                           np.zeros(k[2])])
    P = np.concatenate([_hemisphere(rng, k[0], radius), _hemisphere(rng, k[1], ri), rim]) + [0, 0, radius]
    return P + rng.normal(0, noise, P.shape)


def _box_surface(rng, n, half, T):
    """n points uniform over the surface of a box of half extents ``half`` posed at T."""
    h = np.asarray(half, float)
    areas = np.array([h[1] * h[2], h[0] * h[2], h[0] * h[1]]) * 2
    face = rng.choice(3, size=n, p=areas / areas.sum())
    q = rng.uniform(-1, 1, (n, 3)) * h
    q[np.arange(n), face] = np.where(rng.random(n) < 0.5, -1, 1) * h[face]
    return q @ T[:3, :3].T + T[:3, 3]


def _flat_tool(rng, n=2500, noise=0.0005):
    """A clamp-like tool: two bars 180 x 16 x 20 mm crossing at 40 deg, lying flat on z = 0
    (surface points, the inside of the crossing left out)."""
    half = np.array([0.09, 0.008, 0.010])
    poses = [make_transform(Rotation.from_euler("z", a, degrees=True).as_matrix(), [0.0, 0.0, 0.010])
             for a in (-20.0, 20.0)]
    P = np.concatenate([_box_surface(rng, n // 2, half, T) for T in poses])
    inside = lambda p, T: np.all(np.abs((p - T[:3, 3]) @ T[:3, :3]) < half - 1e-6, axis=1)  # noqa: E731
    P = P[~(inside(P, poses[0]) | inside(P, poses[1]))]
    return P + rng.normal(0, noise, P.shape)


def _holding_points(gmap, rows, points_obj, margin=1e-4):
    """(len(rows),) how many observed points lie inside the gripper's boxes (fingers,
    jaws, housing, arm) of each row at the opening it is executed with, by more than
    ``margin``: an independent check of the boxes, not the planner's kernel."""
    g = gmap.meta.gripper_spec
    boxes = g.collision_boxes()
    R = quat_to_matrix(gmap.wrist_quat[rows].astype(float))
    w = gmap.wrist_position[rows].astype(float)
    opening = g.pregrasp_opening(executed_width(gmap, rows))
    out = np.zeros(len(rows), int)
    for i in range(len(rows)):
        q = (points_obj - w[i]) @ R[i]
        for c, h, s in zip(boxes.centers, boxes.half_extents, boxes.x_sign):
            c = c + np.array([s * 0.5 * opening[i], 0.0, 0.0])
            out[i] += int(np.sum(np.all(np.abs(q - c) < h - margin, axis=1)))
    return out


def test_fit_quality_high_for_a_primitive_low_for_a_bowl_and_a_flat_tool():
    rng = np.random.default_rng(0)
    sphere = Sphere(0.035)
    T = make_transform(np.eye(3), [0.0, 0.0, 0.035])
    p = sphere.surface_samples(0.003).points + T[:3, 3] + rng.normal(0, 0.0005, (1, 3))
    p = p + rng.normal(0, 0.0005, p.shape)
    good = fit_quality(p, [sphere], [T], band=0.002, spacing=0.003)
    assert good.score > 0.9 and good.explained > 0.95 and good.covered > 0.9
    # a bowl explained as the sphere of its outer surface: every point near it, half of it empty
    bowl = _bowl(rng)
    poor = fit_quality(bowl, [Sphere(0.075)], [make_transform(np.eye(3), [0, 0, 0.075])], band=0.004, spacing=0.004)
    assert poor.explained > 0.9 and poor.covered < 0.65 and poor.score < 0.65
    # crossing bars explained as one box over both: the gaps between them are empty
    tool = _flat_tool(rng)
    box = Box(0.18, 0.08, 0.012)
    flat = fit_quality(tool, [box], [make_transform(np.eye(3), [0.0, 0.0, 0.006])], band=0.003, spacing=0.004)
    assert flat.score < 0.7
    # with no part nothing is explained
    assert fit_quality(tool, [], [], band=0.003).score == 0.0
    # a part smaller than the inlier band and the spacing (a pile's 4.4 mm sphere, seen at 10 mm
    # reach) is sampled within its size, not refused: the points on it cover it
    tiny = Sphere(0.0044)
    Tt = make_transform(np.eye(3), [0.0, 0.0, 0.0044])
    pts = tiny.surface_samples(0.002).points + Tt[:3, 3]
    q = fit_quality(pts, [tiny], [Tt], band=0.004, spacing=0.007)
    assert q.explained == 1.0 and q.covered == 1.0


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Sphere(0.03), Box(0.02, 0.12, 0.12)])
    return d


def _config(**kw) -> PlannerConfig:
    return PlannerConfig(table=TablePlane(height=0.0), build_missing=False, **kw)


@pytest.mark.slow
@pytest.mark.parametrize("make", [_bowl, _flat_tool], ids=["bowl", "flat_tool"])
def test_no_offered_grasp_holds_observed_points(db, make):
    """The bowl (a sphere wider than the gripper: no grasp of its own) gets grasps, and
    the flat tool's grasps keep the gripper off its bars' points: every grasp of the
    map (``trial --sample`` draws from all of them) clears the observed cloud at the
    opening it is executed with. Disabling the filter (``clear_observed``, or
    ``_clear_observed`` returning its batch) leaves grasps that hold points."""
    rng = np.random.default_rng(3)
    cloud = make(rng)
    res = plan(cloud, db=db, rng=np.random.default_rng(0), config=_config())
    m = res.map
    assert len(m) > 0
    if make is _bowl:  # one sphere over the bowl: half of it empty
        assert m.meta.extra["identification"]["fit"]["score"] < 0.8
    obj = cloud_in_object(cloud, res.T_cloud_obj)
    rows = np.unique(np.r_[np.arange(min(len(m), 20)), np.linspace(0, len(m) - 1, 300).astype(int)])
    assert not np.any(_holding_points(m, rows, obj))
    assert m.meta.extra["observed"]["dropped"] > 0


def test_clear_observed_off_keeps_colliding_grasps(db):
    """The mutation the test above guards against, made through the config: without
    the filter the same bowl's map holds grasps whose gripper holds observed points."""
    rng = np.random.default_rng(3)
    cloud = _bowl(rng, n=1500)
    res = plan(cloud, db=db, rng=np.random.default_rng(0), config=_config(clear_observed=False))
    m = res.map
    obj = cloud_in_object(cloud, res.T_cloud_obj)
    rows = np.linspace(0, len(m) - 1, min(len(m), 300)).astype(int)
    assert np.any(_holding_points(m, rows, obj))


def test_scene_planning_keeps_no_cloud_filter_and_feature_grasps_only_where_objects_stand_apart():
    """Scene planning's published behaviour: the per-segment planner never drops grasps
    holding observed points; it adds feature grasps only where the objects are known to
    stand apart (``min_gap``: packed tables; in piles they removed fewer objects and planned
    slower: docs/results.md), unless ``feature_grasps`` says otherwise; a one-object plan does
    both by default."""
    from dataclasses import replace

    import pytest

    from graspsim.errors import InvalidParameterError
    from graspsim.planning.scene_config import FEATURE_GRASPS, SceneConfig, with_feature_grasps

    scene = SceneConfig()
    assert scene.planner.clear_observed is False and scene.planner.features is not None
    assert PlannerConfig().clear_observed is True and PlannerConfig().features is not None
    assert scene.feature_grasps == "fallback" and FEATURE_GRASPS == ("apart", "fallback", "always", "never")
    on = {(when, gap): with_feature_grasps(replace(scene, min_gap=gap), when).segment_features is not None
          for when in FEATURE_GRASPS for gap in (None, 0.01)}
    assert on == {("apart", None): False, ("apart", 0.01): True, ("always", None): True, ("always", 0.01): True,
                  ("never", None): False, ("never", 0.01): False,  # fallback: where apart, else only when stuck
                  ("fallback", None): False, ("fallback", 0.01): True}
    assert with_feature_grasps(scene, None) is scene
    off = replace(scene, planner=replace(scene.planner, features=None), feature_grasps="always")
    assert off.segment_features is None  # no settings: none, whatever feature_grasps says
    for bad in ("sometimes", "", 1, None):
        with pytest.raises(InvalidParameterError, match="feature_grasps must be one of apart, fallback, always, never"):
            SceneConfig(feature_grasps=bad)
    with pytest.raises(InvalidParameterError, match="feature grasps must be one of apart, fallback, always, never"):
        with_feature_grasps(scene, "Always")


def test_a_bowl_on_a_table_gets_grasps_in_a_scene_from_its_features_alone(db):
    """A thin-walled bowl wider than the gripper opens, seen on a table from one camera:
    its one sphere gives no grasp; feature grasps (``PlannerConfig.features``), which a scene
    planner makes where objects are known to stand apart (a ``min_gap``), give it some that
    score > 0, each closing on seen points of the bowl; with no ``min_gap`` (objects may
    touch: a pile) and ``feature_grasps="apart"``, or with ``"never"``, none; with ``"fallback"``
    (the default) in a pile too, as the frame's parts give no grasp at all."""
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SceneConfig

    rng = np.random.default_rng(3)
    eye = np.array([0.0, -0.35, 0.45])
    bowl = _bowl(rng, n=4000)
    seen = bowl[_facing(bowl, eye)]
    table = np.c_[rng.uniform(-0.25, 0.25, (6000, 2)), rng.normal(0, 0.0005, 6000)]
    pts = np.r_[table[np.linalg.norm(table[:, :2], axis=1) > 0.08], seen]
    plans = {}
    for name, cfg in {"apart": SceneConfig(workers=1, min_gap=0.01),
                      "may touch": SceneConfig(workers=1, feature_grasps="apart"),
                      "never": SceneConfig(workers=1, min_gap=0.01, feature_grasps="never"),
                      "fallback": SceneConfig(workers=1, feature_grasps="fallback"),
                      "lazy fallback": SceneConfig(workers=1, feature_grasps="fallback", good_enough=0.5)}.items():
        plans[name] = plan_scene(pts, db=db, rng=np.random.default_rng(5), config=cfg, viewpoint=eye)
    for name in ("fallback", "lazy fallback"):  # objects may touch, but the frame's parts give no grasp at all
        fb = plans[name]
        assert any(g.score > 0 for g in fb.grasps) and {g.source for g in fb.grasps} == {"features"}, name
        assert not any(s.status == "deferred" for s in fb.segments), name
    # planned with a previous frame (its identifications reused): not afresh, so no fallback -- a
    # clutter loop plans the frame afresh before it gives up
    again = plan_scene(pts, db=db, rng=np.random.default_rng(5), config=SceneConfig(workers=1), viewpoint=eye,
                       previous=plans["may touch"])
    assert again.segments and not any(g.score > 0 for g in again.grasps)
    on = plans["apart"]
    for name in ("may touch", "never"):
        off = plans[name]
        assert off.segments and not any(g.score > 0 for g in off.grasps), name  # the near wall and the far one
        assert {s.status for s in off.segments} == {"no_grasp"}, name
    assert "planned" in {s.status for s in on.segments} and any(g.score > 0 for g in on.grasps)
    g = db.gripper
    for sg in on.grasps:
        if sg.score > 0:
            own = on.perception.segment_points(sg.segment)
            assert g.points_between(sg.T_world_wrist[None], np.array([sg.opening]), own)[0] >= 5
            assert sg.source == "features"  # the sphere gave none: each was planned from the bowl's own points


def _brick_scene(rng):
    """A 32 x 32 x 23 mm brick on a table seen from one camera (top and front face): the
    cloud and the camera's place."""
    eye = np.array([0.0, -0.35, 0.45])
    brick = _box_surface(rng, 3000, (0.016, 0.016, 0.0115), make_transform(np.eye(3), [0.0, 0.0, 0.0115]))
    seen = brick[_facing(brick, eye)] + rng.normal(0, 0.0005, (int(_facing(brick, eye).sum()), 3))
    table = np.c_[rng.uniform(-0.25, 0.25, (6000, 2)), rng.normal(0, 0.0005, 6000)]
    return np.r_[table[np.abs(table[:, :2]).max(axis=1) > 0.02], seen], eye


def test_other_models_are_the_other_fits_that_make_a_primitive_best_first():
    """``other_models``: an identified part as each other kind its cluster fitted, by RMS --
    those whose fit rate reaches the threshold and whose surface was not rejected for
    reaching beyond the points; none for an unidentified part or where no other kind
    qualifies. A scene's fallback tries them as whole identifications, the r-th of every part
    together. Mutation caught: ranking by fit rate (the first kind's name on ties)."""
    from dataclasses import replace

    from graspsim.perception.classify import Shape
    from graspsim.perception.cluster import other_models
    from graspsim.perception.identify import identify
    from graspsim.perception.identify_config import IdentifyConfig
    from graspsim.planning.scene import _other_identifications

    pts, eye = _brick_scene(np.random.default_rng(1))
    brick = pts[pts[:, 2] > 0.004]
    cfg = IdentifyConfig()
    ident = identify(brick, rng=np.random.default_rng(0), config=cfg)
    part = ident.parts[0]
    assert {"box", "cylinder", "half_toroid"} <= {k for k, f in part.fits.items() if f is not None}
    # the brick's own fits, made to qualify with RMS in the reverse order of fit rate and name
    # (by RMS: half_toroid, cylinder, box; by fit rate or name: box, cylinder, half_toroid)
    made = {"half_toroid": (cfg.min_fit_rate, 1e-4), "cylinder": (0.9, 2e-4), "box": (0.99, 3e-4)}
    fits = {k: replace(f, fit_rate=made[k][0], rms=made[k][1]) if k in made else f for k, f in part.fits.items()}
    as_sphere = replace(part, shape=Shape.SPHERE, fits=fits, coverage={})  # as the rule base might have named it
    alts = other_models(as_sphere, cfg)
    assert [a.shape.value for a in alts] == ["half_toroid", "cylinder", "box"]
    for a in alts:
        assert a.rms == fits[a.shape.value].rms and a.primitive() is not None
        assert np.array_equal(a.indices, part.indices) and a.reason == ""
    below = {**fits, "half_toroid": replace(fits["half_toroid"], fit_rate=np.nextafter(cfg.min_fit_rate, 0))}
    assert [a.shape.value for a in other_models(replace(as_sphere, fits=below), cfg)] == ["cylinder", "box"]
    beyond = replace(as_sphere, coverage={"cylinder": cfg.min_coverage / 2})  # its surface reaching beyond the points
    assert [a.shape.value for a in other_models(beyond, cfg)] == ["half_toroid", "box"]
    assert other_models(replace(part, shape=Shape.UNIDENTIFIED), cfg) == []
    # a scene's fallback tries the r-th other model of every part together (a part with fewer as it is)
    two = replace(ident, parts=(as_sphere, replace(as_sphere, fits=below)))
    assert [[p.shape.value for p in a.parts] for a in _other_identifications(two, cfg)] == [
        ["half_toroid", "cylinder"], ["cylinder", "box"], ["box", "sphere"]]


def test_a_brick_named_a_sphere_is_planned_as_its_box_when_a_frame_has_no_grasp(db, monkeypatch):
    """A frame planned afresh whose parts give no grasp at all (``feature_grasps="fallback"``)
    is planned again with the cloud's features added, and so with each other model its
    clusters fitted, and each segment keeps the plan whose best grasp scores highest: a brick
    the rule base named a sphere wider than the gripper (as a Lego brick's studs made it one
    in E10's piles) gets its grasps on its box, which score higher than those on its seen
    faces' features (the far face unseen), and the plan keeps the box identification (what a
    next frame reuses). ``"apart"`` in a pile gives none. Mutations caught: no other models in
    the fallback, and the features' plan kept whenever it holds a grasp (the grasps' source
    is then the features)."""
    import graspsim.planning.scene as scene_mod
    from graspsim.perception.classify import Shape
    from graspsim.planning.scene_config import SceneConfig

    pts, eye = _brick_scene(np.random.default_rng(1))
    identify_new = scene_mod._identify_new

    def as_big_sphere(segs, olds, rng, cfg):  # the rule base's wrong name for the brick
        from dataclasses import replace
        out = []
        for ident, why in identify_new(segs, olds, rng, cfg):
            parts = tuple(replace(p, shape=Shape.SPHERE, dims={"radius": 0.09}) for p in ident.parts)
            out.append((replace(ident, parts=parts), why))
        return out

    monkeypatch.setattr(scene_mod, "_identify_new", as_big_sphere)
    plans = {name: scene_mod.plan_scene(pts, db=db, rng=np.random.default_rng(5), viewpoint=eye,
                                        config=SceneConfig(workers=1, feature_grasps=name))
             for name in ("apart", "fallback")}
    off, on = plans["apart"], plans["fallback"]
    assert len(off.segments) == len(on.segments) == 1 and not any(g.score > 0 for g in off.grasps)
    assert off.memory[0].ident.parts[0].shape is Shape.SPHERE
    good = [g for g in on.grasps if g.score > 0]
    assert good and {g.source for g in good} == {"box"} and on.segments[0].status == "planned"
    assert [p.shape for p in on.memory[0].ident.parts] == [Shape.BOX]


def _facing(points: np.ndarray, eye: np.ndarray, voxel: float = 0.004) -> np.ndarray:
    """(N,) bool: the points a camera at ``eye`` sees -- the nearest along each ray, by
    binning the directions from ``eye`` (a z-buffer over angles)."""
    d = points - eye
    r = np.linalg.norm(d, axis=1)
    u = d / r[:, None]
    az, el = np.arctan2(u[:, 1], u[:, 0]), np.arcsin(u[:, 2])
    step = voxel / float(np.median(r))
    key = np.round(az / step).astype(np.int64) * 1_000_003 + np.round(el / step).astype(np.int64)
    order = np.lexsort((r, key))
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    out = np.zeros(len(points), bool)
    out[order[first]] = True
    return out




def _reference_chords(x, Y, Z, depths, half_w, pad_length, gap, end_band, margin, widest):
    """The feature chords' rule written as numpy loops (what ``seed_chords`` compiles):
    [(j, k, lo, hi, zc)] for approach j and depth k, in that order."""
    out = []
    for j in range(Y.shape[1]):
        across = np.abs(Y[:, j]) <= half_w
        for k, d in enumerate(depths):
            foot = across & (Z[:, j] <= d) & (Z[:, j] >= d - pad_length)
            xs = np.sort(x[foot])
            if not len(xs):
                continue
            i0 = min(int(np.searchsorted(xs, 0.0)), len(xs) - 1)
            breaks = np.flatnonzero(np.diff(xs) > gap)
            before, after = breaks[breaks < i0], breaks[breaks >= i0]
            lo = xs[int(before[-1]) + 1 if len(before) else 0]
            hi = xs[int(after[0]) if len(after) else len(xs) - 1]
            if not hi - lo <= widest:
                continue
            ends = foot & ((np.abs(x - lo) <= end_band) | (np.abs(x - hi) <= end_band))
            out.append((j, k, lo, hi, min(float(np.median(Z[ends, j])), d - margin)))
    return out


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_feature_chords_are_the_numpy_rule_exactly(seed):
    """seed_chords (numba) gives the very numbers of the rule written in numpy: which
    approach and depth hold a chord, its ends and its contacts' height (odd and even
    counts of end points, gaps, chords too wide, empty footprints)."""
    from graspsim.maps._feature_kernel import seed_chords

    rng = np.random.default_rng(seed)
    M, J = int(rng.integers(1, 400)), int(rng.integers(1, 9))
    x = rng.normal(0, 0.03, M) * rng.choice([1.0, 3.0], M)
    Y, Z = rng.normal(0, 0.015, (M, J)), rng.uniform(-0.05, 0.04, (M, J))
    depths = np.array([0.006, 0.014, 0.022])
    args = (depths, 0.01, 0.04, float(rng.uniform(0.002, 0.02)), 0.004, 0.005, 0.11)
    ok, lo, hi, zc = seed_chords(x, Y, Z, *args)
    got = [(int(f) // 3, int(f) % 3, lo[f], hi[f], zc[f]) for f in np.flatnonzero(ok)]
    assert got == _reference_chords(x, Y, Z, *args)
    assert 0 < len(got) < 3 * J or J == 1  # footprints with a chord and without (empty or too wide)
