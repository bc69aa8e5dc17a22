"""The gripper registry and the Franka hand's spec measured from its vendored model."""

import json
import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from graspsim.errors import GripperError
from graspsim.grippers import get_gripper, gripper_names, model_folder, mount
from graspsim.grippers.franka import hand_to_wrist, hull_points
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec

FRANKA = model_folder("franka_hand")
TOL = 1.5e-4  # [m] the finger mesh's inner face lies 0.1 mm past its joint's zero


def _surface(p: np.ndarray, n: int = 4000) -> np.ndarray:
    """The hull's vertices and ``n`` seeded samples on its faces (the union of boxes is not
    convex: enclosing the vertices alone would not enclose the hull)."""
    hull = ConvexHull(p)
    rng = np.random.default_rng(18)
    tri = p[hull.simplices[rng.integers(len(hull.simplices), size=n)]]
    w = rng.dirichlet(np.ones(3), size=n)
    return np.concatenate([p[hull.vertices], np.einsum("nk,nkj->nj", w, tri)])


def _franka_hulls(opening: float) -> dict[str, np.ndarray]:
    """Collision hull vertices of the vendored hand at a pad gap, in the wrist frame."""
    m = mujoco.MjModel.from_xml_path(str(FRANKA / "franka_hand.xml"))
    d = mujoco.MjData(m)
    d.qpos[:] = 0.5 * opening
    mujoco.mj_kinematics(m, d)
    z0 = -mount("franka_hand").pos[2]
    return {g: hand_to_wrist(hull_points(m, d, g), z0)
            for g in ("hand_collision", "left_finger_collision", "right_finger_collision")}


@pytest.mark.parametrize("opening", [0.0, 0.013, 0.04, 0.0799, 0.08])
def test_franka_spec_boxes_enclose_the_collision_hulls_at_every_opening(opening):
    g = get_gripper("franka_hand")
    c, h = g.boxes_at(opening)
    for geom, p in _franka_hulls(opening).items():
        p = _surface(p)
        inside = np.all(np.abs(p[:, None, :] - c[None]) <= h[None] + TOL, axis=-1).any(axis=1)
        assert inside.all(), (geom, p[~inside])


def test_franka_spec_is_tight_pads_at_the_gap_and_tips_at_the_fingertip():
    g = get_gripper("franka_hand")
    for opening in (0.0, 0.05):
        hulls = _franka_hulls(opening)
        for geom, sign in (("left_finger_collision", 1), ("right_finger_collision", -1)):
            x = sign * hulls[geom][:, 0]  # distance from the closing axis, outwards
            assert x.min() == pytest.approx(opening / 2, abs=TOL)
            pad = hulls[geom][x <= x.min() + 2.5e-4]
            # the flat pad is the finger box's inner face, from (about) the tip up by pad_length
            assert pad[:, 2].max() == pytest.approx(g.fingertip_z, abs=5e-4)
            assert pad[:, 2].min() == pytest.approx(g.fingertip_z - g.pad_length, abs=2e-5)
        every = np.concatenate(list(hulls.values()))
        c, h = g.boxes_at(opening)
        lo, hi = (c - h).min(axis=0), (c + h).max(axis=0)
        # the boxes (centred on the axis) reach no further than the hulls (arm keep-out aside)
        reach = np.maximum(np.abs(every.min(axis=0)), np.abs(every.max(axis=0)))
        assert np.allclose(reach[:2], np.maximum(np.abs(lo), np.abs(hi))[:2], atol=1e-4)
        assert every[:, 2].max() == pytest.approx(hi[2], abs=1e-4)
        assert every[:, 2].min() == pytest.approx(0.0, abs=1e-4)


def test_franka_stroke_force_and_speed_come_from_the_model():
    urdf = ET.parse(FRANKA / "hand.urdf").getroot()
    for j in urdf.iter("joint"):
        if j.get("type") == "prismatic":
            lim = j.find("limit")
            assert (float(lim.get("lower")), float(lim.get("upper"))) == (0.0, 0.04)
    g = get_gripper("franka_hand")
    assert g.stroke_per_jaw == pytest.approx(0.04) and g.closed_gap == 0.0
    assert (g.min_opening, g.max_opening) == (0.0, pytest.approx(0.08))
    assert g.grip_force == 70.0 and g.closing_speed == pytest.approx(0.2)  # URDF velocity limit
    assert g.model == "franka_hand"


def test_registry_names_files_and_specs(tmp_path):
    assert set(gripper_names()) == {"festo_hgpl_25_60_a", "franka_hand", "robotiq_2f85", "rethink_gripper"}
    assert get_gripper("festo_hgpl_25_60_a") is HGPL_25_60_A and get_gripper(None) is HGPL_25_60_A
    custom = GripperSpec(name="my_gripper", finger_size=(0.008, 0.02, 0.06), stroke_per_jaw=0.03)
    path = tmp_path / "my.json"
    path.write_text(custom.to_json())
    assert get_gripper(str(path)) == custom and get_gripper(path) == custom
    assert get_gripper(custom) is custom
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({"name": "short", "stroke_per_jaw": 0.02}))
    assert get_gripper(partial).max_opening == pytest.approx(0.04)


@pytest.mark.parametrize("text, match", [
    ("{not json", "not valid JSON"),
    ('{"name": "x", "finger_size": [0.01, 0.02]}', "finger_size"),
    ('{"name": "x", "stroke_per_jaw": [1]}', "stroke_per_jaw"),
    ('{"name": "x", "colour": "red"}', "unknown gripper parameters"),
    ('[1, 2]', "must be a dict"),
    ('{"name": "x", "rated_force": -3}', "rated_force"),
    ('{"name": "x", "model": "../etc"}', "model"),
])
def test_bad_spec_files_are_one_line_errors(tmp_path, text, match):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(GripperError, match=match) as err:
        get_gripper(str(path))
    assert "\n" not in str(err.value) and "bad.json" in str(err.value)


def test_unknown_names_and_missing_files_are_errors(tmp_path):
    with pytest.raises(GripperError, match="unknown gripper 'robotiq'"):
        get_gripper("robotiq")
    with pytest.raises(GripperError, match="cannot read"):
        get_gripper(str(tmp_path / "missing.json"))
    with pytest.raises(GripperError, match="no gripper model 'robotiq_2f140'"):
        mount("robotiq_2f140")
    for odd in ("a\0b.json", str(tmp_path)):  # a NUL byte, a folder
        with pytest.raises(GripperError):
            get_gripper(odd)
    huge = tmp_path / "huge.json"
    with huge.open("wb") as f:
        f.truncate(2 << 20)  # sparse: refused by its size, never read
    with pytest.raises(GripperError, match="a small JSON file"):
        get_gripper(huge)


def test_optional_fields_leave_the_default_spec_and_its_digest_unchanged():
    d = HGPL_25_60_A.to_dict()
    assert "rated_force" not in d and "model" not in d
    assert HGPL_25_60_A.grip_force == pytest.approx(0.85 * 6e5 * math.pi * 0.025**2 / 4)
    franka = get_gripper("franka_hand")
    assert GripperSpec.from_dict(franka.to_dict()) == franka
    assert GripperSpec.from_json(franka.to_json()).rated_force == 70.0
