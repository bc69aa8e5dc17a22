"""graspsim: graspability maps from shape primitives for two-jaw grippers.

Implements Eizicovits & Berman (2018), "Automatic graspability map generation based on
shape-primitives for unknown and familiar objects", with MuJoCo validation.

The names users reach for first are here, one import away::

    import numpy as np
    import graspsim as gs

    fs = gs.generate_fs_map(gs.Cylinder(radius=0.02, height=0.2))  # every collision-free pose
    best = fs.filter(accepted=True).top_k(10)                          # grade > 0.7, best first
    cloud = gs.synthetic_cloud(gs.Sphere(0.04), np.random.default_rng(0), noise=0.001)
    result = gs.plan(cloud.points, db=gs.MapDatabase(), rng=np.random.default_rng(0))

* shapes: ``Box``, ``Cylinder``, ``Sphere``, ``Cone``, ``HalfToroid``, ``Compound``,
  ``make_primitive``, ``synthetic_cloud``; the gripper: ``GripperSpec``, ``HGPL_25_60_A``,
  ``get_gripper`` (``"festo_hgpl_25_60_a"``, ``"franka_hand"`` or a spec .json);
  the grade: ``QualityModel``, ``get_grade``, ``regrade``.
* maps: ``generate_fs_map``, ``MapConfig``, ``GraspabilityMap``, ``load_map``,
  ``save_map``, ``map_rates``, ``MapDatabase``, ``adapt_to_gripper`` (a map carried to
  another gripper, paper section 5); robust scores (clearance to the observed
  cloud, success under wrist pose error): ``RobustConfig``, ``score_map``; planning from a
  cloud or a known shape (ranked by the robust score): ``plan``, ``plan_shape``,
  ``PlannerConfig``, ``TablePlane``; perception: ``identify``,
  ``read_point_cloud``, ...
* simulation (MuJoCo): ``simulate_map``, ``run_trials``, ``build_scene``, ...
* errors: every exception is a ``GraspsimError``.

Only the errors are imported eagerly; every other name is imported on first use (PEP 562
``__getattr__``), so ``import graspsim`` loads neither trimesh, scipy, numba nor mujoco.
It registers the Gymnasium environments ``graspsim/GraspSelect-v0``,
``graspsim/GraspPose-v0`` and ``graspsim/ClutterClear-v0`` (by entry-point strings, and only once gymnasium itself is
imported, so that this import stays light: see :mod:`graspsim.envs`).
"""

from __future__ import annotations

import importlib

from graspsim._blas import pin_blas as _pin_blas
from graspsim._version import __version__  # noqa: E402
from graspsim.envs import register_when_imported as _register_envs
from graspsim.errors import (
    DependencyNotInstalled,
    GraspsimError,
    GripperError,
    IdentificationError,
    InvalidParameterError,
    MapDatabaseError,
    MapFileError,
    MeshError,
    NoFeasibleGraspError,
    PointCloudError,
    PrimitiveError,
    SimulationError,
)

_pin_blas()  # before numpy loads: the same BLAS kernels on every x86-64 CPU with AVX2 (graspsim._blas)


def _from(module: str, *names: str) -> dict[str, str]:
    return dict.fromkeys(names, module)


# public name -> the module that defines it, imported when the name is first used
_LAZY: dict[str, str] = {
    # geometry
    **_from("graspsim.primitives", "Primitive", "Box", "Cylinder", "Sphere", "Cone", "HalfToroid",
            "Compound", "make_primitive", "synthetic_cloud"),
    # gripper and grades
    **_from("graspsim.grippers.spec", "GripperSpec", "HGPL_25_60_A"),
    **_from("graspsim.grippers", "get_gripper", "gripper_names"),
    **_from("graspsim.grades.paper", "QualityModel"),
    **_from("graspsim.grades", "get_grade", "regrade", "PaperGrade", "LogisticGrade"),
    # maps: generation, files, metrics, the full-scale database
    **_from("graspsim.maps.generate", "generate_fs_map"),
    **_from("graspsim.maps.map_config", "MapConfig"),
    **_from("graspsim.maps.graspmap", "GraspabilityMap", "MapMeta"),
    **_from("graspsim.maps.io", "load_map", "save_map"),
    **_from("graspsim.maps.metrics", "map_rates"),
    **_from("graspsim.maps.database", "MapDatabase"),
    **_from("graspsim.maps.robust", "RobustConfig", "score_map"),
    **_from("graspsim.maps.regrip", "adapt_to_gripper"),
    # run-time planning: point cloud (or known shape) -> adapted map
    **_from("graspsim.planning.planner", "plan", "plan_shape", "PlannerConfig", "PlanResult", "PlanStatus"),
    **_from("graspsim.geometry.table", "TablePlane"),
    # perception: point-cloud input and primitive identification (paper 2.2-2.3)
    **_from("graspsim.perception", "identify", "IdentifyConfig", "Identification",
            "IdentificationStatus", "PartResult", "Shape", "read_point_cloud", "LoadedCloud",
            "min_volume_box", "OrientedBox"),
    **_from("graspsim.maps.match", "classify_match", "MatchKind", "MatchDecision"),
    # scenes: a table with several objects -> ranked grasps
    **_from("graspsim.planning.scene", "plan_scene", "perceive_scene", "ScenePlan", "SceneGrasp"),
    **_from("graspsim.planning.scene_config", "SceneConfig"),
    # grade-vs-success calibration
    **_from("graspsim.calibration", "calibrate", "TrialTable"),
    # MuJoCo validation
    **_from("graspsim.sim", "TrialOutcome", "TrialResults", "SimSettings", "GripperPhysics",
            "LiftPlace", "Tug", "ExecutionNoise", "SimObject", "Scene", "object_from_shape",
            "object_from_mesh", "prepare_mesh", "build_scene", "run_trials", "simulate_map", "render_trial"),
    # table-top scenes and the simulated depth camera
    **_from("graspsim.geometry.camera", "Camera", "Intrinsics"),
    **_from("graspsim.tabletop", "DepthNoise", "render_depth", "TableScene", "SceneSim",
            "make_scene", "load_scene", "save_scene"),
}

__all__ = [
    "__version__",
    "GraspsimError", "InvalidParameterError", "PrimitiveError", "GripperError",
    "NoFeasibleGraspError", "MapFileError", "MapDatabaseError", "PointCloudError",
    "IdentificationError", "MeshError", "SimulationError", "DependencyNotInstalled",
    *_LAZY,
]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'graspsim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


_register_envs()
