"""The BLAS kernels pinned (graspsim._blas): importing graspsim before numpy sets
``OPENBLAS_CORETYPE`` on an x86-64 Linux CPU with AVX2 and FMA, leaves a user's own choice
and a process that loaded numpy first alone, and the kernels that ran are readable (the
experiments record them). Each case runs in a fresh interpreter: OpenBLAS reads the
variable once, when it loads."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest

from graspsim._blas import PINNED_CORE, _cpu_flags, pin_blas

PINNABLE = (sys.platform.startswith("linux") and platform.machine().lower() in ("x86_64", "amd64")
            and {"avx2", "fma"} <= _cpu_flags())


def _fresh(code: str, **env: str) -> dict:
    base = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**base, **env})
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


REPORT = ("import json, os\nfrom graspsim._blas import blas_cores\n"
          "print(json.dumps({'env': os.environ.get('OPENBLAS_CORETYPE'), 'cores': blas_cores()}))")


@pytest.mark.skipif(not PINNABLE, reason="the pin applies to x86-64 Linux CPUs with AVX2 and FMA")
def test_importing_graspsim_first_pins_the_kernels_that_run():
    got = _fresh("import graspsim\n" + REPORT)
    assert got["env"] == PINNED_CORE
    assert got["cores"] and set(got["cores"].values()) == {PINNED_CORE}  # numpy's OpenBLAS runs them


@pytest.mark.skipif(not PINNABLE, reason="OpenBLAS's kernel names are read on x86-64 Linux")
def test_a_users_choice_and_numpy_loaded_first_are_left_alone():
    mine = _fresh("import graspsim\n" + REPORT, OPENBLAS_CORETYPE="Sandybridge")
    assert mine["env"] == "Sandybridge" and set(mine["cores"].values()) == {"Sandybridge"}
    late = _fresh("import numpy\nimport graspsim\n" + REPORT)
    assert late["env"] is None  # too late to pin: OpenBLAS chose already, and the record says what it chose
    assert late["cores"]


def test_pin_blas_does_nothing_once_numpy_is_loaded():
    import numpy  # noqa: F401

    before = os.environ.get("OPENBLAS_CORETYPE")
    assert pin_blas() is None
    assert os.environ.get("OPENBLAS_CORETYPE") == before


def test_experiment_records_carry_the_blas_kernels():
    from graspsim.calibration.outputs import library_versions

    rec = library_versions()
    assert isinstance(rec["blas"], dict)
    if PINNABLE:
        assert rec["blas"]  # a Linux x86-64 numpy wheel's OpenBLAS names its kernels
