"""What the robust score chooses is what executors do: the scored jaw openings by default,
every executor opening to width + 2 x the chosen extra, the scored top-down stand-in,
and the occluded-space term of single-view clouds."""

from dataclasses import replace

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.maps import load_map, save_map
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.occlusion import ViewDepth
from graspsim.maps.robust import (
    DEFAULT_OPENINGS,
    OCCLUSION_POWER,
    RobustConfig,
    executed_width,
    score_poses,
    score_rows,
)
from graspsim.primitives import Box, Cylinder, HalfToroid, synthetic_cloud


def _cyl_map(n=4):
    ang = np.linspace(0.0, np.pi / 2, n)
    T = np.stack([grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0]) for a in ang])
    return hand_made_map(Cylinder(0.02, 0.20), T, np.full(n, 0.04), grades=np.linspace(0.5, 0.9, n))


def test_the_scored_openings_are_the_default_and_exact():
    from graspsim.planning.planner import PlannerConfig

    assert RobustConfig().openings == DEFAULT_OPENINGS and len(DEFAULT_OPENINGS) > 1 and DEFAULT_OPENINGS[0] == 0
    assert PlannerConfig().robust.openings == DEFAULT_OPENINGS
    assert PlannerConfig(rank="paper").rank == "paper"  # the paper's ranking scores nothing
    # scoring wider openings only where the narrower fell short gives the best over all openings
    box = Box(0.04, 0.05, 0.08)
    m = generate_fs_map(box, config=MapConfig(surface_step=0.01)).filter(accepted=True)
    m = m.sample_uniform_surface(200, np.random.default_rng(0))
    cloud = synthetic_cloud(box, np.random.default_rng(3), resolution=0.005, noise=0.0005).points
    rows = np.arange(len(m))
    cfg = RobustConfig(samples=16, margin=0.002)
    both = score_rows(m, rows, cloud, cfg)
    each = np.array([score_rows(m, rows, cloud, replace(cfg, openings=(o,))).robust for o in cfg.openings])
    np.testing.assert_allclose(both.robust, each.max(axis=0), atol=1e-12)
    first_best = np.asarray(cfg.openings)[np.argmax(each, axis=0)]
    np.testing.assert_array_equal(both.extra_opening, first_best)  # the narrowest on ties
    assert np.any(both.extra_opening > 0)


def test_trial_opens_the_jaws_to_the_chosen_extra(tmp_path, monkeypatch, capsys):
    import graspsim.sim.mapsim as mapsim

    extra = np.array([0.003, 0.0, np.nan, 0.010])
    m = replace(_cyl_map(), robust=np.array([0.9, 0.8, np.nan, 0.7]), robust_extra_opening=extra)
    path = save_map(m, tmp_path / "cyl.h5")
    seen = {}
    real = mapsim.run_trials

    def spy(scene, T, widths, *args, **kwargs):
        seen["widths"] = np.array(widths, float)
        return real(scene, T, widths, *args, **kwargs)

    monkeypatch.setattr(mapsim, "run_trials", spy)
    assert main(["trial", str(path), "--top", "4", "--threads", "1", "--json"]) == 0
    capsys.readouterr()
    order = mapsim.select_grasps(load_map(path), top=4)
    want = m.width[order] + 2.0 * np.nan_to_num(extra[order])
    np.testing.assert_allclose(seen["widths"], want, atol=1e-7)
    assert np.ptp(seen["widths"]) > 0.015  # the extras made a difference
    np.testing.assert_allclose(executed_width(m), m.width + 2.0 * np.nan_to_num(extra), atol=1e-7)


def test_the_pose_env_and_e09_execute_the_chosen_extra():
    import sys
    from pathlib import Path

    from graspsim.envs.baselines import planner_pose

    class Result:
        map = replace(_cyl_map(), robust=np.array([0.2, 0.9, 0.5, 0.1]),
                      robust_extra_opening=np.array([0.0, 0.006, 0.0, 0.0]))
        T_cloud_obj = np.eye(4)

    T, width = planner_pose(Result(), "robust")
    assert width == pytest.approx(0.04 + 2 * 0.006)
    assert planner_pose(Result(), "paper")[1] == pytest.approx(0.04)  # the paper: the map's opening

    # E09 executes through the function `graspsim trial` is a layer over (its widths: the test above)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    import e09_everyday_objects as e09

    from graspsim.sim import mapsim

    assert e09.simulate_map is mapsim.simulate_map and not hasattr(e09, "run_trials")


