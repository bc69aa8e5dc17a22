"""``render_mode="rgb_array"`` frames of the grasp environments (offscreen MuJoCo).

Before a trial: the object on the table and the gripper parked above it. After a
trial: the executed grasp replayed step by step (the same states as the batched run)
up to its key moment -- the end of the hold for ``lift_place`` (the object lifted), the
end of closing for ``tug``. Headless GL is picked by ``import graspsim.sim`` (EGL or
OSMesa); without one, rendering raises :class:`DependencyNotInstalled`.
"""

from __future__ import annotations

import numpy as np

from graspsim._gl import import_mujoco
from graspsim.errors import DependencyNotInstalled
from graspsim.sim.batch import initial_states, pregrasp_opening
from graspsim.sim.protocols import Protocol
from graspsim.sim.trial_scene import Scene

__all__ = ["FrameRenderer"]

mujoco = import_mujoco()
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
_MOMENT = {"lift_place": "hold", "tug": "close"}


class FrameRenderer:
    """Renders (H, W, 3) uint8 frames of one scene at a time (the GL context is
    remade when the scene changes). size: (height, width) in pixels."""

    def __init__(self, size: tuple[int, int] = (480, 640)):
        self.size = (int(size[0]), int(size[1]))
        self._renderer: mujoco.Renderer | None = None
        self._model: mujoco.MjModel | None = None

    def _get(self, model: mujoco.MjModel) -> mujoco.Renderer:
        if self._model is not model:
            self.close()
            try:
                self._renderer = mujoco.Renderer(model, *self.size)
            except Exception as err:  # GL errors come as many exception types
                import os

                raise DependencyNotInstalled(
                    f"offscreen rendering failed with MUJOCO_GL={os.environ.get('MUJOCO_GL', '')!r}: "
                    f"{err}. Install EGL (libegl1 + a Mesa or GPU driver) or OSMesa (libosmesa6) "
                    "and set MUJOCO_GL=egl or osmesa before mujoco is imported") from err
            self._model = model
        return self._renderer

    @staticmethod
    def _camera(scene: Scene, lift: float) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = scene.T_world_obj[:3, 3] + np.array([0.0, 0.0, 0.5 * lift])
        cam.distance = 0.25 + 1.5 * float(np.ptp(scene.obj.surface.vertices, axis=0).max()) + 0.8 * lift
        cam.azimuth, cam.elevation = 135.0, -25.0
        return cam

    def scene_frame(self, scene: Scene) -> np.ndarray:
        """The scene in its initial state (object at rest, gripper parked above)."""
        m = scene.model
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        r = self._get(m)
        r.update_scene(d, self._camera(scene, 0.0))
        return r.render().copy()

    def trial_frame(self, scene: Scene, T_world_wrist: np.ndarray, width: float,
                    protocol: Protocol) -> np.ndarray:
        """The trial of the wrist pose ``T_world_wrist`` (4, 4; the scene's world frame)
        at its key moment."""
        m = scene.model
        T = np.asarray(T_world_wrist, float).reshape(1, 4, 4)
        state0 = initial_states(scene, T, pregrasp_opening(scene, [width]))[0]
        control = protocol.controls(scene, T, pregrasp_opening(scene, [width]))[0]
        phases = protocol.steps(m.opt.timestep)
        last = phases.get(_MOMENT.get(protocol.name, ""), (0, len(control) - 1))[1]
        d = mujoco.MjData(m)
        mujoco.mj_setState(m, d, state0, _FULL)
        for k in range(last + 1):
            mujoco.mj_setState(m, d, control[k], protocol.control_spec)
            mujoco.mj_step(m, d)
        r = self._get(m)
        r.update_scene(d, self._camera(scene, float(getattr(protocol, "lift_height", 0.0))))
        return r.render().copy()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
        self._renderer = None
        self._model = None
