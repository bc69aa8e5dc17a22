"""A single view's box parts completed down to the table they rest on
(graspsim.planning.table_completion, PlannerConfig.complete_to_table)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.geometry.table import TablePlane
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.occlusion import ViewDepth
from graspsim.perception import identify
from graspsim.planning.planner import PlannerConfig, canonical_box
from graspsim.planning.scene_config import SceneConfig
from graspsim.planning.table_completion import complete_to_table, segment_depth
from graspsim.primitives import Box

EYE = np.array([0.0, -0.402, 0.603])  # E10's camera: 0.4 m in front of the table's centre, 0.6 m above it
TABLE = TablePlane(height=0.0)
FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


def _faces(size, centre, rng, n=1500, sigma=0.001):
    """A single view of an axis-aligned box ``size`` (3,) at ``centre`` (3,) resting on the
    z = 0 table: points on its faces turned to EYE (not the bottom), with depth noise
    ``sigma`` [m] along the line of sight."""
    half, c = 0.5 * np.asarray(size, float), np.asarray(centre, float)
    pts = []
    for j in range(3):
        for s in (1.0, -1.0):
            nrm = np.zeros(3)
            nrm[j] = s
            face = c + half[j] * nrm
            if (EYE - face) @ nrm <= 0 or (j == 2 and s < 0):
                continue
            o = [k for k in range(3) if k != j]
            area = 4 * half[o[0]] * half[o[1]]
            m = max(int(n * area / (4 * half[0] * half[1])), 20)
            p = np.tile(face, (m, 1))
            p[:, o] += rng.uniform(-half[o], half[o], (m, 2))
            pts.append(p)
    p = np.concatenate(pts)
    ray = (p - EYE) / np.linalg.norm(p - EYE, axis=1, keepdims=True)
    return p + ray * rng.normal(0, sigma, (len(p), 1))


def _check_completed(prim, T, pts, size, sigma):
    new, T2, how = complete_to_table(prim, T, pts, TABLE, EYE)
    assert how.axis is not None and abs(how.axis[2]) > 0.9  # completed straight down
    dims = np.array([new.x, new.y, new.z])
    height = dims[int(np.argmax(np.abs(T2[2, :3])))]
    assert abs(height - size[2]) <= 3 * sigma + 0.001, (prim, new)
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * 0.5 * dims
    low = (corners @ T2[:3, :3].T + T2[:3, 3])[:, 2].min()
    assert abs(low) < 1e-6  # down to the table, not through it


def test_a_thin_plate_fitted_to_a_domino_lying_flat_is_completed_to_its_thickness():
    """A domino (48 x 24 x 6 mm) lying flat, seen from E10's camera: the scene's 6 mm table
    band leaves only its top, which E10's segments fitted as a plate 2 to 4 mm thick at the
    seen top (its hidden bottom 2 to 4 mm above the table). Completed down to the table
    plane, its height is the true one within the noise."""
    rng = np.random.default_rng(1)
    size, sigma = np.array([0.048, 0.024, 0.006]), 0.001
    pts = _faces(size, [0.0, 0.0, 0.003], rng, sigma=sigma)
    pts = pts[pts[:, 2] > 0.0045]  # the table band's cut: the top face's points (the sides are lower)
    T = np.eye(4)
    T[2, 3] = 0.006 - 0.00105
    _check_completed(Box(0.048, 0.024, 0.0021), T, pts, size, sigma)


@pytest.mark.parametrize("seed", [0, 2])
def test_a_carton_lying_on_its_side_identified_from_one_view_is_completed_down_to_the_table(seed):
    """A carton (15 x 5 x 5 cm) lying on its side, seen from E10's camera with depth noise
    (1.5 mm) above the scene's 6 mm table band: identified with the scene planner's
    settings, its hidden bottom is fitted 5 to 7 mm above the table (the band cut its near
    face's foot); completed down to the table, its height is the true one within the noise."""
    rng = np.random.default_rng(seed)
    size, sigma = np.array([0.15, 0.05, 0.05]), 0.0015
    pts = _faces(size, [0.0, 0.0, 0.025], rng, sigma=sigma)
    pts = pts[pts[:, 2] > 0.006]  # the table band
    ident = identify(pts, rng=np.random.default_rng(0), config=SceneConfig().planner.identify)
    (part,) = ident.parts
    prim, T = canonical_box(part.primitive(), part.T_world_obj)
    _check_completed(prim, T, pts, size, sigma)


def test_a_box_that_does_not_touch_the_table_or_whose_underside_the_camera_saw_is_left_as_fitted():
    """The same plate 4 cm above the table (lying on a neighbour): no completion. A plate
    whose far face is turned to the camera's side, or with nothing hidden under it (the
    camera saw past it), is left as it is; so are non-boxes and a table of unknown height."""
    rng = np.random.default_rng(2)
    size = np.array([0.048, 0.024, 0.004])
    plate = Box(*size)
    T = np.eye(4)
    T[2, 3] = 0.04
    pts = _faces(size, T[:3, 3], rng)
    assert complete_to_table(plate, T, pts, TABLE, EYE)[2].axis is None  # does not touch the table
    size = np.array([0.048, 0.024, 0.008])
    plate = Box(*size)
    T[2, 3] = 0.013  # touching (its near face's foot 9 mm up), half of it seen: the slab under the rest was not hidden
    edge = _faces(size, T[:3, 3], rng)
    edge = edge[edge[:, 1] > 0.0]  # half the plate seen: the rest of the slab beside the points is not hidden
    assert complete_to_table(plate, T, edge, TABLE, EYE)[2].axis is None
    assert complete_to_table(plate, T, pts, TablePlane(), EYE)[2].axis is None
    assert complete_to_table(plate, T, pts, TABLE, None)[2].axis is None
    T[2, 3] = 0.002  # resting on the table already
    assert complete_to_table(plate, T, _faces(size, T[:3, 3], rng), TABLE, EYE)[2].axis is None


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    return MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)


