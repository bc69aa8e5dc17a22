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
