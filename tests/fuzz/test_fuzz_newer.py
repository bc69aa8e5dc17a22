"""Fuzz: the commands and API added since issue 13 (issue 35): plan-scene, scene, view,
adapt-gripper, design, trial --mesh, db check, --gripper SPEC.json, plan_scene,
read_depth_image, adapt_to_gripper."""

import pytest

from .registry import ci_test

pytestmark = pytest.mark.slow

test_newer_options = ci_test("newer_options")
test_gripper_specs = ci_test("gripper_specs")
test_depth_images = ci_test("depth_images")
test_scene_api = ci_test("scene_api")
test_regrip_api = ci_test("regrip_api")
