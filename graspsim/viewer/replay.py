"""Trial replay in the viewer: a recorded trial's gripper and object moving on a timeline.

A :class:`~graspsim.sim.recording.TrialRecording` is in the simulator's world frame
(table top at z = 0). The replay is drawn under one scene node placed so that the
object's first recorded pose coincides with the map's object frame: the replayed object
starts where the map's object is, and a failed grasp can be watched against its map.
GUI: the trial (map row and outcome), a frame slider (the timeline), play / pause and
a checkbox that shows the replay instead of the map's glyphs.
"""

from __future__ import annotations

import threading

import numpy as np

from graspsim.geometry.boxes import box_mesh
from graspsim.transforms import invert_transform, make_transform, matrix_to_quat, quat_to_matrix
from graspsim.viewer.glyphs import OUTCOME_COLOURS

__all__ = ["Replay", "gripper_mesh_at"]


def gripper_mesh_at(gripper, T_world_wrist: np.ndarray, opening: float) -> tuple[np.ndarray, np.ndarray]:
    """The gripper's collision boxes (arm keep-out left out) as one mesh [m], world
    frame, at a wrist pose (4, 4) and pad gap ``opening`` [m]."""
    b = gripper.collision_boxes()
    keep = np.array([n != "arm" for n in b.names])
    centers = b.centers.copy()
    centers[:, 0] += b.x_sign * 0.5 * opening
    v, f = box_mesh(centers[keep], b.half_extents[keep])
    T = np.asarray(T_world_wrist, float)
    return (v @ T[:3, :3].T + T[:3, 3]).astype(np.float32), f


def _pose(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    return make_transform(quat_to_matrix(np.asarray(quat, float)), np.asarray(pos, float))


class Replay:
    """The replay GUI and scene of ``recording`` on ``server``; ``hide``: a
    :class:`~graspsim.viewer.app.MapViewer` whose glyphs are hidden while replaying."""

    def __init__(self, server, recording, *, hide=None) -> None:
        from graspsim.sim.outcomes import TrialOutcome

        self.server, self.rec, self.viewer = server, recording, hide
        self.gripper = recording.gripper_spec
        self.trial = 0
        self._stop = threading.Event()
        labels = [f"row {int(r)}: {TrialOutcome(int(o)).label}" for r, o in zip(recording.rows, recording.outcome)]
        gui = server.gui
        with gui.add_folder("trial replay"):
            self.g_on = gui.add_checkbox("replay", True)
            self.g_trial = gui.add_dropdown("trial", labels, initial_value=labels[0])
            self.g_frame = gui.add_slider("frame", 0, len(recording.time) - 1, 1, 0)
            self.g_play = gui.add_checkbox("play", True)
            self.g_time = gui.add_markdown("")
        self._labels = labels
        self.root = server.scene.add_frame("/replay", show_axes=False)
        if recording.table:
            v, f = box_mesh(np.array([[0.0, 0.0, -0.005]]), np.array([[0.25, 0.25, 0.005]]))
            server.scene.add_mesh_simple("/replay/table", v, f, color=(200, 180, 150), opacity=0.6,
                                         receive_shadow=False, cast_shadow=False)
        self.obj = server.scene.add_mesh_simple("/replay/object", recording.vertices, recording.faces,
                                                color=(230, 120, 60))
        self.g_trial.on_update(lambda _: self._select(self._labels.index(self.g_trial.value)))
        self.g_frame.on_update(lambda _: self.show_frame(int(self.g_frame.value)))
        self.g_on.on_update(lambda _: self._visibility())
        if hide is not None:  # the gripper is larger than most objects: step back
            hide.frame_camera(max(hide.extent, 0.6 * float(np.ptp(recording.vertices, axis=0).max()), 0.15))
        self._select(0)
        self._visibility()
        self._thread = threading.Thread(target=self._play, name="graspsim-replay", daemon=True)
        self._thread.start()

    def _select(self, k: int) -> None:
        self.trial = k
        # the replay's frame: the object's first pose onto the map's object frame
        T0 = _pose(self.rec.obj_pos[k, 0], self.rec.obj_quat[k, 0])
        T = invert_transform(T0)
        self.root.wxyz, self.root.position = matrix_to_quat(T[:3, :3]), T[:3, 3]
        self.show_frame(int(self.g_frame.value))

    def show_frame(self, s: int) -> None:
        """Draw frame ``s`` of the chosen trial."""
        from graspsim.sim.outcomes import TrialOutcome

        r, k = self.rec, self.trial
        s = int(np.clip(s, 0, len(r.time) - 1))
        self.obj.position = r.obj_pos[k, s]
        self.obj.wxyz = r.obj_quat[k, s]
        T = _pose(r.wrist_pos[k, s], r.wrist_quat[k, s])
        opening = float(np.clip(r.jaws[k, s].sum(), self.gripper.min_opening, self.gripper.max_opening))
        v, f = gripper_mesh_at(self.gripper, T, opening)
        colour = OUTCOME_COLOURS.get(TrialOutcome(int(r.outcome[k])).label, (120, 120, 120))
        self.server.scene.add_mesh_simple("/replay/gripper", v, f, color=colour, opacity=0.8)
        self.g_time.content = f"t = {r.time[s]:.2f} s of {r.time[-1]:.2f} s"

    def _visibility(self) -> None:
        on = bool(self.g_on.value)
        self.root.visible = on
        if self.viewer is not None:
            self.viewer.set_visible(not on)

    def _play(self) -> None:
        """Advance the timeline at the recording's rate while ``play`` is ticked."""
        r = self.rec
        dt = float(r.time[1] - r.time[0]) if len(r.time) > 1 else 0.04
        while not self._stop.wait(dt):
            if self.g_play.value and self.g_on.value:
                self.g_frame.value = (int(self.g_frame.value) + 1) % len(r.time)

    def stop(self) -> None:
        """End the playback thread."""
        self._stop.set()
        self._thread.join(timeout=2.0)
