"""Fuzz: the Python API (clouds, cloud files, dimensions and budgets, map files)."""

import pytest

from .registry import ci_test

pytestmark = pytest.mark.slow

test_cloud_arrays = ci_test("cloud_arrays")
test_cloud_files = ci_test("cloud_files")
test_primitive_specs = ci_test("primitive_specs")
test_budget_sizes = ci_test("budget_sizes")
test_map_files = ci_test("map_files")
