"""``graspsim plan-scene``: a scene cloud of the user's own (here rendered by the simulated
depth camera and written as a file, as a real camera's driver would) -> table, segments
and ranked grasps in a JSON file; bad input is a one-line error that writes nothing."""

import json
import math

import numpy as np
import pytest

from graspsim.cli import main
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.perception import read_point_cloud
from graspsim.planning.planner import PlannerConfig
from graspsim.planning.scene import plan_scene
from graspsim.planning.scene_config import SceneConfig
from graspsim.primitives import Box, Cylinder, Sphere

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))
FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.2), Sphere(0.035)])
    return d


@pytest.fixture(scope="module")
def scene_cloud(tmp_path_factory):
    """A 3-object packed scene seen by the D435-like camera, written in the camera's frame
    with its camera record (.pcd + .pcd.json), and its ground-truth object per point."""
    from graspsim.geometry.camera import backproject, rig
    from graspsim.tabletop.cloud_io import save_view
    from graspsim.tabletop.table_scene import make_scene

    sim = make_scene(3, "packed", 5, object_set="primitives").sim()
    frame = sim.render(rig(1)[0])
    sim.close()
    view = backproject(frame)
    path = tmp_path_factory.mktemp("cloud") / "table.pcd"
    save_view(path, view)
    return path, view, frame


def _run(capsys, *args):
    code = main(["plan-scene", *map(str, args), "--json"])
    out = capsys.readouterr()
    return code, json.loads(out.out.strip().splitlines()[-1]) if out.out.strip() else None, out.err


@pytest.mark.slow
def test_a_scene_file_gets_the_grasps_the_library_plans(tmp_path, capsys, db, scene_cloud):
    path, view, _ = scene_cloud
    out, lab = tmp_path / "grasps.json", tmp_path / "labels.npy"
    code, s, _ = _run(capsys, path, "-o", out, "--labels", lab, "--min-gap", 0.01, "--db", db.root, *FAST_FLAGS)
    assert code == 0 and s["file"] == str(out) and s["labels"] == str(lab)
    r = json.loads(out.read_text())
    # the camera record beside the cloud: the camera at the origin; the table's up towards it
    assert r["viewpoint"] == [0.0, 0.0, 0.0] and r["points"] == len(view.points)
    n = np.array(r["table"]["normal"])
    assert n @ (np.zeros(3) - np.median(view.points, axis=0)) > 0
    scores = [g["score"] for g in r["grasps"]]
    assert scores == sorted(scores, reverse=True) and r["best"] == r["grasps"][0] and scores[0] > 0
    assert {g["segment"] for g in r["grasps"]} <= {d["segment"] for d in r["segments"]}
    # exactly what plan_scene gives for the same cloud, settings and seed
    cloud = read_point_cloud(path, min_points=100, max_extent=10.0, what="a table-top scene")
    cfg = SceneConfig(min_gap=0.01, up=tuple(float(v) for v in r["up"]))
    lib = plan_scene(cloud.points, db=db, rng=np.random.default_rng(0), config=cfg, viewpoint=np.zeros(3))
    assert len(lib.grasps) == len(r["grasps"])
    for mine, theirs in zip(r["grasps"], lib.grasps):
        assert mine["segment"] == theirs.segment and mine["score"] == pytest.approx(theirs.score, abs=1e-12)
        np.testing.assert_allclose(mine["T_world_wrist"], theirs.T_world_wrist, atol=1e-12)
    # each file point's segment: every object's points fall (almost all) in one segment of their own
    labels = np.load(lab)
    assert labels.shape == (len(view.points),)
    for obj in np.unique(view.labels[view.labels >= 0]):
        seg, count = np.unique(labels[view.labels == obj], return_counts=True)
        assert seg[np.argmax(count)] >= 0 and count.max() >= 0.9 * (view.labels == obj).sum()
    assert np.all(labels[view.labels < 0] < 0) or (labels[view.labels < 0] >= 0).mean() < 0.01
    # the best grasp's segment is one object's
    best = labels == r["best"]["segment"]
    assert np.unique(view.labels[best]).size == 1


