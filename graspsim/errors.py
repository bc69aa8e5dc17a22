"""One exception tree for graspsim.

Every error a user can trigger is a :class:`GraspsimError`. Messages say what was wrong
and what would have been valid. Errors from third-party libraries (h5py, coacd, fcl,
mujoco) are wrapped with ``raise ... from err`` so the original traceback survives.
"""

from __future__ import annotations

__all__ = [
    "GraspsimError",
    "InvalidParameterError",
    "PrimitiveError",
    "GripperError",
    "NoFeasibleGraspError",
    "MapFileError",
    "OutputPathError",
    "MapDatabaseError",
    "InvalidMapError",
    "BudgetExceededError",
    "PointCloudError",
    "IdentificationError",
    "MeshError",
    "SimulationError",
    "CampaignError",
    "DependencyNotInstalled",
    "PlannerError",
]


class GraspsimError(Exception):
    """Base class of every error raised by graspsim."""


class InvalidParameterError(GraspsimError, ValueError):
    """A configuration value is out of its valid range or of the wrong kind."""


class PrimitiveError(InvalidParameterError):
    """Impossible shape-primitive dimensions (zero, negative, self-intersecting, NaN)."""


class GripperError(InvalidParameterError):
    """An inconsistent gripper specification."""


class NoFeasibleGraspError(GraspsimError):
    """The object cannot be grasped at all with the given gripper (e.g. too wide)."""


class MapFileError(GraspsimError, OSError):
    """A map file is missing, truncated, foreign or cannot be written."""


class OutputPathError(GraspsimError, OSError):
    """An output file or folder cannot be written (a directory given as a file, a missing
    folder, no permission); raised before any work is done."""


class MapDatabaseError(GraspsimError):
    """The FS map database cannot answer or store a request."""


class InvalidMapError(GraspsimError, ValueError):
    """A graspability map breaks its invariants (no grasps, non-finite columns, a
    degenerate object); see :func:`graspsim.maps.validate.validate_map`."""


class BudgetExceededError(GraspsimError, MemoryError):
    """A request would need more memory than the configured budget; the message gives
    the estimate, the budget and how to change it."""


class PointCloudError(GraspsimError, ValueError):
    """A point cloud cannot be read or processed (empty, NaN-only, degenerate)."""


class IdentificationError(GraspsimError):
    """Primitive identification could not run (not: ran and failed to identify)."""


class MeshError(GraspsimError):
    """A mesh cannot be read, repaired or decomposed."""


class SimulationError(GraspsimError):
    """A simulation could not be built or run (bad scene, bad map keys, bad mass)."""


class CampaignError(SimulationError):
    """A simulation campaign folder that does not match the requested campaign, or is
    damaged (:mod:`graspsim.apps.campaign`)."""


class PlannerError(GraspsimError):
    """A user's grasp planner (``graspsim scene --planner module:function``) raised or
    returned something that is not grasps; the message names the planner and the fault."""


class DependencyNotInstalled(GraspsimError, ImportError):
    """An optional backend is needed but not installed; the message says what to install."""
