"""Fuzz: the command line in-process (cloud files, corrupted maps, output paths,
option values, database content)."""

import pytest

from .registry import ci_test

pytestmark = pytest.mark.slow

test_cloud_files_cli = ci_test("cloud_files_cli")
test_map_files_cli = ci_test("map_files_cli")
test_output_paths = ci_test("output_paths")
test_options = ci_test("options")
test_database = ci_test("database")
test_input_paths = ci_test("input_paths")
