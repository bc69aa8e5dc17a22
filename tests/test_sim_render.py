"""Offscreen renders of a trial's key moments (skipped without a headless GL backend)."""

import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.primitives import Box
from graspsim.sim import LiftPlace, build_scene, object_from_shape


@pytest.fixture(scope="module")
def gl():
    import mujoco

    from graspsim.sim.trial_render import gl_backend

    m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='.1'/></worldbody></mujoco>")
    try:
        r = mujoco.Renderer(m, 32, 32)
        r.close()
    except Exception as err:  # no EGL/OSMesa, or mujoco was imported with GLFW and no display
        pytest.skip(f"no headless OpenGL (MUJOCO_GL={gl_backend()!r}): {err}; "
                    "install libegl1 or libosmesa6")


def test_render_writes_key_moments_and_a_gif(gl, tmp_path):
    from PIL import Image

    from graspsim.sim.trial_render import render_trial

    scene = build_scene(object_from_shape(Box(0.06, 0.06, 0.06)))
    T = grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])
    paths = render_trial(scene, T, 0.06, tmp_path, LiftPlace(), size=(120, 160), gif=True, gif_fps=5)
    names = sorted(p.name for p in paths)
    assert names == sorted(["trial_open.png", "trial_closed.png", "trial_lifted.png",
                            "trial_placed.png", "trial.gif"])
    opened = np.asarray(Image.open(tmp_path / "trial_open.png"))
    lifted = np.asarray(Image.open(tmp_path / "trial_lifted.png"))
    assert opened.shape == (120, 160, 3) and opened.std() > 5
    assert np.abs(opened.astype(int) - lifted.astype(int)).mean() > 1  # the object moved
    assert Image.open(tmp_path / "trial.gif").n_frames > 5


@pytest.mark.slow
def test_trial_cli_renders_the_first_trials_that_start_clear(gl, tmp_path, capsys):
    import json

    from hand_made import hand_made_map

    from graspsim.cli import main
    from graspsim.maps import save_map
    from graspsim.primitives import Cylinder

    # the two best poses come from under the table (START_COLLISION); the third is fine
    T = np.stack([grasp_pose([0, 0, -0.04], [0, 0, 1], [1, 0, 0]), grasp_pose([0, 0, -0.045], [0, 0, 1], [0, 1, 0]),
                  grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])])
    path = save_map(hand_made_map(Cylinder(0.02, 0.10), T, [0.04] * 3, grades=[0.9, 0.85, 0.8]), tmp_path / "c.h5")
    assert main(["trial", str(path), "--top", "3", "--render", str(tmp_path / "r"), "--render-count", "1",
                 "--threads", "1", "--no-write", "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["counts"]["start_collision"] == 2
    assert s["renders"] and all("grasp000002" in p for p in s["renders"])


def test_every_mujoco_import_goes_through_the_gl_choice():
    """MuJoCo reads MUJOCO_GL once, at its first import: a module outside graspsim.sim,
    graspsim.robots and graspsim.tabletop (whose __init__ files pick the backend first) that imported
    mujoco directly made a later offscreen render fail in a fresh process (the Franka
    hand's measurements did)."""
    import re
    from pathlib import Path

    import graspsim

    root = Path(graspsim.__file__).parent
    direct = [str(p.relative_to(root)) for p in root.rglob("*.py")
              if p.parent not in (root / "sim", root / "robots", root / "tabletop") and p.name != "_gl.py"
              and re.search(r"^\s*(import mujoco|from mujoco)", p.read_text(), re.M)]
    assert direct == []


def test_the_franka_hand_first_then_the_same_gl_backend():
    """The order a `--gripper franka_hand --render` run meets: the hand's measurements
    load mujoco before graspsim.sim does; the backend must be the one graspsim.sim picks
    (checked in fresh processes with no display and no MUJOCO_GL, on any machine)."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    show = "import os, sys; print(os.environ.get('MUJOCO_GL', ''), 'mujoco' in sys.modules)"

    def backend(first: str) -> list[str]:
        r = subprocess.run([sys.executable, "-c", f"{first}\n{show}"], capture_output=True, text=True,
                           env=env, timeout=120)
        assert r.returncode == 0, r.stderr[-400:]
        return r.stdout.split()

    hand = backend("from graspsim.grippers import get_gripper; get_gripper('franka_hand')")
    assert hand[1] == "True"  # the measurements did load mujoco
    assert hand[0] == backend("import graspsim.sim")[0]
