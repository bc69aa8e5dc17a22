"""Low-profile grasps: objects lower than the pad's planned region (a domino lying flat)
get poses lifted clear of the table, their contacts nearer the fingertip
(``maps.table_clearance.lift_clear``, ``PlannerConfig.low_profile``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.geometry.table import TablePlane, table_frame
from graspsim.grippers.spec import HGPL_25_60_A as GRIPPER
from graspsim.maps.collide import boxes_clear_sdf
from graspsim.maps.database import MapDatabase
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.table_clearance import LowProfile, clears_table, heights_above, lift_clear, low_part
from graspsim.perception import IdentifyConfig
from graspsim.planning.planner import PlannerConfig, plan
from graspsim.primitives import Box

FAST = MapConfig(surface_step=0.005, rotation_step=math.radians(22))
FLAT = Box(0.006, 0.03, 0.05)  # 6 mm thick: x, the thinnest edge, is up


def _table_under(box: Box) -> np.ndarray:
    """T_table_obj of a table under the box's -x face (the box lies flat on it)."""
    return table_frame((1.0, 0.0, 0.0), -0.5 * box.x)


def test_a_flat_box_has_no_pose_clear_of_the_table_but_lifted_ones_that_touch_it_only_by_the_pads():
    gmap = generate_fs_map(FLAT, GRIPPER, config=FAST)
    T = _table_under(FLAT)
    assert not clears_table(gmap, T, GRIPPER, 0.002).any()  # the problem: every pose under the table
    low = LowProfile()
    rows, pos = lift_clear(gmap, T, GRIPPER, 0.002, low)
    assert len(rows) >= 10
    lifted = gmap.select(rows)
    from dataclasses import replace

    lifted = replace(lifted, wrist_position=pos)
    # clear of the table by the low-profile clearance, under the other grasps' clearance
    h = heights_above(GRIPPER, T, lifted.wrist_quat, lifted.wrist_position, lifted.width)
    assert np.all(h >= low.clearance) and np.all(h < 0.002) and np.mean(h < low.clearance + 1e-5) > 0.5
    # the same contacts, mostly nearer the fingertip than the maps' tip margin, still on the pad
    assert np.array_equal(lifted.grasp_point, gmap.grasp_point[rows])
    d = GRIPPER.contact_depth(lifted.grasp_point.astype(float), lifted.wrist_position.astype(float),
                              lifted.approach.astype(float))
    assert np.all(d >= low.min_depth - 1e-6) and np.any(d < GRIPPER.depth_lo)
    # the pads reach down to the table: both tip edges within max_tip of it
    x = lifted.wrist_transforms()[:, :3, 0]
    tip = lifted.wrist_position @ T[2, :3] + T[2, 3] + GRIPPER.fingertip_z * (lifted.approach @ T[2, :3])
    assert np.all(tip + 0.5 * GRIPPER.pregrasp_opening(lifted.width) * np.abs(x @ T[2, :3]) <= low.max_tip + 1e-6)
    # collision-free with the object at the pre-grasp opening (the exact signed-distance check)
    free = boxes_clear_sdf(FLAT, GRIPPER, lifted.T_obj_wrist, GRIPPER.pregrasp_opening(lifted.width),
                           tolerance=FAST.collision_tolerance)
    assert free.all()
    # one pose per closing line and roll: the depths of one line lift to the same pose
    key = np.column_stack([lifted.contacts.reshape(len(lifted), 6), lifted.wrist_quat])
    assert len(np.unique(key, axis=0)) == len(lifted)
    # the grasps come from above: the pads close across the box, across the table's normal
    up = T[2, :3]
    assert np.all(np.abs(lifted.contacts[:, 1] - lifted.contacts[:, 0]) @ np.abs(up) < 1e-3 + 0.5 * FLAT.x)


