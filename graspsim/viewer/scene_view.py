"""The viewer's scene mode: a table-top scene as the robot's depth camera saw it and planned it.

Draws a :class:`~graspsim.planning.scene.ScenePlan` -- one look of
:class:`~graspsim.tabletop.clutter.ClutterEpisode` (the clutter-removal protocol's render ->
plan step) in the world frame (metres, z up), or a scene cloud of the user's own planned
by ``graspsim plan-scene --view`` in the cloud's frame (up: the table's normal) -- as the
depth cloud in grey, the points above the table coloured by segment (one colour per
segment, :data:`SEGMENT_COLOURS`), the fitted table plane as a translucent plate, and
the grasps: each segment's ``top K`` as fork glyphs coloured by their robust score
(viridis, 0 -> 1), each segment's best as a gripper wireframe in the segment's colour,
and the scene's chosen grasp (what the protocol executes) as a thick black gripper.
GUI: top K per object, the raw cloud on/off, a table of the segments (points,
identified primitives, status, best score).
"""

from __future__ import annotations

import numpy as np

from graspsim.geometry.boxes import box_mesh
from graspsim.grippers.wireframe import gripper_wireframe
from graspsim.transforms import frame_from_axes, matrix_to_quat
from graspsim.viewer.browser_view import BrowserView
from graspsim.viewer.glyphs import PART_COLOURS, colormap, fork_glyph

__all__ = ["SceneViewer", "SEGMENT_COLOURS", "CLOUD_COLOUR"]

#: colour of segment k: SEGMENT_COLOURS[k % len]
SEGMENT_COLOURS = PART_COLOURS
CLOUD_COLOUR = (150, 150, 150)
CHOSEN_COLOUR = (15, 15, 15)
MAX_CLOUD = 200_000  # raw cloud points sent to the browser at most


