"""FS map generation: geometry of stored poses, collision exactness, determinism."""

import math

import numpy as np
import pytest
from conftest import PAPER_SHAPES

from graspsim.errors import NoFeasibleGraspError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.collide import collision_free
from graspsim.maps.collide_fcl import FclChecker, penetration_depth
from graspsim.maps.generate import closing_directions, closing_lines, generate_fs_map, roll_angles, sweep_collisions
from graspsim.maps.hierarchy import sample_levels
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Cylinder, Sphere
from graspsim.transforms import make_transform, quat_to_matrix, random_rotation

# a coarser scan keeps the per-primitive tests fast; the default is exercised below
FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def fast_maps():
    return {k: generate_fs_map(s, config=FAST) for k, s in PAPER_SHAPES.items()}


def test_closing_directions_cover_rings_around_inward_normal():
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    u, polar = closing_directions(n, math.radians(22), math.radians(11))
    assert u.shape == (2, 19, 3) and len(polar) == 19
    np.testing.assert_allclose(np.linalg.norm(u, axis=2), 1.0)
    ang = np.degrees(np.arccos(np.clip(np.einsum("mkj,mj->mk", u, -n), -1, 1)))
    np.testing.assert_allclose(ang, np.broadcast_to(np.degrees(polar), ang.shape), atol=1e-9)
    assert sorted(set(np.round(np.degrees(polar), 6))) == [0.0, 11.0, 22.0]


def test_stored_poses_are_consistent_with_contacts(shape, fast_maps):
    m = fast_maps[[k for k, v in PAPER_SHAPES.items() if v == shape][0]]
    assert len(m) > 1000
    c = m.contacts.astype(float)
    # contacts on the surface, grasp point between them, width = contact distance
    assert np.abs(shape.sdf(c.reshape(-1, 3))).max() < 2e-6
    np.testing.assert_allclose(m.grasp_point, c.mean(axis=1), atol=1e-6)
    np.testing.assert_allclose(m.width, np.linalg.norm(c[:, 1] - c[:, 0], axis=1), atol=1e-6)
    assert np.all(m.width + 2 * G.approach_clearance <= G.max_opening + 1e-6)
    # wrist frame: x along the closing line, grasp point on the approach axis at a pad depth
    R = quat_to_matrix(m.wrist_quat)
    u = (c[:, 1] - c[:, 0]) / m.width[:, None]
    np.testing.assert_allclose(np.einsum("ni,ni->n", R[:, :, 0], u), 1.0, atol=1e-5)
    local = np.einsum("nji,nj->ni", R, m.grasp_point - m.wrist_position)
    np.testing.assert_allclose(local[:, :2], 0.0, atol=1e-5)
    depth = G.fingertip_z - local[:, 2]
    allowed = G.contact_depths(FAST.depth_step)
    assert np.abs(depth[:, None] - allowed[None]).min(axis=1).max() < 1e-5


def test_grades_are_the_quality_model(shape, fast_maps):
    m = fast_maps[[k for k, v in PAPER_SHAPES.items() if v == shape][0]]
    q = QualityModel().evaluate(m.contacts[:, 0], m.contacts[:, 1], m.normals[:, 0],
                                m.normals[:, 1], np.zeros(3), m.meta.quality["d_ref"])
    np.testing.assert_allclose(m.grade, q.grade, atol=1e-5)
    assert m.meta.quality["d_ref"] == pytest.approx(shape.circumradius)
    assert np.all((m.grade >= 0) & (m.grade <= 1))
    assert np.all(m.grade[m.accepted] > 0.7)


@pytest.mark.slow
def test_stored_poses_do_not_penetrate_the_object(shape, fast_maps, rng):
    """Independent check: dense points on every gripper box stay outside the object."""
    m = fast_maps[[k for k, v in PAPER_SHAPES.items() if v == shape][0]]
    idx = rng.choice(len(m), 150, replace=False)
    T = m.T_obj_wrist[idx]
    opening = m.width[idx] + 2 * G.approach_clearance
    chk = FclChecker(shape, G)
    assert not chk.collides_many(T, opening).any()
    for i in idx[:40]:
        j = list(idx).index(i)
        assert penetration_depth(shape, G, T[j], opening[j], step=1e-3) == 0.0


def test_sphere_antipodal_grasps_through_centre_are_perfect():
    m = generate_fs_map(Sphere(0.03), config=FAST)
    assert m.grade.max() == pytest.approx(1.0, abs=1e-4)
    best = m.top_k(1)
    assert np.linalg.norm(best.grasp_point) < 0.004


def test_same_input_same_map_whatever_the_thread_count():
    s = Cylinder(0.02, 0.1)
    a = generate_fs_map(s, config=FAST, threads=1)
    b = generate_fs_map(s, config=FAST, threads=2)
    for k, v in a.columns().items():
        np.testing.assert_array_equal(v, getattr(b, k))


def test_object_too_wide_for_the_gripper():
    with pytest.raises(NoFeasibleGraspError, match="maximum opening"):  # before any work
        generate_fs_map(Sphere(0.08), config=FAST)
    # fits the 12 cm opening, but no chord leaves the 2 x 5 mm approach clearance
    with pytest.raises(NoFeasibleGraspError, match="clearance"):
        generate_fs_map(Sphere(0.0598), config=FAST)