def test_a_short_pad_with_one_planned_depth_gets_its_fingertips_lowered_to_the_table():
    """A pad shorter than the maps' depth step has one planned depth (the Franka hand's 18 mm
    pad at the 1 cm step): a plate seen a few mm higher than it lies (a domino's top face, the
    table band cutting its sides) puts every fingertip between the target and the clearance,
    none under the table to lift. Those poses move down to the target, contacts deeper on
    the pad within its planned region."""
    from dataclasses import replace

    short = replace(GRIPPER, name="short_pad", pad_length=0.018, finger_size=(0.01, 0.02, 0.018))
    cfg = replace(FAST, depth_step=0.01)
    assert len(short.contact_depths(cfg.depth_step)) == 1
    gmap = generate_fs_map(FLAT, short, config=cfg)
    T = table_frame((1.0, 0.0, 0.0), -0.5 * FLAT.x - 0.005)  # the plate 5 mm up, its mid-plane at 8 mm
    low = LowProfile()
    rows, pos = lift_clear(gmap, T, short, 0.002, low)
    assert len(rows) >= 5
    lifted = replace(gmap.select(rows), wrist_position=pos)
    h = heights_above(short, T, lifted.wrist_quat, lifted.wrist_position, lifted.width)
    assert np.all(np.abs(h - low.clearance) < 1e-5)  # at the target, not left 1-2 mm up
    d = short.contact_depth(lifted.grasp_point.astype(float), lifted.wrist_position.astype(float),
                            lifted.approach.astype(float))
    assert np.all(d >= low.min_depth - 1e-6) and np.all(d <= short.depth_hi + 1e-6)
    assert np.any(d > short.depth_lo + 1e-4)  # moved down: contacts deeper than the one planned depth
    free = boxes_clear_sdf(FLAT, short, lifted.T_obj_wrist, short.pregrasp_opening(lifted.width),
                           tolerance=cfg.collision_tolerance)
    assert free.all()
    # the default gripper's deeper planned contacts lift to the same height: nothing moves down
    full = generate_fs_map(FLAT, GRIPPER, config=cfg)
    rows, pos = lift_clear(full, T, GRIPPER, 0.002, low)
    d = GRIPPER.contact_depth(full.grasp_point[rows].astype(float), pos, full.approach[rows].astype(float))
    assert len(rows) and np.all(d <= np.max(GRIPPER.contact_depths(cfg.depth_step)) + 1e-6)


def test_which_parts_are_low_and_a_minimum_depth_beyond_the_pad_leaves_none():
    tall = Box(0.03, 0.04, 0.08)  # standing on its 30 x 40 face: its z is up
    T = table_frame((0.0, 0.0, 1.0), -0.5 * tall.z)
    flat = generate_fs_map(FLAT, GRIPPER, config=FAST)
    rows, _ = lift_clear(flat, _table_under(FLAT), GRIPPER, 0.002, LowProfile(min_depth=GRIPPER.pad_length))
    assert len(rows) == 0
    # which parts are low: the top below clearance + tip margin + surface step (12 mm here)
    assert low_part(FLAT, _table_under(FLAT), GRIPPER, 0.002, 0.005) and not low_part(tall, T, GRIPPER, 0.002, 0.005)
    lid = Box(0.011, 0.05, 0.05)
    assert low_part(lid, _table_under(lid), GRIPPER, 0.002, 0.005)
    assert not low_part(Box(0.013, 0.05, 0.05), _table_under(Box(0.013, 0.05, 0.05)), GRIPPER, 0.002, 0.005)


def test_bad_low_profile_settings_are_refused():
    with pytest.raises(InvalidParameterError, match="min_depth"):
        LowProfile(min_depth=-0.001)
    with pytest.raises(InvalidParameterError, match="LowProfile or None"):
        PlannerConfig(low_profile=0.001)


def _flat_cloud(rng: np.random.Generator, n: int = 3000) -> np.ndarray:
    """A 6 x 30 x 50 mm box lying flat on the table z = 0: its top and sides, no bottom, 0.5 mm noise."""
    dims = np.array([0.05, 0.03, 0.006])
    pts = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            if axis == 2 and sign < 0:
                continue  # the table hides the bottom
            area = np.prod(np.delete(dims, axis))
            k = max(20, int(n * area / 0.0033))
            p = (rng.random((k, 3)) - 0.5) * dims
            p[:, axis] = sign * 0.5 * dims[axis]
            pts.append(p)
    p = np.concatenate(pts) + [0.0, 0.0, 0.003]
    return p + rng.normal(0.0, 0.0005, p.shape)


@pytest.fixture(scope="module")
def flat_db(tmp_path_factory):
    return MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)


