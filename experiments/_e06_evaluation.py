"""E06's offline evaluation: each policy's choice among the logged candidates of the
test episodes (``_e06_episodes.collect``), its success rate with a 95 % Wilson interval,
paired comparisons (exact McNemar), rates per object kind, the chosen grasps' outcomes
with and without the execution error, the robust score's ablations, and an episode's
cost."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import math

import numpy as np

from graspsim.envs.baselines import FEATURE_NAMES, PRE_ROBUST_FEATURES, LogisticPolicy, wilson_interval
from graspsim.envs.candidates import CANDIDATE_FEATURES
from graspsim.maps.robust import ABLATIONS
from graspsim.stats import mcnemar

__all__ = ["POLICIES", "MAP_ONLY", "PRE_ROBUST", "OUTCOMES", "stack", "choices", "rate", "evaluate", "costs"]

POLICIES = ("random", "highest_grade", "robust", "learned", "learned_pre_robust", "learned_map_only", "oracle")
MAP_ONLY = tuple(FEATURE_NAMES.index(n) for n in ("grade", "q_fc", "q_st", "fc_angle",
                                                  "stability_distance", "width"))
#: The columns of the episodes' ``features_map`` (features at the map's opening) the
#: learned policy had before the robust score (``PRE_ROBUST_FEATURES``).
PRE_ROBUST = tuple(FEATURE_NAMES.index(n) for n in PRE_ROBUST_FEATURES)
OUTCOMES = ("success", "start_collision", "no_contact", "slipped", "dropped", "place_failed",
            "sim_unstable")


def stack(eps: list[dict], key: str) -> np.ndarray:
    return np.stack([e[key] for e in eps])


def choices(eps: list[dict], learned: LogisticPolicy, map_only: LogisticPolicy, pre_robust: LogisticPolicy,
            rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Chosen candidate (E,) per policy; the oracle's is a successful one if any.
    ``pre_robust``: fitted on the ``PRE_ROBUST`` columns of ``features_map``."""
    X, M, O = stack(eps, "features").astype(float), stack(eps, "mask").astype(bool), stack(eps, "outcome")
    cand = stack(eps, "candidates")
    grade = cand[:, :, CANDIDATE_FEATURES.index("grade")]
    robust = cand[:, :, CANDIDATE_FEATURES.index("robust")]
    A = stack(eps, "ablation")  # (E, len(ABLATIONS), K)
    E, K, F = X.shape

    def argmax_valid(score):
        return np.argmax(np.where(M, score, -np.inf), axis=1)

    def by_robust(score):  # ties by grade (grades are < 1: the score's order comes first)
        return argmax_valid(np.round(score.astype(float), 6) * 10.0 + grade)

    p_full = learned.predict_proba(X.reshape(-1, F)).reshape(E, K)
    p_map = map_only.predict_proba(X.reshape(-1, F)[:, MAP_ONLY]).reshape(E, K)
    X0 = stack(eps, "features_map").astype(float).reshape(-1, F)
    p_pre = pre_robust.predict_proba(X0[:, PRE_ROBUST]).reshape(E, K)
    rand = np.array([rng.choice(np.flatnonzero(m)) for m in M])
    return {"random": rand, "highest_grade": argmax_valid(grade), "robust": by_robust(robust),
            "learned": argmax_valid(p_full), "learned_map_only": argmax_valid(p_map),
            "learned_pre_robust": argmax_valid(p_pre),
            "oracle": argmax_valid(np.where(O == 0, 2.0, 0.0) + grade),
            **{f"robust_{a}": by_robust(A[:, j]) for j, a in enumerate(ABLATIONS)}}


def rate(ok: np.ndarray) -> dict:
    n, s = len(ok), int(np.sum(ok))
    lo, hi = wilson_interval(s, n)
    return {"n": n, "successes": s, "rate": s / n if n else math.nan, "ci95": [lo, hi]}


