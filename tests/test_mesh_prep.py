"""Meshes as users have them (issue 33): prepare_mesh bounded in time, cached by content,
open meshes, NaN vertices, units, huge meshes -- and `graspsim trial --mesh` on them."""

import json
import logging
import os
import time

import numpy as np
import pytest
import trimesh

from graspsim.cli import main
from graspsim.errors import MeshError
from graspsim.sim import CoacdParams, prepare_mesh
from graspsim.sim._coacd_worker import decimate
from graspsim.sim.meshes import check_mesh_arrays


def _open_cylinder(radius=0.03, height=0.1, sections=64) -> trimesh.Trimesh:
    """A tube: a cylinder without its caps (not watertight, no volume of its own)."""
    c = trimesh.creation.cylinder(radius, height, sections=sections)
    normal_z = np.abs(c.face_normals[:, 2])
    return trimesh.Trimesh(c.vertices, c.faces[normal_z < 0.5], process=True)


def test_an_open_mesh_past_its_time_bound_gets_the_hull_model_with_a_warning(tmp_path, caplog):
    """The decomposition's worker is killed at the bound (0.2 s of its CPU time: it cannot
    even import CoACD in that), and the model
    falls back to the tube's hull: one line of warning, a model with a volume, mass
    properties from the parts (the tube itself encloses nothing)."""
    tube = _open_cylinder()
    assert not tube.is_watertight
    seen = []
    with caplog.at_level(logging.WARNING, logger="graspsim.sim.meshes"):
        prepared = prepare_mesh(tube, params=CoacdParams(time_limit=0.2), cache_dir=tmp_path,
                                progress=lambda stage, f: seen.append((stage, f)))
    assert all(stage == "decomposing" and 0.0 <= f <= 1.0 for stage, f in seen)
    assert prepared.method == "hull" and prepared.mass_from == "parts"
    assert "limit of 0.2 s of CPU time" in prepared.warning and "\n" not in prepared.warning
    assert [r for r in caplog.records if r.levelno == logging.WARNING and "convex hull" in r.getMessage()]
    assert len(prepared.parts) == 1
    hull = trimesh.convex.convex_hull(prepared.parts[0])
    assert hull.volume == pytest.approx(np.pi * 0.03**2 * 0.1, rel=0.01)  # the 64-gon's area
    assert prepared.volume == pytest.approx(hull.volume)
    np.testing.assert_allclose(prepared.com, 0.0, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(prepared.unit_inertia) > 0)


def test_closed_parts_are_decomposed_without_remeshing_and_open_ones_with_the_time_left(tmp_path, monkeypatch):
    """A mesh of a closed non-convex body (an annulus), an open tube and a stray triangle:
    the annulus goes to CoACD as closed (its manifold remeshing skipped: the duck's
    decomposition took 46 s of CPU with it and 7.6 s without, and came out thicker), the
    tube as open with what the first call left of the limit, the triangle nowhere (it spans
    no volume). A closed mesh stays closed when cleaning drops its zero-area slivers.
    Mutations: sending every component as open, or giving the second call the whole limit,
    fail the recorded calls."""
    from graspsim.sim import meshes

    calls = []

    def record(mesh, params, progress, *, closed, limit):
        calls.append((len(mesh.faces), closed, limit))
        return [np.asarray(mesh.convex_hull.vertices, float)], None, False, 1.5

    monkeypatch.setattr(meshes, "_decompose", record)
    ring = trimesh.creation.annulus(0.02, 0.04, 0.02, sections=24)
    tube = _open_cylinder(sections=16)
    tube.apply_translation([0.2, 0, 0])
    stray = trimesh.Trimesh([[0.4, 0, 0], [0.41, 0, 0], [0.4, 0.01, 0]], [[0, 1, 2]])
    prepared = prepare_mesh(trimesh.util.concatenate([ring, tube, stray]), params=CoacdParams(time_limit=10.0),
                            cache_dir=tmp_path)
    assert prepared.method == "coacd" and prepared.warning is None
    assert calls == [(len(ring.faces), True, 10.0), (len(tube.faces), False, 8.5)]
    # a sliver (a zero-area triangle on a split edge) keeps a closed mesh closed
    v, f = _box_with_a_sliver()
    assert trimesh.Trimesh(v, f, process=True).is_watertight
    cleaned = meshes._clean(v, f, 1.0, "box")
    assert len(cleaned.faces) == len(f) - 1 and not cleaned.is_watertight
    assert cleaned.metadata["closed"]
    # the worker's own test (after decimation, without trimesh): a closed torus decimated stays
    # closed; a cylinder less one face, or two copies of a face, is not
    from graspsim.sim._coacd_worker import closed_surface

    torus = trimesh.creation.torus(0.04, 0.012, major_sections=64, minor_sections=64)
    assert closed_surface(decimate(np.asarray(torus.vertices), np.asarray(torus.faces), 2000)[1])
    cylinder = np.asarray(trimesh.creation.cylinder(0.03, 0.1).faces)
    assert closed_surface(cylinder) and not closed_surface(cylinder[1:])
    assert not closed_surface(np.vstack([cylinder, cylinder[:1]]))


