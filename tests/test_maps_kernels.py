"""Compiled map kernels: one specialisation each, the first-run compile notice, the
on-disk cache, and the thread runner."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from graspsim.maps import kernels as K
from graspsim.maps.generate import MapConfig, generate_fs_map
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
    process loads from the cache silently."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    cli = "import sys; from graspsim.cli import main; sys.exit(main(['warmup', '--json']))"
    first = subprocess.run([sys.executable, "-c", cli], env=env, capture_output=True, text=True,
                           timeout=600)
    assert first.returncode == 0, first.stderr
    assert "graspsim: compiling map kernels (first run only" in first.stderr
    assert "[5/5]" in first.stderr and '"compiled": true' in first.stdout
    assert any(tmp_path.rglob("*.nbi"))
    code = ("from graspsim.maps.kernels import ensure_compiled, cache_dir\n"
            "print(ensure_compiled(), cache_dir())")
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                            timeout=600)
    assert second.returncode == 0, second.stderr
    assert second.stdout.split()[0] == "False" and second.stdout.split()[1].startswith(str(tmp_path))
    assert "compiling" not in second.stderr
