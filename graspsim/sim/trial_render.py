"""Offscreen pictures of a trial's key moments (PNG) and, optionally, an animated GIF.

Rendering is headless: MuJoCo needs EGL or OSMesa, chosen by ``MUJOCO_GL`` *before*
mujoco is first imported. ``import graspsim.sim`` sets ``MUJOCO_GL`` when it is unset
and no display is present (EGL if libEGL is found, else OSMesa); set it yourself to
choose. Without a working backend :func:`render_trial` raises
:class:`DependencyNotInstalled` saying what to install.

The trial is re-simulated step by step in Python (the debugging backend, which gives the
same states as the batched one) and pictured at the end of chosen phases: for
``lift_place`` open (after settling), closed, lifted (end of hold) and placed (end of
rest); for ``tug`` open, closed and tugged.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import mujoco
import numpy as np

from graspsim.errors import DependencyNotInstalled, InvalidParameterError
from graspsim.sim.batch import initial_states, pregrasp_opening
from graspsim.sim.protocols import LiftPlace, Protocol
from graspsim.sim.trial_scene import Scene

__all__ = ["render_trial", "gl_backend", "offscreen_renderer", "KEY_MOMENTS"]

log = logging.getLogger(__name__)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS

KEY_MOMENTS = {"lift_place": {"open": "settle", "closed": "close", "lifted": "hold", "placed": "rest"},
               "tug": {"open": "settle", "closed": "close", "tugged": None}}


def gl_backend() -> str:
    """The OpenGL backend mujoco was imported with (``MUJOCO_GL``; "" = default/GLFW)."""
    return os.environ.get("MUJOCO_GL", "")


def offscreen_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """A MuJoCo offscreen renderer of ``model`` at height x width pixels: a bad size or a
    GL backend that cannot render is a one-line error."""
    if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
        raise InvalidParameterError(
            f"image size {height}x{width} exceeds the scene's offscreen buffer "
            f"{model.vis.global_.offheight}x{model.vis.global_.offwidth}")
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as err:  # GL errors come as many exception types
        raise DependencyNotInstalled(
            f"offscreen rendering failed with MUJOCO_GL={gl_backend()!r}: {err}. Install EGL "
            "(libegl1 + a Mesa or GPU driver) or OSMesa (libosmesa6) and set MUJOCO_GL=egl or "
            "osmesa before mujoco is imported") from err


def _camera(scene: Scene, protocol: Protocol) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    lift = getattr(protocol, "lift_height", 0.0)
    cam.lookat[:] = scene.T_world_obj[:3, 3] + np.array([0.0, 0.0, 0.5 * lift])
    cam.distance = 0.2 + 1.5 * float(np.ptp(scene.obj.surface.vertices, axis=0).max()) + 0.8 * lift
    cam.azimuth, cam.elevation = 135.0, -20.0
    return cam


def render_trial(scene: Scene, T_obj_wrist: np.ndarray, width: float, out_dir: str | os.PathLike,
                 protocol: Protocol = LiftPlace(), *, name: str = "trial",
                 size: tuple[int, int] = (480, 640), gif: bool = False, gif_fps: float = 25.0,
                 T_world_wrist: np.ndarray | None = None) -> list[Path]:
    """Simulate one grasp and write ``<name>_<moment>.png`` (and ``<name>.gif``).

    T_obj_wrist: (4, 4) wrist pose in the object frame (or give ``T_world_wrist``, e.g.
    a noisy pose from :class:`TrialResults`); width: contact distance [m];
    size: (height, width) in pixels. Returns the written paths.
    """
    from PIL import Image

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if T_world_wrist is None:
        T_world_wrist = scene.T_world_obj @ np.asarray(T_obj_wrist, float)
    T_world_wrist = np.asarray(T_world_wrist, float).reshape(1, 4, 4)
    if gif_fps <= 0:
        raise InvalidParameterError(f"gif_fps must be > 0, got {gif_fps!r}")
    m = scene.model
    dt = m.opt.timestep
    state0 = initial_states(scene, T_world_wrist, pregrasp_opening(scene, [width]))[0]
    control = protocol.controls(scene, T_world_wrist, pregrasp_opening(scene, [width]))[0]
    phases = protocol.steps(dt)
    last = max(b for _, b in phases.values())
    moments = {k: (phases[v][1] if v else last) for k, v in KEY_MOMENTS[protocol.name].items()}
    every = max(1, int(round(1.0 / (gif_fps * dt))))
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, state0, _FULL)
    renderer = offscreen_renderer(m, *size)
    cam = _camera(scene, protocol)
    paths, frames = [], []
    try:
        for k in range(len(control)):
            mujoco.mj_setState(m, d, control[k], protocol.control_spec)
            mujoco.mj_step(m, d)
            snap = [key for key, s in moments.items() if s == k]
            if snap or (gif and k % every == 0):
                renderer.update_scene(d, cam)
                img = renderer.render()
                for key in snap:
                    p = out / f"{name}_{key}.png"
                    Image.fromarray(img).save(p)
                    paths.append(p)
                if gif and k % every == 0:  # half size keeps GIFs small
                    frames.append(Image.fromarray(img).reduce(2))
    finally:
        renderer.close()
    if gif and frames:
        p = out / f"{name}.gif"
        frames[0].save(p, save_all=True, append_images=frames[1:], duration=int(1000 / gif_fps), loop=0)
        paths.append(p)
    log.info("rendered %d files to %s", len(paths), out)
    return paths
