"""The simulated depth camera's rendering: MuJoCo depth frames (:class:`DepthRenderer`,
:func:`render_depth`) of the pinhole model of :mod:`graspsim.geometry.camera`
(intrinsics, pose, back-projection), with the sensor's noise of
:mod:`graspsim.tabletop.depth_noise`.

Frames. The camera frame is OpenCV's: x right, y down, z forward (the viewing
direction); a pixel (u, v) (column, row; pixel centres at integer coordinates) sees the
ray ``((u - cx) / fx, (v - cy) / fy, 1)``. ``T_world_camera`` (4, 4) places that frame in
the world. MuJoCo's and OpenGL's cameras look along their -z with y up; the conversion
(flip y and z) happens here and nowhere else. Depth images hold z-depth (the camera-frame
z of the surface, not the distance along the ray) in metres, 0 where nothing valid was
seen, as a RealSense reports them.

Rendering goes through ``mujoco.Renderer`` (offscreen: EGL or OSMesa, chosen by
``import graspsim.sim``). Any principal point and focal lengths are honoured by setting
the OpenGL frustum of the rendered scene directly, so the model needs no camera of its own.

    cam = Camera(Intrinsics.preset("d435"), look_at([0.5, 0, 0.6], [0, 0, 0]))
    frame = render_depth(model, data, cam, noise=DepthNoise(), rng=rng)
    view = backproject(frame)                  # points in the camera frame
    world = to_world(view.points, cam.T_world_camera)
"""

from __future__ import annotations

import mujoco
import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.geometry.camera import (
    Camera,
    DepthFrame,
    Intrinsics,
)
from graspsim.tabletop.depth_noise import DepthNoise

__all__ = ["DepthRenderer", "render_depth"]

_GL_FROM_CV = np.diag([1.0, -1.0, -1.0])  # camera-frame axes: OpenCV -> OpenGL/MuJoCo


class DepthRenderer:
    """Renders :class:`DepthFrame` s of one model at one image size (build once, render
    many; ``close()`` frees the GL context). The model's offscreen buffer must hold the image;
    scene_option: what is drawn (e.g. geom groups hidden)."""

    def __init__(self, model: mujoco.MjModel, intrinsics: Intrinsics, *,
                 scene_option: mujoco.MjvOption | None = None) -> None:
        from graspsim.sim.trial_render import offscreen_renderer

        self.model, self.intrinsics, self.scene_option = model, intrinsics, scene_option
        self._r = offscreen_renderer(model, intrinsics.height, intrinsics.width)
        self._rays = intrinsics.rays()

    def close(self) -> None:
        self._r.close()

    def __enter__(self) -> DepthRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _set_view(self, data: mujoco.MjData, camera: Camera) -> None:
        """Update the scene, then replace its GL camera by ours: pose and off-centre frustum."""
        self._r.update_scene(data, mujoco.MjvCamera(), self.scene_option)
        k, T = camera.intrinsics, camera.T_world_camera
        R = T[:3, :3] @ _GL_FROM_CV
        for c in self._r.scene.camera:
            c.pos[:], c.forward[:], c.up[:] = T[:3, 3], -R[:, 2], R[:, 1]
            n = c.frustum_near
            left, right = (-0.5 - k.cx) / k.fx * n, (k.width - 0.5 - k.cx) / k.fx * n
            c.frustum_center, c.frustum_width = 0.5 * (left + right), 0.5 * (right - left)
            c.frustum_top, c.frustum_bottom = (k.cy + 0.5) / k.fy * n, -(k.height - 0.5 - k.cy) / k.fy * n
            c.orthographic = 0

    def render(self, data: mujoco.MjData, camera: Camera, *, noise: DepthNoise | None = None,
               rng: np.random.Generator | None = None, segmentation: bool = True,
               rgb: bool = False) -> DepthFrame:
        """One view of ``data``'s state (its kinematics must be current: mj_forward)."""
        if camera.intrinsics != self.intrinsics:
            raise InvalidParameterError("the camera's intrinsics differ from this renderer's; make another")
        if noise is not None and rng is None:
            raise InvalidParameterError("a noisy render needs rng (a seeded numpy Generator)")
        self._set_view(data, camera)
        r = self._r
        r.enable_depth_rendering()
        depth = r.render().astype(np.float32)
        far = self.model.vis.map.zfar * self.model.stat.extent
        depth[~(depth < 0.999 * far)] = 0.0  # nothing there: the far plane
        seg = image = None
        if segmentation:
            r.enable_segmentation_rendering()
            s = r.render()
            seg = np.where(s[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), s[..., 0], -1).astype(np.int32)
        r.disable_segmentation_rendering()
        r.disable_depth_rendering()
        if rgb:
            image = r.render().copy()
        if noise is not None:
            depth = noise.apply(depth, self._rays, rng)
        return DepthFrame(depth, camera, seg, None, image, None if noise is None else noise.to_dict())


def render_depth(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera, *,
                 noise: DepthNoise | None = None, rng: np.random.Generator | None = None,
                 segmentation: bool = True, rgb: bool = False) -> DepthFrame:
    """Render one :class:`DepthFrame` (a one-off :class:`DepthRenderer`; keep one for many)."""
    with DepthRenderer(model, camera.intrinsics) as r:
        return r.render(data, camera, noise=noise, rng=rng, segmentation=segmentation, rgb=rgb)
