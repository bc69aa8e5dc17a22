"""Cheap per-grasp features for grade models: contact geometry, flat-pad contact, placing.

The paper's grade sees only the two sampled contact points. A two-jaw gripper with flat
finger pads does not touch the object there: each pad first meets the part of the
object nearest to it within the finger's face, and the object turns in the hand until
a face lies flat on the pad (the paper saw the glue bottle re-orient, its fig. 8D).
These features describe that, from the map's own object model (never from the
simulator), all vectorised over grasps:

* ``alpha`` [rad]: the paper's force-closure angle (the larger contact angle);
  ``alpha_min`` [rad]: the smaller one.
* ``stability``: distance from the centre of mass to the grasp point / d_ref.
* ``pad_normal_angle`` [rad]: the larger, over both pads, angle between the object's
  mean outward normal in the pad's contact patch and the pad's normal: 0 for a face
  lying flat on the pad; large where a rim, an edge or a tilted face touches it.
* ``pad_residual_angle`` [rad]: half the difference of the two rotations that would
  lay each patch flat on its pad. The object can turn by their mean (a tilted cylinder
  aligns with the pads) but not by their difference: a sphere touched off-centre by a
  pad's edge, or a cone's tapered side, stays wedged at this angle -- the flat-pad
  analogue of the force-closure angle (squeezed out beyond atan(mu)).
* ``pad_edge_margin`` [m]: the smaller, over both pads, mean distance of the contact
  patch from the border of the finger face (capped): 0 when only the fingertip or a
  side edge of the finger touches.
* ``pad_log_area``: log of the smaller patch area [m^2] (+ 1e-5).
* ``place_tilt_ratio``: the tilt of the object's up axis caused by turning both
  patches flat onto the pads (rotations about the closing axis excluded), divided by
  the object's tipping angle on the table (capped): >= 1 predicts that the object,
  put back down, falls over.

Patches are computed from surface samples (``FeatureConfig.sample_step``) by the
compiled kernel in :mod:`~graspsim.grades.pad_kernel`; the rest is numpy.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from graspsim.checks import POSITIVE, check_fields
from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec
from graspsim.primitives import shape_from_dict
from graspsim.transforms import angle_between, normalize, quat_to_matrix

__all__ = ["FeatureConfig", "ObjectContext", "FEATURES", "object_context", "grasp_features",
           "map_features", "resting_frame"]

FEATURES = ("alpha", "alpha_min", "stability", "pad_normal_angle", "pad_residual_angle",
            "pad_edge_margin", "pad_log_area", "place_tilt_ratio")
_PAD = ("pad_normal_angle", "pad_residual_angle", "pad_edge_margin", "pad_log_area",
        "place_tilt_ratio")


@dataclass(frozen=True)
class FeatureConfig:
    """sample_step: surface sample spacing for the pad patches [m]; patch_tol: depth of
    a patch below the first touching sample [m]; edge_cap [m] and ratio_cap: upper caps
    of pad_edge_margin and place_tilt_ratio; min_tip: floor of the tipping angle [rad];
    support_tol: height band of the lowest mesh vertices that form the support [m]."""

    sample_step: float = 0.003
    patch_tol: float = 0.001
    edge_cap: float = 0.006
    ratio_cap: float = 3.0
    min_tip: float = 0.05
    support_tol: float = 0.001

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE, owner="FeatureConfig")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ObjectContext:
    """What the features need to know about the object (object frame): its shape,
    centre of mass com (3,) [m], stability reference d_ref [m], the up axis (3,) when it
    rests on a table and its tipping angle there [rad], and surface samples (points,
    normals (M, 3), areas (M,) [m^2])."""

    shape: object
    com: np.ndarray
    d_ref: float
    up: np.ndarray
    tip_angle: float
    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray


def _inside_margin(poly: np.ndarray, point: np.ndarray) -> float:
    """Distance of the 2D ``point`` inside the convex hull of ``poly`` (K, 2) from its
    border (negative outside; -inf when the hull is degenerate)."""
    if len(poly) < 3:
        return -math.inf
    try:
        hull = ConvexHull(poly)
    except QhullError:
        return -math.inf
    return float(-np.max(hull.equations[:, :2] @ point + hull.equations[:, 2]))


def resting_frame(shape, support_tol: float = 0.001) -> tuple[np.ndarray, float]:
    """The object's up axis (3,) in its frame when resting on a table, and its tipping
    angle [rad]: atan(distance from the COM's projection to the support polygon's border
    / COM height). The rule follows ``graspsim.sim.trial_scene.resting_pose`` (pure geometry
    here, no mujoco): +z up when the COM lies over the support, else the convex-hull
    face nearest the COM that it can stand on."""
    v = np.asarray(shape.mesh(64).vertices, float)
    com = np.asarray(shape.com, float)
    candidates = [np.array([0.0, 0.0, 1.0])]
    hull = ConvexHull(v)
    normals = np.unique(np.round(hull.equations[:, :3], 6), axis=0)
    d_face = -(v @ normals.T).max(axis=0)  # plane offsets
    order = np.argsort(np.abs(normals @ com + d_face))
    candidates += [-normals[k] for k in order]
    for up in candidates:
        up = up / np.linalg.norm(up)
        e1 = normalize(np.cross(up, [1.0, 0, 0] if abs(up[0]) < 0.9 else [0, 1.0, 0]))
        e2 = np.cross(up, e1)
        h = v @ up
        low = v[h < h.min() + support_tol]
        margin = _inside_margin(np.stack([low @ e1, low @ e2], 1), np.array([com @ e1, com @ e2]))
        if margin > 0:
            return up, math.atan2(margin, float(com @ up - h.min()))
    raise InvalidParameterError(f"{shape} has no stable resting pose on a table")


@functools.lru_cache(maxsize=16)
def _context(obj_json: str, d_ref: float, cfg: FeatureConfig) -> ObjectContext:
    obj = json.loads(obj_json)
    shape = shape_from_dict(obj)
    up, tip = resting_frame(shape, cfg.support_tol)
    smp = shape.surface_samples(cfg.sample_step)
    com = np.asarray(obj.get("com", shape.com), float)
    return ObjectContext(shape, com, float(d_ref), up, tip, smp.points, smp.normals, smp.areas)


def object_context(obj: dict | object, d_ref: float | None = None,
                   config: FeatureConfig = FeatureConfig()) -> ObjectContext:
    """Context of a map's object description (``meta.object``) or of a shape (a
    Primitive or Compound). d_ref defaults to the circumradius (the paper's)."""
    desc = dict(obj) if isinstance(obj, dict) else obj.to_dict()
    if "primitive" not in desc or desc["primitive"] == "mesh":
        raise InvalidParameterError(
            "grade features need the map's object as a primitive or compound; got "
            f"{ {k: desc.get(k) for k in ('primitive', 'file')} }")
    if d_ref is None:
        d_ref = shape_from_dict(desc).circumradius
    key = {k: desc[k] for k in ("primitive", "dims", "parts", "poses", "com") if k in desc}
    return _context(json.dumps(key, sort_keys=True), float(d_ref), config)


def grasp_features(ctx: ObjectContext, gripper: GripperSpec, contacts: np.ndarray,
                   normals: np.ndarray, R_obj_wrist: np.ndarray, p_obj_wrist: np.ndarray,
                   names: tuple[str, ...] = FEATURES,
                   config: FeatureConfig = FeatureConfig()) -> dict[str, np.ndarray]:
    """Features ``names`` (each (N,)) of N grasps: contacts, normals (N, 2, 3), wrist
    rotations (N, 3, 3) and positions (N, 3), object frame [m]."""
    unknown = sorted(set(names) - set(FEATURES))
    if unknown:
        raise InvalidParameterError(f"unknown grade features {unknown}; valid: {list(FEATURES)}")
    c = np.asarray(contacts, float)
    n = np.asarray(normals, float)
    u = c[:, 1] - c[:, 0]
    a1 = angle_between(-n[:, 0], u)
    a2 = angle_between(-n[:, 1], -u)
    out = {"alpha": np.maximum(a1, a2), "alpha_min": np.minimum(a1, a2),
           "stability": np.linalg.norm(c.mean(axis=1) - ctx.com, axis=1) / ctx.d_ref}
    if any(k in names for k in _PAD):
        out.update(_pad_features(ctx, gripper, np.asarray(R_obj_wrist, float),
                                 np.asarray(p_obj_wrist, float), config))
    return {k: out[k] for k in names}


def _pad_features(ctx: ObjectContext, g: GripperSpec, R: np.ndarray, p: np.ndarray,
                  cfg: FeatureConfig) -> dict[str, np.ndarray]:
    from graspsim.grades.pad_kernel import run_pad_patches

    patches = run_pad_patches(ctx.points, ctx.normals, ctx.areas, R, p,
                              0.5 * g.finger_size[1], g.fingertip_z, g.finger_size[2],
                              cfg.patch_tol)
    area = patches[:, :, 0]
    touched = area > 0
    safe = np.where(touched, area, 1.0)
    nrm = normalize(np.where(touched[..., None], patches[:, :, 1:4], [[[-1.0, 0, 0], [1.0, 0, 0]]]))
    pad_n = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # outward object normal wanted
    ang = angle_between(nrm, pad_n[None])
    ang = np.where(touched, ang, 0.5 * math.pi)
    margin = np.where(touched, patches[:, :, 4] / safe, 0.0)
    # the rotation turning each patch flat onto its pad (about axes normal to the
    # closing axis: a turn about it changes nothing at the pads); the object can make
    # the common part (the mean), not the difference
    axis = np.cross(nrm, pad_n[None])
    s = np.linalg.norm(axis, axis=-1, keepdims=True)
    rot = np.where(s > 1e-12, axis / np.maximum(s, 1e-12), 0.0) * ang[..., None]
    rot[..., 0] = 0.0
    rotvec = rot.mean(axis=1)
    residual = 0.5 * np.linalg.norm(rot[:, 0] - rot[:, 1], axis=-1)
    up_w = np.einsum("nji,j->ni", R, ctx.up)
    from scipy.spatial.transform import Rotation

    tilt = angle_between(Rotation.from_rotvec(rotvec).apply(up_w), up_w)
    tip = max(ctx.tip_angle, cfg.min_tip)
    return {"pad_normal_angle": ang.max(axis=1), "pad_residual_angle": residual,
            "pad_edge_margin": np.minimum(margin.min(axis=1), cfg.edge_cap),
            "pad_log_area": np.log(area.min(axis=1) + 1e-5),
            "place_tilt_ratio": np.minimum(tilt / tip, cfg.ratio_cap)}


def map_features(gmap, names: tuple[str, ...] = FEATURES, rows=None,
                 config: FeatureConfig = FeatureConfig()) -> dict[str, np.ndarray]:
    """Features of a :class:`GraspabilityMap`'s rows (all, or ``rows``: indices/mask)."""
    sel = slice(None) if rows is None else np.asarray(rows)
    gripper = gmap.meta.gripper_spec
    ctx = object_context(gmap.meta.object, gmap.meta.quality.get("d_ref"), config)
    R = quat_to_matrix(np.asarray(gmap.wrist_quat[sel], float))
    return grasp_features(ctx, gripper, gmap.contacts[sel], gmap.normals[sel], R,
                          gmap.wrist_position[sel], names, config)
