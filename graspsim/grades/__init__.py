"""Grade models for graspability maps: the paper's grade (default) and a calibrated
flat-pad contact grade, with the cheap per-grasp features they use.

May use: the base modules, geometry, primitives and grippers (never maps or anything
above: maps are graded with these).
"""

from __future__ import annotations

from graspsim.grades.grade_features import (
    FEATURES,
    FeatureConfig,
    ObjectContext,
    grasp_features,
    map_features,
    object_context,
    resting_frame,
)
from graspsim.grades.models import (
    GRADE_NAMES,
    LogisticGrade,
    PaperGrade,
    get_grade,
    regrade,
)

__all__ = [
    "FEATURES", "FeatureConfig", "ObjectContext", "grasp_features", "map_features",
    "object_context", "resting_frame",
    "GRADE_NAMES", "PaperGrade", "LogisticGrade", "get_grade", "regrade", "default_model_path",
]
