"""Any grasp planner in the clutter-removal benchmark: the interface, graspsim's planner
through it, and a geometric baseline.

A planner is a callable ``planner(obs: Observation) -> Proposals`` (or a class whose
instances are; it is made with no arguments), named on the command line as
``graspsim scene --planner module:function``. It receives what a robot has:

* ``depth`` (H, W) [m], z-depth in the OpenCV camera frame (x right, y down, z forward),
  0 where invalid, with the sensor's noise; ``intrinsics`` (``fx, fy, cx, cy, width,
  height``: :class:`graspsim.geometry.camera.Intrinsics`) and ``T_world_camera`` (4, 4);
* ``cloud`` (N, 3): the depth image back-projected into the world frame (z up), for
  planners that take a cloud; ``gripper``: the :class:`~graspsim.grippers.spec.GripperSpec`
  (sizes, opening range, the wrist frame); ``rng``: draw from this generator only (the
  benchmark is then deterministic).

It returns :class:`Proposals`, best first: wrist poses ``T_world_wrist`` (K, 4, 4) in
graspsim's wrist frame (origin at the flange, z = approach towards the fingertips, x =
the jaws' closing axis, y = z x x; a planner in another convention converts, e.g. with
``graspsim.maps.formats.graspnet_to_wrist`` for GraspNet's), the pre-grasp pad gap
``opening`` (K,) [m] and a ``score`` (K,). The benchmark executes the first proposal
that does not close on the contacts of a grasp that already failed in the episode; an
empty list ends the episode (``no_grasp``), as for graspsim's planner.

Shipped: :class:`GraspsimPlanner` (graspsim's scene planner, ``plan_scene``, called
through this interface: no frame-to-frame reuse) and :func:`antipodal` (GPD-style:
surface points sampled from the cloud, approached against their normal at eight turns
about it, the jaws centred on the points they enclose and opened fully, collision-checked
against the cloud and the fitted table and ranked by clearance).
"""

from __future__ import annotations

import importlib
import inspect
import logging
from dataclasses import dataclass

import numpy as np

from graspsim.errors import GraspsimError, InvalidParameterError, PlannerError
from graspsim.grippers.spec import GripperSpec

log = logging.getLogger(__name__)

__all__ = ["Observation", "Proposals", "ProposedGrasp", "load_planner", "GraspsimPlanner", "antipodal", "BUILTIN",
           "plan_frame", "grasp_target"]


@dataclass(frozen=True, eq=False)
class Observation:
    """What a planner gets each frame (see the module doc)."""

    depth: np.ndarray
    intrinsics: object
    T_world_camera: np.ndarray
    cloud: np.ndarray
    gripper: GripperSpec
    rng: np.random.Generator


@dataclass(frozen=True, eq=False)
class Proposals:
    """Ranked grasps, best first: T_world_wrist (K, 4, 4), opening (K,) [m], score (K,)."""

    T_world_wrist: np.ndarray
    opening: np.ndarray
    score: np.ndarray

    def __post_init__(self) -> None:
        T = np.asarray(self.T_world_wrist, float).reshape(-1, 4, 4)
        o, s = (np.asarray(v, float).reshape(-1) for v in (self.opening, self.score))
        if not (len(o) == len(s) == len(T)) or not (np.isfinite(T).all() and np.isfinite(o).all()):
            raise InvalidParameterError(f"a planner returned {len(T)} poses, {len(o)} openings and {len(s)} "
                                        "scores (all finite, one each)")
        R = T[:, :3, :3]
        if len(T) and np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max() > 1e-5:
            raise InvalidParameterError("a planner returned wrist poses whose rotations are not orthonormal")
        object.__setattr__(self, "T_world_wrist", T)
        object.__setattr__(self, "opening", o)
        object.__setattr__(self, "score", s)

    def __len__(self) -> int:
        return len(self.opening)


@dataclass(frozen=True, eq=False)
class ProposedGrasp:
    """One proposal as the benchmark executes it (the fields a scene grasp has)."""

    T_world_wrist: np.ndarray
    opening: float
    score: float
    segment: int | None = None


