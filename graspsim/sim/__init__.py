"""MuJoCo validation of grasps on one object: gripper model, trial scenes, trial protocols,
batched runs, map simulation and recordings. Table-top scenes of several objects (the
depth camera, clutter removal) are :mod:`graspsim.tabletop`, which builds on this package.

May use: the base modules, primitives, grippers, grades, maps and plots (never
perception, planning, tabletop or anything above).

With :mod:`graspsim.tabletop` (and the environments), the only package that imports mujoco. Build once, run many::

    obj = object_from_shape(Cylinder(0.02, 0.20))
    scene = build_scene(obj, HGPL_25_60_A, SimSettings())
    results = run_trials(scene, T_obj_wrist, widths, LiftPlace(), threads=2)
    results.counts(), results.success_rate

or, for a map file, ``simulate_map(path, top=50)``.
"""

from __future__ import annotations

from graspsim._gl import default_gl

default_gl()  # before any submodule imports mujoco

from graspsim.sim.batch import initial_states, pregrasp_opening, run_trials, start_penetration  # noqa: E402
from graspsim.sim.harness import build_gripper_spec, gripper_xml  # noqa: E402
from graspsim.sim.mapsim import MapTrials, map_object, select_grasps, simulate_map, write_results  # noqa: E402
from graspsim.sim.meshes import CoacdParams, PreparedMesh, convex_parts, load_mesh, prepare_mesh, surface_model  # noqa: E402
from graspsim.sim.model import GripperPhysics  # noqa: E402
from graspsim.sim.noise import ExecutionNoise  # noqa: E402
from graspsim.sim.objects import SimObject, object_from_mesh, object_from_shape  # noqa: E402
from graspsim.sim.outcomes import TrialOutcome  # noqa: E402
from graspsim.sim.protocols import PROTOCOLS, LiftPlace, Protocol, Tug, make_protocol  # noqa: E402
from graspsim.sim.results import RESULT_GROUPS, TrialResults  # noqa: E402
from graspsim.sim.trial_scene import (  # noqa: E402
    CONTACT_MODELS,
    Scene,
    SimSettings,
    build_scene,
    contact_model,
    contact_settings,
    resting_pose,
)

__all__ = [
    "GripperPhysics", "build_gripper_spec", "gripper_xml",
    "SimObject", "object_from_shape", "object_from_mesh", "CoacdParams", "convex_parts", "load_mesh",
    "prepare_mesh", "PreparedMesh", "surface_model",
    "SimSettings", "CONTACT_MODELS", "contact_model", "contact_settings", "Scene", "build_scene", "resting_pose",
    "Protocol", "LiftPlace", "Tug", "PROTOCOLS", "make_protocol", "ExecutionNoise",
    "TrialOutcome", "TrialResults", "RESULT_GROUPS",
    "run_trials", "start_penetration", "initial_states", "pregrasp_opening",
    "MapTrials", "simulate_map", "select_grasps", "map_object", "write_results",
    "render_trial",
]


def __getattr__(name: str):
    if name == "render_trial":  # keeps PIL out of plain imports
        from graspsim.sim.trial_render import render_trial

        return render_trial
    raise AttributeError(f"module 'graspsim.sim' has no attribute {name!r}")
