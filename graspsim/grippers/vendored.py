"""Gripper models simulated as authored: where the vendored ones live, how a model mounts.

A gripper with a ``model`` (a vendored folder name such as ``franka_hand``, in
``mjcf/<name>/<name>.xml``, or a model file's path) is simulated from its model file as it is:
:func:`graspsim.sim.harness.build_gripper_spec` attaches the file's root body
under the harness's wrist body at the pose its :class:`Mount` gives. The mount is
measured from the file (:mod:`graspsim.grippers.model_file`): the gripper's joints and
their positions at every opening of its table, the two jaw joints (one per side), the
two pad geoms (contact sensors), the actuators and their controls that close, open and
hold each opening, and the model's own grip force.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim.errors import GripperError

__all__ = ["Mount", "mjcf_root", "model_folder"]


@dataclass(frozen=True, eq=False)
class Mount:
    """How a model sits on the wrist and is driven. pos [m], quat (w, x, y, z): the
    model's root body frame in the wrist frame (z = approach, x = closing axis).

    joints (J,): the gripper's joints; openings (K,) [m]: the pad gaps of the opening
    table, qpos (K, J) the joints there, ctrl_hold (K, nu) the controls that hold each
    row (position actuators; ``hold`` False: force actuators, held by 0); ctrl_open /
    ctrl_close (nu,): the controls that open / close. pad_z (K, 2) [m]: height of each
    pad's centre above the wrist origin at each row (the pads' arc; constant for a
    prismatic gripper). pad_face (K, 2, 2) [m]: each pad's flat face at each row, (upper
    end, lower end) above the wrist origin (None: a cache from before it was measured).
    model_force: the model's grip force per finger [N]."""

    name: str
    path: Path
    root_body: str
    jaw_joints: tuple[str, str]      # (neg, pos): the fingers at -x / +x of the wrist
    pad_geoms: tuple[str, str]       # (neg, pos)
    actuators: tuple[str, ...]
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    joints: tuple[str, ...]
    openings: np.ndarray
    qpos: np.ndarray
    ctrl_open: np.ndarray
    ctrl_close: np.ndarray
    ctrl_hold: np.ndarray
    hold: bool
    model_force: float
    pad_z: np.ndarray
    prismatic: bool
    options: tuple = ()
    pad_face: np.ndarray | None = None

    @property
    def xml(self) -> Path:
        return self.path

    @property
    def actuator(self) -> str:
        return self.actuators[0]

    def joint_positions(self, openings) -> np.ndarray:
        """(N, J) the gripper's joints at pad gaps ``openings`` (N,) [m] (the table, interpolated)."""
        w = np.atleast_1d(np.asarray(openings, float))
        return np.stack([np.interp(w, self.openings, self.qpos[:, j]) for j in range(self.qpos.shape[1])], -1)


def mjcf_root() -> Path:
    """``mjcf``: the model folders, installed with the package (package data)."""
    from graspsim._resources import package_path

    return package_path("mjcf")


def model_folder(name: str) -> Path:
    """The folder of the vendored model ``name``; a clear error when it is missing."""
    folder = mjcf_root() / name
    if not (folder / f"{name}.xml").is_file():
        have = sorted(p.name for p in mjcf_root().glob("*") if (p / f"{p.name}.xml").is_file())
        raise GripperError(f"no vendored gripper model {name!r} (looked for {folder / (name + '.xml')}); "
                           f"available: {have}")
    return folder
