"""Full-scale (FS) graspability maps by the surface-to-voxel method (paper 2.1, ref. [9]).

The object surface is scanned at ``surface_step``; from every first contact p1 the
closing directions u are sampled on rings around the inward normal at the rotation
step (up to ``closing_cone``); the second contact p2 is where the line leaves the
object; openings the gripper cannot span are rejected; then the gripper's roll about
u (rotation step) and the contact depth along the pad (``depth_step``) are swept, the
wrist pose follows from the gripper's kinematics, and every pose whose gripper
(fingers and jaws opened to the contact width plus clearance, housing, arm) collides
with the object is rejected by the compiled sweep in ``_kernel``. All collision-free
poses are kept with their grade, low grades included.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from graspsim._version import __version__
from graspsim.errors import GripperError, InvalidParameterError, NoFeasibleGraspError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.maps.graspmap import GraspabilityMap, MapMeta
from graspsim.maps.hierarchy import clear_caches, clusters, sample_levels
from graspsim.maps.map_config import MapConfig, ring_sizes, roll_count
from graspsim.maps.preflight import check_graspable, check_memory, estimate_map_memory
from graspsim.maps.preflight import memory_budget as preflight_budget
from graspsim.transforms import normalize

__all__ = [
    "ClosingLines",
    "generate_fs_map",
    "closing_directions",
    "closing_lines",
    "sweep_collisions",
    "roll_angles",
    "object_description",
    "clear_caches",
]

log = logging.getLogger(__name__)


def closing_directions(normals: np.ndarray, cone: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Closing directions around the inward normals.

    normals: (M, 3) outward unit normals. Returns u (M, K, 3) unit directions -- ring 0
    is the inward normal itself, ring k is k * step away with ~2 pi sin(k step) / step
    azimuths -- and their angles to the inward normal (K,) [rad].
    """
    polar, azim = [0.0], [0.0]
    for k, n in enumerate(ring_sizes(cone, step)[1:], start=1):
        polar += [k * step] * n
        azim += list(2 * math.pi * np.arange(n) / n)
    polar, azim = np.array(polar), np.array(azim)
    t1, t2 = _tangents(normals)
    inward = -normals
    u = (np.cos(polar)[None, :, None] * inward[:, None, :]
         + (np.sin(polar) * np.cos(azim))[None, :, None] * t1[:, None, :]
         + (np.sin(polar) * np.sin(azim))[None, :, None] * t2[:, None, :])
    return normalize(u), polar


