"""Meshes: reading, CoACD decomposition and its on-disk cache, mesh objects."""

import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from graspsim.errors import MeshError
from graspsim.sim import CoacdParams, convex_parts, load_mesh, object_from_mesh

BREAD = Path(__file__).resolve().parents[1] / "assets/objects/robosuite/bread.stl"


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
    parts = convex_parts(box, cache_dir=tmp_path)
    assert len(parts) == 1 and not any(tmp_path.iterdir())


@pytest.mark.slow
def test_coacd_parts_are_cached_on_disk(mesh_cache):
    mesh = load_mesh(BREAD)
    first = convex_parts(mesh, cache_dir=mesh_cache)
    assert len(first) >= 2 and list(mesh_cache.glob("*.npz"))
    t = time.perf_counter()
    again = convex_parts(mesh, cache_dir=mesh_cache)
    assert time.perf_counter() - t < 0.5
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    # other parameters, other cache entry
    assert CoacdParams(threshold=0.2) != CoacdParams()


@pytest.mark.slow
def test_mesh_objects_take_mass_from_density_or_given(mesh_cache):
    mesh = load_mesh(BREAD)
    obj = object_from_mesh(BREAD, density=500.0, cache_dir=mesh_cache)
    assert obj.mass == pytest.approx(500.0 * mesh.volume)
    np.testing.assert_allclose(obj.com, mesh.center_mass, atol=1e-12)
    heavy = object_from_mesh(BREAD, mass=1.0, cache_dir=mesh_cache)
    np.testing.assert_allclose(heavy.inertia, obj.inertia / obj.mass, rtol=1e-9)
    shifted = object_from_mesh(BREAD, T_obj_mesh=np.diag([1.0, 1, 1, 1]) + np.eye(4, k=3) * 0,
                               cache_dir=mesh_cache)
    assert shifted.description["file"].endswith("bread.stl")
