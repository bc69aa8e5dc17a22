"""What the viewer draws, as plain arrays (no viser here): grasp glyphs, gripper
wireframes, colours.

* :func:`fork_glyph`: a compact "fork" (two prongs, a bridge, a stem) in a grasp frame
  whose origin is the grasp point and whose axes are the wrist's (x closing, z
  approach). It is drawn once per grasp as an instance scaled in x by the grasp's
  opening, so thousands of grasps cost one mesh.
* :func:`gripper_wireframe`: the edges of a :class:`~graspsim.grippers.spec.GripperSpec`'s
  collision boxes at a pose and opening (the full gripper of a chosen grasp).
* :func:`colormap`: values -> RGB (viridis), :data:`OUTCOME_COLOURS`: one colour per
  trial outcome.
"""

from __future__ import annotations

import numpy as np

from graspsim.geometry.boxes import box_mesh

__all__ = ["fork_glyph", "colormap", "OUTCOME_COLOURS", "REACH_COLOURS",
           "NOT_SIMULATED_COLOUR", "PART_COLOURS"]

# viridis at 0, 1/8, ..., 1 (matplotlib's table), interpolated linearly: close enough
# for a colour scale and no matplotlib import on the viewer's start-up path.
_VIRIDIS = np.array([
    [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
    [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37]], float)

#: trial outcome label -> RGB (success green, failures warm, infeasible grey)
OUTCOME_COLOURS: dict[str, tuple[int, int, int]] = {
    "success": (40, 170, 70), "start_collision": (150, 150, 150), "no_contact": (140, 80, 200),
    "slipped": (250, 150, 30), "dropped": (220, 40, 40), "place_failed": (230, 200, 40),
    "sim_unstable": (30, 30, 30)}
NOT_SIMULATED_COLOUR = (205, 205, 215)
#: colours of the map's ``reachable`` verdicts (an arm at a base; unchecked: NOT_SIMULATED_COLOUR)
REACH_COLOURS: dict[str, tuple[int, int, int]] = {
    "reachable": (40, 170, 70), "first cut only": (170, 215, 90), "unreachable": (220, 40, 40)}
#: colours of identified parts (cycled)
PART_COLOURS = ((230, 120, 60), (70, 130, 200), (120, 190, 90), (200, 90, 160), (230, 200, 60),
                (90, 200, 200))


def colormap(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(N,) values -> (N, 3) uint8 viridis colours over [lo, hi] (NaN: grey)."""
    v = np.asarray(values, float)
    t = np.clip((v - lo) / (hi - lo), 0.0, 1.0) if hi > lo else np.full(v.shape, 0.5)
    x = np.linspace(0.0, 1.0, len(_VIRIDIS))
    t0 = np.nan_to_num(t)
    rgb = np.stack([np.interp(t0, x, _VIRIDIS[:, c]) for c in range(3)], axis=-1)
    rgb[~np.isfinite(v)] = NOT_SIMULATED_COLOUR
    return rgb.round().astype(np.uint8)


def fork_glyph(prong: float = 0.02, thickness: float = 0.0015) -> tuple[np.ndarray, np.ndarray]:
    """The fork glyph for a unit opening: prongs at x = +-0.5 reaching ``prong`` [m]
    past the grasp point (the origin) towards the approach (+z) and as far back, a
    bridge at z = -prong, and a stem to z = -3 prong. Scale x by the grasp's opening [m]
    (the prongs' x thickness scales with it: they are 4 % of the opening)."""
    t, p = thickness, prong
    centers = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, -p], [0.0, 0.0, -2 * p]])
    half = np.array([[0.02, t, p], [0.02, t, p], [0.5, t, t], [0.02, t, p]])
    return box_mesh(centers, half)
