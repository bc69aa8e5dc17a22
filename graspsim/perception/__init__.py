"""Run-time perception (paper 2.2-2.3): point-cloud input, minimum-volume bounding
boxes and the hierarchical fit-and-split, MLESAC primitive fitting, the four shape
features, rule-based identification, and the known/familiar decision.

May use: the base modules, geometry and primitives only (never maps, planning or
anything above): it turns clouds into identified primitives and nothing else.
"""

from __future__ import annotations

from graspsim.perception.classify import Shape, classify
from graspsim.perception.cloud_input import LoadedCloud, check_cloud, read_point_cloud
from graspsim.perception.depth_image import read_depth_image
from graspsim.perception.identify import (
    Identification,
    IdentificationStatus,
    IdentifyConfig,
    PartResult,
    identify,
    identify_cluster,
)
from graspsim.perception.mlesac import ModelFit, fit_model, mixture_loglik
from graspsim.perception.mvbb import OrientedBox, min_volume_box, pca_box
from graspsim.perception.normals import LocalSurface, estimate_local_surface, remove_outliers
from graspsim.perception.prepare import Downsampling, check_solid, to_metres, voxel_downsample
from graspsim.perception.shape_features import ShapeFeatures, shape_features
from graspsim.perception.split import Split, best_split, theta_star

__all__ = [
    "Shape", "classify", "ShapeFeatures", "shape_features",
    "Identification", "IdentificationStatus", "IdentifyConfig", "PartResult",
    "identify", "identify_cluster",
    "LoadedCloud", "check_cloud", "read_point_cloud", "read_depth_image",
    "ModelFit", "fit_model", "mixture_loglik",
    "OrientedBox", "min_volume_box", "pca_box",
    "LocalSurface", "estimate_local_surface", "remove_outliers",
    "Downsampling", "check_solid", "to_metres", "voxel_downsample",
    "Split", "best_split", "theta_star",
]
