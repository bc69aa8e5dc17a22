"""Baseline policies for ``GraspSelect-v0`` and a small learned one (numpy only).

Policies map an observation (and a generator, where they draw) to an action:

* :func:`random_policy`: a valid candidate uniformly at random;
* :func:`highest_grade_policy`: the valid candidate with the highest grade (the paper's
  choice);
* :func:`robust_policy`: the valid candidate with the highest robust score (the
  planner's default ranking, :mod:`graspsim.maps.robust`), ties by grade;
* :func:`oracle_choice`: given every candidate's simulated reward
  (``env.evaluate_candidates()``), one that succeeds, if any (an upper bound);
* :func:`planner_pose` (``GraspPose-v0``): the run-time planner's best grasp of the
  observed cloud, by the robust ranking (default) or the paper's grade;
* :class:`LogisticPolicy`: L2-regularised logistic regression of a candidate's success
  on :func:`grasp_features`, trained on logged candidates; it picks the valid candidate
  with the highest predicted success probability.

:func:`grasp_features` adds to the map's own columns what the observation shows about
the scene: the grasp's pose relative to the table (approach and closing directions,
height, gripper clearance above the table) and relative to the *observed cloud* -- how
close the gripper's boxes come to the sensor points and how many points lie between the
pads. The grade knows only the identified primitive; the cloud also shows what
identification missed (a mug's handle) and how much room the fingers have, which is
what the robot's execution error eats into.

Pure numpy: no mujoco here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graspsim.envs.candidates import CANDIDATE_FEATURES
from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.maps.robust import executed_width
from graspsim.stats import fit_logistic, wilson_interval
from graspsim.transforms import make_transform, quat_to_matrix

__all__ = ["random_policy", "highest_grade_policy", "robust_policy", "oracle_choice", "planner_pose", "grasp_features",
           "FEATURE_NAMES", "PRE_ROBUST_FEATURES", "LogisticPolicy", "wilson_interval"]

_COL = {name: i for i, name in enumerate(CANDIDATE_FEATURES)}

FEATURE_NAMES = ("grade", "q_fc", "q_st", "fc_angle", "stability_distance", "width",
                 "approach_z", "closing_z", "tcp_height", "tcp_height_rel", "table_clearance",
                 "cloud_clearance", "points_in_gripper", "points_between_pads", "robust")
#: The learned policy's features as they were before the robust ranking existed (the
#: baseline E06 compares the robust score against): all but the robust score, computed at
#: the map's pre-grasp opening (``grasp_features(..., opening="map")``) -- nothing the
#: robust score computes (its score, its opening) enters.
PRE_ROBUST_FEATURES = FEATURE_NAMES[:-1]


def _valid(obs: dict) -> np.ndarray:
    return np.flatnonzero(np.asarray(obs["action_mask"]) > 0)


def random_policy(obs: dict, rng: np.random.Generator) -> int:
    """A valid candidate uniformly at random (candidate 0 if none is valid)."""
    v = _valid(obs)
    return int(rng.choice(v)) if len(v) else 0


def highest_grade_policy(obs: dict) -> int:
    """The valid candidate with the highest grade (the first such on ties)."""
    v = _valid(obs)
    if not len(v):
        return 0
    g = np.asarray(obs["candidates"])[v, _COL["grade"]]
    return int(v[np.argmax(g)])


def robust_policy(obs: dict) -> int:
    """The valid candidate with the highest robust score, ties broken by grade (the
    first such on full ties)."""
    v = _valid(obs)
    if not len(v):
        return 0
    c = np.asarray(obs["candidates"])[v]
    order = np.lexsort((-c[:, _COL["grade"]], -c[:, _COL["robust"]]))
    return int(v[order[0]])


def oracle_choice(obs: dict, rewards: np.ndarray) -> int:
    """The valid candidate with the highest simulated reward (K,), ties broken by grade."""
    v = _valid(obs)
    if not len(v):
        return 0
    g = np.asarray(obs["candidates"])[v, _COL["grade"]]
    order = np.lexsort((-g, -np.asarray(rewards)[v]))
    return int(v[order[0]])


def planner_pose(result, rank: str = "robust") -> tuple[np.ndarray, float] | None:
    """(T_world_wrist (4, 4), width [m]) of a plan's best grasp by ``rank`` (the contact
    width, plus twice the extra opening per side its robust score assumed, if any)
    (``graspsim.planning.planner.plan`` of a world-frame cloud, e.g. with the table known:
    ``PlannerConfig(table=TablePlane(height=0.0))``), or None when the map is empty or,
    ranked robustly, its best grasp scored 0 (it collides with the cloud at its pose
    or no perturbation stays feasible)."""
    gmap = result.map
    if not len(gmap):
        return None
    best = gmap.top_k(1, rank=rank)
    if rank == "robust" and best.has_robust and not best.robust[0] > 0:
        return None
    # the robust score assumed the jaws that much wider per side
    width = float(executed_width(best)[0]) if rank == "robust" else float(best.width[0])
    return result.T_cloud_obj @ best.T_obj_wrist[0], width


def _box_sdf(p: np.ndarray, centers: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance (..., B) of points p (..., 3) to boxes (..., B, 3) (same frame)."""
    q = np.abs(p[..., None, :] - centers) - half
    out = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return out + np.minimum(q.max(axis=-1), 0.0)