def test_the_budget_flags_help_names_the_default_scene_config_holds():
    """--budget's help spells out the default budget (it is written there so that --help
    imports no planning code): it must be SceneConfig's."""
    import argparse

    from graspsim.cli._common import add_budget_flag

    p = argparse.ArgumentParser()
    add_budget_flag(p)
    cfg = SceneConfig()
    assert f"SceneConfig's, {cfg.enough}:{cfg.per_segment})" in " ".join(p.format_help().split())


def test_the_unseen_margin_flag_reaches_the_robust_score(tmp_path, capsys, db):
    """--unseen-margin alone is the measured margin, with a value that value (0: none),
    absent the scene planner's default (the measured margin); scene and plan-scene read it
    alike, and plan-scene records the margin it planned with (none without a viewpoint)."""
    from dataclasses import replace

    from graspsim.cli import build_parser
    from graspsim.cli._common import scene_planning_from_args
    from graspsim.maps.robust import UNSEEN_MARGIN

    planner = SceneConfig().planner
    for command in ("scene", "plan-scene"):
        head = [command] if command == "scene" else [command, "c.npy", "-o", "g.json"]
        for flag, want in (([], UNSEEN_MARGIN), (["--unseen-margin"], UNSEEN_MARGIN),
                           (["--unseen-margin", "0.01"], 0.01), (["--unseen-margin", "0"], 0.0)):
            args = build_parser().parse_args([*head, *flag])
            got = scene_planning_from_args(args, SceneConfig()).planner.robust.unseen_margin
            assert got == want, (command, flag)
    assert UNSEEN_MARGIN > 0 and replace(planner.robust).unseen_margin == UNSEEN_MARGIN  # on by default in scenes
    assert PlannerConfig().robust.unseen_margin == 0.0  # not in the single-object planner's settings
    rng = np.random.default_rng(1)
    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), rng.normal(0, 0.0005, 3000)]
    box = np.c_[rng.uniform(-0.03, 0.03, (800, 2)), rng.uniform(0, 0.06, 800)]
    f, out = tmp_path / "cloud.npy", tmp_path / "grasps.json"
    np.save(f, np.r_[table, box])
    code, s, _ = _run(capsys, f, "-o", out, "--viewpoint", 0, -0.4, 0.5, "--unseen-margin", 0.015,
                      "--db", db.root, *FAST_FLAGS)
    rec = json.loads(out.read_text())
    assert code == 0 and rec["unseen_margin"] == 0.015
    assert rec["seen_between"] == SceneConfig().planner.seen_between > 0  # the record says what the plan asked
    code, s, _ = _run(capsys, f, "-o", out, "--db", db.root, *FAST_FLAGS)  # no viewpoint: no unseen side known
    assert code == 0 and json.loads(out.read_text())["unseen_margin"] == 0.0


