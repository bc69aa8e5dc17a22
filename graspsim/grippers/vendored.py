"""Vendored MuJoCo gripper models: where they live and how they mount on the wrist.

A vendored model (``mjcf/<name>/<name>.xml``, authored outside graspsim) is simulated
as it is: :func:`graspsim.sim.vendored.build_vendored_gripper_spec` attaches its root
body under the harness's wrist body at ``T_wrist_root``. A :class:`Mount` names the
elements the trial harness needs: the two jaw joints (value = half the pad gap [m]),
the two pad geoms (contact sensors) and the grip actuator (control in [-1, 1]: -1
closes with the grip force, +1 opens; the harness's valve convention).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from graspsim.errors import GripperError

__all__ = ["Mount", "mjcf_root", "model_folder"]


@dataclass(frozen=True)
class Mount:
    """How a vendored model sits on the wrist. pos [m], quat (w, x, y, z): the model's
    root body frame in the wrist frame (z = approach, x = closing axis)."""

    name: str
    root_body: str
    jaw_joints: tuple[str, str]      # (neg, pos): the fingers at -x / +x of the wrist
    pad_geoms: tuple[str, str]       # (neg, pos)
    actuator: str
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]

    @property
    def xml(self) -> Path:
        return model_folder(self.name) / f"{self.name}.xml"


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
