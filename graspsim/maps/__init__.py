"""Graspability maps: data structure, FS generation, metrics, storage, database.

May use: the base modules, geometry, primitives, grippers and grades (never perception,
planning, sim or anything above).
"""

from __future__ import annotations

from graspsim.maps.generate import generate_fs_map
from graspsim.maps.graspmap import COLUMNS, GraspabilityMap, MapMeta
from graspsim.maps.io import load_map, read_sim_results, save_map, write_reach, write_sim_results
from graspsim.maps.map_config import MapConfig
from graspsim.maps.preflight import estimate_map_memory, memory_budget
from graspsim.maps.validate import map_problems, validate_map

__all__ = [
    "COLUMNS",
    "GraspabilityMap",
    "MapMeta",
    "MapConfig",
    "generate_fs_map",
    "load_map",
    "save_map",
    "write_sim_results",
    "write_reach",
    "read_sim_results",
    "estimate_map_memory",
    "memory_budget",
    "map_problems",
    "validate_map",
]