@pytest.mark.parametrize("name", ["seen_between", "sparse_between"])
def test_the_point_count_flags_reach_the_planner(tmp_path, capsys, db, name):
    """--seen-between N, the points of its own segment a grasp must close on, and
    --sparse-between N, the points below which a scene grasp's score is discounted (0: off
    for both), absent the scene planner's measured defaults (SEEN_BETWEEN, SPARSE_BETWEEN);
    scene and plan-scene read them alike, plan-scene records the count it planned with, and
    a bad count is one line naming the flag, with nothing written."""
    import argparse

    from graspsim.cli import _common, build_parser
    from graspsim.errors import InvalidParameterError
    from graspsim.planning.observed import SEEN_BETWEEN
    from graspsim.planning.scene_config import SPARSE_BETWEEN

    flag = "--" + name.replace("_", "-")
    measured, read = {"seen_between": (SEEN_BETWEEN, lambda sc: sc.planner.seen_between),
                      "sparse_between": (SPARSE_BETWEEN, lambda sc: sc.sparse_between)}[name]
    for command in ("scene", "plan-scene"):
        head = [command] if command == "scene" else [command, "c.npy", "-o", "g.json"]
        for given, want in (([], measured), ([flag, "0"], 0), ([flag, "12"], 12)):
            args = build_parser().parse_args([*head, *given])
            assert read(_common.scene_planning_from_args(args, SceneConfig())) == want, (command, given)
        for bad in ("-1", "2.5", "many"):
            args = build_parser().parse_args([*head, flag, bad])
            with pytest.raises(InvalidParameterError, match=f"{flag} must be a whole number"):
                _common.scene_planning_from_args(args, SceneConfig())
    assert SEEN_BETWEEN > 0 and PlannerConfig().seen_between == 0  # on in scenes, off for single objects
    assert SPARSE_BETWEEN > SEEN_BETWEEN
    p = argparse.ArgumentParser()
    getattr(_common, f"add_{name}_flag")(p)
    assert f"the measured {measured};" in " ".join(p.format_help().split())  # the help says the value in use
    rng = np.random.default_rng(1)
    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), rng.normal(0, 0.0005, 3000)]
    box = np.c_[rng.uniform(-0.03, 0.03, (800, 2)), rng.uniform(0, 0.06, 800)]
    f, out = tmp_path / "cloud.npy", tmp_path / "grasps.json"
    np.save(f, np.r_[table, box])
    code, _, _ = _run(capsys, f, "-o", out, "--db", db.root, *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())[name] == measured
    code, _, _ = _run(capsys, f, "-o", out, flag, 0, "--db", db.root, *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())[name] == 0
    code, _, err = _run(capsys, f, "-o", tmp_path / "other.json", flag, -3, "--db", db.root, *FAST_FLAGS)
    assert code != 0 and f"{flag} must be a whole number" in err and "Traceback" not in err
    assert not (tmp_path / "other.json").exists()


def test_the_feature_grasps_flag_reaches_the_planner(tmp_path, capsys, db):
    """--feature-grasps {apart,always,never} says where a segment's planning adds grasps on
    its cloud's own features; absent: apart (only with a known gap between objects); scene
    and plan-scene read it alike, and plan-scene records it."""
    from graspsim.cli import build_parser
    from graspsim.cli._common import scene_planning_from_args
    from graspsim.planning.scene_config import FEATURE_GRASPS

    for command in ("scene", "plan-scene"):
        head = [command] if command == "scene" else [command, "c.npy", "-o", "g.json"]
        for flag, want in (([], "fallback"), *((["--feature-grasps", w], w) for w in FEATURE_GRASPS)):
            args = build_parser().parse_args([*head, *flag])
            assert scene_planning_from_args(args, SceneConfig()).feature_grasps == want, (command, flag)
    rng = np.random.default_rng(1)
    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), rng.normal(0, 0.0005, 3000)]
    box = np.c_[rng.uniform(-0.03, 0.03, (800, 2)), rng.uniform(0, 0.06, 800)]
    f, out = tmp_path / "cloud.npy", tmp_path / "grasps.json"
    np.save(f, np.r_[table, box])
    code, _, _ = _run(capsys, f, "-o", out, "--db", db.root, *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())["feature_grasps"] == "fallback"
    code, _, _ = _run(capsys, f, "-o", out, "--feature-grasps", "never", "--db", db.root, *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())["feature_grasps"] == "never"


@pytest.mark.slow
def test_a_smaller_planning_budget_scores_fewer_grasps_per_object(tmp_path, capsys, db, scene_cloud):
    path, _, _ = scene_cloud
    runs = {}
    for budget in ("", "2:20"):
        out = tmp_path / f"grasps{budget.replace(':', '_')}.json"
        code, _, _ = _run(capsys, path, "-o", out, "--min-gap", 0.01, "--db", db.root, *FAST_FLAGS,
                          *(["--budget", budget] if budget else []))
        assert code == 0
        runs[budget] = json.loads(out.read_text())
    assert runs[""]["budget"] == "32:200" and runs["2:20"]["budget"] == "2:20"
    small = {d["segment"]: d for d in runs["2:20"]["segments"]}
    for d in runs[""]["segments"]:  # the same segments, each scoring at most 20 grasps per part
        s = small[d["segment"]]
        assert s["primitives"] == d["primitives"] and s["scored"] <= 20 * len(s["primitives"])
    assert sum(d["scored"] for d in runs[""]["segments"]) > sum(s["scored"] for s in small.values())


