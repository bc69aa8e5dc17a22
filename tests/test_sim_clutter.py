"""Clutter removal: the protocol on small simulated scenes (deterministic, counts that
add up, segmentation against the render's labels) and the ``graspsim scene`` CLI."""

import json
import math

import numpy as np
import pytest

from graspsim.cli import main
from graspsim.errors import InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Cylinder, Sphere
from graspsim.tabletop.clutter import (
    STOPS,
    ClutterConfig,
    ClutterEpisode,
    one_cluster_objects,
    run_benchmark,
    run_clutter,
    scene_settings,
    summarize,
)
from graspsim.tabletop.table_scene import PACKED_GAP, known_gap, load_scene, make_scene

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))
FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.2), Sphere(0.035)])
    return d


def test_one_cluster_objects_counts_merges_and_splits():
    truth = np.array([0] * 50 + [1] * 50 + [2] * 50 + [3] * 10)
    found = np.array([0] * 50 + [1] * 25 + [2] * 25 + [3] * 50 + [-1] * 10)
    assert one_cluster_objects(truth, found, min_seen=40) == (3, 2)  # 0, 2 fine; 1 split; 3 too small
    merged = np.array([0] * 100 + [1] * 50 + [-1] * 10)
    assert one_cluster_objects(truth, merged, min_seen=40) == (3, 1)  # 0 and 1 share a segment
    noisy = found.copy()
    noisy[[0, 1]] = -1  # unsegmented points do not count against the object
    assert one_cluster_objects(truth, noisy, min_seen=40) == (3, 2)


def test_scene_settings_know_the_gap_of_packed_scenes_only():
    assert known_gap("packed") == PACKED_GAP == 0.01 and known_gap("pile") is None
    assert scene_settings("packed").min_gap == PACKED_GAP and scene_settings("pile").min_gap is None
    assert scene_settings("packed", neighbours=False).neighbours is False
    assert scene_settings("packed", min_gap=0.02).min_gap == 0.02  # the user's word wins
    with pytest.raises(InvalidParameterError, match="heap"):
        known_gap("heap")
    for kind, gap in (("packed", PACKED_GAP), ("pile", None)):  # an episode's default settings: its kind's
        ep = ClutterEpisode(make_scene(2, kind, 0, object_set="primitives"), db=None, rng=np.random.default_rng(0))
        assert ep.config.scene.min_gap == gap
        ep.close()


def test_clutter_episode_is_deterministic_and_its_counts_add_up(db):
    scene = make_scene(2, "packed", seed=4, object_set="primitives")
    run_clutter(scene, db=db, rng=np.random.default_rng(1))  # maps of new sizes built on first use
    a = run_clutter(scene, db=db, rng=np.random.default_rng(1))
    b = run_clutter(scene, db=db, rng=np.random.default_rng(1))
    strip = lambda r: [{k: v for k, v in s.items() if k not in ("planning", "timing")}  # noqa: E731
                       for s in r.to_dict()["steps"]]
    assert strip(a) == strip(b) and a.stop == b.stop and a.removed == b.removed
    assert a.stop in STOPS and a.placed == 2
    assert a.removed == a.successes + a.other_objects and a.successes <= len(a.attempts) <= 2 * 2 + 2
    assert a.declutter_rate == a.removed / 2
    assert a.first_seen == 2 and a.first_one_cluster == 2  # packed, >= 1 cm apart
    assert a.stop != "cleared" or a.removed == 2
    for s in a.attempts:
        assert s.planning > 0 and s.timing["total"] <= s.planning + 1e-6 and s.success == (s.cause == "success")


def test_benchmark_pairs_scenes_across_conditions_and_summarises(db):
    seen = {}

    def scene_of(label):
        return lambda i, scene, r: seen.setdefault(label, []).append(scene.to_dict())

    runs = {}
    for label, cfg in (("full", ClutterConfig(max_attempts=1)),
                       ("truth", ClutterConfig(max_attempts=1, ground_truth=True))):
        runs[label] = run_benchmark(2, "packed", 1, 3, db=db, config=cfg, object_set="primitives", first=1,
                                    on_scene=scene_of(label))
    assert seen["full"] == seen["truth"]  # the same scene for both conditions
    s = summarize(runs["full"] + runs["truth"])
    assert s["scenes"] == 2 and s["attempts"] == sum(len(r.attempts) for v in runs.values() for r in v) <= 2
    assert s["successes"] + sum(s["failure_causes"].values()) == s["attempts"]
    assert s["placed"] == 4 and s["cleared_rate"] == s["removed"] / 4
    assert sum(s["stops"].values()) == 2
    with pytest.raises(InvalidParameterError):
        ClutterConfig(max_failures=0)


