"""Trial recordings: the trajectories a batch of trials already computes, kept small.

:func:`graspsim.sim.batch.run_trials` records every step of every simulated trial to
judge it; a :class:`Recorder` passed as its ``on_record`` hook keeps those records at
``fps`` frames per second (float32), and :meth:`TrialRecording.save` writes them with the
scene's object surface, the gripper and the outcomes to one compressed ``.npz`` (atomic)
that ``graspsim view --replay`` plays back. Trials whose start pose collided were not
simulated and have no trajectory; they are not in the recording.

Sizes: a two-second ``lift_place`` trial at 25 fps is 51 frames x 16 floats, ~3 kB per
trial before compression.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim.errors import InvalidParameterError, MapFileError

__all__ = ["TrialRecording", "Recorder", "load_recording", "RECORDING_FORMAT"]

RECORDING_FORMAT = "graspsim-trials-1"
_ARRAYS = ("time", "rows", "outcome", "wrist_pos", "wrist_quat", "obj_pos", "obj_quat", "jaws",
           "vertices", "faces")


@dataclass(frozen=True, eq=False)
class TrialRecording:
    """n recorded trials of S frames, world frame (table top at z = 0).

    time: (S,) [s]; rows: (n,) map rows of the trials; outcome: (n,) int8
    :class:`~graspsim.sim.TrialOutcome` codes; wrist_pos (n, S, 3) [m], wrist_quat
    (n, S, 4) w, x, y, z; obj_pos (n, S, 3) [m] and obj_quat (n, S, 4): the object frame;
    jaws (n, S, 2) half openings [m]; vertices (V, 3) [m] and faces (F, 3): the object's
    surface in the object frame; gripper: ``GripperSpec.to_dict()``; protocol: the
    protocol record; table: whether the scene has a table.
    """

    time: np.ndarray
    rows: np.ndarray
    outcome: np.ndarray
    wrist_pos: np.ndarray
    wrist_quat: np.ndarray
    obj_pos: np.ndarray
    obj_quat: np.ndarray
    jaws: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    gripper: dict
    protocol: dict
    table: bool = True

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def gripper_spec(self):
        from graspsim.grippers.spec import GripperSpec

        return GripperSpec.from_dict(self.gripper)

    def save(self, path: str | os.PathLike) -> Path:
        """Write to ``path`` (a compressed ``.npz``) atomically; returns the path."""
        from graspsim._atomic import atomic_path

        path = Path(path)
        meta = json.dumps({"format": RECORDING_FORMAT, "gripper": self.gripper,
                           "protocol": self.protocol, "table": bool(self.table)}, sort_keys=True)
        try:
            with atomic_path(path) as tmp, open(tmp, "wb") as fh:
                np.savez_compressed(fh, meta=np.array(meta), **{k: getattr(self, k) for k in _ARRAYS})
        except OSError as err:
            raise MapFileError(f"cannot write the trial recording {path}: {err}") from err
        return path


def load_recording(path: str | os.PathLike) -> TrialRecording:
    """Read a file written by :meth:`TrialRecording.save`; anything else raises
    :class:`MapFileError` naming the problem."""
    import zipfile

    path = Path(path)
    if not path.is_file():
        raise MapFileError(f"trial recording {path} does not exist")
    if not zipfile.is_zipfile(path):
        raise MapFileError(f"{path} is not a graspsim trial recording (not an .npz file; write one with "
                           "'graspsim trial MAP --record FILE.npz')")
    try:
        with np.load(path, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile) or "meta" not in z.files:
                raise MapFileError(f"{path} is not a graspsim trial recording (no meta)")
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != RECORDING_FORMAT:
                raise MapFileError(f"{path} is not a graspsim trial recording "
                                   f"(format {meta.get('format')!r}, expected {RECORDING_FORMAT!r})")
            missing = [k for k in _ARRAYS if k not in z.files]
            if missing:
                raise MapFileError(f"{path} is a damaged trial recording: missing {', '.join(missing)}")
            arrays = {k: z[k] for k in _ARRAYS}
    except (OSError, ValueError, TypeError, EOFError, KeyError, zipfile.BadZipFile) as err:
        raise MapFileError(f"{path} is not a readable trial recording: {err}") from err
    rec = TrialRecording(**arrays, gripper=meta["gripper"], protocol=meta["protocol"],
                         table=bool(meta.get("table", True)))
    n, s = len(rec.rows), len(rec.time)
    for k, tail in (("outcome", ()), ("wrist_pos", (s, 3)), ("wrist_quat", (s, 4)),
                    ("obj_pos", (s, 3)), ("obj_quat", (s, 4)), ("jaws", (s, 2))):
        if getattr(rec, k).shape != (n, *tail):
            raise MapFileError(f"{path} is a damaged trial recording: {k} has shape "
                               f"{getattr(rec, k).shape}, expected {(n, *tail)}")
    return rec


class Recorder:
    """The ``on_record`` hook of :func:`~graspsim.sim.batch.run_trials`: keeps every
    trial's record at ``fps`` frames per second (at most ``max_trials`` trials, the first
    ones simulated)."""

    def __init__(self, *, fps: float = 25.0, max_trials: int = 2000) -> None:
        if not fps > 0:
            raise InvalidParameterError(f"fps must be > 0, got {fps!r}")
        if max_trials < 1:
            raise InvalidParameterError(f"max_trials must be >= 1, got {max_trials!r}")
        self.fps, self.max_trials = float(fps), int(max_trials)
        self._parts: list[tuple[np.ndarray, object]] = []
        self._kept = 0

    def __call__(self, index: np.ndarray, record) -> None:
        """index: (n,) trial numbers (positions in the batch); record: their
        :class:`~graspsim.sim.outcomes.Record`."""
        room = self.max_trials - self._kept
        if room <= 0:
            return
        k = min(room, len(index))
        t = record.time[0]
        dt = float(t[1] - t[0]) if len(t) > 1 else 1.0  # the scene's timestep [s]
        s = slice(None, None, max(1, int(round(1.0 / (self.fps * dt)))))
        f32 = np.float32
        self._parts.append((np.asarray(index[:k]), {
            "time": np.asarray(record.time[0, s], float),
            "wrist_pos": record.wrist_pos[:k, s].astype(f32), "wrist_quat": record.wrist_quat[:k, s].astype(f32),
            "obj_pos": record.obj_pos[:k, s].astype(f32), "obj_quat": record.obj_quat[:k, s].astype(f32),
            "jaws": record.jaws[:k, s].astype(f32)}))
        self._kept += k

    def recording(self, scene, rows: np.ndarray, outcome: np.ndarray, protocol: dict) -> TrialRecording:
        """The kept trials as a :class:`TrialRecording`; rows, outcome: (N,) map rows
        and outcome codes of every trial of the batch (indexed by trial number)."""
        if not self._parts:
            raise InvalidParameterError("no trial was simulated (every start pose collided): "
                                        "nothing to record")
        index = np.concatenate([i for i, _ in self._parts])
        cat = {k: np.concatenate([p[k] for _, p in self._parts]) for k in
               ("wrist_pos", "wrist_quat", "obj_pos", "obj_quat", "jaws")}
        surf = scene.obj.surface
        return TrialRecording(
            time=self._parts[0][1]["time"] - self._parts[0][1]["time"][0],
            rows=np.asarray(rows)[index].astype(np.int64), outcome=np.asarray(outcome)[index].astype(np.int8),
            **cat, vertices=np.asarray(surf.vertices, np.float32), faces=np.asarray(surf.faces, np.int32),
            gripper=scene.gripper.to_dict(), protocol=protocol, table=bool(scene.table))
