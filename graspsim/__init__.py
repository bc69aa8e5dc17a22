"""graspsim: graspability maps from shape primitives for two-jaw grippers.

Implements Eizicovits & Berman (2018), "Automatic graspability map generation based on
shape-primitives for unknown and familiar objects", with MuJoCo validation.
"""

from __future__ import annotations

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
from graspsim.gripper import HGPL_25_60_A, GripperSpec
from graspsim.primitives import (
    Box,
    Compound,
    Cone,
    Cylinder,
    HalfToroid,
    Primitive,
    Sphere,
    make_primitive,
    synthetic_cloud,
)
from graspsim.quality import QualityModel

__version__ = "0.1.0"

__all__ = [
    "__version__",
    # errors
    "GraspsimError",
    "InvalidParameterError",
    "PrimitiveError",
    "GripperError",
    "NoFeasibleGraspError",
    "MapFileError",
    "MapDatabaseError",
    "PointCloudError",
    "IdentificationError",
    "MeshError",
    "SimulationError",
    "DependencyNotInstalled",
    # geometry
    "Primitive",
    "Box",
    "Cylinder",
    "Sphere",
    "Cone",
    "HalfToroid",
    "Compound",
    "make_primitive",
    "synthetic_cloud",
    # gripper and quality
    "GripperSpec",
    "HGPL_25_60_A",
    "QualityModel",
]

# perception: point-cloud input and primitive identification (paper 2.2-2.3)
from graspsim.perception import (  # noqa: E402
    Identification,
    IdentificationStatus,
    IdentifyConfig,
    LoadedCloud,
    MatchDecision,
    MatchKind,
    OrientedBox,
    PartResult,
    Shape,
    classify_match,
    identify,
    min_volume_box,
    read_point_cloud,
)

__all__ += [
    "identify",
    "IdentifyConfig",
    "Identification",
    "IdentificationStatus",
    "PartResult",
    "Shape",
    "read_point_cloud",
    "LoadedCloud",
    "min_volume_box",
    "OrientedBox",
    "classify_match",
    "MatchKind",
    "MatchDecision",
]

# MuJoCo validation (graspsim.sim), imported on first use so that `import graspsim`
# does not load mujoco.
_SIM_NAMES = (
    "TrialOutcome", "TrialResults", "SimSettings", "GripperPhysics", "LiftPlace", "Tug",
    "ExecutionNoise", "SimObject", "Scene", "object_from_shape", "object_from_mesh",
    "build_scene", "run_trials", "simulate_map", "render_trial",
)
__all__ += list(_SIM_NAMES)


def __getattr__(name: str):
    if name in _SIM_NAMES:
        import graspsim.sim

        return getattr(graspsim.sim, name)
    raise AttributeError(f"module 'graspsim' has no attribute {name!r}")

# Gymnasium environments (graspsim.envs), registered by entry-point strings: no mujoco
# import here.
from graspsim.envs import register_envs as _register_envs  # noqa: E402

_register_envs()

# grade models and grade-vs-success calibration (no mujoco import at this point)
from graspsim.calibration import TrialTable, calibrate  # noqa: E402
from graspsim.grades import LogisticGrade, PaperGrade, get_grade, regrade  # noqa: E402

__all__ += ["get_grade", "regrade", "PaperGrade", "LogisticGrade", "calibrate", "TrialTable"]