def _tangents(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) completing unit ``v`` (N, 3) to a right-handed frame
    (t1 x t2 = v), chosen deterministically."""
    helper = np.where(np.abs(v[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = normalize(np.cross(helper, v))
    return t1, np.cross(v, t1)


def object_description(shape, mass: float | None, density: float) -> dict:
    """The ``object`` metadata of a map: primitive/compound dict + com + mass [kg]."""
    d = dict(shape.to_dict())
    m = float(mass) if mass is not None else density * shape.volume
    if not m > 0:
        raise InvalidParameterError(f"object mass must be > 0 kg, got {m!r}")
    d.update(com=[0.0, 0.0, 0.0], mass=m, volume=float(shape.volume))
    return d


def _footprints(g: GripperSpec) -> tuple[np.ndarray, np.ndarray]:
    """Kernel description of the nested finger/jaw/housing columns and the minimum
    distance from the closing axis at which jaw and housing can be reached."""
    fx, fy, _ = g.finger_size
    jx, jy, _ = g.jaw_size
    hx, hy, hz = g.housing_size
    if not (fx <= jx and fy <= jy and jy <= hy and g.max_opening / 2 + jx <= hx / 2 + 1e-12):
        raise GripperError(
            "the collision sweep needs nested footprints: finger inside jaw inside housing "
            f"(finger {g.finger_size}, jaw {g.jaw_size}, housing {g.housing_size})")
    ft = g.fingertip_z
    fp = np.array([
        [0.0, fx, fy / 2, 0.0, 1.0],                        # finger: top = fingertip
        [0.0, jx, jy / 2, ft - g.jaw_base_z, 1.0],          # jaw: top = jaw's lower face
        [0.0, hx / 2, hy / 2, ft - hz, 0.0],                # housing + arm: top = housing face
    ], dtype=np.float32)
    return fp, fp[:, 3]


@dataclass(frozen=True)
class ClosingLines:
    """Feasible closing lines of a scan: contacts p1, p2 (L, 3), outward normals
    n1, n2 (L, 3), closing axis u (L, 3), contact distance width (L,), grasp point
    gp (L, 3), a roll frame e1, e2 (L, 3) with e1 x e2 = u, and ``outside`` (L,):
    the points just behind both pads lie outside the object."""

    p1: np.ndarray
    p2: np.ndarray
    n1: np.ndarray
    n2: np.ndarray
    u: np.ndarray
    width: np.ndarray
    gp: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    outside: np.ndarray
    contacts: int
    directions: int


def closing_lines(shape, gripper: GripperSpec, cfg: MapConfig) -> ClosingLines:
    """Scan the surface: first contacts, closing directions, second contacts, and the
    lines whose width fits the gripper's opening range."""
    smp = shape.surface_samples(cfg.surface_step)
    u, _ = closing_directions(smp.normals, cfg.closing_cone, cfg.rotation_step)
    M, K = u.shape[:2]
    p1 = np.repeat(smp.points, K, axis=0)
    n1 = np.repeat(smp.normals, K, axis=0)
    u = u.reshape(-1, 3)
    width = shape.ray_exit(p1, u)
    clearance = gripper.approach_clearance
    ok = np.isfinite(width) & (width >= max(cfg.min_width, gripper.min_opening)) \
        & (width + 2 * clearance <= gripper.max_opening + 1e-12)
    if not np.any(ok):
        widest = float(np.nanmax(np.where(np.isfinite(width), width, np.nan)))
        raise NoFeasibleGraspError(
            f"no chord of {shape} fits {gripper.name}: the grasp width plus 2 x "
            f"{clearance} m clearance must lie in [{gripper.min_opening}, "
            f"{gripper.max_opening}] m; the object's chords span up to {widest:.4f} m")
    p1, n1, u, width = p1[ok], n1[ok], u[ok], width[ok]
    p2 = p1 + width[:, None] * u
    # a finger inside the object (possible on non-convex shapes): test the points
    # just behind both pads
    back = clearance + 0.5 * gripper.finger_size[0]
    outside = (shape.sdf(p1 - back * u) > 0) & (shape.sdf(p2 + back * u) > 0)
    e1, e2 = _tangents(u)
    return ClosingLines(p1, p2, n1, shape.normals(p2), u, width, 0.5 * (p1 + p2), e1, e2,
                        outside, int(M), int(K))


def roll_angles(cfg: MapConfig) -> np.ndarray:
    """Rolls about the closing axis: a whole number of steps around the circle [rad]."""
    n = roll_count(cfg)
    return 2 * math.pi * np.arange(n) / n


