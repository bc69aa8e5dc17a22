"""The space behind a neighbour's seen points (``SceneConfig.shadow_depth``): samples along
the camera's rays up to the depth, above the table only; the setting's bounds; and a scene
planned with it keeps every grasp's gripper clear of the neighbours' shadows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.perception.plane import PlaneFit
from graspsim.planning.scene import _shadow_samples, plan_scene, shadow_step
from graspsim.planning.scene_config import MAX_SHADOW_DEPTH, SHADOW_DEPTH, SceneConfig, with_shadow_depth
from graspsim.primitives import Box, Cylinder, synthetic_cloud
from graspsim.transforms import quat_to_matrix

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))
TABLE = PlaneFit(np.array([0.0, 0.0, 1.0]), 0.0, np.zeros(0, bool), 0.0, 1.0)


def test_shadow_samples_lie_on_the_rays_behind_each_point_and_above_the_table():
    eye = np.array([0.0, -0.5, 0.5])
    seg = np.array([[0.0, 0.0, 0.05], [0.05, 0.0, 0.004], [0.0, 0.05, 0.08]])
    s = _shadow_samples(seg, TABLE, eye, 0.03, 0.004)
    assert len(s) and np.all(s[:, 2] > 0)
    for p in s:  # each on the ray through a seen point, 4 to 30 mm behind it
        d = p - eye
        u = d / np.linalg.norm(d)
        k = np.argmin([np.linalg.norm(np.cross(q - eye, u)) for q in seg])
        q = seg[k]
        assert np.linalg.norm(np.cross(q - eye, u)) < 1e-9
        behind = np.linalg.norm(p - eye) - np.linalg.norm(q - eye)
        assert 0.004 - 1e-9 <= behind <= 0.03 + 1e-9
    # the point 4 mm over the table: its ray reaches the table (down at 45 deg) within 6 mm
    low = s[np.linalg.norm(np.cross(s - eye, seg[1] - eye), axis=1) < 1e-9]
    assert 0 < len(low) < 7
    assert len(_shadow_samples(seg, TABLE, eye, 0.0, 0.004)) == 0


def test_the_step_along_the_rays_keeps_a_finger_from_fitting_between_samples():
    """Along the rays the samples lie twice the grid step apart, less where the finger is
    thinner, never closer than the grid; on a regular 4 mm grid seen from afar, every
    10 mm cube (the Festo finger's thinnest side, in any direction) inside a shadow holds
    a sample."""
    from dataclasses import replace

    assert shadow_step(0.004, HGPL_25_60_A) == pytest.approx(0.008)
    assert shadow_step(0.004, replace(HGPL_25_60_A, finger_size=(0.0075, 0.02, 0.08))) == pytest.approx(0.006)
    assert shadow_step(0.004, replace(HGPL_25_60_A, finger_size=(0.003, 0.02, 0.08))) == pytest.approx(0.004)
    eye = np.array([0.0, 0.0, 50.0])  # far above: the rays nearly parallel, straight down
    g = (np.arange(-12, 13) + 0.5) * 0.004
    wall = np.c_[np.repeat(g, len(g)), np.tile(g, len(g)), np.full(len(g) ** 2, 0.08)]  # a flat top, 4 mm grid
    along = shadow_step(0.004, HGPL_25_60_A)
    s = _shadow_samples(wall, TABLE, eye, 0.04, 0.004, along)
    behind = 0.08 - s[:, 2]
    assert np.allclose(np.unique(np.round(behind, 5)), np.arange(1, 6) * along, atol=1e-4)
    rng = np.random.default_rng(3)
    for _ in range(300):  # 10 mm cubes, any orientation, wholly within the shadow (under the top, 40 mm deep)
        q = rng.normal(size=4)
        R = quat_to_matrix(q / np.linalg.norm(q))
        c = np.r_[rng.uniform(-0.03, 0.03, 2), rng.uniform(0.08 - 0.04 + 0.009, 0.08 - 0.009)]
        local = (s - c) @ R
        assert np.any(np.all(np.abs(local) <= 0.005, axis=1)), "a finger-thick cube between the samples"


@pytest.mark.parametrize("bad", [-0.01, MAX_SHADOW_DEPTH + 0.01, True, "0.03", float("nan")])
def test_the_shadow_depth_is_bounded(bad):
    with pytest.raises(InvalidParameterError, match="shadow"):
        SceneConfig(shadow_depth=bad)
    with pytest.raises(InvalidParameterError, match="shadow"):
        with_shadow_depth(SceneConfig(), bad)
    assert SceneConfig().shadow_depth == SHADOW_DEPTH > 0
    assert with_shadow_depth(SceneConfig(), 0.05).shadow_depth == 0.05
    assert with_shadow_depth(SceneConfig(), 0).shadow_depth == 0.0


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("shadowdb"), config=FAST)
    d.build([Cylinder(0.025, 0.1), Box(0.02, 0.06, 0.1)])
    return d


def test_a_scene_planned_with_shadows_keeps_grasps_out_of_them(db, monkeypatch):
    """A can behind a lower plate, both seen from one camera in front: with a 4 cm shadow
    depth no grasp of the can puts a finger behind the plate's seen face, within the depth,
    and the can keeps grasps; a segment's obstacles hold the other segment's shadow samples,
    not its own; each segment's depth images (the single-view rules', the occlusion term's)
    hold what the camera saw alone, not the shadow and solid samples among its obstacles,
    and have the pixel of its own points' spacing."""
    import graspsim.maps.occlusion as occlusion
    import graspsim.planning.planner as planner
    from graspsim.geometry.spacing import median_spacing

    views, scored = [], []

    class Recorded(planner.ViewDepth):
        def __init__(self, points, viewpoint, tolerance=None, *, spacing=None, into=views):
            super().__init__(points, viewpoint, tolerance, spacing=spacing)
            into.append((np.asarray(points, float).copy(), self.spacing))

    class Scored(Recorded):  # the occlusion term's (object frame)
        def __init__(self, points, viewpoint, tolerance=None, *, spacing=None):
            super().__init__(points, viewpoint, tolerance, spacing=spacing, into=scored)

    monkeypatch.setattr(planner, "ViewDepth", Recorded)
    monkeypatch.setattr(occlusion, "ViewDepth", Scored)
    rng = np.random.default_rng(4)
    eye = np.array([0.0, -0.6, 0.5])
    lo, hi = np.array([-0.04, -0.055, 0.0]), np.array([0.04, -0.045, 0.06])  # the plate

    def seen(pts):  # not behind the plate along the ray to the camera
        t = np.linspace(0.02, 0.98, 60)
        ray = eye + t[None, :, None] * (pts[:, None, :] - eye)
        return ~np.any(np.all((ray > lo) & (ray < hi), axis=2), axis=1)

    can = synthetic_cloud(Cylinder(0.025, 0.1), rng, resolution=0.003, noise=0.0002).points + [0.0, 0.0, 0.05]
    can = can[((can[:, 1] < 0.005) | (can[:, 2] > 0.099)) & seen(can)]  # its front and top, over the plate
    plate = synthetic_cloud(Box(0.08, 0.01, 0.06), rng, resolution=0.003, noise=0.0002).points + [0.0, -0.05, 0.03]
    plate = plate[(plate[:, 1] < -0.0545) | (plate[:, 2] > 0.0595)]  # its front face and top
    table = np.c_[rng.uniform(-0.25, 0.25, (8000, 2)), rng.normal(0, 0.0005, 8000)]
    table = table[(np.linalg.norm(table[:, :2], axis=1) > 0.03) & seen(table)
                  & ~np.all((table[:, :2] > lo[:2]) & (table[:, :2] < hi[:2]), axis=1)]
    pts = np.r_[table, can[can[:, 2] > 0.008], plate[plate[:, 2] > 0.008]]
    out = {}
    for depth in (0.0, 0.04):
        sp = plan_scene(pts, db=db, rng=np.random.default_rng(5), viewpoint=eye,
                        config=SceneConfig(workers=1, shadow_depth=depth, crease_angle=None))
        out[depth] = sp
        segs = {len(sp.perception.segment_points(k)): sp.perception.segment_points(k) for k in range(2)}
        own = sorted(median_spacing(p) for p in segs.values())
        assert views and scored and all(any(abs(v - o) < 1e-12 for o in own) for _, v in views + scored)
        camera = {tuple(p) for p in np.round(sp.perception.points, 9)}
        for P, _ in views:  # the camera's points only (the cloud frame), each segment's with its neighbour's
            assert len(P) > max(segs) and all(tuple(p) in camera for p in np.round(P, 9))
        assert {len(P) for P, _ in scored} <= {len(P) for P, _ in views}  # the same points, in the object frame
        views.clear()
        scored.clear()
    for depth, sp in out.items():
        assert sp.perception.n_segments == 2
        seg_of = [sp.perception.segment_points(k) for k in range(2)]
        k_can = int(np.argmax([s[:, 1].mean() for s in seg_of]))
        shadow = _shadow_samples(seg_of[1 - k_can], sp.perception.plane, eye, 0.04, SceneConfig().solid_step)
        mine = [g for g in sp.grasps if g.segment == k_can]
        assert mine, "the can keeps grasps"
        if depth > 0:
            assert not any(_in_fingers(g, shadow).any() for g in mine)
    # a known gap between objects turns the shadows off: the plan is the one without them
    apart = [plan_scene(pts, db=db, rng=np.random.default_rng(5), viewpoint=eye,
                        config=SceneConfig(workers=1, shadow_depth=d, crease_angle=None, min_gap=0.01))
             for d in (0.0, 0.1)]
    assert [(g.segment, g.score, g.T_world_wrist.tolist()) for g in apart[0].grasps] == \
        [(g.segment, g.score, g.T_world_wrist.tolist()) for g in apart[1].grasps]
    # the obstacles of a segment hold the other segments' shadows, not its own
    from graspsim.planning.scene import _obstacles

    per = out[0.04].perception
    shadows = [_shadow_samples(per.segment_points(k), per.plane, eye, 0.04, 0.004) for k in range(2)]
    for k in range(2):
        obs, seen = _obstacles(per, k, [np.zeros((0, 3))] * 2, 1.0, None, shadows)
        as_set = {tuple(p) for p in np.round(obs, 9)}
        assert all(tuple(p) in as_set for p in np.round(shadows[1 - k], 9))
        assert not any(tuple(p) in as_set for p in np.round(shadows[k], 9))
        # of them, the camera saw the other segment's points, not the shadow's samples
        assert np.array_equal(obs[seen], per.points[per.segment != k]) and len(obs[~seen]) == len(shadows[1 - k])


def _in_fingers(g, pts: np.ndarray) -> np.ndarray:
    """Which points lie inside either finger box of grasp ``g`` at its opening."""
    from graspsim.grippers.spec import HGPL_25_60_A as G

    local = (pts - g.T_world_wrist[:3, 3]) @ g.T_world_wrist[:3, :3]
    fx, fy, fz = G.finger_size
    return (np.abs(np.abs(local[:, 0]) - 0.5 * g.opening - 0.5 * fx) < 0.5 * fx) & (np.abs(local[:, 1]) < 0.5 * fy) \
        & (local[:, 2] > G.fingertip_z - fz) & (local[:, 2] < G.fingertip_z)