def test_grasps_close_across_a_depth_the_table_bounds(db):
    """A carton lying on its side seen from above shows its top: its depth is unmeasured
    and unseen_depth refuses every grasp across it. Completed down to the table, that
    axis is bounded (``bounded``): the grasps across it are offered again."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.observed import ObservedChecks

    plate = Box(0.004, 0.044, 0.06)  # the top face fitted as a plate, x up
    m = generate_fs_map(plate, G, config=FAST)
    rng = np.random.default_rng(3)
    T = np.eye(4)
    T[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]  # the plate's x axis straight up
    T[:3, 3] = [0, 0, 0.048]
    top = np.column_stack([rng.uniform(-0.03, 0.03, 800), rng.uniform(-0.022, 0.022, 800), np.full(800, 0.05)])
    checks = ObservedChecks(top + rng.normal(0, 0.0005, top.shape), None, np.eye(4), viewpoint=EYE,
                            noise=0.0005, gripper=G, quality=db.quality, cfg=PlannerConfig())
    up = T[:3, 0]
    closing = np.abs((T[:3, :3] @ m.wrist_transforms()[:, :3, 0].T).T @ up)
    refused = checks.unseen_depth(m, plate, T, T)
    vertical = int(np.sum(np.abs((T[:3, :3] @ refused.wrist_transforms()[:, :3, 0].T).T @ up) > 0.9))
    assert vertical < np.sum(closing > 0.9) / 2  # most across the depth refused
    offered = checks.unseen_depth(m, plate, T, T, bounded=up)
    assert len(offered) == len(m)


def test_only_scene_planning_completes():
    """Single-object planning (PlannerConfig's default) is unchanged; the scene planner completes."""
    assert PlannerConfig().complete_to_table is False
    assert SceneConfig().planner.complete_to_table is True
    assert replace(PlannerConfig(), complete_to_table=True).complete_to_table
    assert PlannerConfig().merge_boxes is False and PlannerConfig().hidden_depth is False
    assert SceneConfig().planner.merge_boxes is True and SceneConfig().planner.hidden_depth is True


def test_a_domino_standing_face_on_is_given_the_depth_the_view_can_tell_and_grasps_across_it(db):
    """A domino (24 x 6 x 48 mm) standing face-on to E10's camera shows only its front face;
    the fit makes it a plate 2.6 mm thick. Its far contact then lies among the front face's
    own noisy points, which face the other way: grasps across the thickness are taken as
    contradicted (borne_out keeps a handful at the face's edges). ``hidden_depth`` gives the unmeasured depth at
    least ``least_hidden_depth`` (contact tolerance + 2 sigmas), the seen face kept in place:
    grasps across it are borne out again."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.planning.observed import ObservedChecks
    from graspsim.planning.planner import _deepened

    rng = np.random.default_rng(4)
    front = np.column_stack([rng.uniform(-0.012, 0.012, 900), np.full(900, -0.003), rng.uniform(0.007, 0.048, 900)])
    ray = (front - EYE) / np.linalg.norm(front - EYE, axis=1, keepdims=True)
    pts = front + ray * rng.normal(0, 0.001, (len(front), 1))
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # the plate's x (its thickness) along the line of sight's y
    T[:3, 3] = [0.0, -0.003 + 0.0013, 0.024]
    plate = Box(0.0026, 0.024, 0.048)
    checks = ObservedChecks(pts, None, np.eye(4), viewpoint=EYE, noise=0.001, gripper=G, quality=db.quality,
                            cfg=PlannerConfig(hidden_depth=True))
    view = ViewDepth(pts, EYE)
    (deep,), (T2,), _ = _deepened([plate], [T], [None], checks, TABLE, EYE, pts, view, 0.006)
    assert deep.x >= checks.least_hidden_depth - 1e-9 and (deep.y, deep.z) == (plate.y, plate.z)
    assert T2[1, 3] - 0.5 * deep.x == pytest.approx(-0.003, abs=1e-9)  # the seen face kept
    (same,), _, _ = _deepened([plate], [T], [np.array([[0.0, 1.0, 0.0]])], checks, TABLE, EYE, pts, view, 0.006)
    assert same == plate  # an axis the table bounds is left alone

    def across(box, pose):
        m = generate_fs_map(box, G, config=FAST)
        kept = checks.borne_out(m, pose, box, pose)
        u = (pose[:3, :3] @ kept.wrist_transforms()[:, :3, 0].T).T
        return int(np.sum(np.abs(u[:, 1]) > 0.9))

    thin, deeper = across(plate, T), across(deep, T2)
    assert deeper > 20 * thin  # 15 vs 3753 when written: the thin plate's far contacts contradicted


def _carton(rng, top=True):
    """A standing carton (44 x 44 x 125 mm) seen by E10's camera: its front face (facing -y,
    towards EYE) and, with ``top``, its top face, which reaches back its whole depth."""
    front = np.column_stack([rng.uniform(-0.022, 0.022, 1200), np.full(1200, -0.022), rng.uniform(0.007, 0.125, 1200)])
    pts = [front]
    if top:
        pts.append(np.column_stack([rng.uniform(-0.022, 0.022, 500), rng.uniform(-0.022, 0.022, 500),
                                    np.full(500, 0.125)]))
    return np.concatenate(pts)


def test_a_box_part_is_as_deep_as_its_segment_reaches_behind_it():
    """A standing carton fitted as a 4 mm plate on its front face (the top fitted apart, as
    the milk carton's gable is): the segment's top points reach 44 mm back, so the plate's
    unmeasured depth is at least that, where the volume gained lies in the camera's shadow."""
    from graspsim.planning.observed import ObservedChecks
    from graspsim.planning.planner import _deepened

    rng = np.random.default_rng(5)
    pts = _carton(rng)
    plate = Box(0.004, 0.044, 0.118)
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # the plate's x (its thickness) along y
    T[:3, 3] = [0.0, -0.022 + 0.002, 0.066]
    d = np.array([0.0, 1.0, 0.0])  # away from the camera
    view = ViewDepth(pts, EYE)
    added = segment_depth(plate, T, 0, d, pts, view, TABLE)
    assert 0.035 <= added <= 0.040 + 1e-9  # its top reaches 40 mm behind the plate (a quantile of it)
    front = _carton(rng, top=False)
    assert segment_depth(plate, T, 0, d, front, ViewDepth(front, EYE), TABLE) == 0.0  # nothing behind it
    # the camera saw the space behind the plate (points beyond it, e.g. the table seen past it): not hidden
    past = np.column_stack([rng.uniform(-0.02, 0.02, 3000), rng.uniform(-0.018, 0.02, 3000),
                            rng.uniform(0.01, 0.12, 3000)])
    open_view = ViewDepth(np.concatenate([pts[:1200], past[past[:, 2] < 0.02]]), EYE)
    assert segment_depth(plate, T, 0, d, pts, open_view, TABLE) == 0.0
    # through the planner's step: deepened to the segment's reach, that axis counted as measured
    checks = ObservedChecks(pts, None, np.eye(4), viewpoint=EYE, noise=0.001, gripper=G, quality=None,
                            cfg=PlannerConfig(hidden_depth=True))
    (deep,), (T2,), (axes,) = _deepened([plate], [T], [None], checks, TABLE, EYE, pts, view, 0.006)
    assert 0.039 <= deep.x <= 0.044 + 1e-9 and deep.z == plate.z
    assert T2[1, 3] - 0.5 * deep.x == pytest.approx(-0.022, abs=1e-9)  # the seen face kept
    assert axes is not None and abs(float(axes[0] @ d)) > 0.99


def test_a_box_whose_foot_a_neighbour_hides_is_completed_unless_it_rests_on_one():
    """A box 30 x 60 x 40 mm lying on the table behind a 20 mm neighbour: the camera sees its
    top and its front face above 20 mm; fitted as a 12 mm plate. The neighbour's points are
    in front of the volume down to the table, not in it: completed. A neighbour under it
    (points inside that volume): left as fitted; without the neighbours: as before."""
    rng = np.random.default_rng(6)
    size, c = np.array([0.030, 0.060, 0.040]), np.array([0.0, 0.0, 0.020])
    pts = _faces(size, c, rng)
    pts = pts[pts[:, 2] > 0.020]
    wall = np.column_stack([rng.uniform(-0.03, 0.03, 800), np.full(800, -0.045), rng.uniform(0.006, 0.020, 800)])
    plate = Box(0.030, 0.060, 0.012)
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.034]
    seen = np.concatenate([pts, wall])
    new, T2, how = complete_to_table(plate, T, pts, TABLE, EYE, ViewDepth(seen, EYE), neighbours=wall)
    assert how.axis is not None and new.z == pytest.approx(0.040, abs=1e-6)
    assert T2[2, 3] - 0.5 * new.z == pytest.approx(0.0, abs=1e-6)  # down to the table
    assert complete_to_table(plate, T, pts, TABLE, EYE, ViewDepth(seen, EYE))[2].axis is None
    under = np.column_stack([rng.uniform(-0.01, 0.01, 50), rng.uniform(-0.02, 0.02, 50), np.full(50, 0.015)])
    held = np.concatenate([wall, under])
    assert complete_to_table(plate, T, pts, TABLE, EYE, ViewDepth(np.concatenate([pts, held]), EYE),
                             neighbours=held)[2].axis is None