def load_planner(name: str):
    """``"module:function"`` (or ``module:Class``, made with no arguments), or a shipped
    one (:data:`BUILTIN`), as a planner callable."""
    target = BUILTIN.get(name, name)
    mod, _, attr = target.partition(":")
    if not mod or not attr:
        raise InvalidParameterError(f"--planner {name!r}: give module:function, or one of {sorted(BUILTIN)}")
    try:
        obj = getattr(importlib.import_module(mod), attr)
    except (ImportError, AttributeError) as err:
        raise InvalidParameterError(f"--planner {name!r}: cannot import {attr} from {mod}: {err}") from err
    try:
        planner = obj() if isinstance(obj, type) else obj
    except Exception as err:  # the user's class: one line, not its traceback
        raise InvalidParameterError(f"--planner {name!r}: making {attr}() failed: {type(err).__name__}: {err}") from err
    if not callable(planner):
        raise InvalidParameterError(f"--planner {name!r} is not callable")
    try:
        inspect.signature(planner).bind(None)
    except TypeError as err:
        raise InvalidParameterError(f"--planner {name!r}: a planner is called with one argument, the Observation "
                                    f"(planner(obs) -> Proposals); {attr} cannot be: {err}") from None
    except ValueError:  # some built-ins have no signature to check: the first call tells
        pass
    return planner


def plan_frame(planner, frame, gripper: GripperSpec, rng: np.random.Generator):
    """(the back-projected view, the planner's Proposals, them as ProposedGrasps, the
    seconds from the depth frame to the proposals) for one depth ``frame``."""
    import time

    from graspsim.geometry.camera import backproject

    t1 = time.perf_counter()
    view = backproject(frame)
    cam = frame.camera
    obs = Observation(frame.depth, cam.intrinsics, cam.T_world_camera, view.world(), gripper, rng)
    who = getattr(planner, "__qualname__", type(planner).__qualname__)
    try:
        props = planner(obs)
    except GraspsimError:
        raise
    except Exception as err:  # a user's planner: one line naming it; its traceback with -v
        log.info("the planner %s raised:", who, exc_info=True)
        raise PlannerError(f"the planner {who} raised {type(err).__name__}: {err} (run with -v for its "
                           "traceback)") from err
    if not isinstance(props, Proposals):
        if not isinstance(props, (tuple, list)) or len(props) != 3:
            raise PlannerError(f"the planner {who} returned {type(props).__name__}; a planner returns Proposals "
                               "(or a tuple: T_world_wrist (K, 4, 4), opening (K,), score (K,))")
        try:
            props = Proposals(*props)
        except (TypeError, ValueError) as err:
            raise PlannerError(f"the planner {who} returned grasps of the wrong shape ({err}); T_world_wrist "
                               "(K, 4, 4), opening (K,), score (K,)") from err
    planning = time.perf_counter() - t1
    grasps = tuple(ProposedGrasp(T, float(o), float(sc))
                   for T, o, sc in zip(props.T_world_wrist, props.opening, props.score))
    return view, props, grasps, planning


def grasp_target(look, grasp, gripper: GripperSpec) -> int | None:
    """The object a grasp of a ``ClutterFrame`` aims at (ground truth; None: unknown): the
    object most of its segment's points show, or for a planner that does not segment the
    object of the seen point nearest its TCP."""
    labels = look.view.labels
    if grasp.segment is not None:
        per = look.plan.perception
        t = labels[per.indices[per.segment == grasp.segment]]
        t = t[t >= 0]
        return int(np.bincount(t).argmax()) if len(t) else None
    ok = labels >= 0
    if not ok.any():
        return None
    T = grasp.T_world_wrist
    d = look.view.world()[ok] - (T[:3, 3] + gripper.tcp_offset(gripper.nominal_depth) * T[:3, 2])
    return int(labels[ok][np.argmin(np.einsum("ij,ij->i", d, d))])


class GraspsimPlanner:
    """graspsim's scene planner (``perception.scene.plan_scene``: table, segments, every
    segment planned from the FS map database, the robust score against the whole
    scene) through the interface. db: a MapDatabase (default: the default folder, for
    the observation's gripper)."""

    def __init__(self, db=None, config=None):
        self.db, self.config = db, config

    def __call__(self, obs: Observation) -> Proposals:
        from graspsim.maps.database import MapDatabase
        from graspsim.planning.scene import plan_scene
        from graspsim.planning.scene_config import SceneConfig

        if self.db is None:
            self.db = MapDatabase(gripper=obs.gripper)
        sp = plan_scene(obs.cloud, db=self.db, rng=obs.rng, config=self.config or SceneConfig(),
                        viewpoint=obs.T_world_camera[:3, 3])
        keep = [g for g in sp.grasps if g.score > 0]
        return Proposals(np.array([g.T_world_wrist for g in keep]).reshape(-1, 4, 4),
                         np.array([g.opening for g in keep]), np.array([g.score for g in keep]))


