"""Deliberate breaks that the success-rate regression must catch (its own self-test).

Each :class:`Mutation` patches the library where such a bug would live, for the
duration of a ``with mutated(name):`` block, and names the bands it trips by a wide
margin (``trips``: the suite runs just those sets, to stay short);
``experiments/golden_regression.py --mutations`` runs every mutation on every case and
records which bands trip in tests/data/regression_mutations.json. Grade mutations change
the maps, so the cases must be rebuilt inside the block; the others change only the
simulation.

* ``wrist_frame_-5mm`` / ``wrist_frame_+5mm``: the simulated gripper sits 5 mm off the
  planner's wrist frame along the approach (every part of the MuJoCo gripper shifted
  along the wrist's z): contacts 5 mm nearer the fingertips, or nearer the palm.
* ``normals_flipped``: the grade's force-closure angle takes the contact normals inward.
* ``stability_dropped``: the grade is force closure alone (stability weight 0).
* ``grip_below_weight``: grip force per jaw 0.6 x m g / (2 mu), less than friction needs
  to hold the object's weight.
* ``grip_force_div10`` / ``pad_friction_0.075``: the issue's measured breaks (8 N -> 0.8 N
  per jaw; pad mu 0.5 -> 0.075).
* ``mass_not_applied``: the condition's mass is ignored (the light map masses again):
  a break that raises success, for the ceilings.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from graspsim.errors import InvalidParameterError

__all__ = ["Mutation", "MUTATIONS", "mutated"]

_G = 9.81


@dataclass(frozen=True)
class Mutation:
    """A break: ``patches`` ((module, attribute, wrapper of the original), ...);
    ``trips``: bands ("<case group>/<set>") it trips by a wide margin in the full run
    (the suite checks those); ``regrade``: it changes map grades (rebuild the cases
    inside the block)."""

    name: str
    description: str
    patches: tuple[tuple[str, str, Callable], ...]
    trips: tuple[str, ...]
    regrade: bool = False


def _shift_gripper(dz: float):
    """build_gripper_spec whose gripper parts sit ``dz`` [m] along the wrist's z."""
    def wrap(orig):
        def build(*args, **kwargs):
            spec = orig(*args, **kwargs)
            wrist = spec.body("wrist")
            for el in (*wrist.geoms, *wrist.bodies, *wrist.sites):
                el.pos = np.asarray(el.pos, float) + [0.0, 0.0, dz]
            return spec
        return build
    return wrap


def _scene_settings(change: Callable):
    """build_scene whose settings are ``change(settings, obj, gripper)``."""
    def wrap(orig):
        def build(obj, gripper=None, settings=None, **kwargs):
            from graspsim.grippers.spec import HGPL_25_60_A
            from graspsim.sim.trial_scene import SimSettings

            gripper = gripper or HGPL_25_60_A
            settings = settings or SimSettings()
            return orig(obj, gripper, change(settings, obj, gripper), **kwargs)
        return build
    return wrap


def _force(s, gripper) -> float:
    return float(gripper.grip_force if s.grip_force is None else s.grip_force)


def _flip_normals(orig):
    return lambda p1, p2, n1, n2: orig(p1, p2, -np.asarray(n1), -np.asarray(n2))


def _force_closure_only(orig):
    def combine(self, q_fc, dist, d_ref):
        q_st, _ = orig(self, q_fc, dist, d_ref)
        return q_st, np.asarray(q_fc, float)
    return combine


_SCENE = ("graspsim.sim", "build_scene")
MUTATIONS: dict[str, Mutation] = {m.name: m for m in (
    Mutation("wrist_frame_-5mm", "gripper 5 mm back along the approach (contacts nearer the tips)",
             (("graspsim.sim.trial_scene", "build_gripper_spec", _shift_gripper(-0.005)),), ("half_toroid/hi",)),
    Mutation("wrist_frame_+5mm", "gripper 5 mm forward along the approach (contacts nearer the palm)",
             (("graspsim.sim.trial_scene", "build_gripper_spec", _shift_gripper(0.005)),), ("half_toroid/hi",)),
    Mutation("normals_flipped", "the grade's force-closure angle with inward contact normals",
             (("graspsim.grades.paper", "force_closure_angle", _flip_normals),), ("cylinder/hi", "box/lo"),
             regrade=True),
    Mutation("stability_dropped", "the grade is force closure alone (no stability term)",
             (("graspsim.grades.paper", "QualityModel.combine", _force_closure_only),), ("cone/hi", "sphere/lo"),
             regrade=True),
    Mutation("grip_below_weight", "grip force per jaw 0.6 m g / (2 mu): friction cannot hold the weight",
             (_SCENE + (_scene_settings(lambda s, obj, g: replace(
                 s, grip_force=0.6 * obj.mass * _G / (2.0 * s.friction))),),), ("cylinder/hi",)),
    Mutation("grip_force_div10", "grip force per jaw cut 10 x",
             (_SCENE + (_scene_settings(lambda s, obj, g: replace(s, grip_force=_force(s, g) / 10.0)),),),
             ("cylinder/hi",)),
    Mutation("pad_friction_0.075", "pad friction 0.075 instead of 0.5",
             (_SCENE + (_scene_settings(lambda s, obj, g: replace(s, friction=0.075)),),), ("cylinder/hi",)),
    Mutation("mass_not_applied", "the condition's object mass is not applied (light map masses)",
             (("graspsim.calibration.trials", "conditioned_object", lambda orig: lambda obj, cond: obj),),
             ("box/lo",)),
)}


def _resolve(module: str, attr: str):
    owner = importlib.import_module(module)
    *path, name = attr.split(".")
    for p in path:
        owner = getattr(owner, p)
    return owner, name


@contextmanager
def mutated(name: str):
    """Apply the mutation ``name`` (see :data:`MUTATIONS`) inside the block."""
    if name not in MUTATIONS:
        raise InvalidParameterError(f"unknown mutation {name!r}; valid: {sorted(MUTATIONS)}")
    undo = []
    try:
        for module, attr, wrap in MUTATIONS[name].patches:
            owner, key = _resolve(module, attr)
            orig = getattr(owner, key)
            undo.append((owner, key, orig))
            setattr(owner, key, wrap(orig))
        yield MUTATIONS[name]
    finally:
        for owner, key, orig in reversed(undo):
            setattr(owner, key, orig)
