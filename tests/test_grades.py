"""Grade models and their features: flat-pad contact geometry, the shipped model, regrading."""

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.grades import (
    FEATURES,
    LogisticGrade,
    PaperGrade,
    get_grade,
    grasp_features,
    object_context,
    regrade,
    resting_frame,
)
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Cylinder, Sphere

COARSE = MapConfig(surface_step=0.012, rotation_step=math.radians(30.0), closing_cone=math.radians(30.0))


def _grasp(p1, p2, n1, n2, approach, depth=0.02):
    """One grasp: contacts, normals (1, 2, 3) and the wrist pose (x = closing axis,
    z = approach) with the contacts ``depth`` from the fingertip."""
    p1, p2 = np.asarray(p1, float), np.asarray(p2, float)
    x = (p2 - p1) / np.linalg.norm(p2 - p1)
    z = np.asarray(approach, float)
    z = z - (z @ x) * x
    z /= np.linalg.norm(z)
    R = np.column_stack([x, np.cross(z, x), z])
    wrist = 0.5 * (p1 + p2) - (G.fingertip_z - depth) * z
    return (np.array([[p1, p2]]), np.array([[n1, n2]], float), R[None], wrist[None])


def _features(shape, *grasp):
    return grasp_features(object_context(shape), G, *grasp)


def test_centred_box_side_grasp_lies_flat_on_both_pads():
    f = _features(Box(0.06, 0.06, 0.06),
                  *_grasp([-0.03, 0, 0], [0.03, 0, 0], [-1, 0, 0], [1, 0, 0], [0, 0, -1]))
    assert f["alpha"][0] == pytest.approx(0.0, abs=1e-9)
    assert f["pad_normal_angle"][0] == pytest.approx(0.0, abs=1e-6)
    assert f["pad_residual_angle"][0] == pytest.approx(0.0, abs=1e-6)
    assert f["place_tilt_ratio"][0] == pytest.approx(0.0, abs=1e-6)
    assert f["pad_edge_margin"][0] > 0.002  # the face covers the finger, not just its edge
    assert set(f) == set(FEATURES)


def test_off_centre_sphere_is_wedged_by_the_pad_edges():
    r, y = 0.035, 0.02  # chord 2 cm off the centre: the centre is outside the 2 cm pad
    x = math.sqrt(r * r - y * y)
    f = _features(Sphere(r), *_grasp([-x, y, 0], [x, y, 0], [-x / r, y / r, 0], [x / r, y / r, 0],
                                     [0, 0, -1]))
    # the pads touch the sphere at their side edge, 1 cm off the centre line
    assert f["pad_residual_angle"][0] == pytest.approx(math.asin(0.01 / r), abs=0.05)
    assert f["alpha"][0] == pytest.approx(math.asin(y / r), abs=1e-9)


def test_tilted_cylinder_grasp_turns_it_over_its_tipping_angle():
    cyl = Cylinder(0.02, 0.20)
    a = math.radians(11.0)
    u = np.array([math.cos(a), 0.0, math.sin(a)])
    t = 0.02 / math.cos(a)
    f = _features(cyl, *_grasp(-t * u, t * u, [-1, 0, 0], [1, 0, 0], [0, 1, 0]))
    assert f["pad_residual_angle"][0] < 0.05  # both pads want the same turn: it can make it
    assert f["place_tilt_ratio"][0] == pytest.approx(a / math.atan(0.02 / 0.10), rel=0.25)
    level = _features(cyl, *_grasp([-0.02, 0, 0], [0.02, 0, 0], [-1, 0, 0], [1, 0, 0], [0, 1, 0]))
    assert level["place_tilt_ratio"][0] < 0.05


def test_resting_frame_tipping_angles():
    up, tip = resting_frame(Cylinder(0.02, 0.20))
    np.testing.assert_allclose(up, [0, 0, 1])
    assert math.degrees(tip) == pytest.approx(math.degrees(math.atan(0.2)), abs=0.2)
    assert math.degrees(resting_frame(Box(0.06, 0.06, 0.06))[1]) == pytest.approx(45.0, abs=0.1)