def antipodal(obs: Observation, *, samples: int = 300, turns: int = 8, cell: float = 0.003) -> Proposals:
    """The geometric baseline (see the module doc). samples: surface points drawn;
    turns: closing directions about each approach; cell: thinning [m]."""
    from graspsim.maps.robust import score_poses
    from graspsim.perception.normals import estimate_local_surface
    from graspsim.perception.plane import fit_table

    g = obs.gripper
    table = fit_table(obs.cloud, obs.rng, up=np.array([0.0, 0.0, 1.0]))
    above = obs.cloud[table.heights(obs.cloud) > 0.005]
    pts = above[np.unique(np.floor(above / cell).astype(np.int64), axis=0, return_index=True)[1]]
    if len(pts) < 20:
        return Proposals(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0))
    nrm = estimate_local_surface(pts).normals
    eye = obs.T_world_camera[:3, 3]
    nrm = np.where((np.einsum("ij,ij->i", nrm, eye - pts) < 0)[:, None], -nrm, nrm)  # towards the camera
    pick = obs.rng.choice(len(pts), min(samples, len(pts)), replace=False)
    T, width = _candidates(pts, pts[pick], -nrm[pick], g, turns)
    if not len(T):
        return Proposals(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0))
    x = T[:, :3, 0]
    tcp = T[:, :3, 3] + g.tcp_offset(g.nominal_depth) * T[:, :3, 2]
    contacts = np.stack([tcp - 0.5 * width[:, None] * x, tcp + 0.5 * width[:, None] * x], axis=1)
    full = np.full(len(T), g.max_opening - 2 * g.approach_clearance)  # opened fully, as GPD's hand
    s = score_poses(T, full, contacts, np.stack([-x, x], axis=1), pts, g, table=(table.normal, table.height))
    ok = (s.flags[:, 0] == 0) & np.isfinite(s.clearance)  # the nominal pose clear of cloud and table
    order = np.flatnonzero(ok)[np.argsort(-s.clearance[ok], kind="stable")]
    return Proposals(T[order], g.pregrasp_opening(full[order]), s.clearance[order])


def _candidates(pts: np.ndarray, at: np.ndarray, approach: np.ndarray, g: GripperSpec,
                turns: int) -> tuple[np.ndarray, np.ndarray]:
    """Wrist poses (n, 4, 4) approaching ``at`` (m, 3) along ``approach`` at ``turns``
    closing directions each, the pads' middle a pad length below the point and the jaws
    centred on the cloud points between them; and the chord they enclose (n,) [m]."""
    from graspsim.transforms import frame_from_axes

    out_T, out_w = [], []
    half_y = 0.5 * g.finger_size[1]
    reach = g.max_opening - 2 * g.approach_clearance
    for p, a in zip(at, approach):
        ref = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(a, ref)
        u /= np.linalg.norm(u)
        v = np.cross(a, u)
        tcp = p + a * (0.5 * g.pad_length)
        for t in np.arange(turns) * np.pi / turns:
            R = frame_from_axes(np.cos(t) * u + np.sin(t) * v, a)
            local = (pts - tcp) @ R  # points in the frame at the TCP
            between = (np.abs(local[:, 1]) <= half_y) & (np.abs(local[:, 2]) <= 0.5 * g.pad_length) \
                & (np.abs(local[:, 0]) <= 0.5 * reach)
            if between.sum() < 5:
                continue
            lo, hi = local[between, 0].min(), local[between, 0].max()
            if not 0.005 <= hi - lo <= reach:
                continue
            centre = tcp + R[:, 0] * 0.5 * (lo + hi)
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = centre - g.tcp_offset(g.nominal_depth) * a
            out_T.append(T)
            out_w.append(hi - lo)
    return np.array(out_T).reshape(-1, 4, 4), np.array(out_w)


#: the shipped planners by name
BUILTIN = {"graspsim-interface": "graspsim.tabletop.planners:GraspsimPlanner",
           "antipodal": "graspsim.tabletop.planners:antipodal"}