@pytest.mark.slow
def test_no_depth_rows_and_a_crop_keep_the_labels_on_the_file_rows(tmp_path, capsys, db, scene_cloud):
    path, view, _ = scene_cloud
    pts = view.points.copy()
    pts[::7] = np.nan  # an organised cloud's missing depth
    f = tmp_path / "holes.npy"
    np.save(f, pts)
    lo, hi = view.points.min(axis=0), view.points.max(axis=0)
    obj = np.unique(view.labels[view.labels >= 0])[0]  # crop one object out: the box stops before it
    cut = float(view.points[view.labels == obj, 0].min()) - 0.005
    crop = [*(lo - 1), cut, *(hi[1:] + 1)] if cut > float(np.median(view.points[:, 0])) else None
    if crop is None:  # the object is on the low side of x: crop from the other end
        cut = float(view.points[view.labels == obj, 0].max()) + 0.005
        crop = [cut, *(lo[1:] - 1), *(hi + 1)]
    out, lab = tmp_path / "g.json", tmp_path / "l.npy"
    code, s, _ = _run(capsys, f, "-o", out, "--labels", lab, "--viewpoint", 0, 0, 0, "--crop", *crop,
                      "--db", db.root, *FAST_FLAGS)
    assert code == 0
    labels = np.load(lab)
    assert labels.shape == (len(pts),) and np.all(labels[::7] == -1)  # one per file row, none where no depth
    assert np.all(labels[view.labels == obj] == -1)  # cropped away
    assert s["used"] < s["points"] - len(pts[::7])


@pytest.mark.slow
def test_a_depth_image_is_planned_in_the_cameras_frame(tmp_path, capsys, db, scene_cloud):
    """A 16-bit PNG in millimetres (a RealSense driver's) with the d435 preset, and a float
    .npy in metres with explicit intrinsics: each planned as plan_scene plans its pixels
    back-projected; the labels file is the image's (H, W)."""
    from PIL import Image

    from graspsim.geometry.camera import Camera, DepthFrame, backproject

    _, _, frame = scene_cloud
    k = frame.camera.intrinsics
    mm = np.round(frame.depth * 1000).astype(np.uint16)
    png, npy = tmp_path / "depth.png", tmp_path / "depth.npy"
    Image.fromarray(mm).save(png)
    np.save(npy, frame.depth.astype(np.float64))
    for f, flags, depth in ((png, ["--camera", "d435"], mm * 0.001),
                            (npy, ["--intrinsics", k.fx, k.fy, k.cx, k.cy], frame.depth.astype(np.float64))):
        out, lab = tmp_path / f"{f.stem}.json", tmp_path / f"{f.stem}_labels.npy"
        code, s, _ = _run(capsys, f, *flags, "-o", out, "--labels", lab, "--min-gap", 0.01, "--db", db.root,
                          *FAST_FLAGS)
        assert code == 0 and s["input"] == "depth image" and s["viewpoint"] == [0.0, 0.0, 0.0]
        r = json.loads(out.read_text())
        assert r["points"] == k.width * k.height and r["intrinsics"]["fx"] == pytest.approx(k.fx)
        pts = backproject(DepthFrame(depth, Camera(k, np.eye(4)))).points
        assert r["used"] == len(pts)
        lib = plan_scene(pts, db=db, rng=np.random.default_rng(0),
                         config=SceneConfig(min_gap=0.01, up=tuple(r["up"])), viewpoint=np.zeros(3))
        assert [g["segment"] for g in r["grasps"]] == [g.segment for g in lib.grasps]
        np.testing.assert_allclose(r["best"]["T_world_wrist"], lib.best.T_world_wrist, atol=1e-12)
        labels = np.load(lab)
        assert labels.shape == frame.depth.shape and np.all(labels[frame.depth == 0] == -1)
        for obj in np.unique(frame.labels[frame.labels >= 0]):  # each object's pixels: one segment
            seg, count = np.unique(labels[frame.labels == obj], return_counts=True)
            assert seg[np.argmax(count)] >= 0 and count.max() >= 0.9 * (frame.labels == obj).sum()