def sweep_collisions(shape, lines: ClosingLines, gripper: GripperSpec, cfg: MapConfig,
                     threads: int | None = None, progress=None, *, rolls: np.ndarray | None = None,
                     depths: np.ndarray | None = None, need: np.ndarray | None = None
                     ) -> tuple[np.ndarray, dict]:
    """Collision-free flags (L, R, D) uint8 of every line x roll x depth, and stats.
    Rolls [rad] and contact depths [m] default to the config's sampling (depths must be
    increasing). ``need`` (L, R, D) bool: only these poses' answers are wanted (others
    may come back 0 = colliding); None: all."""
    from graspsim.maps.kernels import default_threads, kernels, run_chunks

    kern = kernels()
    lv = sample_levels(shape, cfg)
    fmargin = lv["fine_cover"]
    fp, offs = _footprints(gripper)
    depths = np.asarray(gripper.contact_depths(cfg.depth_step) if depths is None else depths,
                        np.float32)
    if np.any(np.diff(depths) <= 0):
        raise InvalidParameterError("contact depths must be strictly increasing")
    reach = float(np.max(lv["RT"] + lv["HN"])) + fmargin
    reach2 = np.maximum(0.0, offs - depths[-1] - reach) ** 2
    roll = roll_angles(cfg) if rolls is None else np.asarray(rolls, float)
    L, R, D = len(lines.u), len(roll), len(depths)
    free = np.zeros((L, R, D), np.uint8)
    n_ref = np.zeros(L, np.int32)
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    i64 = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
    if "_kernel_args" not in lv:  # the samples as the kernel takes them, once per (cached) hierarchy
        order, start, centre, radius, reach_max = clusters(lv["Q"], lv["RT"] + lv["HN"])
        lv["_kernel_args"] = (
            f32(lv["Q"]), f32(lv["NQ"]), f32(lv["RT"]), f32(lv["HN"]), i64(order), i64(start), f32(centre),
            f32(radius), f32(reach_max), f32(lv["M"]), f32(lv["NM"]), f32(lv["RTM"]), f32(lv["HNM"]),
            i64(lv["mstart"]), f32(lv["F"]), f32(lv["NF"]), f32(lv["RTF"]), f32(lv["HNF"]), i64(lv["fstart"]))
    args = (f32(lines.gp), f32(lines.u), f32(lines.e1), f32(lines.e2),
            f32(0.5 * lines.width + gripper.approach_clearance), *lv["_kernel_args"], fp, f32(reach2),
            f32(np.cos(roll)), f32(np.sin(roll)), f32(depths), np.float32(fmargin), bool(cfg.collision_refine),
            np.ones((1, 1, 1), np.uint8) if need is None else np.ascontiguousarray(need, np.uint8),
            free, n_ref)
    used = default_threads(threads)
    nchunk = min(L, 512)  # chunk c: lines c, c + nchunk, ... (spread over the object)
    run_chunks(lambda c0, c1: kern.sweep_lines(*args, c0, c1, nchunk), nchunk, used,
               parts=max(16, 4 * used) if progress else used, progress=progress)
    free[~lines.outside] = 0
    stats = {"refined_rolls": int(n_ref.sum()), "coarse_samples": int(len(lv["Q"])),
             "middle_samples": int(len(lv["M"])), "fine_samples": int(len(lv["F"])),
             "fine_cover": fmargin, "threads": int(used)}
    return free, stats