class SceneViewer:
    """A scene's ``plan`` (a :class:`~graspsim.planning.scene.ScenePlan`) on ``server``
    (a ``viser.ViserServer``): ``cloud`` (N, 3) the points it was planned from (the
    plan's frame); ``gripper``: the GripperSpec that planned it; ``eye`` (3,): where the
    camera was (new browsers look from its side; None: from above the table); ``best``:
    the chosen grasp (default the plan's best)."""

    def __init__(self, server, plan, cloud, gripper, *, eye=None, best=None, top_k: int = 3,
                 glyph_size: float = 0.5) -> None:
        self.server, self.plan, self.gripper = server, plan, gripper
        self.best = plan.best if best is None else best
        self.per = self.plan.perception
        self.eye = None if eye is None else np.asarray(eye, float)
        self.glyph_size = float(glyph_size)
        scene = server.scene
        self.root = scene.add_frame("/scene", show_axes=False)
        pts = np.asarray(cloud, float).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) > MAX_CLOUD:  # a seeded subset: the browser needs no more
            pts = pts[np.sort(np.random.default_rng(0).choice(len(pts), MAX_CLOUD, replace=False))]
        self.cloud = scene.add_point_cloud("/scene/cloud", pts.astype(np.float32), CLOUD_COLOUR,
                                           point_size=0.002, point_shape="circle")
        self.segments = scene.add_point_cloud("/scene/segments", self.per.points.astype(np.float32),
                                              self.point_colours(), point_size=0.004, point_shape="circle")
        self.centre = (self.per.points.mean(axis=0) if len(self.per.points)
                       else pts.mean(axis=0) if len(pts) else np.zeros(3))
        self._draw_table()
        self._glyph = fork_glyph()
        self._build_gui(top_k)
        scene.set_up_direction(tuple(float(v) for v in self.per.plane.normal))
        scene.configure_default_lights(cast_shadow=False)
        scene.add_light_hemisphere("/light", intensity=0.6)
        self.view = BrowserView(server)
        self._aim()
        self.refresh()

    # ------------------------------------------------------------------ static scene
    def point_colours(self) -> np.ndarray:
        """(M, 3) uint8: the colour of each point above the table by its segment (noise: grey)."""
        seg = self.per.segment
        table = np.array(SEGMENT_COLOURS, np.uint8)
        out = np.tile(np.array(CLOUD_COLOUR, np.uint8), (len(seg), 1))
        ok = seg >= 0
        out[ok] = table[seg[ok] % len(table)]
        return out

    def _draw_table(self) -> None:
        """A translucent 60 cm plate on the fitted plane, under the objects."""
        plane = self.per.plane
        n = np.asarray(plane.normal, float)
        foot = self.centre - n * float(plane.heights(self.centre[None])[0])
        R = frame_from_axes(np.eye(3)[int(np.argmin(np.abs(n)))], n)
        v, f = box_mesh(np.array([[0.0, 0.0, -0.001]]), np.array([[0.3, 0.3, 0.001]]))
        self.table = self.server.scene.add_mesh_simple(
            "/scene/table", v, f, color=(200, 180, 150), opacity=0.5, receive_shadow=False, cast_shadow=False,
            wxyz=matrix_to_quat(R), position=foot)

    def _aim(self) -> None:
        """New browsers look at the objects from the depth camera's side, at half its
        distance (no camera known: from 40 cm above the table, a little to the side)."""
        if self.eye is not None:
            eye = self.eye
        else:
            n = np.asarray(self.per.plane.normal, float)
            side = np.eye(3)[int(np.argmin(np.abs(n)))]
            eye = self.centre + 0.8 * n + 0.3 * (side - (side @ n) * n)
        self.view.aim(self.centre + 0.5 * (eye - self.centre), self.centre)

    @property
    def camera(self) -> tuple[tuple, tuple]:
        """(position, look_at) [m] of the view new browsers get."""
        return self.view.pose

    # ------------------------------------------------------------------ GUI and grasps
    def _build_gui(self, top_k: int) -> None:
        gui = self.server.gui
        best = self.best
        gui.add_markdown(f"**scene** · {self.per.n_segments} segments · {len(self.plan.grasps)} grasps planned · "
                         + ("no grasp with a robust score > 0" if best is None else
                            f"chosen: segment {best.segment}, score {best.score:.2f}"))
        self.g_top = gui.add_slider("top K per object", 0, max(1, self._keep()), 1, int(min(top_k, self._keep())))
        self.g_cloud = gui.add_checkbox("raw depth cloud", True)
        self.g_status = gui.add_markdown("")
        gui.add_markdown(self.segment_table())
        self.g_top.on_update(lambda _: self.refresh())
        self.g_cloud.on_update(lambda _: setattr(self.cloud, "visible", bool(self.g_cloud.value)))

    def _keep(self) -> int:
        seg = [g.segment for g in self.plan.grasps]
        return max((seg.count(k) for k in set(seg)), default=0)

    def segment_table(self) -> str:
        """Markdown: one row per segment (colour index, points, primitives, status, best score)."""
        rows = ["| segment | points | identified | status | best score |", "|---|---|---|---|---|"]
        for s in self.plan.segments:
            mine = [g.score for g in self.plan.grasps if g.segment == s.segment]
            rows.append(f"| {s.segment} | {s.points} | {', '.join(s.primitives) or '-'} | {s.status} | "
                        + (f"{max(mine):.2f} |" if mine else "- |"))
        return "\n".join(rows)

    def shown(self, top_k: int) -> list:
        """Each segment's best ``top_k`` grasps (the scene's ranking is best first)."""
        out, count = [], {}
        for g in self.plan.grasps:
            if count.get(g.segment, 0) < top_k:
                out.append(g)
                count[g.segment] = count.get(g.segment, 0) + 1
        return out

    def refresh(self) -> None:
        """Draw each segment's top K, its best as a wireframe and the chosen grasp."""
        scene = self.server.scene
        grasps = self.shown(int(self.g_top.value))
        self.drawn = grasps
        for name in ("/scene/grasps", "/scene/best", "/scene/chosen"):
            scene.remove_by_name(name)
        self.g_status.content = f"showing {len(grasps)} grasps"
        best = self.best
        if best is not None:
            scene.add_line_segments("/scene/chosen", gripper_wireframe(self.gripper, best.T_world_wrist, best.opening),
                                    CHOSEN_COLOUR, thickness=3.0, thickness_units="screen")
        if not grasps:
            return
        T = np.stack([g.T_world_wrist for g in grasps])
        opening = np.array([g.opening for g in grasps])
        tcp = T[:, :3, :3] @ self.gripper.nominal_tcp + T[:, :3, 3]
        s = self.glyph_size
        scales = np.stack([opening, np.full(len(T), s), np.full(len(T), s)], axis=1).astype(np.float32)
        scene.add_batched_meshes_simple(
            "/scene/grasps", *self._glyph, batched_wxyzs=matrix_to_quat(T[:, :3, :3]), batched_positions=tcp,
            batched_scales=scales, batched_colors=colormap(np.array([g.score for g in grasps]), 0.0, 1.0),
            lod="off", cast_shadow=False, receive_shadow=False)
        firsts = {}
        for g in grasps:
            firsts.setdefault(g.segment, g)
        seg = [gripper_wireframe(self.gripper, g.T_world_wrist, g.opening) for g in firsts.values()]
        cols = [np.tile(SEGMENT_COLOURS[k % len(SEGMENT_COLOURS)], (len(w), 2, 1)) for k, w in zip(firsts, seg)]
        scene.add_line_segments("/scene/best", np.concatenate(seg), np.concatenate(cols).astype(np.uint8),
                                thickness=1.5, thickness_units="screen")