def _box_with_a_sliver():
    """A closed box whose face (a, b, c) is split at the midpoint m of edge ab, and the gap
    this opens against the face across ab closed by the zero-area triangle (a, m, b) -- as
    exporters leave them."""
    box = trimesh.creation.box([0.03, 0.03, 0.03])
    faces = np.asarray(box.faces)
    a, b, c = faces[0]
    m = len(box.vertices)
    v = np.vstack([box.vertices, (box.vertices[a] + box.vertices[b]) / 2])
    for sliver in ([a, b, m], [b, a, m]):
        f = np.vstack([faces[1:], [[a, m, c], [m, b, c], sliver]])
        if trimesh.Trimesh(v, f, process=False).is_watertight:
            return v, f
    raise AssertionError("no orientation closes the box")


def test_the_limit_counts_the_workers_cpu_time_and_a_starved_worker_is_not_cached(tmp_path, monkeypatch):
    """The limit is the worker's CPU time (the same model on an idle and a loaded
    machine); a worker the machine's load starves past the wall-clock backstop falls back
    to hulls with a warning saying so, and that model is not cached (a later run on a
    quieter machine decomposes it). Mutation: caching every fallback fails the last line."""
    from graspsim.sim import meshes

    cpu = meshes._cpu_seconds(os.getpid())
    if cpu is None:
        pytest.skip("no /proc: the limit is wall-clock time here")
    assert 0.0 < cpu <= time.process_time() + 0.05
    monkeypatch.setattr(meshes, "_cpu_seconds", lambda pid: 0.0)  # a worker that never runs
    monkeypatch.setattr(meshes, "WALL_FACTOR", 0.0)
    monkeypatch.setattr(meshes, "WALL_SLACK", 0.3)
    prepared = prepare_mesh(_open_cylinder(), params=CoacdParams(time_limit=5.0), cache_dir=tmp_path)
    assert prepared.method == "hull" and "starved of CPU" in prepared.warning
    assert not list(tmp_path.rglob("*.npz"))


def test_a_cache_hit_gives_the_identical_model(tmp_path):
    """Two convex bodies side by side (each its own hull) and an open tube: prepared once,
    then read from the cache: the same parts, mass properties and surface, to the bit."""
    a = trimesh.creation.box([0.04, 0.04, 0.04])
    b = trimesh.creation.icosphere(radius=0.02)
    b.apply_translation([0.05, 0.0, 0.0])
    for mesh, params in ((trimesh.util.concatenate([a, b]), CoacdParams()),
                         (_open_cylinder(), CoacdParams(time_limit=0.2))):
        first = prepare_mesh(mesh, params=params, cache_dir=tmp_path)
        again = prepare_mesh(mesh, params=params, cache_dir=tmp_path)
        assert not first.from_cache and again.from_cache and again.key == first.key
        assert again.method == first.method and again.warning == first.warning
        assert len(again.parts) == len(first.parts)
        assert all(np.array_equal(p, q) for p, q in zip(first.parts, again.parts))
        assert again.volume == first.volume and again.mass_from == first.mass_from
        assert np.array_equal(again.com, first.com) and np.array_equal(again.unit_inertia, first.unit_inertia)
        assert np.array_equal(again.surface.vertices, first.surface.vertices)
        assert np.array_equal(again.surface.faces, first.surface.faces)
    assert first.method == "hull"
    two = prepare_mesh(trimesh.util.concatenate([a, b]), cache_dir=tmp_path)
    assert two.method == "components" and len(two.parts) == 2 and two.mass_from == "mesh"
    # another scale is another model, not the cached one
    assert prepare_mesh(trimesh.util.concatenate([a, b]), scale=2.0, cache_dir=tmp_path).key != two.key


