import math

import numpy as np
import pytest
import trimesh

from graspsim.errors import PrimitiveError
from graspsim.primitives import (
    Compound,
    Cone,
    Cylinder,
    HalfToroid,
    Sphere,
    make_primitive,
    primitive_from_dict,
    synthetic_cloud,
)
from graspsim.transforms import make_transform, random_rotation


def test_mesh_is_watertight_and_matches_mass_properties(shape):
    m = shape.mesh(sections=128)
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume == pytest.approx(shape.volume, rel=3e-3)
    np.testing.assert_allclose(m.center_mass, shape.com, atol=2e-4)
    I_mesh = m.moment_inertia / m.volume  # unit mass
    np.testing.assert_allclose(I_mesh, shape.inertia(1.0), rtol=5e-3, atol=1e-8)


def test_surface_samples_lie_on_surface_with_outward_normals(shape):
    s = shape.surface_samples(0.005)
    assert np.abs(shape.sdf(s.points)).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=1), 1.0, atol=1e-9)
    assert np.min(np.sum(shape.normals(s.points) * s.normals, axis=1)) > 0.999
    assert s.areas.sum() == pytest.approx(shape.mesh(256).area, rel=3e-3)
    # stepping outward along the normal leaves the solid
    assert np.all(shape.sdf(s.points + 1e-4 * s.normals) > 0)


def test_cover_radius_bounds_distance_to_nearest_sample(shape, rng):
    from scipy.spatial import cKDTree

    s = shape.surface_samples(0.006)
    m = shape.mesh(128)
    q, _ = trimesh.sample.sample_surface(m, 4000, seed=1)
    q = q - shape.sdf(q)[:, None] * shape.normals(q)
    d, _ = cKDTree(s.points).query(q)
    assert d.max() <= s.cover_radius + 1e-6
    assert s.cover_radius <= 0.006 * 0.75


def test_sdf_sign_matches_mesh_containment(shape, rng):
    m = shape.mesh(256)
    b = shape.aabb
    P = rng.uniform(b[0] - 0.01, b[1] + 0.01, size=(3000, 3))
    sdf = shape.sdf(P)
    clear = np.abs(sdf) > 2e-4  # away from the faceting of the mesh
    assert np.array_equal((sdf < 0)[clear], m.contains(P[clear]))


def test_sdf_is_a_distance(shape, rng):
    m = shape.mesh(256)
    b = shape.aabb
    P = rng.uniform(b[0] - 0.02, b[1] + 0.02, size=(400, 3))
    _, dist, _ = trimesh.proximity.closest_point(m, P)
    np.testing.assert_allclose(np.abs(shape.sdf(P)), dist, atol=1e-4)