def generate_fs_map(
    shape,
    gripper: GripperSpec = HGPL_25_60_A,
    quality: QualityModel | None = None,
    config: MapConfig | None = None,
    *,
    mass: float | None = None,
    threads: int | None = None,
    progress=None,
    grade=None,
    memory_budget: int | str | None = None,
) -> GraspabilityMap:
    """Full-scale graspability map of ``shape`` (a Primitive or Compound).

    Returns every collision-free pose with its grade (``map.accepted`` marks grade >
    threshold). ``threads`` limits numba's threads (default: all cores);
    ``progress`` is an optional callable ``progress(done_fraction)``.
    ``grade``: a grade model of :mod:`graspsim.grades` (e.g. ``get_grade("pad_contact")``)
    that re-grades the finished map (``meta.quality["name"]`` records it); None keeps the
    quality model's grade, the paper's.
    ``memory_budget``: bytes or a size string ("4GiB", "50%"); None: ``$GRASPSIM_MEMORY_BUDGET``
    or half the machine's memory (see :mod:`graspsim.maps.preflight`).
    Raises :class:`NoFeasibleGraspError` if no part of the object fits the gripper, and
    :class:`BudgetExceededError` -- before allocating it -- if the map would need more
    memory than the budget.
    """
    quality = quality or QualityModel()
    cfg = config or MapConfig()
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    check_graspable(shape, gripper)
    budget = preflight_budget(memory_budget)
    estimate = estimate_map_memory(shape, gripper, cfg)
    check_memory(shape, estimate, budget)
    lines = closing_lines(shape, gripper, cfg)
    timing["lines"] = time.perf_counter() - t0

    t = time.perf_counter()
    d_ref = quality.reference_distance(shape.circumradius)
    q = quality.evaluate(lines.p1, lines.p2, lines.n1, lines.n2, shape.com, d_ref)
    timing["quality"] = time.perf_counter() - t

    t = time.perf_counter()
    free, stats = sweep_collisions(shape, lines, gripper, cfg, threads, progress)
    timing["collision"] = time.perf_counter() - t

    t = time.perf_counter()
    check_memory(shape, replace(estimate, contacts=len(lines.u), directions=1), budget,
                 grasps=int(free.sum(dtype=np.int64)))
    roll = roll_angles(cfg)
    depths = gripper.contact_depths(cfg.depth_step)
    cols = _assemble(free, lines, roll, gripper.tcp_offset(depths), q, threads)
    n_rows = len(cols["grade"])
    gmap = GraspabilityMap(
        **cols,
        part=np.zeros(n_rows, np.int16),
        meta=MapMeta(
            object=object_description(shape, mass, cfg.density),
            gripper=gripper.to_dict(),
            quality={**quality.to_dict(), "d_ref": d_ref},
            resolution={**cfg.to_dict(), "n_roll": len(roll), "n_depth": len(depths),
                        "closing_directions": lines.directions},
            method="surface_to_voxel",
            version=__version__,
        ),
    )
    timing["assemble"] = time.perf_counter() - t
    timing["total"] = time.perf_counter() - t0
    stats.update(contacts=lines.contacts, lines=lines.contacts * lines.directions,
                 feasible_lines=int(len(lines.u)), candidates=int(free.size),
                 collision_free=n_rows)
    log.info("FS map %s: %d candidates, %d collision-free in %.3f s", shape, free.size,
             n_rows, timing["total"])
    if grade is not None:
        t = time.perf_counter()
        gmap = grade.apply(gmap)
        timing["grade"] = time.perf_counter() - t
        timing["total"] = time.perf_counter() - t0
    return gmap.with_meta(timing=timing, extra={"stats": stats})


_SCALARS = ("width", "fc_angle", "q_fc", "stability_distance", "q_st", "grade")


def _assemble(free: np.ndarray, lines: ClosingLines, roll: np.ndarray, tcp: np.ndarray,
              q, threads: int | None = None) -> dict[str, np.ndarray]:
    """Map columns (float32, one row per free pose in (line, roll, depth) order), filled
    in one parallel pass without per-column temporaries."""
    from graspsim.maps.kernels import default_threads, kernels, run_chunks

    counts = free.reshape(len(free), -1).sum(axis=1, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    n = int(offsets[-1])
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    pair = f32(np.stack([np.stack([lines.p1, lines.p2], 1), np.stack([lines.n1, lines.n2], 1)], 1))
    width_q = {"width": lines.width, **{k: getattr(q, k) for k in _SCALARS[1:]}}
    scal = f32(np.column_stack([width_q[k] for k in _SCALARS]))
    wrist = np.empty((n, 3), np.float32)
    quat = np.empty((n, 4), np.float32)
    gp = np.empty((n, 3), np.float32)
    contacts = np.empty((n, 2, 3), np.float32)
    normals = np.empty((n, 2, 3), np.float32)
    rows_scal = np.empty((len(_SCALARS), n), np.float32)
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    args = (free, f64(lines.u), f64(lines.e1), f64(lines.e2), f64(lines.gp), f64(np.cos(roll)),
            f64(np.sin(roll)), f64(tcp), offsets, f32(lines.gp), pair, scal, wrist, quat, gp,
            contacts, normals, rows_scal)
    kern, threads = kernels(), default_threads(threads)
    run_chunks(lambda l0, l1: kern.assemble_rows(*args, l0, l1), len(free), threads, parts=4 * threads)
    cols = {"wrist_position": wrist, "wrist_quat": quat, "grasp_point": gp,
            "contacts": contacts, "normals": normals}
    cols.update({k: rows_scal[i] for i, k in enumerate(_SCALARS)})
    return cols
