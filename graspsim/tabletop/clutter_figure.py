"""A picture of one clutter-removal step: what the camera saw, how it was segmented,
and the grasp chosen (the gripper's collision boxes projected into the image).

Three panels: the colour image with the grasp; the depth image; the segments found,
coloured over the grey depth, with the grasp. Written with matplotlib (Agg) through a
temporary file, so a failed write leaves no half-written image.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim.errors import OutputPathError
from graspsim.transforms import invert_transform

__all__ = ["grasp_pixels", "save_step_figure"]

_COLOURS = np.array([[0.90, 0.30, 0.25], [0.25, 0.55, 0.90], [0.30, 0.75, 0.35], [0.95, 0.70, 0.20],
                     [0.60, 0.40, 0.80], [0.20, 0.80, 0.80], [0.90, 0.45, 0.70], [0.55, 0.35, 0.20]])


def grasp_pixels(camera, gripper, T_world_wrist: np.ndarray, opening: float) -> np.ndarray:
    """(S, 2, 2) pixel segments (u, v) of the gripper's box edges at the pose, those in
    front of the camera."""
    from graspsim.grippers.wireframe import gripper_wireframe

    seg = gripper_wireframe(gripper, T_world_wrist, opening)  # (S, 2, 3) world
    T = invert_transform(camera.T_world_camera)
    cam = seg @ T[:3, :3].T + T[:3, 3]
    front = np.all(cam[..., 2] > 1e-3, axis=1)
    cam = cam[front]
    return camera.intrinsics.project(cam.reshape(-1, 3)).reshape(-1, 2, 2)


def _segment_image(frame, perception, points_uv: np.ndarray) -> np.ndarray:
    """(H, W, 3) the depth in grey with each segment's pixels in its colour."""
    d = np.asarray(frame.depth, float)
    valid = d > 0
    g = np.zeros_like(d)
    if valid.any():
        lo, hi = np.quantile(d[valid], [0.01, 0.99])
        g[valid] = 1.0 - 0.7 * np.clip((d[valid] - lo) / max(hi - lo, 1e-9), 0, 1)
    img = np.repeat(g[..., None], 3, axis=2)
    lab = perception.labels
    k = lab >= 0
    uv = points_uv[k]
    img[uv[:, 1], uv[:, 0]] = _COLOURS[lab[k] % len(_COLOURS)]
    return img


def _view_box(shape, uv: np.ndarray, lines, margin: int = 60) -> tuple[tuple, tuple]:
    """((u0, u1), (v1, v0)) around the segmented pixels and the grasp, within the image
    (the whole image when nothing was segmented)."""
    h, w = shape
    pts = [uv.reshape(-1, 2)] + ([] if lines is None else [lines.reshape(-1, 2)])
    pts = np.concatenate(pts)
    if not len(pts):
        return (0, w), (h, 0)
    lo = np.maximum(pts.min(axis=0) - margin, 0)
    hi = np.minimum(pts.max(axis=0) + margin, (w, h))
    return (lo[0], hi[0]), (hi[1], lo[1])


def save_step_figure(path: str | Path, frame, plan, uv: np.ndarray, gripper, *, title: str = "",
                     grasp=None) -> Path:
    """Write the three-panel picture of a step to ``path`` (.png): ``frame`` (a
    DepthFrame, RGB rendered), ``plan`` (its ScenePlan), ``uv`` (N, 2) the pixel of each
    point given to the planner, ``grasp`` (a SceneGrasp; default the plan's best)."""
    from graspsim.plots import pyplot

    plt = pyplot()
    grasp = grasp if grasp is not None else plan.best
    lines = None if grasp is None else grasp_pixels(frame.camera, gripper, grasp.T_world_wrist, grasp.opening)
    box = _view_box(frame.depth.shape, uv[plan.perception.labels >= 0], lines)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    rgb = frame.rgb if frame.rgb is not None else np.zeros((*frame.depth.shape, 3), np.uint8)
    panels = [(rgb, "colour + chosen grasp"), (None, "depth [m]"),
              (_segment_image(frame, plan.perception, uv), f"{plan.perception.n_segments} segments + grasp")]
    for ax, (img, name) in zip(axes, panels):
        if img is None:
            d = np.where(frame.depth > 0, frame.depth, np.nan)
            im = ax.imshow(d, cmap="viridis")
            fig.colorbar(im, ax=ax, fraction=0.035)
        else:
            ax.imshow(img)
        if lines is not None and name != "depth [m]":
            for (u0, v0), (u1, v1) in lines:
                ax.plot([u0, u1], [v0, v1], color="white" if img is rgb else "black", lw=0.8)
        ax.set_xlim(*box[0])
        ax.set_ylim(*box[1])
        ax.set_title(name, fontsize=10)
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    try:
        with atomic_path(path, OutputPathError) as tmp:
            fig.savefig(tmp, dpi=90, format="png")
    finally:
        plt.close(fig)
    return path