@pytest.mark.parametrize("image, args, message", [
    ("rgb", ["--camera", "d435"], "one channel"),
    ("small", ["--camera", "d435"], "preset is 640 x 480"),
    ("mm", ["--camera", "d435", "--depth-scale", "1"], "is the depth scale right"),
    ("mm", ["--camera", "d435", "--depth-scale", "0"], "depth scale"),
    ("zeros", ["--camera", "d435"], "no pixel has a valid depth"),
    ("mm", ["--camera", "kinect"], "unknown camera preset"),
    ("mm", ["--camera", "d435", "--intrinsics", "300", "300", "320", "240"], "not both"),
    ("mm", ["--camera", "d435", "--units", "mm"], "--units is for point clouds"),
    ("mm", ["--intrinsics", "300", "300", "9999", "240"], "principal point"),
    ("cloud", ["--depth-scale", "0.001"], "--depth-scale is for depth images"),
    ("cloud", ["--camera", "d435"], "depth image"),
])
def test_bad_depth_input_is_a_one_line_error_and_writes_nothing(image, args, message, tmp_path, capsys, db):
    from PIL import Image

    rng = np.random.default_rng(3)
    mm = rng.integers(500, 800, (480, 640)).astype(np.uint16)
    f = tmp_path / ("cloud.npy" if image == "cloud" else "depth.png")
    if image == "rgb":
        Image.fromarray(np.zeros((480, 640, 3), np.uint8)).save(f)
    elif image == "cloud":
        np.save(f, rng.uniform(0, 0.3, (1000, 3)))
    else:
        Image.fromarray({"mm": mm, "small": mm[:240, :320], "zeros": 0 * mm}[image]).save(f)
    out = tmp_path / "g.json"
    code = main(["plan-scene", str(f), "-o", str(out), *args, "--db", str(db.root), *FAST_FLAGS])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_nothing_to_grasp_exits_1_and_leaves_the_output_as_it_was(tmp_path, capsys, db):
    rng = np.random.default_rng(0)
    table = np.c_[rng.uniform(-0.3, 0.3, (5000, 2)), rng.normal(0, 0.0005, 5000)]  # a bare table
    f = tmp_path / "bare.npy"
    np.save(f, table)
    out = tmp_path / "grasps.json"
    out.write_text("earlier")
    code, s, err = _run(capsys, f, "-o", out, "--db", db.root, *FAST_FLAGS)
    assert code == 1 and s["file"] is None and s["segments"] == [] and s["best"] is None
    assert "no grasp" in err and out.read_text() == "earlier"


def test_a_cloud_too_big_for_the_memory_budget_is_refused_before_any_work(tmp_path, capsys, db, monkeypatch):
    from graspsim.errors import BudgetExceededError
    from graspsim.planning.scene_config import SCENE_BYTES_PER_POINT

    rng = np.random.default_rng(2)
    pts = np.c_[rng.uniform(-0.3, 0.3, (20_000, 2)), rng.normal(0, 0.0005, 20_000)]
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", str(SCENE_BYTES_PER_POINT * 19_999))
    with pytest.raises(BudgetExceededError, match="20000 points"):
        plan_scene(pts, db=db, rng=np.random.default_rng(0))
    f, out = tmp_path / "big.npy", tmp_path / "g.json"
    np.save(f, pts)
    code, _, err = _run(capsys, f, "-o", out, "--db", db.root)
    assert code == 2 and "GRASPSIM_MEMORY_BUDGET" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", str(SCENE_BYTES_PER_POINT * 20_000))  # just enough: planned
    assert plan_scene(pts, db=db, rng=np.random.default_rng(0)).segments == ()


