"""The map viewer on a viser server: object, table, cloud, mesh, grasp glyphs and the GUI.

Everything is drawn in the map's object frame (metres). The object's primitives come
from the map (identified parts coloured by part); an observed cloud and a true mesh,
both in the cloud's frame, are placed by the map's ``T_cloud_obj`` (as the simulator
places a mesh). Filters run on all grasps (:class:`~graspsim.viewer.columns.ViewData`);
at most ``max drawn`` are drawn as fork glyphs, one instanced mesh. Clicking a glyph
(or typing a row) shows the grasp's numbers and the full gripper at its pose.
"""

from __future__ import annotations

import threading

import numpy as np

from graspsim.geometry.boxes import box_mesh
from graspsim.grippers.wireframe import gripper_wireframe
from graspsim.transforms import frame_from_axes, invert_transform, matrix_to_quat, transform_points
from graspsim.viewer.browser_view import BrowserView
from graspsim.viewer.columns import OUTCOME_PREFIX, REACH, Selection, ViewData
from graspsim.viewer.glyphs import PART_COLOURS, fork_glyph

__all__ = ["MapViewer", "OBJECT_COLOUR", "MAX_WIREFRAMES", "GLYPHS"]

GLYPHS = ("fork", "gripper wireframe")
MAX_WIREFRAMES = 300  # full-gripper glyphs drawn at most (72 edges each)
MAX_CLOUD = 200_000  # cloud points sent to the browser at most

#: colour of a single-part object (the screenshot test looks for it)
OBJECT_COLOUR = PART_COLOURS[0]


