import math

import numpy as np
import pytest

from graspsim.errors import GripperError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec


def test_defaults_follow_the_type_code():
    g = HGPL_25_60_A
    assert g.stroke_per_jaw == pytest.approx(0.060)
    assert g.max_opening == pytest.approx(0.120)
    assert g.bore == pytest.approx(0.025)
    # 0.85 * 6 bar * pi * (12.5 mm)^2 = 250 N per jaw
    assert g.grip_force == pytest.approx(0.85 * 6e5 * math.pi * 0.0125**2)
    assert 200 < g.grip_force < 300


def test_tcp_lies_on_the_pad_at_the_contact_depth():
    g = HGPL_25_60_A
    depths = g.contact_depths(0.005)
    assert depths[0] == pytest.approx(g.contact_depth_margin)
    assert depths[-1] <= g.pad_length - g.contact_depth_margin + 1e-12
    assert g.tcp_offset(depths[0]) == pytest.approx(g.fingertip_z - depths[0])
    assert g.nominal_tcp == pytest.approx([0, 0, g.fingertip_z - 0.5 * g.pad_length])


def test_wrist_and_grasp_point_round_trip():
    g = HGPL_25_60_A
    rng = np.random.default_rng(0)
    gp = rng.normal(size=(5, 3))
    z = rng.normal(size=(5, 3))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    depth = rng.uniform(0.005, 0.035, 5)
    wrist = g.wrist_from_grasp_point(gp, z, depth)
    # the grasp point sits tcp_offset(depth) along the approach from the wrist
    assert np.linalg.norm(gp - wrist, axis=1) == pytest.approx(g.fingertip_z - depth)
    assert g.contact_depth(gp, wrist, z) == pytest.approx(depth)
    assert g.grasp_point_from_wrist(wrist, z, depth) == pytest.approx(gp)
    assert g.wrist_from_grasp_point(gp, z, 0.01) == pytest.approx(gp - (g.fingertip_z - 0.01) * z)


def test_boxes_open_symmetrically_and_touch_the_pads():
    g = HGPL_25_60_A
    c, h = g.boxes_at(0.05)
    names = g.collision_boxes().names
    fpos = names.index("finger_pos")
    fneg = names.index("finger_neg")
    assert c[fpos, 0] - h[fpos, 0] == pytest.approx(0.025)
    assert c[fneg, 0] + h[fneg, 0] == pytest.approx(-0.025)
    assert c[fpos, 2] + h[fpos, 2] == pytest.approx(g.fingertip_z)
    with pytest.raises(GripperError):
        g.boxes_at(0.2)


def test_json_round_trip():
    g = GripperSpec(pressure=4e5, finger_size=(0.01, 0.025, 0.07))
    assert GripperSpec.from_json(g.to_json()) == g


@pytest.mark.parametrize(
    "kwargs",
    [
        {"stroke_per_jaw": 0},
        {"pressure": -1},
        {"finger_size": (0.01, 0.02)},
        {"pad_length": 0.5},
        {"efficiency": 1.5},
        {"housing_size": (0.05, 0.05, 0.06)},
        {"contact_depth_margin": 0.03},
        {"bore": float("nan")},
    ],
)
def test_inconsistent_specs_raise(kwargs):
    with pytest.raises(GripperError):
        GripperSpec(**kwargs)


def test_unknown_parameter_names_are_reported():
    with pytest.raises(GripperError, match="valid"):
        GripperSpec.from_dict({"nope": 1})


def test_lowest_point_of_a_top_down_gripper():
    g = HGPL_25_60_A
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach straight down
    T[2, 3] = 0.3
    assert g.lowest_point(T[None], [0.05])[0] == pytest.approx(0.3 - g.fingertip_z)
    T2 = np.eye(4)  # approach straight up from below: the arm hangs under the wrist
    assert g.lowest_point(T2[None], [0.05])[0] == pytest.approx(-g.arm_length)
