"""Meshes: reading, CoACD decomposition and its on-disk cache, mesh objects."""

import math
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from graspsim.errors import MeshError
from graspsim.sim import CoacdParams, convex_parts, load_mesh, object_from_mesh, prepare_mesh, surface_model

BREAD = Path(__file__).resolve().parents[1] / "assets/objects/robosuite/bread.stl"
UNBOUNDED = CoacdParams(time_limit=math.inf)  # CoACD's parts whatever the machine's load


@pytest.fixture(scope="module")
def mesh_cache(tmp_path_factory):
    return tmp_path_factory.getbasetemp() / "coacd_cache"


def test_unreadable_or_missing_meshes_raise_mesh_error(tmp_path):
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"solid nothing\nthis is not an stl\n")
    with pytest.raises(MeshError):
        load_mesh(bad)
    with pytest.raises(MeshError, match="does not exist"):
        load_mesh(tmp_path / "missing.obj")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(MeshError, match="unsupported"):
        load_mesh(tmp_path / "notes.txt")
    with pytest.raises(MeshError):
        object_from_mesh(bad)


def test_convex_meshes_skip_coacd(tmp_path):
    box = trimesh.creation.box([0.04, 0.05, 0.06])
    prepared = prepare_mesh(box, cache_dir=tmp_path, params=CoacdParams(time_limit=0.0))
    assert prepared.method == "convex" and len(prepared.parts) == 1 and prepared.warning is None
    assert prepared.mass_from == "mesh" and prepared.volume == pytest.approx(0.04 * 0.05 * 0.06)


@pytest.mark.slow
def test_coacd_parts_are_cached_on_disk(mesh_cache):
    mesh = load_mesh(BREAD)
    first = convex_parts(mesh, UNBOUNDED, cache_dir=mesh_cache)
    assert len(first) >= 2 and list(mesh_cache.glob("*.npz"))
    t = time.perf_counter()
    again = convex_parts(mesh, UNBOUNDED, cache_dir=mesh_cache)
    assert time.perf_counter() - t < 0.5
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    # other parameters, other cache entry
    assert CoacdParams(threshold=0.2) != CoacdParams()


@pytest.mark.slow
def test_mesh_objects_take_mass_from_density_or_given(mesh_cache):
    mesh = load_mesh(BREAD)
    obj = object_from_mesh(BREAD, density=500.0, coacd=UNBOUNDED, cache_dir=mesh_cache)
    assert obj.mass == pytest.approx(500.0 * mesh.volume)
    np.testing.assert_allclose(obj.com, mesh.center_mass, atol=1e-12)
    heavy = object_from_mesh(BREAD, mass=1.0, coacd=UNBOUNDED, cache_dir=mesh_cache)
    np.testing.assert_allclose(heavy.inertia, obj.inertia / obj.mass, rtol=1e-9)
    assert heavy.mass == pytest.approx(1.0)


@pytest.mark.slow
def test_mesh_objects_are_placed_by_T_obj_mesh(mesh_cache):
    """A mesh posed by T_obj_mesh (a quarter turn about z and a 5 cm shift) is the same
    solid moved: mass kept, centre of mass and inertia moved and turned with it, its
    collision parts and surface where the moved mesh is."""
    obj = object_from_mesh(BREAD, density=500.0, coacd=UNBOUNDED, cache_dir=mesh_cache)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = np.array([0.03, -0.02, 0.05])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    moved = object_from_mesh(BREAD, density=500.0, T_obj_mesh=T, coacd=UNBOUNDED, cache_dir=mesh_cache)
    assert moved.mass == pytest.approx(obj.mass, rel=1e-9)
    np.testing.assert_allclose(moved.com, R @ obj.com + t, atol=1e-9)
    np.testing.assert_allclose(moved.inertia, R @ obj.inertia @ R.T, atol=1e-12 * obj.inertia.max() + 1e-15)
    np.testing.assert_allclose(np.sort(moved.surface.vertices, axis=0),
                               np.sort(obj.surface.vertices @ R.T + t, axis=0), atol=1e-9)
    # the model is prepared in the mesh's frame and moved: the same parts, moved
    assert len(moved.geoms) == len(obj.geoms)
    for g, h in zip(obj.geoms, moved.geoms):
        np.testing.assert_allclose(h.vertices, g.vertices @ R.T + t, atol=1e-12)
    assert moved.description["file"].endswith("bread.stl")