class MapViewer:
    """The scene and GUI of one map on ``server`` (a ``viser.ViserServer``)."""

    def __init__(self, server, data: ViewData, *, cloud: np.ndarray | None = None, mesh=None,
                 selection: Selection = Selection(), glyph_size: float = 0.5) -> None:
        self.server, self.data = server, data
        self.gmap = data.gmap
        self.gripper = self.gmap.meta.gripper_spec
        self._lock = threading.Lock()
        self.rows = np.zeros(0, int)  # what is drawn, in glyph instance order
        self.selected_rows = np.zeros(0, int)
        self.picked: int | None = None
        self.root = server.scene.add_frame("/map", show_axes=False)  # every map node under it
        placement = self.gmap.meta.placement
        self.T_obj_cloud = np.eye(4) if placement is None else invert_transform(placement.T_cloud_obj)
        self._draw_object()
        if placement is not None and placement.table is not None:
            self._draw_table(placement)
        if cloud is not None:
            cloud = np.asarray(cloud, float)
            if len(cloud) > MAX_CLOUD:  # a seeded subset: the browser needs no more
                cloud = cloud[np.sort(np.random.default_rng(0).choice(len(cloud), MAX_CLOUD, replace=False))]
            pts = transform_points(self.T_obj_cloud, cloud).astype(np.float32)
            self.cloud = server.scene.add_point_cloud("/map/cloud", pts, (40, 40, 40), point_size=0.0015,
                                                      point_shape="circle")
        if mesh is not None:
            v = transform_points(self.T_obj_cloud, np.asarray(mesh.vertices, float)).astype(np.float32)
            self.mesh = server.scene.add_mesh_simple("/map/mesh", v, np.asarray(mesh.faces),
                                                     color=(160, 160, 170), opacity=0.5)
        self._glyph = fork_glyph()
        self._build_gui(selection, glyph_size)
        server.scene.set_up_direction("+z")
        server.scene.configure_default_lights(cast_shadow=False)  # shadows cost more than they show
        server.scene.add_light_hemisphere("/light", intensity=0.6)
        self.view = BrowserView(server)
        self.frame_camera(self.extent + 3 * 0.02 * glyph_size)  # the object and its glyphs' reach
        self.refresh()

    # ------------------------------------------------------------------ static scene
    def _object_meshes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(vertices, faces) per part in the object frame ([] if the object is a mesh
        file or cannot be rebuilt)."""
        from graspsim.errors import GraspsimError
        from graspsim.primitives import Compound

        obj = self.gmap.meta.object
        if obj.get("file"):  # a mesh object (its frame is the object frame): its file, if readable
            from pathlib import Path

            from graspsim.sim.meshes import load_mesh

            path = Path(obj["file"])
            if not path.is_absolute() and self.data.path is not None:
                path = Path(self.data.path).parent / path  # as the simulator resolves it
            try:
                m = load_mesh(path, scale=float(obj.get("scale", 1.0)))
            except GraspsimError:
                return []
            return [(np.asarray(m.vertices), m.faces)]
        try:
            shape = self.gmap.meta.shape
        except (GraspsimError, KeyError, TypeError, ValueError):
            return []
        if isinstance(shape, Compound):
            out = []
            for part, T in zip(shape.parts, shape.poses):
                m = part.mesh(sections=48)
                out.append((transform_points(T, m.vertices), m.faces))
            return out
        m = shape.mesh(sections=48)
        return [(m.vertices, m.faces)]

    def _draw_object(self) -> None:
        """The parts, coloured by part; sets ``centre`` and ``extent`` (the bounding
        box's centre and half diagonal [m]) for the camera."""
        lo, hi = np.full(3, -0.03), np.full(3, 0.03)
        for i, (v, f) in enumerate(self._object_meshes()):
            self.server.scene.add_mesh_simple(f"/map/object/part{i}", np.asarray(v, np.float32),
                                              np.asarray(f, np.int32), color=PART_COLOURS[i % len(PART_COLOURS)])
            lo, hi = (np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))) if i else (v.min(axis=0),
                                                                                              v.max(axis=0))
        self.centre, self.extent = 0.5 * (lo + hi), float(0.5 * np.linalg.norm(hi - lo))

    def _draw_table(self, placement) -> None:
        """A translucent plate on the recorded support plane, under the object."""
        n_cloud = np.asarray(placement.table["normal"], float)
        h = float(placement.table.get("height") or 0.0)
        n = self.T_obj_cloud[:3, :3] @ n_cloud
        on_plane = transform_points(self.T_obj_cloud, h * n_cloud[None])[0]
        centre = n * float(np.dot(on_plane, n))  # the foot of the object origin on the plane
        R = frame_from_axes(np.eye(3)[int(np.argmin(np.abs(n)))], n)
        s = 3 * self.extent
        v, f = box_mesh(np.array([[0.0, 0.0, -0.001]]), np.array([[s, s, 0.001]]))
        self.table = self.server.scene.add_mesh_simple("/map/table", v, f, color=(200, 180, 150), opacity=0.6,
                                          receive_shadow=False, cast_shadow=False, wxyz=matrix_to_quat(R),
                                          position=centre)

    def frame_camera(self, extent: float) -> None:
        """Aim every (new) browser's camera at the object's centre from where a sphere of radius
        ``extent`` [m] fills about 60 % of the view (fov 75 deg)."""
        d = 1.4 * extent
        c = self.centre
        self.view.aim((c[0] + d, c[1] - d, c[2] + 0.6 * d), c)

    @property
    def camera(self) -> tuple[tuple, tuple]:
        """(position, look_at) [m] of the view new browsers get."""
        return self.view.pose

    # ------------------------------------------------------------------ GUI
    def _build_gui(self, sel: Selection, glyph_size: float) -> None:
        gui = self.server.gui
        m = self.gmap
        gui.add_markdown(f"**{_object_name(m.meta.object)}** · {len(m):,} grasps · "
                         f"{int(m.accepted.sum()):,} with grade > {m.threshold:g}")
        names = self.data.colour_names()
        self.g_colour = gui.add_dropdown("colour by", names, initial_value=sel.colour)
        self.g_min = gui.add_slider("min grade", 0.0, 1.0, 0.01, float(sel.min_grade))
        self.g_top = gui.add_number("top K (0: all)", int(sel.top_k), min=0, step=1)
        labels = ["any", *sorted(set().union(*(self.data.outcome_labels(g).values()
                                               for g in self.data.outcomes))), "not simulated"]
        self.g_outcome = gui.add_dropdown("outcome", labels if self.data.outcomes else ["any"],
                                          initial_value=sel.outcome, disabled=not self.data.outcomes)
        self.g_max = gui.add_slider("max drawn", 1, max(50_000, sel.max_drawn), 1, int(sel.max_drawn))
        self.g_glyph = gui.add_dropdown("glyphs", GLYPHS, initial_value=GLYPHS[0])
        self.g_size = gui.add_slider("glyph size", 0.1, 2.0, 0.05, float(glyph_size))
        self.g_status = gui.add_markdown("")
        self.g_scale = gui.add_markdown("")
        with gui.add_folder("grasp"):
            self.g_row = gui.add_number("row", -1, min=-1, max=len(m) - 1, step=1)
            self.g_details = gui.add_markdown("click a grasp (or type its row)")
        for h in (self.g_colour, self.g_min, self.g_top, self.g_outcome, self.g_max, self.g_glyph, self.g_size):
            h.on_update(lambda _: self.refresh())
        self.g_row.on_update(lambda _: self.pick(int(self.g_row.value)))

    def selection(self) -> Selection:
        return Selection(colour=self.g_colour.value, min_grade=float(self.g_min.value),
                         outcome=self.g_outcome.value, top_k=int(self.g_top.value or 0),
                         max_drawn=int(self.g_max.value))

    # ------------------------------------------------------------------ drawing
    def refresh(self) -> None:
        """Apply the GUI's filters to all grasps and redraw the glyphs."""
        with self._lock:
            sel = self.selection()
            self.selected_rows = self.data.selected(sel)
            wire = self.g_glyph.value != GLYPHS[0]
            self.rows = self.data.drawn(self.selected_rows, min(sel.max_drawn, MAX_WIREFRAMES) if wire
                                        else sel.max_drawn)
            self._draw_glyphs(sel, wire)
        self.g_status.content = (f"showing {len(self.rows):,} of {len(self.selected_rows):,} selected "
                                 f"({len(self.gmap):,} in the map)"
                                 + (f"; at most {MAX_WIREFRAMES} wireframes" if wire else ""))

    def _draw_glyphs(self, sel: Selection, wire: bool) -> None:
        rows, m = self.rows, self.gmap
        if not len(rows):
            self.server.scene.remove_by_name("/map/grasps")
            self.server.scene.remove_by_name("/map/wires")
            return
        colours, (lo, hi) = self.data.colours(rows, sel.colour)
        self.g_scale.content = ("green: success, red: dropped, orange: slipped, grey: start collision"
                                if sel.colour.startswith(OUTCOME_PREFIX) else
                                "green: reachable, light green: first cut only, red: unreachable, grey: unchecked"
                                if sel.colour == REACH else f"{sel.colour}: purple {lo:.3g} → yellow {hi:.3g}")
        s = float(self.g_size.value)
        opening = self.gripper.pregrasp_opening(m.width[rows])
        if wire:  # the full gripper's boxes at each pose, edges in the grasp's colour (forks: to click)
            seg = gripper_wireframe(self.gripper, m.select(rows).T_obj_wrist, opening)
            self.server.scene.add_line_segments(
                "/map/wires", seg, np.repeat(colours, len(seg) // len(rows), axis=0)[:, None].repeat(2, axis=1),
                thickness=1.5, thickness_units="screen")
        else:
            self.server.scene.remove_by_name("/map/wires")
        scales = np.stack([opening, np.full(len(rows), s), np.full(len(rows), s)], axis=1)
        handle = self.server.scene.add_batched_meshes_simple(
            "/map/grasps", *self._glyph, batched_wxyzs=m.wrist_quat[rows], batched_positions=m.grasp_point[rows],
            batched_scales=scales.astype(np.float32), batched_colors=colours, lod="off",
            cast_shadow=False, receive_shadow=False)
        handle.on_click(self._on_click)

    def set_visible(self, on: bool) -> None:
        """Show or hide everything of the map (e.g. while a replay plays)."""
        self.root.visible = bool(on)

    def _on_click(self, event) -> None:
        rows = self.rows
        i = event.instance_index
        if i is None or not 0 <= i < len(rows):  # no instance id: the grasp nearest the ray
            o, d = np.asarray(event.ray_origin), np.asarray(event.ray_direction)
            p = self.gmap.grasp_point[rows] - o
            i = int(np.argmin(np.linalg.norm(p - np.outer(p @ d, d), axis=1)))
        self.g_row.value = int(rows[i])  # its on_update picks it

    def pick(self, row: int) -> None:
        """Show grasp ``row``'s numbers and the full gripper at its pose (-1: none)."""
        if not 0 <= row < len(self.gmap):
            self.picked = None
            self.server.scene.remove_by_name("/map/picked")
            self.g_details.content = "click a grasp (or type its row)"
            return
        self.picked = row
        m = self.gmap
        T = m.select([row]).T_obj_wrist[0]
        seg = gripper_wireframe(self.gripper, T, float(self.gripper.pregrasp_opening(m.width[row])))
        self.server.scene.add_line_segments("/map/picked/gripper", seg, (20, 20, 20), thickness=2.0,
                                            thickness_units="screen")
        self.server.scene.add_point_cloud("/map/picked/contacts", m.contacts[row].astype(np.float32),
                                          (230, 30, 30), point_size=0.004, point_shape="circle")
        self.g_details.content = _details_markdown(self.data.details(row))


def _object_name(obj: dict) -> str:
    if obj.get("primitive"):
        return str(obj["primitive"])
    if obj.get("parts"):
        return f"compound of {len(obj['parts'])} parts"
    return str(obj.get("file", "object"))


def _details_markdown(d: dict) -> str:
    lines = []
    for k, v in d.items():
        if isinstance(v, float):
            v = f"{v:.4g}"
        lines.append(f"- **{k}**: {v}")
    return "\n".join(lines)
