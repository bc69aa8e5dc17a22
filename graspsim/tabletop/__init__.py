"""Table-top scenes of several objects: drawing and settling a scene (``table_scene``,
``scene_objects``), simulating grasps among neighbours (``scene_sim``), the simulated
depth camera and its noise (``camera``, ``depth_noise``), cloud files written with their
camera (``cloud_io``) and the clutter-removal protocol (``clutter``, with its pictures in
``clutter_figure``). Single-object trials are :mod:`graspsim.sim`.

May use: the base modules, primitives, grippers, grades, maps, plots, perception,
planning and sim (never calibration, envs, viewer, apps or the CLI).

    scene = make_scene(5, "pile", seed=0)
    sim = scene.sim()                       # a SceneSim: render, execute, remove
"""

from __future__ import annotations

from graspsim._gl import default_gl

default_gl()  # before any submodule imports mujoco

from graspsim.geometry.camera import Camera, DepthFrame, Intrinsics, look_at  # noqa: E402
from graspsim.tabletop.depth_noise import DepthNoise  # noqa: E402
from graspsim.tabletop.depth_render import render_depth  # noqa: E402
from graspsim.tabletop.table_scene import (  # noqa: E402
    SceneOutcome,
    SceneSim,
    TableScene,
    load_scene,
    make_scene,
    save_scene,
)

__all__ = [
    "Camera", "Intrinsics", "DepthNoise", "DepthFrame", "look_at", "render_depth",
    "TableScene", "SceneSim", "SceneOutcome", "make_scene", "save_scene", "load_scene",
]