# ---------------------------------------------------------------------- the surface model
def _ring(r_in=0.03, wall=0.004, height=0.06):
    """A thin-walled ring (a cup without its bottom): closed, concave, a hole inside."""
    return trimesh.creation.annulus(r_min=r_in, r_max=r_in + wall, height=height)


def test_surface_model_keeps_cavities_and_thin_walls():
    """Each face a prism reaching inwards only: nothing of the model lies outside the mesh
    and the ring's hole stays free, which its hull (the fallback) fills. Mutation:
    extruding outwards puts the model 1.5 mm outside the surface and trips the first assert."""
    ring = _ring()
    model = surface_model(ring)
    assert model.method == "surface" and len(model.parts) == len(ring.faces) and model.mass_from == "mesh"
    pts = np.concatenate(model.parts)
    assert trimesh.proximity.signed_distance(ring, pts).min() > -1e-9  # >= 0: inside or on the surface
    hulls = [trimesh.convex.convex_hull(p) for p in model.parts]
    hole = np.array([[0.0, 0.0, 0.0], [0.025, 0.0, 0.02]])
    assert not any(h.contains(hole).any() for h in hulls)
    assert ring.convex_hull.contains(hole).all()
    wall = np.array([[0.0305, 0.001, 0.001], [0.001, -0.0335, 0.011]])  # 0.5 mm inside the inner / outer face
    assert all(any(h.contains(w[None])[0] for h in hulls) for w in wall)
    assert model.volume == pytest.approx(ring.volume)
    with pytest.raises(MeshError, match="at most"):
        surface_model(ring, max_faces=10)


def test_a_grasp_pinching_a_thin_wall_starts_clear_on_the_surface_model(tmp_path):
    """The Franka hand pinching the ring's 4 mm wall from above, one finger in the hole:
    clear and held against the surface model; inside the hull model (the cavity filled)."""
    from graspsim.grippers import get_gripper
    from graspsim.sim import TrialOutcome, build_scene, make_protocol, object_from_mesh, run_trials
    from graspsim.sim.trial_scene import SimSettings

    franka = get_gripper("franka_hand")
    ring = _ring()
    R = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # closing x, approach -z
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = franka.wrist_from_grasp_point(np.array([0.032, 0.0, 0.02]), R[:, 2], 0.012)
    tug = make_protocol("tug")
    out = {}
    for name, prepared in (("surface", surface_model(ring)),
                           ("hull", prepare_mesh(ring, cache_dir=tmp_path, params=CoacdParams(time_limit=0.0)))):
        scene = build_scene(object_from_mesh(prepared, mass=0.02), franka, SimSettings(friction=1.0),
                            table=False, gravity=False)
        out[name] = run_trials(scene, T[None], np.array([0.004]), tug, threads=1).outcome[0]
    assert out["surface"] == TrialOutcome.SUCCESS
    assert out["hull"] == TrialOutcome.START_COLLISION


@pytest.mark.slow
def test_an_unbounded_model_in_the_cache_does_not_change_a_bounded_call(tmp_path):
    """A model CoACD made without a time limit is served only to limits at least the CPU
    time it took: a call with a smaller limit gets the fallback it would get on an empty
    cache. Mutation: serving the complete model to every limit (the earlier rule) trips it."""
    ring = _ring()
    full = prepare_mesh(ring, cache_dir=tmp_path, params=UNBOUNDED)
    assert full.method == "coacd" and full.decompose_cpu > 0
    again = prepare_mesh(ring, cache_dir=tmp_path, params=UNBOUNDED)
    assert again.from_cache and again.method == "coacd" and again.decompose_cpu == full.decompose_cpu
    bounded = prepare_mesh(ring, cache_dir=tmp_path, params=CoacdParams(time_limit=0.0))
    assert bounded.method == "hull" and bounded.warning
    roomy = prepare_mesh(ring, cache_dir=tmp_path, params=CoacdParams(time_limit=full.decompose_cpu + 60))
    assert roomy.from_cache and roomy.method == "coacd"