@pytest.mark.parametrize("how, args, message", [
    ("mm", [], "--units mm"),
    ("ok", ["--crop", "0", "0", "0", "0", "1", "1"], "--crop"),
    ("ok", ["--crop", "0", "0", "nan", "1", "1", "1"], "--crop"),
    ("ok", ["--up", "0", "0", "0"], "--up"),
    ("ok", ["--viewpoint", "0", "inf", "0"], "--viewpoint"),
    ("ok", ["--labels", "labels.txt"], "--labels"),
    ("ok", ["--min-gap", "0.5"], "--min-gap"),
    ("ok", ["--budget", "8"], "--budget"),
    ("ok", ["--budget", "0:100"], "--budget"),
    ("missing", [], "does not exist"),
    ("blob", [], "no table plane"),
    ("ok", ["-o", "."], "directory"),
    ("ok", ["--screenshot", "."], "directory"),
    ("ok", ["--view", "--port", "70000"], "--port"),
    ("ok", ["--unseen-margin"], "needs the camera's place"),
    ("ok", ["--unseen-margin", "0.5", "--viewpoint", "0", "0", "1"], "--unseen-margin"),
    ("ok", ["--unseen-margin", "nan", "--viewpoint", "0", "0", "1"], "--unseen-margin"),
    ("ok", ["--unseen-margin", "-0.01", "--viewpoint", "0", "0", "1"], "--unseen-margin"),
    ("ok", ["--seen-between", "-1"], "--seen-between must be a whole number"),
    ("ok", ["--seen-between", "2.5"], "--seen-between must be a whole number"),
    ("ok", ["--seen-between", "many"], "--seen-between must be a whole number"),
    ("ok", ["--feature-grasps", "sometimes"], "--feature-grasps"),
    ("ok", ["--pose-error", "-0.001", "2"], "--pose-error: the pose error must be"),
    ("ok", ["--pose-error", "0.003", "nan"], "--pose-error: the pose error must be"),
    ("ok", ["--pose-error", "0.5", "2"], "--pose-error: the pose error must be"),
])
def test_bad_input_is_a_one_line_error_and_writes_nothing(how, args, message, tmp_path, capsys, db):
    rng = np.random.default_rng(1)
    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), rng.normal(0, 0.0005, 3000)]
    box = np.c_[rng.uniform(-0.03, 0.03, (800, 2)), rng.uniform(0, 0.06, 800)]
    pts = {"ok": np.r_[table, box], "mm": 1000 * np.r_[table, box],
           "blob": rng.normal(0, 0.05, (2000, 3))}.get(how)
    f = tmp_path / "cloud.npy"
    if pts is not None:
        np.save(f, pts)
    out = tmp_path / "grasps.json"
    out.write_text("earlier")
    argv = ["plan-scene", str(f), *(["-o", str(out)] if "-o" not in args else []), *args,
            "--db", str(db.root), *FAST_FLAGS]
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own errors
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 or err.startswith("usage")
    assert err.count("--unseen-margin") <= 1  # the flag named once, not prefixed again
    assert out.read_text() == "earlier" and not (tmp_path / "labels.txt").exists()


needs_viser = pytest.mark.skipif(__import__("importlib").util.find_spec("viser") is None,
                                 reason="viser is not installed (pip install -e '.[viewer]')")


@needs_viser
@pytest.mark.slow
def test_a_planned_scene_cloud_in_the_viewer(tmp_path, capsys, db, scene_cloud):
    """show_plan: the plan of a camera-frame cloud, up along the table's normal, seen
    from the camera's side; plan-scene --screenshot draws it (where Chromium is)."""
    from graspsim.viewer import show_plan, stop

    path, view, _ = scene_cloud
    plan = plan_scene(view.points, db=db, rng=np.random.default_rng(0),
                      config=SceneConfig(min_gap=0.01, up=(0.0, -0.6, -0.8)), viewpoint=np.zeros(3))
    server = show_plan(plan, view.points, eye=np.zeros(3), port=0)
    try:
        v = server.graspsim_viewer
        assert v.per is plan.perception and v.best is plan.best
        assert len(v.segments.points) == len(plan.perception.points)
        position, look_at = v.camera
        n = plan.perception.plane.normal
        assert (np.array(position) - look_at) @ n > 0  # looking down at the table from the camera's side
        assert {g.segment for g in v.drawn} == {g.segment for g in plan.grasps}
    finally:
        stop(server)
    from graspsim.viewer.snapshot import find_browser

    if find_browser() is None:
        return
    png, out = tmp_path / "scene.png", tmp_path / "g.json"
    code, s, _ = _run(capsys, path, "-o", out, "--min-gap", 0.01, "--db", db.root, *FAST_FLAGS, "--screenshot", png,
                      "--port", 0)
    assert code == 0 and s["screenshot"] == str(png) and png.stat().st_size > 10_000 and out.exists()