def test_sample_hierarchy_bounds_every_fine_sample():
    lv = sample_levels(Cylinder(0.02, 0.1), MapConfig())
    F, M, Q = lv["F"], lv["M"], lv["Q"]
    mid = np.repeat(np.arange(len(M)), np.diff(lv["fstart"]))
    coarse = np.repeat(np.arange(len(Q)), np.diff(lv["mstart"]))[mid]
    for P, N, RT, HN, parent in ((M, lv["NM"], lv["RTM"], lv["HNM"], mid),
                                 (Q, lv["NQ"], lv["RT"], lv["HN"], coarse)):
        d = F - P[parent]
        h = np.sum(d * N[parent], axis=1)
        rt = np.linalg.norm(d - h[:, None] * N[parent], axis=1)
        assert np.all(rt <= RT[parent] + 1e-12) and np.all(np.abs(h) <= HN[parent] + 1e-12)
    assert lv["fine_cover"] <= MapConfig().collision_tolerance


def _random_poses(shape, n, rng):
    R = random_rotation(rng, n)
    b = shape.aabb
    tcp = rng.uniform(b[0] - 0.03, b[1] + 0.03, size=(n, 3))
    depth = rng.uniform(0, G.pad_length, n)
    T = make_transform(R, tcp - (G.fingertip_z - depth)[:, None] * R[:, :, 2])
    return T, rng.uniform(G.min_opening, G.max_opening, n)


@pytest.mark.slow
def test_collision_test_agrees_with_fcl_on_random_poses():
    """>= 99.5 % agreement with python-fcl over random poses around all five primitives;
    never a missed penetration (the test is conservative), and every disagreement is a
    pose within the collision tolerance of touching."""
    rng = np.random.default_rng(7)
    agree, total = 0, 0
    for shape in PAPER_SHAPES.values():
        T, opening = _random_poses(shape, 1500, rng)
        ours = ~collision_free(shape, G, T, opening)
        chk = FclChecker(shape, G)
        ref = chk.collides_many(T, opening)
        agree += int(np.sum(ours == ref))
        total += len(T)
        assert np.mean(ours == ref) >= 0.99, shape
        for i in np.flatnonzero(~ours & ref):  # only mesh-facet artefacts could do this
            assert penetration_depth(shape, G, T[i], opening[i]) < 0.0005
        for i in np.flatnonzero(ours & ~ref):
            assert chk.distance(T[i], opening[i]) <= 2 * MapConfig().collision_tolerance
    assert agree / total >= 0.995


@pytest.mark.slow
def test_sweep_never_misses_a_collision_on_map_candidates():
    """The generator's own candidate poses (near-contact, the hard case) vs fcl."""
    s, cfg = PAPER_SHAPES["cylinder"], MapConfig()
    lines = closing_lines(s, G, cfg)
    free, _ = sweep_collisions(s, lines, G, cfg)
    rng = np.random.default_rng(3)
    n = 1500
    li, ri, di = (rng.integers(k, size=n) for k in free.shape)
    roll = roll_angles(cfg)[ri]
    z = np.cos(roll)[:, None] * lines.e1[li] + np.sin(roll)[:, None] * lines.e2[li]
    x = lines.u[li]
    R = np.stack([x, np.cross(z, x), z], axis=-1)
    depth = G.contact_depths(cfg.depth_step)[di]
    T = make_transform(R, lines.gp[li] - (G.fingertip_z - depth)[:, None] * z)
    opening = lines.width[li] + 2 * G.approach_clearance
    ref = FclChecker(s, G).collides_many(T, opening)
    ours = free[li, ri, di] == 0
    assert not np.any(ref & ~ours)
    assert np.mean(ours == ref) > 0.97


def test_compound_objects_get_maps():
    from graspsim.primitives import Box, Compound
    from graspsim.transforms import make_transform

    c = Compound.from_parts([Sphere(0.03), Box(0.015, 0.04, 0.05)],
                            [np.eye(4), make_transform(np.eye(3), [0.035, 0, 0])])
    m = generate_fs_map(c, config=FAST)
    assert len(m) > 0 and m.meta.object["primitive"] == "compound"
    assert np.abs(c.sdf(m.contacts.reshape(-1, 3).astype(float))).max() < 1e-6
    idx = np.random.default_rng(2).choice(len(m), 100, replace=False)
    assert not FclChecker(c, G).collides_many(m.T_obj_wrist[idx], m.width[idx] + 2 * G.approach_clearance).any()


def test_grouped_grasps_with_off_grid_depths_are_checked_exactly():
    """Grasps sharing closing lines but at many continuous contact depths (as Combined
    scaling's wrist slides produce) go through the grouped sweep: same answers as pose by
    pose, and never a missed collision against python-fcl."""
    from graspsim.maps.collide import grasps_collision_free

    s, cfg = PAPER_SHAPES["cylinder"], MapConfig()
    lines = closing_lines(s, G, cfg)
    rng = np.random.default_rng(11)
    li = np.repeat(rng.choice(len(lines.u), 60, replace=False), 8)
    roll = roll_angles(cfg)[rng.integers(len(roll_angles(cfg)), size=len(li))]
    depth = rng.uniform(G.contact_depth_margin, G.pad_length - G.contact_depth_margin, len(li))
    assert len(np.unique(depth)) > 64  # off the map's depth grid
    z = np.cos(roll)[:, None] * lines.e1[li] + np.sin(roll)[:, None] * lines.e2[li]
    x = lines.u[li]
    R = np.stack([x, np.cross(z, x), z], axis=-1)
    free = grasps_collision_free(s, G, lines.gp[li], R, depth, lines.width[li], cfg, line=li)
    T = make_transform(R, lines.gp[li] - (G.fingertip_z - depth)[:, None] * z)
    opening = lines.width[li] + 2 * G.approach_clearance
    assert np.mean(free == collision_free(s, G, T, opening, cfg)) > 0.99
    ref = FclChecker(s, G).collides_many(T, opening)
    assert not np.any(ref & free)
    assert 0 < free.sum() < len(free)
