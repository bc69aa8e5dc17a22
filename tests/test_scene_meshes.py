"""Scenes of mesh objects: a user's folder with a manifest, the shipped household set and
its held-out split, masses, frames, and saved scenes that reload with their meshes."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.tabletop.mesh_objects import SHIPPED, default_mass, file_sha256, heldout_split, read_folder, shipped_set
from graspsim.tabletop.scene_objects import draw_object, prepare_objects
from graspsim.tabletop.table_scene import load_scene, make_scene, save_scene

BOX_OFFSET = np.array([0.2, 0.1, 0.3])  # the box file's frame is far from the box


def _folder(tmp_path, manifest=None):
    """Three convex meshes (no convex decomposition: fast), one of each file type."""
    import trimesh

    d = tmp_path / "objs"
    d.mkdir()
    box = trimesh.creation.box([0.05, 0.04, 0.08])
    box.apply_translation(BOX_OFFSET)
    box.export(d / "box.stl")
    trimesh.creation.cylinder(0.025, 0.09, sections=32).export(d / "can.obj")
    trimesh.creation.icosphere(2, 0.03).export(d / "ball.ply")
    (d / "notes.txt").write_text("not a mesh")
    if manifest is not None:
        (d / "objects.json").write_text(json.dumps(manifest))
    return d


def test_a_scene_from_a_folder_of_three_meshes(tmp_path):
    d = _folder(tmp_path)
    assert sorted(e.name for e in read_folder(d).entries) == ["ball", "box", "can"]
    scene = make_scene(4, "pile", 3, object_set=str(d))
    assert len(scene.objects) == 4 and {o.name for o in scene.objects} <= {"ball", "box", "can"}
    assert all(o.spec.source == "mesh" and o.spec.sha256 == file_sha256(o.spec.file) for o in scene.objects)
    assert all(abs(o.pos[0]) < 0.35 and abs(o.pos[1]) < 0.35 for o in scene.objects)  # on the table
    again = make_scene(4, "pile", 3, object_set=str(d))  # deterministic
    assert [o.pos for o in again.objects] == [o.pos for o in scene.objects]


def test_the_mesh_frame_is_its_centre_of_mass_and_the_file_frame_is_kept(tmp_path):
    d = _folder(tmp_path)
    entry = next(e for e in read_folder(d).entries if e.name == "box")
    from graspsim.tabletop.scene_objects import mesh_spec

    spec = mesh_spec(entry)
    obj = spec.sim_object()
    assert np.allclose(obj.surface.vertices.mean(0), 0, atol=1e-9)  # origin at the box's centre, not the file's
    assert np.allclose(spec.T_obj_file[:3, 3], -BOX_OFFSET)
    scene = make_scene(3, "packed", 2, object_set=str(d))
    for o in scene.objects:  # file vertices placed by the file pose land where the body's surface is
        import trimesh

        raw = trimesh.load(o.spec.file, force="mesh")
        world_file = raw.vertices @ o.T_world_file[:3, :3].T + o.T_world_file[:3, 3]
        world_obj = o.spec.sim_object().surface.vertices @ o.T_world_obj[:3, :3].T + o.T_world_obj[:3, 3]
        assert np.allclose(np.sort(world_file, 0), np.sort(world_obj, 0), atol=1e-6)


def test_a_manifests_mass_and_friction_are_the_simulated_bodys(tmp_path):
    d = _folder(tmp_path, {"defaults": {"density": 300}, "objects": {"box.stl": {"mass": 0.25, "friction": 0.7}}})
    scene = make_scene(6, "packed", 1, object_set=str(d))
    sim = scene.sim()
    names = [o.name for o in scene.objects]
    assert "box" in names and len(set(names)) > 1
    for k, o in enumerate(scene.objects):
        mass = sim.model.body_mass[sim.body[k]]
        geoms = np.flatnonzero(sim.geom_object == k)
        if o.name == "box":
            assert mass == pytest.approx(0.25)
            assert np.allclose(sim.model.geom_friction[geoms, 0], 0.7)
            assert np.all(sim.model.geom_priority[geoms] == 1)
        else:  # the default density of the manifest: 300 kg/m^3 of the enclosed volume
            vol = o.spec.sim_object().surface.volume
            assert mass == pytest.approx(300 * vol, rel=0.02)
    sim.close()


def test_default_mass_fills_closed_solids_and_weighs_shells_by_area():
    import trimesh

    box = trimesh.creation.box([0.1, 0.03, 0.15])  # a cereal box: filled
    m, model = default_mass(box)
    assert model == "filled" and m == pytest.approx(400 * 0.1 * 0.03 * 0.15)
    cup = trimesh.creation.annulus(0.04, 0.042, 0.1)  # a thin-walled cup, closed: a shell
    m, model = default_mass(cup)
    assert model == "shell" and 0.03 < m < 0.2 and m == pytest.approx(2.0 * cup.area / 2)


def test_a_saved_scene_of_user_meshes_reloads_and_refuses_a_changed_mesh(tmp_path):
    d = _folder(tmp_path, {"objects": {"ball.ply": {"mass": 0.05}}})
    scene = make_scene(3, "pile", 5, object_set=str(d))
    path = tmp_path / "scene.json"
    save_scene(scene, path)
    text = json.loads(path.read_text())
    assert all("sha256" in o["object"] and "file_pose" in o for o in text["objects"])
    back = load_scene(path)
    assert [o.spec for o in back.objects] == [o.spec for o in scene.objects]
    assert [o.pos for o in back.objects] == [o.pos for o in scene.objects]
    assert [o.quat for o in back.objects] == [o.quat for o in scene.objects]
    a, b = scene.sim(), back.sim()
    assert np.array_equal(a.model.body_mass, b.model.body_mass) and np.array_equal(a.data.qpos, b.data.qpos)
    a.close(), b.close()
    victim = next(o.spec.file for o in scene.objects)
    import trimesh

    trimesh.creation.box([0.03, 0.03, 0.03]).export(victim)  # the user edits the mesh
    from graspsim.tabletop import scene_objects

    scene_objects._sim_object.cache_clear()
    with pytest.raises(InvalidParameterError, match="changed since the scene was written"):
        load_scene(path).sim()


@pytest.mark.parametrize("manifest, message", [
    ({"objects": {"cup.stl": {"mass": 1}}}, "not in the folder"),
    ({"objects": {"box.stl": {"weight": 1}}}, "unknown settings"),
    ({"objects": {"box.stl": {"mass": -1}}}, "mass must be a number > 0"),
    ({"objects": {"box.stl": {"mass": 1, "density": 3}}}, "mass or density"),
    ({"things": {}}, "expected the tables"),
])
def test_a_bad_manifest_is_one_clear_error(tmp_path, manifest, message):
    d = _folder(tmp_path, manifest)
    with pytest.raises(InvalidParameterError, match=message):
        read_folder(d)


def test_a_folder_without_fitting_meshes_is_refused_naming_the_units(tmp_path):
    import trimesh

    d = tmp_path / "mm"
    d.mkdir()
    trimesh.creation.box([50.0, 40.0, 80.0]).export(d / "box_mm.stl")  # millimetres read as metres
    with pytest.raises(InvalidParameterError, match="scale"):
        draw_object(np.random.default_rng(0), str(d))
    (d / "objects.json").write_text(json.dumps({"defaults": {"scale": 0.001}}))  # the fix the message names
    assert prepare_objects(str(d)) == ["box_mm"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(InvalidParameterError, match="no mesh file"):
        read_folder(tmp_path / "empty")


def test_a_folder_of_unusable_meshes_is_refused_naming_each_file_and_its_fault(tmp_path):
    """Each mesh left out is named with its own fault (unreadable, flat, too wide, in
    millimetres), and the scale hint names the folder's manifest, not another command's flag."""
    import trimesh

    d = tmp_path / "bad"
    d.mkdir()
    (d / "notes.stl").write_text("not a mesh")
    trimesh.Trimesh([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0]], [[0, 1, 2]]).export(d / "sheet.stl")
    trimesh.creation.box([0.3, 0.3, 0.3]).export(d / "crate.stl")
    with pytest.raises(InvalidParameterError) as err:
        draw_object(np.random.default_rng(0), str(d))
    text = str(err.value)
    assert "notes.stl holds no triangles" in text and "sheet.stl is flat" in text
    assert re.search(r"crate\.stl is \d+ mm across at its narrowest, wider than the gripper", text)
    assert "scale" not in text  # no unit problem here: no hint about units
    trimesh.creation.box([50.0, 40.0, 80.0]).export(d / "mm.stl")
    with pytest.raises(InvalidParameterError, match="the manifest's scale 0.001") as err:
        draw_object(np.random.default_rng(0), str(d))
    assert "--mesh-scale" not in str(err.value)
    (d / "objects.json").write_text(json.dumps({"objects": {"mm.stl": {"scale": 0.001, "friction": 0}}}))
    with pytest.raises(InvalidParameterError, match=r"objects\.json, mm\.stl: friction must be a number > 0"):
        read_folder(d)


def test_the_shipped_split_is_the_documented_rule():
    for name in SHIPPED:
        whole = shipped_set(name).entries
        tuning, held = heldout_split(whole)
        assert len(held) == len(whole) // 3
        assert {e.name for e in shipped_set(f"{name}-heldout").entries} == {e.name for e in held}
        assert {e.name for e in shipped_set(f"{name}-tuning").entries} == {e.name for e in tuning}
    held = {e.name for e in shipped_set("household-heldout").entries}
    assert held == {"bread", "can", "cereal", "teddy"}  # as the assets README's table says


def test_the_failure_table_counts_each_object_by_name():
    from graspsim.tabletop.clutter import Attempt, ClutterResult, failure_rows, per_object, per_source, summarize

    def a(target, ok, cause, source=None):
        return Attempt(target, {}, ok, cause, 1.0, 0.1, {}, 2, 2, 2, source=source)

    r1 = ClutterResult(3, (a(0, True, "success"), a(1, False, "start_collision_target"), a(1, False, "slipped")),
                       1, "failures", 3, 2, 1.0, ("mug", "can", "lemon"), {1: "no_grasp", 2: "merged"})
    r2 = ClutterResult(2, (a(0, True, "success"), a(1, True, "success")), 2, "cleared", 2, 2, 1.0, ("can", "mug"))
    t = per_object([r1, r2])
    assert list(t) == ["can", "lemon", "mug"]  # most left first
    assert t["can"] == {"placed": 2, "removed": 1, "grasps": 3, "lifted": 1,
                        "failed": {"slipped": 1, "start_collision_target": 1}, "left": {"no_grasp": 1}}
    assert t["lemon"]["left"] == {"merged": 1} and t["lemon"]["grasps"] == 0
    assert t["mug"]["placed"] == t["mug"]["removed"] == t["mug"]["lifted"] == 2
    assert summarize([r1, r2])["per_object"] == t
    assert failure_rows(t)[0] == ("can", 2, 1, 3, 1, "slipped 1, start_collision_target 1", "no_grasp 1")
    assert per_source([r1, r2]) == {} and summarize([r1, r2])["per_source"] == {}  # sources not known
    r3 = ClutterResult(2, (a(0, True, "success", "box"), a(1, False, "no_contact", "features"),
                           a(1, True, "success", "features"), a(0, False, "dropped", "cylinder"),
                           a(1, True, "success")), 2, "cleared", 2, 2, 1.0, ("can", "mug"))
    assert per_source([r3]) == {"features": {"grasps": 2, "lifted": 1, "failed": {"no_contact": 1}},
                                "box": {"grasps": 1, "lifted": 1, "failed": {}},
                                "cylinder": {"grasps": 1, "lifted": 0, "failed": {"dropped": 1}}}
    assert list(per_source([r3])) == ["features", "box", "cylinder"]  # most grasps first, then by name
    from graspsim.cli.scene_cmd import _sources_line

    assert _sources_line(per_source([r3])).strip() == "grasps by source (lifted/grasps): features 1/2, box 1/1, " \
                                                      "cylinder 0/1"
    assert _sources_line({}) == ""


def test_the_clutter_env_takes_a_folder_or_a_named_mesh_set(tmp_path):
    from graspsim.envs.clutter_config import ClutterEnvConfig

    d = _folder(tmp_path)
    assert ClutterEnvConfig(object_set=str(d)).object_set == str(d)
    assert ClutterEnvConfig(object_set="household-heldout").object_set == "household-heldout"
    with pytest.raises(InvalidParameterError, match="object_set"):
        ClutterEnvConfig(object_set=str(tmp_path / "nowhere"))


def test_the_benchmark_draws_from_the_household_set_wherever_no_set_is_named(monkeypatch):
    """graspsim scene, run_benchmark / benchmark_episode, ClutterClear-v0 and E15 draw from one
    default set, the shipped household meshes (BENCHMARK_SET): a user's Python call meets the
    scenes the command reports on."""
    import inspect
    from types import SimpleNamespace

    import graspsim.tabletop.table_scene as table_scene
    from graspsim.envs.clutter_config import ClutterEnvConfig
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.tabletop import clutter
    from graspsim.tabletop.mesh_objects import BENCHMARK_SET, SHIPPED

    assert BENCHMARK_SET == "household" and BENCHMARK_SET in SHIPPED
    for f in (clutter.run_benchmark, clutter.benchmark_episode):
        assert inspect.signature(f).parameters["object_set"].default == BENCHMARK_SET
    assert ClutterEnvConfig().object_set == BENCHMARK_SET
    drawn = {}
    scene = SimpleNamespace(kind="packed", objects=(), sim=lambda **kw: SimpleNamespace(
        objects_left=lambda: [], outside=lambda: [], close=lambda: None))
    monkeypatch.setattr(table_scene, "make_scene", lambda *a, **kw: drawn.update(kw) or scene)
    clutter.run_benchmark(1, "packed", 1, 0, db=SimpleNamespace(gripper=HGPL_25_60_A))
    assert drawn["object_set"] == BENCHMARK_SET
