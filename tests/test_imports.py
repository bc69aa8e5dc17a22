"""What importing costs: ``import graspsim`` and the CLI's help load no heavy library,
the package face resolves every public name lazily, and the Gymnasium environments are
registered whichever of graspsim and gymnasium is imported first.

(Import times are measured by ``experiments/bench_fsmap.py``, not here: these tests
check which modules load, which does not depend on the machine's load.)
"""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import graspsim
from graspsim.cli import COMMAND_MODULES, build_parser

HEAVY = ("numpy", "scipy", "trimesh", "numba", "h5py", "mujoco", "gymnasium", "matplotlib", "tqdm", "viser")


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout


def _loaded_heavy(statement: str) -> list[str]:
    code = (f"import sys\n{statement}\n"
            f"print('loaded:', *(m for m in {HEAVY!r} if m in sys.modules))")
    return _run(code).strip().splitlines()[-1].split()[1:]


def test_import_graspsim_loads_no_heavy_library():
    assert _loaded_heavy("import graspsim") == []


def test_cli_help_of_every_command_loads_no_heavy_library():
    commands = sorted(build_parser()._subparsers._group_actions[0].choices)  # noqa: SLF001
    assert {"map", "info", "db", "adapt", "trial", "warmup"} <= set(commands)
    stmt = ("import contextlib, io\nfrom graspsim.cli import main\n"
            f"for argv in [['--help']] + [[c, '--help'] for c in {commands!r}]:\n"
            "    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
            "        main(argv)")
    assert _loaded_heavy(stmt) == []


def test_every_public_name_resolves_to_its_defining_object():
    assert len(set(graspsim.__all__)) == len(graspsim.__all__)
    for name in graspsim.__all__:
        value = getattr(graspsim, name)
        module = graspsim._LAZY.get(name)  # noqa: SLF001
        if module is not None:
            assert value is getattr(importlib.import_module(module), name), name
    assert set(graspsim.__all__) <= set(dir(graspsim))
    for name in ("GraspabilityMap", "plan", "plan_shape", "MapDatabase", "generate_fs_map",
                 "MapConfig", "Cylinder", "GripperSpec", "synthetic_cloud", "GraspsimError"):
        assert name in graspsim.__all__
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        graspsim.nonexistent  # noqa: B018


def test_cli_modules_are_importable_and_register():
    for name in COMMAND_MODULES:
        assert callable(importlib.import_module(name).register)


@pytest.mark.parametrize("order", ["graspsim, gymnasium", "gymnasium, graspsim",
                                   "graspsim, gymnasium.envs.registration"])
def test_envs_registered_in_either_import_order_without_mujoco(order):
    code = (f"import sys, {order}\nimport gymnasium\n"
            "assert 'mujoco' not in sys.modules\n"
            "print(sorted(i for i in gymnasium.registry if i.startswith('graspsim/')))")
    assert _run(code).strip() == "['graspsim/ClutterClear-v0', 'graspsim/GraspPose-v0', 'graspsim/GraspSelect-v0']"