def _lying_arch_cloud():
    pts = synthetic_cloud(HalfToroid(0.045, 0.01), np.random.default_rng(0), resolution=0.004, noise=0.0005).points
    return pts - [0.0, 0.0, pts[:, 2].min() - 0.0005]  # a 2 cm arch lying on the table at z = 0


def _clear_fraction(cloud, gripper, T, width):
    """(fraction of 64 wrist perturbations clear of the cloud and the table, clear at the pose)."""
    tcp = T[:3, 3] + gripper.nominal_tcp[2] * T[:3, 2]
    s = score_poses(T[None], [width], [[tcp - 0.5 * width * T[:3, 0], tcp + 0.5 * width * T[:3, 0]]],
                    [[-T[:3, 0], T[:3, 0]]], cloud, gripper, table=(np.array([0, 0, 1.0]), 0.0),
                    config=RobustConfig(openings=(0.0,), terms=("cloud", "table"), samples=64))
    return float(s.feasible[0]), s.flags[0, 0] == 0


def test_the_stand_in_keeps_clear_of_what_was_seen_under_pose_error():
    from graspsim.envs.top_down import robust_top_down, top_down_pose
    from graspsim.grippers.spec import HGPL_25_60_A as g

    cloud = _lying_arch_cloud()
    heuristic, _ = _clear_fraction(cloud, g, *top_down_pose(cloud, g))
    assert heuristic < 0.9  # the plain heuristic's fingertips meet the table under the 3 mm / 2 deg error
    T, w = robust_top_down(cloud, g)
    feasible, at_pose = _clear_fraction(cloud, g, T, w)
    assert at_pose and feasible == 1.0
    # nothing a top-down grasp can span: no grasp rather than a colliding pose
    x, y = np.meshgrid(np.linspace(-0.15, 0.15, 40), np.linspace(-0.15, 0.15, 40))
    slab = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 0.05)])
    assert robust_top_down(np.concatenate([slab, slab - [0, 0, 0.02]]), g) is None


def _box_view():
    box = Box(0.04, 0.05, 0.08)
    camera = np.array([0.5, 0.0, 0.1])  # looking along -x at the box
    pts = synthetic_cloud(box, np.random.default_rng(2), resolution=0.004, noise=0.0003, camera=camera).points
    return box, pts, camera


def test_the_depth_image_tells_seen_from_occluded_space():
    _, pts, camera = _box_view()
    v = ViewDepth(pts, camera)
    assert not v.occluded(np.array([[0.05, 0.0, 0.0]])).any()  # in front of the seen face
    assert v.occluded(np.array([[-0.03, 0.0, 0.0], [0.0, 0.0, 0.0]])).all()  # behind it
    assert not v.occluded(np.array([[0.0, 0.08, 0.0], [0.0, 0.0, 0.2]])).any()  # beside, above: seen free


def test_the_compiled_occlusion_term_agrees_with_numpy_sample_by_sample():
    """finger_occlusion (compiled) against its numpy reference for grasps all around a
    seen box, at two openings: the same fraction per pose (the kernel sums in a fixed
    order where numpy's matrix products may not, so one sample at a pixel's edge may
    fall the other way; no more), over poses occluded to many degrees."""
    from graspsim.grippers.spec import HGPL_25_60_A as g
    from graspsim.maps.occlusion import finger_occlusion, finger_occlusion_numpy, finger_samples

    box, pts, camera = _box_view()
    v = ViewDepth(pts, camera)
    T = generate_fs_map(box, config=MapConfig(surface_step=0.01)).wrist_transforms()
    T = T[np.random.default_rng(3).choice(len(T), 400, replace=False)]
    S = len(finger_samples(g)[0])
    for gap in (0.05, 0.08):
        got = finger_occlusion(v, T[:, :3, :3], T[:, :3, 3], np.full(len(T), gap), g)
        want = finger_occlusion_numpy(v, T[:, :3, :3], T[:, :3, 3], np.full(len(T), gap), g)
        assert got.shape == want.shape == (len(T),)
        assert np.abs(got - want).max() <= 1.0 / S + 1e-12 and np.sum(got != want) <= 1
        assert len(np.unique(got)) > 10 and got.max() > 0.3  # occluded in many degrees
    assert finger_occlusion(v, np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0), g).shape == (0,)