def test_shipped_model_loads_with_provenance():
    m = get_grade("pad_contact")
    assert isinstance(m, LogisticGrade) and m.name == "pad_contact"
    assert set(m.features) <= set(FEATURES) and 0.0 < m.threshold < 1.0
    for k in ("script", "seed", "mujoco_version", "objects", "cv_auc"):
        assert k in m.provenance
    again = LogisticGrade.from_dict(m.to_dict())
    assert again == m


def test_pad_grade_prefers_grasps_that_lie_flat():
    m = get_grade("pad_contact")
    cyl = Cylinder(0.02, 0.20)
    a = math.radians(22.0)
    u = np.array([math.cos(a), 0.0, math.sin(a)])
    t = 0.02 / math.cos(a)
    tilted = m.score(_features(cyl, *_grasp(-t * u, t * u, [-1, 0, 0], [1, 0, 0], [0, 1, 0])))
    level = m.score(_features(cyl, *_grasp([-0.02, 0, 0], [0.02, 0, 0], [-1, 0, 0], [1, 0, 0], [0, 1, 0])))
    assert level[0] > m.threshold > tilted[0]


def test_regrade_records_the_grade_and_paper_grade_round_trips(tmp_path):
    fs = generate_fs_map(Box(0.05, 0.05, 0.08), config=COARSE, threads=1)
    pad = regrade(fs, get_grade("pad_contact"))
    assert pad.meta.quality["name"] == "pad_contact"
    assert pad.threshold == pytest.approx(get_grade("pad_contact").threshold)
    assert pad.meta.quality["base_quality"]["name"] == "paper"
    assert np.all((pad.grade >= 0) & (pad.grade <= 1))
    np.testing.assert_array_equal(pad.contacts, fs.contacts)
    np.testing.assert_array_equal(pad.q_fc, fs.q_fc)
    back = regrade(pad, PaperGrade())
    assert back.meta.quality["name"] == "paper"
    np.testing.assert_allclose(back.grade, fs.grade, atol=1e-6)
    model_file = tmp_path / "m.json"
    get_grade("pad_contact").save(model_file)
    np.testing.assert_allclose(get_grade(model_file).grade_rows(fs, np.arange(50)), pad.grade[:50],
                               atol=1e-6)


def test_generate_fs_map_grade_hook_keeps_the_paper_grade_by_default():
    shape = Box(0.05, 0.05, 0.08)
    plain = generate_fs_map(shape, config=COARSE, threads=1)
    again = generate_fs_map(shape, config=COARSE, threads=1, grade=None)
    np.testing.assert_array_equal(plain.grade, again.grade)
    assert plain.meta.quality["name"] == "paper"
    pad = generate_fs_map(shape, config=COARSE, threads=1, grade=get_grade("pad_contact"))
    assert pad.meta.quality["name"] == "pad_contact" and "grade" in pad.meta.timing
    np.testing.assert_array_equal(pad.wrist_position, plain.wrist_position)
    np.testing.assert_allclose(pad.grade, regrade(plain, get_grade("pad_contact")).grade, atol=1e-7)


def test_bad_grade_specs_are_rejected():
    with pytest.raises(InvalidParameterError, match="unknown grade"):
        get_grade("best")
    m = get_grade("pad_contact").to_dict()
    with pytest.raises(InvalidParameterError, match="unknown grade features"):
        LogisticGrade.from_dict({**m, "features": ["alpha"] * (len(m["features"]) - 1) + ["luck"]})
    with pytest.raises(InvalidParameterError, match="one mean, scale and coef"):
        LogisticGrade.from_dict({**m, "coef": m["coef"][:-1]})
    with pytest.raises(InvalidParameterError, match="primitive or compound"):
        object_context({"primitive": "mesh", "file": "x.obj"})
