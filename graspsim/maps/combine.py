"""Map combination for unknown objects (paper 2.5).

The maps of an object's parts (each in its part's frame, scaled or as stored) are
moved into the compound object's frame. Force closure does not change; stability is
re-assessed against the compound's centre of mass; a grasp whose contact lies inside
another part (that surface does not exist on the compound) is dropped, and so is one
whose gripper collides with an adjacent part (each part's map already avoids its own
part). Part ids are kept.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from graspsim._version import __version__
from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel, stability_distance
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.collide import grasps_collision_free
from graspsim.maps.generate import object_description
from graspsim.maps.graspmap import GraspabilityMap, MapMeta
from graspsim.maps.map_config import MapConfig
from graspsim.maps.rowids import row_ids
from graspsim.primitives import Compound
from graspsim.transforms import invert_transform, matrix_to_quat, quat_multiply, quat_to_matrix

__all__ = ["combine_maps", "combine_part"]

log = logging.getLogger(__name__)


def combine_part(part_map: GraspabilityMap, index: int, compound: Compound, *,
                 gripper: GripperSpec, quality: QualityModel, d_ref: float,
                 config: MapConfig | None = None, meta: MapMeta | None = None) -> GraspabilityMap:
    """Part ``index``'s map (in the part's frame) as rows of the compound's map."""
    cfg = config or MapConfig()
    T = compound.poses[index]
    R, t = T[:3, :3], T[:3, 3]
    c = part_map.contacts.astype(float) @ R.T + t
    # contacts buried in another part are not on the compound's surface
    others = [j for j in range(len(compound.parts)) if j != index]
    flat = c.reshape(-1, 3)
    on_surface = np.ones(len(part_map), bool)
    for j in others:
        local = (flat - compound.poses[j][:3, 3]) @ compound.poses[j][:3, :3]
        on_surface &= np.all(compound.parts[j].sdf(local).reshape(-1, 2) > -1e-7, axis=1)
    keep = np.flatnonzero(on_surface)
    c = c[keep]
    # contact depth and width do not depend on the frame: take them in the part's
    gp_part = part_map.grasp_point[keep].astype(float)
    R_part = quat_to_matrix(part_map.wrist_quat[keep])
    depth = gripper.contact_depth(gp_part, part_map.wrist_position[keep], R_part[:, :, 2])
    width = part_map.width[keep].astype(float)
    # collisions with the adjacent parts, each in its own frame (one cached sample
    # hierarchy per primitive), grouped by closing line
    free = np.ones(len(keep), bool)
    lines = row_ids(part_map.contacts[keep])
    for j in others:
        T_j_part = invert_transform(compound.poses[j]) @ T
        idx = np.flatnonzero(free)
        if len(idx) == 0:
            break
        gp_j = gp_part[idx] @ T_j_part[:3, :3].T + T_j_part[:3, 3]
        R_j = np.einsum("ij,njk->nik", T_j_part[:3, :3], R_part[idx])
        ok = grasps_collision_free(compound.parts[j], gripper, gp_j, R_j, depth[idx], width[idx],
                                   cfg, line=lines[idx])
        free[idx[~ok]] = False
    sel = np.flatnonzero(free)
    rows = keep[sel]
    # force closure is the contacts' own; stability moves with the compound's COM
    c = c[sel]
    dist = stability_distance(c[:, 0], c[:, 1], compound.com, quality.stability_mode)
    q_st, grade = quality.combine(part_map.q_fc[rows], dist, d_ref)
    return GraspabilityMap(
        wrist_position=part_map.wrist_position[rows].astype(float) @ R.T + t,
        wrist_quat=quat_multiply(matrix_to_quat(R), part_map.wrist_quat[rows]),
        grasp_point=gp_part[sel] @ R.T + t, contacts=c,
        normals=part_map.normals[rows].astype(float) @ R.T, width=width[sel],
        fc_angle=part_map.fc_angle[rows], q_fc=part_map.q_fc[rows], stability_distance=dist,
        q_st=q_st, grade=grade, part=np.full(len(rows), index, np.int16),
        meta=meta or part_map.meta)


def combine_maps(part_maps: list[GraspabilityMap], compound: Compound, *,
                 quality: QualityModel | None = None, config: MapConfig | None = None,
                 keep_min_grade: float | None = None, mass: float | None = None) -> GraspabilityMap:
    """The combined map of a compound object from one map per part (``part_maps[i]`` in
    the frame of ``compound.parts[i]``, placed by ``compound.poses[i]``).

    keep_min_grade: drop grasps whose re-assessed grade is not above it (None keeps
    every grasp that survives; the part maps usually hold accepted grasps already).
    """
    if len(part_maps) != len(compound.parts):
        raise InvalidParameterError(
            f"one map per part: {len(part_maps)} maps for {len(compound.parts)} parts")
    if not part_maps:
        raise InvalidParameterError("combine_maps needs at least one part")
    t0 = time.perf_counter()
    gripper = part_maps[0].meta.gripper_spec
    quality = quality or part_maps[0].meta.quality_model
    cfg = config or part_maps[0].meta.map_config
    d_ref = quality.reference_distance(compound.circumradius)
    meta = MapMeta(object=object_description(compound, mass, cfg.density), gripper=part_maps[0].meta.gripper,
                   quality={**quality.to_dict(), "d_ref": d_ref}, resolution=part_maps[0].meta.resolution,
                   method="combined", version=__version__,
                   extra={"parts": [m.meta.object for m in part_maps],
                          "part_methods": [m.meta.method for m in part_maps]})
    pieces = [combine_part(m, i, compound, gripper=gripper, quality=quality, d_ref=d_ref,
                           config=cfg, meta=meta) for i, m in enumerate(part_maps)]
    out = GraspabilityMap.concat(pieces, meta=meta)
    if keep_min_grade is not None:
        out = out.filter(min_grade=keep_min_grade)
    out = out.select(np.argsort(-out.grade, kind="stable"))
    log.info("combined %d part maps into %d grasps", len(part_maps), len(out))
    return out.with_meta(timing={"total": time.perf_counter() - t0})
