"""Fuzz: worst cases for memory, in a child process capped at 4 GiB of address space,
each command's own peak resident memory measured (VmHWM reset before it)."""

import shutil

import numpy as np
import pytest

from graspsim.primitives import Cylinder

from .assets import FAST_FLAGS, _cloud, assets
from .harness import run_capped
from .props_memory import ADDRESS_SPACE, BUDGET, _pcd, check_capped_results
from .registry import ci_test

pytestmark = pytest.mark.slow

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