def test_pose_error_tells_the_planner_the_robots_accuracy():
    """``--pose-error M DEG`` sets the robust score's sigmas (the one path,
    ``with_pose_error``); without it the planner assumes the default 3 mm / 2 deg; a bad
    value names what is valid."""
    import math

    from graspsim.cli import build_parser
    from graspsim.cli.plan_scene_cmd import _pose_error
    from graspsim.errors import InvalidParameterError
    from graspsim.maps.robust import POSITION_SIGMA, ROTATION_SIGMA
    from graspsim.planning.scene_config import SceneConfig, with_pose_error

    head = ["plan-scene", "c.npy", "-o", "g.json"]
    args = build_parser().parse_args([*head, "--pose-error", "0.001", "0.5"])
    robust = _pose_error(args, SceneConfig()).planner.robust
    assert robust.position_sigma == 0.001 and math.isclose(robust.rotation_sigma, math.radians(0.5))
    plain = _pose_error(build_parser().parse_args(head), SceneConfig()).planner.robust
    assert (plain.position_sigma, plain.rotation_sigma) == (POSITION_SIGMA, ROTATION_SIGMA)
    assert with_pose_error(SceneConfig(), 0.0, 0.0).planner.robust.position_sigma == 0.0  # a perfect robot
    for bad in ((0.021, 2.0), (0.003, 10.5), (True, 2.0), (0.003, float("inf")), ("3mm", 2.0)):
        with pytest.raises(InvalidParameterError, match=r"position sigma in \[0, 0.02\] m and a rotation sigma"):
            with_pose_error(SceneConfig(), *bad)


def test_the_shadow_depth_flag_reaches_the_planner(tmp_path, capsys, db):
    """--shadow-depth M (SceneConfig.shadow_depth): scene and plan-scene read it alike,
    absent the scene planner's default; plan-scene records it when a viewpoint makes it
    apply (0 without one); a depth out of range is one line naming the flag, nothing written."""
    from graspsim.cli import _common, build_parser
    from graspsim.errors import InvalidParameterError

    for command in ("scene", "plan-scene"):
        head = [command] if command == "scene" else [command, "c.npy", "-o", "g.json"]
        for given, want in (([], SceneConfig().shadow_depth), (["--shadow-depth", "0.03"], 0.03),
                            (["--shadow-depth", "0"], 0.0)):
            args = build_parser().parse_args([*head, *given])
            assert _common.scene_planning_from_args(args, SceneConfig()).shadow_depth == want, (command, given)
        for bad in ("-0.01", "0.5", "nan"):
            args = build_parser().parse_args([*head, "--shadow-depth", bad])
            with pytest.raises(InvalidParameterError, match="--shadow-depth must be in"):
                _common.scene_planning_from_args(args, SceneConfig())
    rng = np.random.default_rng(1)
    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), rng.normal(0, 0.0005, 3000)]
    box = np.c_[rng.uniform(-0.03, 0.03, (800, 2)), rng.uniform(0, 0.06, 800)]
    f, out = tmp_path / "cloud.npy", tmp_path / "grasps.json"
    np.save(f, np.r_[table, box])
    code, _, _ = _run(capsys, f, "-o", out, "--viewpoint", 0, -0.4, 0.5, "--shadow-depth", 0.03, "--db", db.root,
                      *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())["shadow_depth"] == 0.03
    code, _, _ = _run(capsys, f, "-o", out, "--shadow-depth", 0.03, "--db", db.root, *FAST_FLAGS)
    assert code == 0 and json.loads(out.read_text())["shadow_depth"] == 0.0  # no viewpoint: no shadows
    code, _, err = _run(capsys, f, "-o", tmp_path / "other.json", "--shadow-depth", 0.5, "--db", db.root, *FAST_FLAGS)
    assert code == 2 and "--shadow-depth" in err and not (tmp_path / "other.json").exists()
