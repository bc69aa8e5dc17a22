"""The fuzz suite's CI run, in one module so that every property runs in one process
(a parallel run sends a whole file to one worker) and the count at its end sees them all:
the Python API (clouds, cloud files, dimensions and budgets, map files); the command line
in-process (cloud files, corrupted maps, output paths, option values, database content);
the commands and API added since issue 13 (issue 35: plan-scene, scene, view,
adapt-gripper, design, trial --mesh, db check, --gripper SPEC.json, plan_scene,
read_depth_image, adapt_to_gripper); worst cases for memory, in a child process capped at
4 GiB of address space, each command's own peak resident memory measured (VmHWM reset
before it); last, how many generated inputs the suite ran."""

import shutil

import numpy as np
import pytest

from graspsim.primitives import Cylinder

from .assets import FAST_FLAGS, _cloud, assets
from .harness import COUNTS, run_capped
from .props_memory import ADDRESS_SPACE, BUDGET, _pcd, check_capped_results
from .registry import all_properties, ci_test

pytestmark = pytest.mark.slow

#: The suite's size: generated bad or extreme inputs per CI run (issue 13: at least 500).
MIN_INPUTS = 500

# the Python API
test_cloud_arrays = ci_test("cloud_arrays")
test_cloud_files = ci_test("cloud_files")
test_primitive_specs = ci_test("primitive_specs")
test_budget_sizes = ci_test("budget_sizes")
test_map_files = ci_test("map_files")

# the command line, in-process
test_cloud_files_cli = ci_test("cloud_files_cli")
test_map_files_cli = ci_test("map_files_cli")
test_output_paths = ci_test("output_paths")
test_options = ci_test("options")
test_database = ci_test("database")
test_input_paths = ci_test("input_paths")

# the commands and API added since issue 13
test_newer_options = ci_test("newer_options")
test_gripper_specs = ci_test("gripper_specs")
test_depth_images = ci_test("depth_images")
test_scene_api = ci_test("scene_api")
test_regrip_api = ci_test("regrip_api")

# memory
test_memory_capped = ci_test("memory_capped")


def test_worst_cases_stay_within_memory(request, capsys):
    """The known worst cases: a map filling its budget, refusals of a 10 m plate, of a
    familiar object 2.75 times its stored map and of a file claiming 10^10 grasps or
    10^9 points, a 10^6-point cloud, identification at the repetition cap."""
    a = assets()
    folder = a.fresh()
    try:
        np.save(folder / "big.npy", _cloud(Cylinder(0.055, 0.55), 4))
        from .corrupt import apply
        from .props_memory import _cloud as cylinder_points

        million = cylinder_points(folder, "million.npy", 10**6, 1.0, 0)
        dense = cylinder_points(folder, "dense.npy", 5000, 1.0, 1)  # memory: per block of hypotheses
        rows = apply(a.hand_map, folder / "rows.h5", [("huge_rows", 10**10)])
        budget = {"GRASPSIM_MEMORY_BUDGET": BUDGET}
        jobs = [
            {"argv": ["map", "sphere", "--radius", "0.01", "-o", folder / "warm.h5", *FAST_FLAGS]},  # kernels
            {"argv": ["map", "sphere", "--radius", "0.022", "-o", folder / "edge.h5"], "env": budget,
             "budget": BUDGET},
            {"argv": ["map", "box", "--x", "10", "--y", "10", "--z", "0.05", "-o", folder / "plate.h5"],
             "env": budget, "budget": BUDGET},
            {"argv": ["adapt", folder / "big.npy", "-o", folder / "big.h5", "--db",
                      shutil.copytree(a.db, folder / "db"), *FAST_FLAGS], "env": budget, "budget": BUDGET},
            {"argv": ["identify", million, "--json"]},
            {"argv": ["identify", dense, "--repetitions", "1000", "--json"]},
            {"argv": ["info", rows]},
            {"argv": ["identify", _pcd(folder / "claim.pcd", 10**9, "binary_compressed")]},
        ]
        jobs = [{**j, "argv": [str(x) for x in j["argv"]], "seconds": 240} for j in jobs]
        results = run_capped(jobs, address_space=ADDRESS_SPACE, timeout=1200, cwd=folder)
        check_capped_results(jobs, results)
        if request.config.get_verbosity() > 0:  # -q's dots stay one line
            with capsys.disabled():
                for r in results:
                    print(f"\n  [{r.code}] {' '.join(r.argv[:2])} ... peak {r.peak_rss / 2**20:.0f} MiB, grew "
                          f"{r.growth / 2**20:.0f} MiB, {r.seconds:.1f} s", end="")
        codes = [r.code for r in results]
        assert codes[:2] == [0, 0], [r.err for r in results[:2]]  # the map within its budget is made
        assert codes[2:4] == [2, 2] and "budget" in results[2].err and "budget" in results[3].err
        assert codes[4:6] == [0, 0] and codes[6:] == [2, 2]
        assert results[1].growth > 0.3 * (256 << 20)  # the edge case does fill a good part of its budget
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_generated_input_count(request, capsys):
    """The suite's size; the count by category is printed with ``-v`` (``-q``'s dots stay
    one line) and is in the test's report either way (``record_property``)."""
    expected = {p.category for p in all_properties().values()}
    if not expected <= set(COUNTS):
        pytest.skip("part of the fuzz suite was deselected: nothing to count")
    request.node.user_properties += sorted(COUNTS.items())
    if request.config.get_verbosity() > 0:
        with capsys.disabled():
            print("\n  fuzz inputs by category:")
            for k, v in sorted(COUNTS.items()):
                print(f"    {v:5d}  {k}")
            print(f"    {sum(COUNTS.values()):5d}  in all")
    assert sum(COUNTS.values()) >= MIN_INPUTS, dict(COUNTS)
