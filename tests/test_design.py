"""Gripper design analysis: design variants, one sweep's numbers, the gripper argument."""

import math
from dataclasses import replace

import pytest

from graspsim.apps.design import PARAMS, DesignConfig, evaluate, param_value, resolve_design, sweep, vary
from graspsim.errors import GripperError, InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A as A
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Sphere

COARSE = DesignConfig(map_config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)), sim_grasps=0,
                      threads=1)


@pytest.mark.parametrize("param, value", [("finger_length", 0.05), ("pad_length", 0.03), ("stroke", 0.045)])
def test_vary_changes_only_its_parameter(param, value):
    g = vary(A, param, value)
    assert param_value(g, param) == value
    for other in set(PARAMS) - {param}:
        assert param_value(g, other) == param_value(A, other)
    changed = {k for k, v in g.to_dict().items() if v != A.to_dict()[k]}
    assert changed == {"name", {"finger_length": "finger_size", "pad_length": "pad_length",
                                "stroke": "stroke_per_jaw"}[param]}


def test_a_longer_stroke_lengthens_the_housing_just_enough():
    g = vary(A, "stroke", 0.09)
    assert g.housing_size[0] == pytest.approx(2 * (0.09 + A.jaw_size[0]))
    assert g.max_opening == pytest.approx(0.18)
    assert vary(A, "stroke", 0.03).housing_size == A.housing_size  # a shorter one keeps it


def test_bad_designs_are_one_line_errors():
    with pytest.raises(InvalidParameterError, match="unknown design parameter"):
        vary(A, "finger_width", 0.01)
    with pytest.raises(GripperError, match="exceeds the finger length"):
        vary(A, "pad_length", 0.09)
    with pytest.raises(InvalidParameterError, match="metres"):
        resolve_design("stroke=wide", A)
    with pytest.raises(GripperError, match="robotiq_2f140"):
        resolve_design("robotiq_2f140", A)
    assert resolve_design("robotiq_2f85", A).model == "robotiq_2f85"  # a model file gripper is a design too
    assert resolve_design("franka_hand", A).name == "franka_hand"
    assert vary(resolve_design("franka_hand", A), "stroke", 0.03).model is None  # the spec-built model
    assert resolve_design("finger_length=0.05", A) == vary(A, "finger_length", 0.05)


def test_sweep_rows_share_one_voxel_box_and_longer_fingers_reach_more_voxels():
    rows = sweep(A, "finger_length", [0.05, 0.11], {"box": Box(0.06, 0.06, 0.06)}, COARSE)
    assert [r["value"] for r in rows] == [0.05, 0.11]
    assert rows[0]["voxels"] == rows[1]["voxels"]
    assert rows[1]["hit_voxels"] > rows[0]["hit_voxels"] and rows[1]["SR"] == pytest.approx(rows[0]["SR"])
    for r in rows:
        assert r["accepted"] <= r["grasps"] and r["share_accepted"] == pytest.approx(r["accepted"] / r["grasps"])


def test_an_object_wider_than_the_opening_gives_zeros_not_an_error():
    r = evaluate(vary(A, "stroke", 0.02), "ball", Sphere(0.05), COARSE)
    assert (r["grasps"], r["accepted"], r["SR"], r["VR"], r["sim"]["drawn"]) == (0, 0, 0.0, 0.0, 0)


def test_simulated_grasps_are_accepted_and_counted():
    cfg = replace(COARSE, sim_grasps=3)
    r = evaluate(A, "box", Box(0.05, 0.05, 0.05), cfg)
    s = r["sim"]
    assert s["drawn"] == 3 and s["success"] <= s["feasible"] <= 3 and sum(s["counts"].values()) == 3