def test_ray_exit_is_first_exit(shape, rng):
    s = shape.surface_samples(0.005)
    d = -s.normals + 0.4 * rng.normal(size=s.normals.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ok = np.sum(d * s.normals, axis=1) < -0.2
    p, d = s.points[ok], d[ok]
    t = shape.ray_exit(p, d)
    assert np.all(np.isfinite(t)) and np.all(t > 0)
    assert np.abs(shape.sdf(p + t[:, None] * d)).max() < 1e-7
    frac = np.linspace(0.02, 0.98, 25)
    chord = p[:, None] + (frac[None, :, None] * t[:, None, None]) * d[:, None]
    assert np.all(shape.sdf(chord.reshape(-1, 3)) < 0)
    assert np.all(shape.sdf(p + (t[:, None] + 1e-5) * d) > 0)


def test_com_is_object_origin_and_z_is_main_axis():
    cone = Cone(0.04, 0.0, 0.12)
    # a full cone's centroid is a quarter of the height above the base
    assert cone.aabb[0, 2] == pytest.approx(-0.03)
    ht = HalfToroid(0.05, 0.01)
    # thin-ring limit: semicircle centroid 2R/pi
    assert ht.com_geo[1] == pytest.approx(2 * (0.05**2 + 0.01**2 / 4) / (math.pi * 0.05))
    assert ht.aabb[1, 2] == pytest.approx(0.01)


@pytest.mark.parametrize(
    "kind,dims",
    [
        ("box", {"x": 0.0, "y": 1, "z": 1}),
        ("box", {"x": -0.1, "y": 1, "z": 1}),
        ("cylinder", {"radius": float("nan"), "height": 0.1}),
        ("sphere", {"radius": -1}),
        ("cone", {"bottom_radius": 0, "top_radius": 0, "height": 0.1}),
        ("cone", {"bottom_radius": 0.02, "top_radius": -0.01, "height": 0.1}),
        ("half_toroid", {"major_radius": 0.01, "minor_radius": 0.02}),
        ("half_toroid", {"major_radius": 0.02, "minor_radius": 0.02}),
        ("cylinder", {"radius": 0.02}),
        ("pyramid", {"x": 1}),
    ],
)
def test_bad_dimensions_raise_clear_errors(kind, dims):
    with pytest.raises(PrimitiveError) as e:
        make_primitive(kind, **dims)
    assert kind.split("_")[0] in str(e.value) or "unknown" in str(e.value)


def test_bad_sampling_step():
    with pytest.raises(PrimitiveError):
        Sphere(0.02).surface_samples(0.0)
    with pytest.raises(PrimitiveError):
        Sphere(0.02).surface_samples(1.0)


def test_dict_round_trip(shape):
    assert primitive_from_dict(shape.to_dict()) == shape


def test_compound_union():
    body, neck = Cylinder(0.03, 0.12), Cylinder(0.012, 0.05)
    T2 = np.eye(4)
    T2[2, 3] = 0.085
    c = Compound.from_parts([body, neck], [np.eye(4), T2])
    assert c.volume == pytest.approx(body.volume + neck.volume)
    # COM at the origin: volume-weighted part centres cancel
    centres = c.poses[:, :3, 3]
    np.testing.assert_allclose(body.volume * centres[0] + neck.volume * centres[1], 0, atol=1e-12)
    s = c.surface_samples(0.004)
    assert np.abs(c.sdf(s.points)).max() < 1e-9
    T3 = np.eye(4)
    T3[2, 3] = 0.05  # neck sunk 3.5 cm into the body
    o = Compound.from_parts([body, neck], [np.eye(4), T3])
    assert o.volume == pytest.approx(body.volume + neck.volume - math.pi * 0.012**2 * 0.035, rel=5e-3)


def test_synthetic_cloud_is_seeded_and_on_surface(shape):
    T = make_transform(random_rotation(np.random.default_rng(3)), [0.4, -0.1, 0.2])
    a = synthetic_cloud(shape, np.random.default_rng(7), resolution=0.005, T_world_obj=T)
    b = synthetic_cloud(shape, np.random.default_rng(7), resolution=0.005, T_world_obj=T)
    np.testing.assert_array_equal(a.points, b.points)
    local = (a.points - T[:3, 3]) @ T[:3, :3]
    assert np.abs(shape.sdf(local)).max() < 1e-8
    assert len(a.points) == pytest.approx(shape.mesh(96).area / 0.005**2, rel=0.02)


def test_partial_view_sees_only_facing_unoccluded_points(shape):
    cam = np.array([0.4, 0.1, 0.3])
    full = synthetic_cloud(shape, np.random.default_rng(1), resolution=0.003)
    part = synthetic_cloud(shape, np.random.default_rng(1), resolution=0.003, camera=cam)
    assert 0.2 * len(full.points) < len(part.points) < 0.7 * len(full.points)
    assert np.all(np.sum(part.normals * (cam - part.points), axis=1) > 0)


def test_cloud_noise_and_outliers(rng):
    s = Sphere(0.03)
    c = synthetic_cloud(s, rng, resolution=0.004, noise=0.001, outliers=0.1)
    assert c.is_outlier.mean() == pytest.approx(0.1, abs=0.01)
    r = np.abs(s.sdf(c.points[~c.is_outlier]))
    assert 0.0006 < np.sqrt(np.mean(r**2)) < 0.0014


def test_a_compounds_volume_is_integrated_once(monkeypatch):
    """Building a compound integrates its mass properties once; its volume (read twice
    by a map's object description, on a planner's path to its first grasp) is not
    integrated again, and equals a fresh integration."""
    import graspsim.primitives.compound as compound
    from graspsim.maps.generate import object_description

    calls = []
    real = compound._mass_properties
    monkeypatch.setattr(compound, "_mass_properties", lambda *a, **k: calls.append(1) or real(*a, **k))
    T = np.eye(4)
    T[2, 3] = 0.1
    c = compound.Compound.from_parts([Cylinder(0.03, 0.16), Cylinder(0.012, 0.06)], [np.eye(4), T])
    d = object_description(c, None, 1000.0)
    assert len(calls) == 1
    assert d["volume"] == c.volume == pytest.approx(real(c.parts, c.poses)[1], rel=1e-12)


@pytest.mark.parametrize("kind,dims", [
    ("box", dict(x=0.03, y=0.05, z=0.08)), ("cylinder", dict(radius=0.02, height=0.07)),
    ("cone", dict(bottom_radius=0.03, top_radius=0.01, height=0.06)), ("sphere", dict(radius=0.03)),
    ("half_toroid", dict(major_radius=0.04, minor_radius=0.01))])
def test_normals_are_the_sdf_gradient_of_six_separate_evaluations(kind, dims):
    """normals() evaluates the six shifted copies in one SDF call: the same numbers, to
    the bit, as one call per shifted copy (scaled grasps' contact normals come from it)."""
    from graspsim.primitives import make_primitive

    prim = make_primitive(kind, **dims)
    rng = np.random.default_rng(0)
    for n in (0, 1, 7, 300):
        pts = prim.surface_samples(0.004).points[:n] + rng.normal(size=(n, 3)) * 1e-4
        p, eps, g = pts + prim.com_geo, 1e-6, np.empty((n, 3))
        for k in range(3):
            e = np.zeros(3)
            e[k] = eps
            g[:, k] = prim._sdf_geo(p + e) - prim._sdf_geo(p - e)
        want = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        assert prim.normals(pts).tobytes() == want.tobytes()