def test_parallel_box_parts_over_hidden_space_are_one_box_but_not_over_seen_space():
    """A carton lying on its side (44 x 44 x 150 mm, long axis along x) fitted as two slabs
    with an 8 mm gap between them under its seen top: the gap lies in the camera's shadow,
    so the slabs are one box, their union. Two blocks side by side with the table seen
    between them stay two."""
    from graspsim.planning.box_merge import merge_boxes

    rng = np.random.default_rng(7)
    carton = _faces([0.150, 0.044, 0.044], [0.0, 0.0, 0.022], rng)
    a, b = Box(0.150, 0.010, 0.044), Box(0.150, 0.026, 0.044)
    Ta, Tb = np.eye(4), np.eye(4)
    Ta[:3, 3] = [0.0, -0.017, 0.022]
    Tb[:3, 3] = [0.0, 0.009, 0.022]  # 8 mm between the slabs
    prims, poses, groups = merge_boxes([a, b], [Ta, Tb], ViewDepth(carton, EYE), TABLE)
    box = canonical_box(prims[0], poses[0])[0]
    assert groups == [[0, 1]] and (box.x, box.y, box.z) == pytest.approx((0.044, 0.044, 0.150), abs=1e-9)
    assert poses[0][:3, 3] == pytest.approx([0.0, 0.0, 0.022], abs=1e-9)
    # two such blocks 50 mm apart, the table seen between them: not one box
    Ta[1, 3], Tb[1, 3] = -0.040, 0.030
    two = np.concatenate([_faces([0.150, 0.010, 0.044], Ta[:3, 3], rng), _faces([0.150, 0.026, 0.044], Tb[:3, 3], rng),
                          np.column_stack([rng.uniform(-0.075, 0.075, 4000), rng.uniform(-0.035, 0.017, 4000),
                                           np.full(4000, 0.0)])])
    assert len(merge_boxes([a, b], [Ta, Tb], ViewDepth(two, EYE), TABLE)[0]) == 2
    hidden = np.concatenate([two[:-4000], _faces([0.150, 0.080, 0.044], [0.0, -0.005, 0.022], rng, n=6000)])
    assert len(merge_boxes([a, b], [Ta, Tb], ViewDepth(hidden, EYE), TABLE)[0]) == 1  # a carton's top over them


