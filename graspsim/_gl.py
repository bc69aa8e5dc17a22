"""The one place that picks MuJoCo's headless OpenGL backend.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported; a process that imports
it without a display and without the variable gets GLFW, and every offscreen render then
fails (or aborts the process). So graspsim never imports mujoco directly: it calls
:func:`import_mujoco`, which sets the backend first.
"""

from __future__ import annotations

import ctypes.util
import os
import sys


def default_gl() -> None:
    """Pick a headless OpenGL backend (EGL, else OSMesa) for offscreen rendering when there
    is no display and the user set none, before mujoco loads; a no-op once it has."""
    if "mujoco" in sys.modules or os.environ.get("MUJOCO_GL"):
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        if ctypes.util.find_library("EGL"):
            os.environ["MUJOCO_GL"] = "egl"
        elif ctypes.util.find_library("OSMesa"):
            os.environ["MUJOCO_GL"] = "osmesa"


def import_mujoco():
    """``mujoco``, imported after :func:`default_gl`."""
    default_gl()
    import mujoco

    return mujoco