def _config(mode: str = "robust", **kw) -> PlannerConfig:
    return PlannerConfig(identify=IdentifyConfig.preset(mode), table=TablePlane(height=0.0), **kw)


def test_planner_offers_a_lying_flat_box_low_profile_grasps_and_the_paper_mode_none(flat_db):
    pts = _flat_cloud(np.random.default_rng(0))
    res = plan(pts, db=flat_db, rng=np.random.default_rng(0), config=_config())
    m = res.map
    table = m.meta.placement.table
    assert len(m) > 0 and table["lifted"] == len(m) and table["low_profile"] == LowProfile().to_dict()
    assert table["low_parts"] == 1
    assert np.any(m.robust > 0)  # scored by the same robust score, some expected to succeed
    T_table_obj = table_frame((0.0, 0.0, 1.0), 0.0) @ m.meta.placement.T_cloud_obj
    h = heights_above(GRIPPER, T_table_obj, m.wrist_quat, m.wrist_position, m.width)
    assert np.all(h >= LowProfile().clearance - 1e-6)
    # off, and in the paper's identification mode, no such grasp: the map as before
    assert len(plan(pts, db=flat_db, rng=np.random.default_rng(0), config=_config(low_profile=None)).map) == 0
    paper = plan(pts, db=flat_db, rng=np.random.default_rng(0), config=_config("paper"))
    assert len(paper.map) == 0 and "lifted" not in paper.map.meta.placement.table


def test_a_low_profile_grasp_lifts_the_flat_box_in_simulation(flat_db, tmp_path):
    from graspsim.maps.io import save_map
    from graspsim.sim.mapsim import simulate_map

    pts = _flat_cloud(np.random.default_rng(1))
    res = plan(pts, db=flat_db, rng=np.random.default_rng(1), config=_config())
    path = tmp_path / "flat.h5"
    save_map(res.map, path)
    out = simulate_map(path, top=3, threads=1, write=False)  # the map's own box, standing as it was seen
    assert out.results.counts()["success"] >= 2, out.results.counts()


def test_a_standing_box_plans_the_same_map_with_and_without_low_profile_grasps(flat_db, rng):
    """Only parts lower than the pad's planned region are lifted: a 50 mm box standing on the
    table gets the very map it got before (none of its poses lifted)."""
    dims = np.array([0.03, 0.04, 0.05])
    pts = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            if axis == 2 and sign < 0:
                continue
            p = (rng.random((600, 3)) - 0.5) * dims
            p[:, axis] = sign * 0.5 * dims[axis]
            pts.append(p)
    pts = np.concatenate(pts) + [0.0, 0.0, 0.025] + rng.normal(0.0, 0.0005, (3000, 3))
    on = plan(pts, db=flat_db, rng=np.random.default_rng(0), config=_config()).map
    off = plan(pts, db=flat_db, rng=np.random.default_rng(0), config=_config(low_profile=None)).map
    assert len(on) > 0 and on.meta.placement.table["low_parts"] == 0 and on.meta.placement.table["lifted"] == 0
    assert len(on) == len(off) and np.array_equal(on.wrist_position, off.wrist_position)
    assert np.array_equal(on.robust, off.robust, equal_nan=True)


def test_cli_adapt_lifts_a_flat_box_and_says_so_off_drops_them_and_a_bad_depth_is_refused(tmp_path, capsys):
    from graspsim.cli import main

    np.save(tmp_path / "flat.npy", _flat_cloud(np.random.default_rng(2)))
    args = ["adapt", str(tmp_path / "flat.npy"), "--db", str(tmp_path / "db"), "--surface-step", "0.005",
            "--rotation-step-deg", "22", "--table", "auto"]
    assert main([*args, "-o", str(tmp_path / "a.h5")]) == 0
    out = capsys.readouterr().out
    assert "lifted clear of it (contacts nearer the fingertip)" in out and (tmp_path / "a.h5").exists()
    assert main([*args, "-o", str(tmp_path / "b.h5"), "--low-profile", "off"]) == 1  # as before: no grasp
    assert "no collision-free grasp" in capsys.readouterr().err and not (tmp_path / "b.h5").exists()
    assert main([*args, "-o", str(tmp_path / "c.h5"), "--low-profile", "-1"]) == 2
    assert "--low-profile takes 'off' or a contact depth >= 0 m" in capsys.readouterr().err