def grasp_features(obs: dict, gripper: GripperSpec = HGPL_25_60_A, *, opening: str = "executed") -> np.ndarray:
    """(K, len(FEATURE_NAMES)) float64 features of every candidate of an observation
    (invalid slots included; mask them yourself). Lengths [m]. ``opening``: the jaw
    opening the gripper's boxes are placed at, ``"executed"`` (the pre-grasp opening plus
    the extra the robust score chose, as the env executes it) or ``"map"`` (the map's
    pre-grasp opening: the features as they were before the robust score)."""
    if opening not in ("executed", "map"):
        raise InvalidParameterError(f"opening must be 'executed' or 'map', got {opening!r}")
    cand = np.asarray(obs["candidates"], float)
    cloud = np.asarray(obs["cloud"], float)
    op = np.asarray(obs["object_pose"], float)
    K = len(cand)
    T_world_obj = make_transform(quat_to_matrix(op[3:7]), op[:3])
    q = cand[:, 3:7].copy()
    q[np.linalg.norm(q, axis=1) < 1e-6] = (1.0, 0.0, 0.0, 0.0)  # empty slots
    T = T_world_obj @ make_transform(quat_to_matrix(q), cand[:, 0:3])  # (K, 4, 4) world
    width = cand[:, _COL["width"]]
    extra = cand[:, _COL["extra_opening"]] if opening == "executed" else np.zeros(K)
    opening = gripper.pregrasp_opening(width) + 2.0 * extra
    tcp_z = float(gripper.nominal_tcp[2])
    tcp = T[:, :3, 3] + tcp_z * T[:, :3, 2]
    top = max(float(cloud[:, 2].max()), 1e-3)
    # the cloud in every wrist frame, against the gripper's boxes at the pre-grasp opening
    b = gripper.collision_boxes()
    centers = np.broadcast_to(b.centers, (K, *b.centers.shape)).copy()
    centers[:, :, 0] += b.x_sign[None] * 0.5 * opening[:, None]
    p_w = np.einsum("kji,knj->kni", T[:, :3, :3], cloud[None] - T[:, None, :3, 3])  # (K, N, 3)
    sdf = _box_sdf(p_w, centers[:, None], np.broadcast_to(b.half_extents, centers.shape)[:, None])
    d = sdf.min(axis=-1)  # (K, N)
    # the closing region: between the pads, along the pad
    pad_lo = gripper.fingertip_z - gripper.pad_length
    between = ((np.abs(p_w[..., 0]) < 0.5 * opening[:, None]) & (np.abs(p_w[..., 1]) < 0.5 * gripper.finger_size[1])
               & (p_w[..., 2] > pad_lo) & (p_w[..., 2] < gripper.fingertip_z))
    f = np.column_stack([
        cand[:, _COL["grade"]], cand[:, _COL["q_fc"]], cand[:, _COL["q_st"]], cand[:, _COL["fc_angle"]],
        cand[:, _COL["stability_distance"]], width,
        T[:, 2, 2], np.abs(T[:, 2, 0]), tcp[:, 2], tcp[:, 2] / top,
        gripper.lowest_point(T, opening),
        np.clip(d.min(axis=1), -0.02, 0.03), (d < 0).mean(axis=1), between.mean(axis=1),
        cand[:, _COL["robust"]],
    ])
    return f


@dataclass
class LogisticPolicy:
    """Logistic regression P(success | features) with an L2 penalty ``l2`` on the
    standardised weights, fitted by Newton's method (IRLS)."""

    l2: float = 1.0
    mean: np.ndarray | None = None
    scale: np.ndarray | None = None
    weights: np.ndarray | None = None  # (F + 1,), intercept last

    def fit(self, X: np.ndarray, y: np.ndarray, *, iterations: int = 50, tol: float = 1e-8) -> LogisticPolicy:
        """Fit on features X (M, F) and 0/1 labels y (M,): :func:`graspsim.stats.fit_logistic`
        on the standardised features (its penalty is per mean log-loss, so ``l2 / 2M``)."""
        X, y = np.asarray(X, float), np.asarray(y, float).reshape(-1)
        if X.ndim != 2 or len(X) != len(y) or len(X) == 0:
            raise InvalidParameterError(f"need X (M, F) and y (M,) with M > 0; got {X.shape}, {y.shape}")
        self.mean = X.mean(axis=0)
        self.scale = np.where(X.std(axis=0) > 1e-12, X.std(axis=0), 1.0)
        b = fit_logistic((X - self.mean) / self.scale, y, l2=self.l2 / (2 * len(X)), max_iter=iterations, tol=tol)
        self.weights = np.concatenate([b[1:], b[:1]])  # intercept last
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        if self.weights is None:
            raise InvalidParameterError("the policy is not fitted: call fit() first")
        Z = (np.asarray(X, float) - self.mean) / self.scale
        return 1.0 / (1.0 + np.exp(-np.clip(Z @ self.weights[:-1] + self.weights[-1], -30, 30)))

    def __call__(self, obs: dict, gripper: GripperSpec = HGPL_25_60_A) -> int:
        v = _valid(obs)
        if not len(v):
            return 0
        p = self.predict_proba(grasp_features(obs, gripper)[v])
        return int(v[np.argmax(p)])

    def to_dict(self) -> dict:
        return {"l2": self.l2, "features": list(FEATURE_NAMES),
                "mean": None if self.mean is None else self.mean.tolist(),
                "scale": None if self.scale is None else self.scale.tolist(),
                "weights": None if self.weights is None else self.weights.tolist()}