def evaluate(eps: list[dict], pick: dict[str, np.ndarray]) -> dict:
    O, M = stack(eps, "outcome"), stack(eps, "mask").astype(bool)
    OX = stack(eps, "outcome_exact")
    rows = np.arange(len(eps))
    kinds = np.array([e["kind"] for e in eps])
    ok = {p: O[rows, pick[p]] == 0 for p in POLICIES}
    sc = OUTCOMES.index("start_collision")
    res = {"overall": {p: rate(ok[p]) for p in POLICIES},
           # the same choices executed at their nominal poses (= overall without error)
           "overall_exact": {**{p: rate(OX[rows, pick[p]] == 0) for p in POLICIES},
                             "oracle": rate(np.any((OX == 0) & M, axis=1))},
           "random_expected": float(np.mean([np.mean(O[i][M[i]] == 0) for i in rows])),
           "by_kind": {k: {"episodes": int(np.sum(kinds == k)),
                           **{p: rate(ok[p][kinds == k])["rate"] for p in POLICIES},
                           "learned_vs_highest_grade": mcnemar(ok["learned"][kinds == k],
                                                               ok["highest_grade"][kinds == k]),
                           "start_collision": {p: int(np.sum(O[rows, pick[p]][kinds == k] == sc)) for p in POLICIES},
                           "start_collision_exact": {p: int(np.sum(OX[rows, pick[p]][kinds == k] == sc))
                                                     for p in POLICIES}}
                       for k in sorted(set(kinds))},
           "chosen_outcomes": {p: {o: int(np.sum(O[rows, pick[p]] == j)) for j, o in enumerate(OUTCOMES)}
                               for p in POLICIES},
           "chosen_outcomes_exact": {p: {o: int(np.sum(OX[rows, pick[p]] == j)) for j, o in enumerate(OUTCOMES)}
                                     for p in POLICIES},
           "learned_vs_highest_grade": mcnemar(ok["learned"], ok["highest_grade"]),
           "robust_vs_highest_grade": mcnemar(ok["robust"], ok["highest_grade"]),
           "robust_vs_learned": mcnemar(ok["robust"], ok["learned"]),
           "robust_vs_learned_pre_robust": mcnemar(ok["robust"], ok["learned_pre_robust"]),
           "map_only_vs_highest_grade": mcnemar(ok["learned_map_only"], ok["highest_grade"]),
           "ablation": {a: {"success": rate(O[rows, pick[f"robust_{a}"]] == 0),
                            "success_exact": rate(OX[rows, pick[f"robust_{a}"]] == 0),
                            "start_collision": int(np.sum(O[rows, pick[f"robust_{a}"]] == sc)),
                            "start_collision_exact": int(np.sum(OX[rows, pick[f"robust_{a}"]] == sc))}
                        for a in ABLATIONS}}
    res.update(paper_setting(eps, ok["robust"]))
    return res


def paper_setting(eps: list[dict], robust_ok: np.ndarray) -> dict:
    """The map's-opening rows (the paper's setting on the same episodes) and the
    planner's robust best of the whole map, with paired comparisons to the robust
    choice at its chosen opening."""
    sc = OUTCOMES.index("start_collision")
    out: dict = {"map_opening": {}}
    for p in ("highest_grade_map", "robust_map", "planner"):
        o = np.array([e["paper"][p] for e in eps])
        has = o >= 0
        out["map_opening"][p] = {**rate(o == 0), "start_collision": int(np.sum(o == sc)),
                                 "no_grasp": int(np.sum(~has)),
                                 "vs_robust": mcnemar(robust_ok, o == 0)}
    return out


def costs(eps: list[dict]) -> dict:
    def ms(key):
        v = np.array([e[key] for e in eps if e[key] is not None], float)
        return {"mean_ms": 1e3 * float(v.mean()), "median_ms": 1e3 * float(np.median(v))}

    trials = np.array([e["trials"] for e in eps])
    return {"reset": ms("reset_s"), "reset_cpu": ms("reset_cpu_s"), "plan": ms("plan_s"),
            "step": ms("step_s"), "step_cpu": ms("step_cpu_s"),
            "trial_in_batch_ms": 1e3 * float(sum(e["evaluate_s"] for e in eps) / max(1, trials.sum())),
            "redraws_mean": float(np.mean([e["redraws"] for e in eps])),
            "valid_candidates_mean": float(trials.mean()),
            "step_agrees_with_evaluate": int(sum(e["step_agrees"] for e in eps)), "episodes": len(eps)}