def test_units_are_checked_as_clouds_are(tmp_path):
    box_mm = trimesh.creation.box([40.0, 50.0, 60.0])  # a 6 cm box written in millimetres
    with pytest.raises(MeshError, match=r"60 m across.*millimetres \(0\.06 m with --mesh-scale 0\.001\)"):
        prepare_mesh(box_mm, cache_dir=tmp_path)
    ok = prepare_mesh(box_mm, scale=0.001, cache_dir=tmp_path)
    assert ok.volume == pytest.approx(0.04 * 0.05 * 0.06)
    with pytest.raises(MeshError, match=r"only 3 mm across.*--mesh-scale"):
        prepare_mesh(trimesh.creation.box([0.003, 0.002, 0.001]), cache_dir=tmp_path)
    with pytest.raises(MeshError, match="scale must be a finite number > 0"):
        prepare_mesh(box_mm, scale=float("nan"), cache_dir=tmp_path)


def test_broken_arrays_are_refused_in_one_line():
    box = trimesh.creation.box([0.04, 0.05, 0.06])
    v = box.vertices.copy()
    v[3, 1] = np.nan
    with pytest.raises(MeshError, match="1 vertices with NaN/inf coordinates"):
        check_mesh_arrays(v, box.faces)
    with pytest.raises(MeshError, match="no triangles"):
        check_mesh_arrays(box.vertices, np.zeros((0, 3), int))
    with pytest.raises(MeshError, match="outside 0..7"):
        check_mesh_arrays(box.vertices, box.faces + 1)
    flat = box.vertices.copy()
    flat[:, 2] = 0.0
    with pytest.raises(MeshError, match="flat or degenerate"):
        check_mesh_arrays(flat, box.faces)


@pytest.mark.slow
def test_a_327k_face_mesh_is_decimated_and_its_hull_thinned(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=7, radius=0.04)  # 327,680 faces
    assert len(sphere.faces) > 300_000
    v, f = decimate(sphere.vertices, sphere.faces, 20_000)
    assert len(f) <= 20_000 and len(f) >= 10_000
    assert np.abs(np.linalg.norm(v, axis=1) - 0.04).max() < 0.002  # still the sphere, within 2 mm
    cylinder = trimesh.creation.cylinder(0.03, 0.1, sections=81_920)  # the 327k-face cylinder
    prepared = prepare_mesh(cylinder, cache_dir=tmp_path)
    assert prepared.method == "convex" and len(prepared.parts[0]) <= CoacdParams().max_hull_vertices
    hull = trimesh.convex.convex_hull(prepared.parts[0])
    assert hull.volume == pytest.approx(np.pi * 0.03**2 * 0.1, rel=0.02)


def _map(tmp_path):
    from hand_made import grasp_pose, hand_made_map

    from graspsim.maps import save_map
    from graspsim.primitives import Cylinder

    T = grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])[None]
    m = hand_made_map(Cylinder(0.02, 0.20), T, np.full(1, 0.04), grades=np.full(1, 0.8))
    return save_map(m, tmp_path / "cyl.h5")


def test_trial_refuses_a_millimetre_mesh_naming_mesh_scale_and_runs_it_scaled(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))
    path = _map(tmp_path)
    mesh = tmp_path / "cyl_mm.stl"
    trimesh.creation.cylinder(20.0, 200.0, sections=32).export(mesh)
    assert main(["trial", str(path), "--top", "1", "--mesh", str(mesh), "--no-write", "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--mesh-scale 0.001" in err[0] and "millimetres" in err[0]
    assert main(["trial", str(path), "--top", "1", "--mesh", str(mesh), "--mesh-scale", "0.001",
                 "--no-write", "--threads", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["trials"] == 1 and summary["mesh_model"]["method"] == "convex"
    assert summary["mesh_model"]["scale"] == 0.001


def test_trial_refuses_a_nan_vertex_in_one_line(tmp_path, capsys):
    path = _map(tmp_path)
    mesh = tmp_path / "nan.obj"
    box = trimesh.creation.box([0.04, 0.05, 0.06])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in box.vertices]
    lines[2] = "v nan 0.0 0.025"
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in box.faces]
    mesh.write_text("\n".join(lines) + "\n")
    assert main(["trial", str(path), "--top", "1", "--mesh", str(mesh), "--no-write"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "NaN/inf" in err[0] and "Traceback" not in err[0]
