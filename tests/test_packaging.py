"""The installed package carries its data: a wheel built from the source holds the
vendored MuJoCo models (top-level mjcf/) and the mesh objects scenes draw (top-level
assets/) inside the package (graspsim/mjcf, graspsim/assets), licences and attributions
included, and the code finds them where the package is installed (a wheel) or beside it
(a checkout, an editable install), never relative to the working directory."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from importlib import resources
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ("mjcf", "assets")
OFFLINE = ("Could not find a version", "No matching distribution", "Temporary failure in name resolution",
           "Network is unreachable", "Failed to establish a new connection")


def _shipped() -> set[str]:
    """Files under the top-level mjcf/ and assets/ of the source, as wheel names."""
    return {f"graspsim/{p.relative_to(ROOT).as_posix()}" for d in DATA for p in (ROOT / d).rglob("*")
            if p.is_file() and "__pycache__" not in p.parts}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built (pip wheel --no-deps) from a copy of the source (nothing is written
    into the checkout); skips when pip cannot reach the build backend's packages."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    for name in ("graspsim", *DATA):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)],
                       capture_output=True, text=True, timeout=600)
    if r.returncode and any(s in r.stdout + r.stderr for s in OFFLINE):
        pytest.skip("pip cannot fetch setuptools to build the wheel (offline): " + r.stderr.strip()[-200:])
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = out.glob("graspsim-*.whl")
    return whl


def test_every_package_is_listed_for_the_wheel():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "graspsim").rglob("__init__.py")}
    assert listed == found | {f"graspsim.{d}" for d in DATA}


def test_a_checkout_finds_its_data_at_the_top_level():
    from graspsim.grippers import mjcf_root, model_folder
    from graspsim.sim.model_folder import default_folder
    from graspsim.tabletop.scene_objects import ASSETS, MESHES

    pkg = Path(str(resources.files("graspsim")))
    assert pkg == ROOT / "graspsim"  # the tests run on the checkout
    assert mjcf_root() == ROOT / "mjcf" and default_folder().parent == ROOT / "mjcf"
    assert ASSETS == ROOT / "assets" / "objects"
    assert (model_folder("franka_hand") / "LICENSE").is_file()
    assert all((ASSETS / f).is_file() and (ASSETS / f).with_name("LICENSE").is_file() for f, _ in MESHES.values())


@pytest.mark.slow
def test_wheel_holds_the_models_meshes_and_licences(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = _shipped() - names
    assert not missing, f"not in the wheel: {sorted(missing)}"
    for must in ("graspsim/mjcf/franka_hand/LICENSE", "graspsim/mjcf/franka_hand/meshes/collision/hand.obj",
                 "graspsim/mjcf/festo_hgpl_25_60_a/festo_hgpl_25_60_a.xml",
                 "graspsim/assets/objects/robosuite/LICENSE", "graspsim/assets/objects/robosuite/bread.stl"):
        assert must in names
    assert not any("__pycache__" in n for n in names)


@pytest.mark.slow
def test_an_installed_wheel_finds_and_loads_its_models_and_meshes(wheel, tmp_path):
    """Installed into a folder of its own and run from elsewhere: the vendored hand
    compiles and the bread mesh loads from the installed copy."""
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q", "--target",
                    str(target), str(wheel)], check=True, capture_output=True, timeout=300)
    code = ("import graspsim, mujoco\n"
            "from graspsim.grippers import model_folder\n"
            "from graspsim.tabletop.scene_objects import ASSETS, MESHES\n"
            "from graspsim.sim import load_mesh\n"
            "m = mujoco.MjModel.from_xml_path(str(model_folder('franka_hand') / 'franka_hand.xml'))\n"
            "mesh = load_mesh(ASSETS / MESHES['bread'][0])\n"
            "print(graspsim.__file__, model_folder('franka_hand'), ASSETS, m.nbody, len(mesh.faces))\n")
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(target), "HOME": str(tmp_path),
           "MUJOCO_GL": "egl"}
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    pkg_file, folder, assets, nbody, faces = r.stdout.split()
    assert all(Path(p).is_relative_to(target) for p in (pkg_file, folder, assets))
    assert int(nbody) > 1 and int(faces) > 0
