"""Compiled map kernels: one specialisation each, the first-run compile notice, the
on-disk cache, and the thread runner."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from graspsim.maps import kernels as K
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Cylinder

COARSE = MapConfig(surface_step=0.02, rotation_step=np.radians(30), depth_step=0.02)


def test_each_kernel_has_exactly_its_declared_signature_and_compiles_no_other():
    generate_fs_map(Cylinder(0.02, 0.06), config=COARSE, threads=2)
    k = K.kernels()
    for name in k.SIGNATURES:
        assert len(getattr(k, name).signatures) == 1, name
    f4, f8 = np.float32, np.float64
    args = [np.zeros((1, 1, 1), np.uint8), *[np.zeros((1, 3), f8)] * 4, np.ones(1, f8),
            np.zeros(1, f8), np.zeros(1, f4),  # <- tcp in float32: a valid but other type
            np.zeros(2, np.int64), np.zeros((1, 3), f4), np.zeros((1, 2, 2, 3), f4),
            np.zeros((1, 6), f4), np.zeros((0, 3), f4), np.zeros((0, 4), f4), np.zeros((0, 3), f4),
            np.zeros((0, 2, 3), f4), np.zeros((0, 2, 3), f4), np.zeros((6, 0), f4), 0, 1]
    with pytest.raises(TypeError, match="No matching definition"):  # refused, not compiled
        k.assemble_rows(*args)
    args[7] = args[7].astype(f8)
    k.assemble_rows(*args)


@pytest.mark.parametrize("threads, parts", [(1, None), (3, None), (2, 7), (4, 2)])
def test_run_chunks_covers_each_index_once_and_reports_progress(threads, parts):
    n = 23
    hits = np.zeros(n, int)
    names, fractions = set(), []
    lock = threading.Lock()

    def fn(lo, hi):
        with lock:
            hits[lo:hi] += 1
            names.add(threading.current_thread().name)

    K.run_chunks(fn, n, threads, parts=parts, progress=fractions.append)
    assert np.all(hits == 1)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert len(fractions) == (parts or threads)
    if threads > 1 and (parts or threads) > 1:
        assert all(t.startswith("graspsim-kernel") for t in names)


def test_run_chunks_passes_kernel_errors_on():
    def fn(lo, hi):
        raise ValueError(f"bad range {lo}")

    with pytest.raises(ValueError, match="bad range"):
        K.run_chunks(fn, 10, 2)


def test_default_threads_clamps_to_numba_threads():
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    assert K.default_threads() == top
    assert K.default_threads(0) == 1 and K.default_threads(10 * top) == top


@pytest.mark.slow
def test_cold_cache_compiles_once_and_says_so(tmp_path):
    """A fresh cache folder: the CLI prints the notice and per-kernel progress; a second
    process loads every kernel (compile_all) from the cache silently."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    cli = "import sys; from graspsim.cli import main; sys.exit(main(['warmup', '--json']))"
    first = subprocess.run([sys.executable, "-c", cli], env=env, capture_output=True, text=True,
                           timeout=600)
    assert first.returncode == 0, first.stderr
    assert "graspsim: compiling map kernels (first run only" in first.stderr
    assert "[5/5]" in first.stderr and '"compiled": true' in first.stdout
    assert "compiled the planning kernels" in first.stderr  # the rest too, saying so
    assert any(tmp_path.rglob("*.nbi"))
    code = ("from graspsim.maps.kernels import cache_dir\nfrom graspsim.maps.warmup import compile_all\n"
            "print(compile_all(), cache_dir())")
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                            timeout=600)
    assert second.returncode == 0, second.stderr
    assert second.stdout.split()[0] == "False" and second.stdout.split()[1].startswith(str(tmp_path))
    assert "compiling" not in second.stderr and "compiled" not in second.stderr


_LIST = ("from graspsim.maps.warmup import compiled_kernels\n"
         "print(json.dumps({k: sorted(str(s) for s in v.signatures) for k, v in compiled_kernels().items()}))\n")
_PLAN_A_SCENE = """
import json, math, sys
import numpy as np
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.planning.scene_config import SceneConfig
from graspsim.planning.scene import plan_scene
from graspsim.primitives import Box, Sphere
from graspsim.primitives.clouds import table_scene_cloud
db = MapDatabase(sys.argv[1], config=MapConfig(surface_step=0.008, rotation_step=math.radians(22)))
db.build([Box(0.05, 0.05, 0.05), Sphere(0.03)])
shapes = [Box(0.05, 0.06, 0.07), Sphere(0.03)]
pts = table_scene_cloud(shapes, np.array([[-0.05, 0.0], [0.05, 0.0]]), np.random.default_rng(0), noise=0.0005)[0]
sp = plan_scene(pts, db=db, rng=np.random.default_rng(1), config=SceneConfig(workers=1),
                viewpoint=np.array([0.0, -0.4, 0.5]))
assert sum(s.status == "planned" for s in sp.segments) == 2, sp.segments
from graspsim.maps.feature_grasps import feature_columns  # a segment whose parts give too few grasps (a bowl)
feature_columns(pts[pts[:, 2] > 0.01], db.gripper, db.quality, gap=0.006, up=sp.table.normal)
""" + _LIST
_COMPILE_ALL = "import json\nfrom graspsim.maps.warmup import compile_all\ncompile_all()\n" + _LIST


def _signatures(code: str, *args) -> dict:
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    return {k: set(v) for k, v in json.loads(out.stdout.strip().splitlines()[-1]).items()}


@pytest.mark.slow
def test_compile_all_compiles_every_kernel_for_the_types_a_scene_plan_passes(tmp_path):
    """``graspsim warmup`` (compile_all) leaves nothing for a machine's first scene plan
    to compile: every kernel signature planning a scene uses, identification, robust
    scores against the neighbours and their occlusion term, collision samples, the
    pad-contact grade and the feature grasps' chords, is one compile_all compiles."""
    planned = _signatures(_PLAN_A_SCENE, str(tmp_path / "db"))
    warmed = _signatures(_COMPILE_ALL)
    for name in ("maps._robust_kernel.robust_flags", "primitives.sdf_kernel.model_sdf_into",
                 "maps._hierarchy_kernel.regroup", "maps._hierarchy_kernel.cluster_tree",
                 "maps._occlusion_kernel.occluded_fraction", "maps._feature_kernel.seed_chords",
                 "grippers.between_kernel.count_between"):
        assert planned[f"graspsim.{name}"], name  # the plan did use them
    assert any(planned[f"graspsim.grades.pad_kernel.{k}"] for k in ("pad_patches", "pad_patches_serial"))
    missing = {k: sorted(v - warmed[k]) for k, v in planned.items() if v - warmed[k]}
    assert not missing