def test_fingers_in_occluded_space_are_scored_down():
    box, pts, camera = _box_view()
    m = generate_fs_map(box, config=MapConfig(surface_step=0.01)).filter(accepted=True)
    m = m.sample_uniform_surface(200, np.random.default_rng(1))
    rows = np.arange(len(m))
    cfg = RobustConfig(samples=8, unseen_margin=0.0)  # the (1 - f) ** k term alone (the margin: test_maps_robust)
    plain = score_rows(m, rows, pts, cfg)
    seen = score_rows(m, rows, pts, cfg, viewpoint=camera)
    closing = np.abs(m.wrist_transforms()[:, :3, 0])  # the closing axis, object frame
    along = (closing[:, 0] > 0.9) & (plain.robust > 0)  # one finger behind the box as seen from +x
    across = (closing[:, 1] > 0.9) & (plain.robust > 0) & (m.wrist_transforms()[:, 2, 2] < -0.9)  # from above
    assert along.any() and across.any()
    assert np.all(seen.occluded[along] > 0.1) and np.all(seen.robust[along] < plain.robust[along])
    assert np.median(seen.occluded[across]) < np.median(seen.occluded[along])
    # the chance of starting in something unseen: (1 - f) ** k, k calibrated (OCCLUSION_POWER); k = 1 the plain fraction
    assert cfg.occlusion_power == OCCLUSION_POWER > 1
    np.testing.assert_allclose(seen.robust, plain.robust * (1 - seen.occluded) ** OCCLUSION_POWER, atol=1e-9)
    linear = score_rows(m, rows, pts, replace(cfg, occlusion_power=1.0), viewpoint=camera)
    np.testing.assert_allclose(linear.robust, plain.robust * (1 - linear.occluded), atol=1e-9)
    assert np.all(seen.robust[along] < linear.robust[along])
    off = score_rows(m, rows, pts, replace(cfg, occlusion=False), viewpoint=camera)
    np.testing.assert_array_equal(off.robust, plain.robust)


def test_finger_samples_handed_out_are_the_callers_own():
    """The occlusion term reuses one set of finger samples per gripper: a caller that
    changes the samples it was given changes no later score."""
    from graspsim.grippers.spec import HGPL_25_60_A as g
    from graspsim.maps.occlusion import finger_occlusion, finger_samples

    _, pts, camera = _box_view()
    v = ViewDepth(pts, camera)
    R = np.repeat(np.diag([1.0, -1.0, -1.0])[None], 3, axis=0)  # from above
    w = np.array([[0.0, 0.0, 0.2], [0.03, 0.0, 0.15], [-0.02, 0.01, 0.16]])
    before = finger_occlusion(v, R, w, np.full(3, 0.05), g)
    q, s = finger_samples(g)
    original = q.copy()
    q += 0.1
    s[:] = 0.0
    np.testing.assert_array_equal(finger_occlusion(v, R, w, np.full(3, 0.05), g), before)
    np.testing.assert_array_equal(finger_samples(g)[0], original)


def test_a_cloud_file_with_a_camera_record_carries_its_viewpoint(tmp_path):
    from graspsim.geometry.camera import Camera, Intrinsics, look_at
    from graspsim.perception.cloud_input import read_point_cloud
    from graspsim.tabletop.cloud_io import save_cloud

    _, pts, eye = _box_view()
    cam = Camera(Intrinsics.preset("d435"), look_at(eye, np.zeros(3)))
    save_cloud(tmp_path / "w.pcd", pts, camera=cam, frame="world")
    np.testing.assert_allclose(read_point_cloud(tmp_path / "w.pcd").viewpoint, eye, atol=1e-9)
    save_cloud(tmp_path / "c.ply", pts, camera=cam, frame="camera")
    np.testing.assert_array_equal(read_point_cloud(tmp_path / "c.ply").viewpoint, np.zeros(3))
    save_cloud(tmp_path / "n.npy", pts)
    assert read_point_cloud(tmp_path / "n.npy").viewpoint is None