@pytest.mark.slow
def test_cli_scene_json_and_renders(tmp_path, capsys, db):
    code = main(["scene", "--objects", "2", "--kind", "packed", "--object-set", "primitives", "--seed", "1",
                 "--max-attempts", "2", "--db", str(db.root), *FAST_FLAGS, "--render", str(tmp_path / "r"),
                 "--save-scenes", str(tmp_path / "s"), "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["scenes"] == 1 and s["placed"] == 2
    assert s["min_gap"] == PACKED_GAP  # a packed scene's objects stand apart: segmentation relies on it
    assert s["budget"] == "32:200"  # SceneConfig's planning budget (no --budget)
    assert s["felt_evidence"] is True  # ClutterConfig.feel, unless --no-feel
    assert s["contacts"] == "stiff"  # the simulation's contact model, unless --contacts
    assert s["grasp_success_rate"] == s["successes"] / s["attempts"] and s["cleared_rate"] == s["removed"] / 2
    assert len(s["details"]) == 1 and s["details"][0]["attempts"] == s["attempts"]
    assert s["feature_grasps"] == "fallback"  # where objects stand apart or nothing else gives one (--feature-grasps)
    steps = s["details"][0]["steps"]
    assert sum(r["grasps"] for r in s["per_source"].values()) == s["attempts"] == len(steps)
    assert {st["source"] for st in steps} == set(s["per_source"]) <= {"box", "cylinder", "sphere", "cone",
                                                                      "half_toroid", "features"}
    assert len(list((tmp_path / "r").glob("scene000_step*.png"))) == s["attempts"]
    assert [o.name for o in load_scene(tmp_path / "s" / "scene000.json").objects] == s["details"][0]["objects"]


@pytest.mark.slow
def test_cli_scene_saves_every_seed_apart(tmp_path, capsys, db, monkeypatch):
    """--seeds 2 --save-scenes: one file per seed and scene (the second seed's scene 0 once
    overwrote the first's), each reloading as the scene its seed drew; --contacts soft reaches
    the clutter runs' ClutterConfig.sim."""
    import graspsim.tabletop.clutter as clutter
    from graspsim.sim import contact_model

    run, sims = clutter.run_benchmark, []
    monkeypatch.setattr(clutter, "run_benchmark", lambda *a, **kw: sims.append(kw["config"].sim) or run(*a, **kw))
    code = main(["scene", "--objects", "1", "--kind", "packed", "--object-set", "primitives", "--seeds", "2",
                 "--max-attempts", "1", "--db", str(db.root), *FAST_FLAGS, "--save-scenes", str(tmp_path / "s"),
                 "--no-feel", "--contacts", "soft", "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and len(s["details"]) == 2 and s["felt_evidence"] is False and s["contacts"] == "soft"
    assert sims == [contact_model("soft")] * 2  # one run per seed, each with the soft settings
    files = sorted(p.name for p in (tmp_path / "s").iterdir())
    assert files == ["seed0_scene000.json", "seed1_scene000.json"]
    seeds = [load_scene(tmp_path / "s" / f).seed for f in files]
    assert seeds == [d["seed"] for d in s["details"]] and seeds[0] != seeds[1]


@pytest.mark.slow
def test_cli_scene_of_a_folder_of_meshes(tmp_path, capsys, db):
    """`--objects-dir`: a user's meshes, their masses from the manifest, poses in each file's
    frame, the failure table per object by name."""
    import trimesh

    d = tmp_path / "mine"
    d.mkdir()
    box = trimesh.creation.box([0.05, 0.04, 0.07])
    box.apply_translation([0.3, 0.0, 0.0])  # a file origin 30 cm from the object
    box.export(d / "carton.stl")
    trimesh.creation.cylinder(0.025, 0.09, sections=32).export(d / "tin.obj")
    (d / "objects.json").write_text(json.dumps({"objects": {"carton.stl": {"mass": 0.2}}}))
    code = main(["scene", "--objects-dir", str(d), "--objects", "2", "--kind", "packed", "--seed", "1",
                 "--max-attempts", "1", "--db", str(db.root), *FAST_FLAGS, "--save-scenes", str(tmp_path / "s"),
                 "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["object_set"] == str(d.resolve()) and sorted(s["meshes"]) == ["carton", "tin"]
    names = s["details"][0]["objects"]
    assert set(s["per_object"]) == set(names) <= {"carton", "tin"}
    assert sum(r["placed"] for r in s["per_object"].values()) == 2
    scene = load_scene(tmp_path / "s" / "scene000.json")
    for o, pose in zip(scene.objects, s["details"][0]["poses"]):
        assert pose["frame"] == "file" and np.allclose(pose["pos"], o.T_world_file[:3, 3])
        if o.name == "carton":
            assert o.spec.mass == 0.2 and abs(np.linalg.norm(np.subtract(pose["pos"], o.pos)) - 0.3) < 1e-6


@pytest.mark.slow
def test_cli_scene_honours_gripper(tmp_path, capsys):
    from graspsim.grippers import get_gripper

    franka = get_gripper("franka_hand")
    code = main(["scene", "--objects", "1", "--kind", "packed", "--object-set", "primitives", "--seed", "2",
                 "--max-attempts", "1", "--db", str(tmp_path / "db"), *FAST_FLAGS, "--gripper", "franka_hand",
                 "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["gripper"] == "franka_hand" and s["placed"] == 1 and s["attempts"] >= 1
    # the maps it planned with are the Franka hand's (the database keys maps by the gripper's spec)
    mine = MapDatabase(tmp_path / "db", gripper=franka, config=FAST)
    maps = mine.entries()
    assert maps and all(mine.load_entry(e).meta.gripper_spec == franka for e in maps)
    assert not MapDatabase(tmp_path / "db", config=FAST).entries()  # none of the default Festo


@pytest.mark.parametrize("args, message", [
    (["--objects", "0"], "--objects"),
    (["--objects", "31"], "at most 30"),
    (["--object-set", "toys"], "unknown"),
    (["--kind", "heap"], "invalid choice"),
    (["--scenes", "x"], "--scenes"),
    (["--min-gap", "0.5"], "--min-gap"),
    (["--min-gap", "-0.01"], "--min-gap"),
    (["--min-gap", "nan"], "--min-gap"),
    (["--min-gap", "1cm"], "--min-gap"),
    (["--budget", "8:"], "--budget"),
    (["--budget", "8:0"], "--budget"),
    (["--objects-dir", "no/such/folder"], "--objects-dir"),
    (["--scenes", "100", "--seeds", "100"], "--scenes x --seeds is 10000 scenes"),
    (["--objects-dir", ".", "--object-set", "primitives"], "not both"),
])
def test_cli_scene_bad_arguments_are_one_line_errors(args, message, capsys, tmp_path):
    try:
        code = main(["scene", *args, "--db", str(tmp_path / "db")])
    except SystemExit as e:  # argparse's own errors
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err


def test_cli_scene_render_into_a_file_fails_before_the_work(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["scene", "--render", str(f), "--db", str(tmp_path / "db")]) == 2
    assert "not a folder" in capsys.readouterr().err and not (tmp_path / "db").exists()


def test_an_attempt_records_the_seen_points_it_closed_on(db):
    """Attempt.between: the points of the grasp's segment (the frame it was planned from)
    between the pads at the pose and opening executed; the scene planner's grasps close on
    at least PlannerConfig.seen_between of them. Attempt.source: what the grasp was planned
    from, one of its segment's parts or its features."""
    from graspsim.planning.observed import SEEN_BETWEEN

    ep = ClutterEpisode(make_scene(3, "packed", 2, object_set="primitives"), db=db, rng=np.random.default_rng(1))
    try:
        assert ep.config.scene.planner.seen_between == SEEN_BETWEEN > 0
        while ep.stop is None and (look := ep.observe()) is not None:
            g = look.best
            a = ep.execute(look, g)
            own = look.plan.perception.segment_points(g.segment)
            want = db.gripper.points_between(np.asarray(g.T_world_wrist)[None], np.array([g.opening]), own)[0]
            assert isinstance(a.between, int) and a.between == want >= SEEN_BETWEEN
            assert a.to_dict()["between"] == a.between
            frame = db.gripper.points_between(np.asarray(g.T_world_wrist)[None], np.array([g.opening]),
                                                  look.plan.perception.points)[0]
            assert a.between <= frame  # the segment's share of what the frame has there
            prims = {p for sp in look.plan.segments if sp.segment == g.segment for p in sp.primitives}
            assert a.source == g.source and a.to_dict()["source"] == g.source
            assert g.source in prims | {"features"}  # a part of its segment, or the segment's own features
        assert ep.attempts
    finally:
        ep.close()