def test_an_axis_the_table_bounds_counts_as_measured_for_the_hidden_faces_rule(db):
    """A block lying along the line of sight (30 x 150 x 40 mm) seen from above shows its top
    alone: its height is a guess, so its edge-on long sides get no hidden-faces grasps. With
    its height bounded (completed down to the table, or reached by its segment's points) the
    sides' extents are no guess: the x axis, both of whose faces are edge-on, is returned."""
    from graspsim.planning.observed import ObservedChecks

    rng = np.random.default_rng(8)
    top = np.column_stack([rng.uniform(-0.015, 0.015, 1500), rng.uniform(-0.075, 0.075, 1500), np.full(1500, 0.040)])
    checks = ObservedChecks(top, None, np.eye(4), viewpoint=np.array([0.0, -0.4, 0.6]), noise=0.001, gripper=G,
                            quality=db.quality, cfg=PlannerConfig(hidden_depth=True))
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.020]
    block = Box(0.030, 0.150, 0.040)
    assert checks._hidden_axes(block, T) is None
    axes = checks._hidden_axes(block, T, np.array([[0.0, 0.0, 1.0]]))
    assert axes is not None and len(axes) == 1 and abs(axes[0][0]) == pytest.approx(1.0)


def test_an_object_seen_on_one_face_is_taken_as_deep_as_that_face_is_narrow(db):
    """A standing carton seen on its front face alone is fitted as a plate whose depth the view
    did not measure: the object behind the face is taken to be as deep as the face is narrow
    (planner._face_depth, 44 mm here), and the scene planner scores its grasps with that as
    its unseen margin where it is wider than the default. The same carton with its top seen
    (its depth measured), an axis the table bounds, and a part that is not a box keep none."""
    from graspsim.planning.observed import ObservedChecks
    from graspsim.planning.planner import _face_depth, plan
    from graspsim.primitives import Cylinder

    rng = np.random.default_rng(5)
    front = _carton(rng, top=False)
    plate = Box(0.004, 0.044, 0.118)
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # the plate's x (its thickness) along y, the line of sight
    T[:3, 3] = [0.0, -0.022 + 0.002, 0.066]

    def checks(pts):
        return ObservedChecks(pts, None, np.eye(4), viewpoint=EYE, noise=0.001, gripper=G, quality=None,
                              cfg=PlannerConfig(hidden_depth=True))

    assert _face_depth([plate], [T], [None], checks(front)) == pytest.approx(0.044)
    assert _face_depth([plate], [T], [np.array([[0.0, 1.0, 0.0]])], checks(front)) == 0.0  # the table bounds it
    whole = Box(0.044, 0.044, 0.118)
    Tw = np.eye(4)
    Tw[:3, 3] = [0.0, 0.0, 0.066]
    assert _face_depth([whole], [Tw], [None], checks(_carton(rng))) == 0.0  # its top seen: the depth measured
    assert _face_depth([Cylinder(0.02, 0.1)], [Tw], [None], checks(front)) == 0.0

    # through the scene planner: the plan's robust settings carry the object's margin
    scene = SceneConfig().planner
    rng = np.random.default_rng(5)
    front = _carton(rng, top=False)
    ray = (front - EYE) / np.linalg.norm(front - EYE, axis=1, keepdims=True)
    noisy = front + ray * rng.normal(0, 0.001, (len(front), 1))  # depth noise along the line of sight
    got = plan(noisy, db=db, rng=np.random.default_rng(0), config=scene, viewpoint=EYE)
    margin = got.map.meta.extra["observed"]["unseen_margin"]
    assert margin > scene.robust.unseen_margin and margin == pytest.approx(0.044, abs=0.003)
    top = _carton(rng)  # its top seen too: the depth measured, the settings' margin
    got = plan(top + rng.normal(0, 0.0005, top.shape), db=db, rng=np.random.default_rng(0), config=scene, viewpoint=EYE)
    assert got.map.meta.extra["observed"]["unseen_margin"] == scene.robust.unseen_margin
