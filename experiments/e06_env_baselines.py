"""Experiment E06: grasp-selection baselines on ``graspsim/GraspSelect-v0``.

Every episode of the environment offers K planned grasps; the execution error of each
is drawn at reset, so a candidate's outcome is fixed for the episode and
``env.evaluate_candidates()`` gives every candidate's outcome (full information, the
same outcomes ``step`` gives -- checked on every episode by stepping the highest-grade
candidate). On the test episodes all policies are scored on the same episodes:

* random: a valid candidate uniformly at random (and its expected success);
* highest grade: the paper's choice;
* robust: the highest robust score (the planner's default ranking: expected success
  under the execution error, clearance to the observed cloud; ``graspsim.maps.robust``),
  and its ablations (``robust_<name>``, ``graspsim.maps.robust.ABLATIONS``: without the
  cloud, without pose error, at half and twice the error, the feasible fraction alone,
  the paper's grade as the success probability), scored on the same candidates;
* oracle: succeeds when any candidate does (an upper bound);
* learned: logistic regression of success on the candidates' features (map columns,
  pose relative to the table, clearance to the observed cloud), trained on the logged
  candidates of separate training episodes; and an ablation trained on the map columns
  only (grade and components, width).

Success rates with 95 % Wilson intervals, the paired comparison learned vs highest grade
(exact McNemar test), rates per object kind, the outcomes of the chosen grasps, and the
cost of an episode (reset, one trial). With execution error, every test candidate is
also simulated at its nominal pose (``evaluate_candidates(execution_error=False)``), so
each policy's choice is scored on the same episodes without the error too, and the
chosen grasps' START_COLLISION counts are broken down per object kind with and without
it. Episodes are seeded by the harness's seed rule (``graspsim.seeding``): episode i of
split s (0 training, 1 test) resets with ``derived_seed(seed, s, i)``, the random policy
draws from ``rng_for(seed, "choices")``, so results do not depend on ``--workers``. The
planner uses the harness's database (``_common.experiment_database``): unless ``--db``
names one, a private ``OUT/fsdb`` built fresh from the paper's five shapes (coarse maps
with ``--coarse-db``, as ``--quick`` sets). Writes summary.json, results.json, table.md,
figure.png, config.json and episodes.npz to ``--out``.

    python experiments/e06_env_baselines.py
    python experiments/e06_env_baselines.py --perception model --out results/e06_env_baselines.model
    python experiments/e06_env_baselines.py --quick --out results/e06-quick

Flags: one per field of :class:`E06Config` (the experiment harness, ``_common.py``);
``--publish`` copies the summary to ``experiments/reported/e06_env_baselines.json`` (the
published ``--perception model`` run's summary is copied by hand to ``...model.json``).
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one BLAS thread per worker process
os.environ.setdefault("OMP_NUM_THREADS", "1")

import logging
import math
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    Clock,
    database_note,
    database_record,
    experiment_database,
    load_average,
    noise_sigmas,
    opt,
    pct,
    rate_ci,
    rng_for,
    start,
    write_json,
)
from _e06_episodes import collect
from _e06_evaluation import MAP_ONLY, OUTCOMES, POLICIES, PRE_ROBUST, choices, costs, evaluate, stack

from graspsim.envs.baselines import (
    FEATURE_NAMES,
    LogisticPolicy,
)
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import ABLATION_LABELS

log = logging.getLogger("e06")


@dataclass(frozen=True)
class E06Config:
    train: int = opt(400, "training episodes")
    test: int = opt(500, "test episodes")
    objects: str = opt("all", "object set")
    k: int = opt(16, "candidates per episode")
    cloud_size: int = opt(512, "points in the observed cloud")
    view: str = opt("full", "camera view", choices=("full", "single"))
    perception: str = opt("cloud", "identify the object in its cloud (the paper), or give the planner the "
                                   "true model", choices=("cloud", "model"))
    position_noise: float = opt(noise_sigmas("default")[0], "execution error sigma [m]")
    rotation_noise_deg: float = opt(noise_sigmas("default")[1], "execution error sigma [deg]")
    l2: float = opt(1.0, "logistic regression L2 penalty")
    seed: int = opt(20180606, "run seed")
    workers: int = opt(os.cpu_count() or 1, "worker processes")
    db: str | None = opt(None, "map database folder, used as it is (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "a coarse map database (8 mm, 22 deg: CI)")
    open_mm: tuple[float, ...] = opt((0.0, 3.0, 6.0, 10.0), "extra jaw openings per side [mm] the robust "
                                     "score chooses among and the trial executes (0: the map's opening only)")
    QUICK: ClassVar[dict] = {"train": 16, "test": 16, "objects": "primitives", "k": 6, "cloud_size": 128,
                             "coarse_db": True}

    def __post_init__(self) -> None:
        if self.train < 2 or self.test < 1:
            raise ValueError(f"need --train >= 2 and --test >= 1, got {self.train} and {self.test}")
        if self.workers < 1:
            raise ValueError(f"--workers must be >= 1, got {self.workers}")

    @property
    def noisy(self) -> bool:
        return self.position_noise > 0 or self.rotation_noise_deg > 0

    @property
    def map_config(self) -> MapConfig:
        return MapConfig(surface_step=0.008, rotation_step=math.radians(22)) if self.coarse_db else MapConfig()

    def env_kwargs(self) -> dict:
        return dict(objects=self.objects, n_candidates=self.k, cloud_size=self.cloud_size, view=self.view,
                    perception=self.perception, position_noise=self.position_noise,
                    rotation_noise=math.radians(self.rotation_noise_deg), db_root=self.db,
                    map_config=self.map_config, openings=tuple(mm / 1000.0 for mm in self.open_mm))






# ---------------------------------------------------------------------- outputs
def write_table(cfg: E06Config, res: dict, cost: dict) -> str:
    names = {"random": "random", "highest_grade": "highest grade", "robust": "robust score",
             "learned": "learned (all features)", "learned_pre_robust": "learned (features before the robust score)",
             "learned_map_only": "learned (map columns only)", "oracle": "oracle"}
    lines = [f"{res['test_episodes']} test episodes, objects `{cfg.objects}`, K = {cfg.k}, "
             f"execution error {1000 * cfg.position_noise:.0f} mm / {cfg.rotation_noise_deg:.0f} deg; "
             f"learned policies trained on {res['train_candidates']} logged candidates of "
             f"{cfg.train} other episodes.", "",
             "| policy | success | 95 % Wilson interval |", "|---|---|---|"]
    for p in POLICIES:
        r = res["overall"][p]
        lines.append(f"| {names[p]} | {100 * r['rate']:.1f} % ({r['successes']}/{r['n']}) | "
                     f"{100 * r['ci95'][0]:.1f} - {100 * r['ci95'][1]:.1f} % |")
    lines.append(f"| random (expected over the valid candidates) | {100 * res['random_expected']:.1f} % | |")
    m = res["learned_vs_highest_grade"]
    lines += ["", f"Learned vs highest grade, paired: learned alone succeeds in {m['only_first']} episodes, "
              f"highest grade alone in {m['only_second']} (exact McNemar p = {m['p_exact']:.2g}).", "",
              "### success by object kind", "",
              "| kind | episodes | " + " | ".join(names[p] for p in POLICIES)
              + " | learned alone / highest grade alone (McNemar p) |",
              "|---|---|" + "---|" * (len(POLICIES) + 1)]
    for k, r in res["by_kind"].items():
        m = r["learned_vs_highest_grade"]
        lines.append(f"| {k} | {r['episodes']} | " + " | ".join(f"{100 * r[p]:.0f} %" for p in POLICIES)
                     + f" | {m['only_first']} / {m['only_second']} ({m['p_exact']:.2g}) |")
    lines += ["", "### outcomes of the chosen grasps", "", "| policy | " + " | ".join(OUTCOMES) + " |",
              "|---|" + "---|" * len(OUTCOMES)]
    for p in POLICIES:
        lines.append(f"| {names[p]} | " + " | ".join(str(res["chosen_outcomes"][p][o]) for o in OUTCOMES) + " |")
    lines += ["", "### cost of an episode (mean wall time, shared 2-core machine)", "",
              f"reset {cost['reset']['mean_ms']:.0f} ms (planner {cost['plan']['mean_ms']:.0f} ms, "
              f"CPU {cost['reset_cpu']['mean_ms']:.0f} ms, median {cost['reset']['median_ms']:.0f} ms); "
              f"step (one trial) {cost['step']['mean_ms']:.0f} ms (CPU {cost['step_cpu']['mean_ms']:.0f} ms); "
              f"a trial in a batch "
              f"{cost['trial_in_batch_ms']:.0f} ms; {cost['redraws_mean']:.2f} redraws per reset; "
              f"step outcome = evaluate_candidates outcome in {cost['step_agrees_with_evaluate']}"
              f"/{cost['episodes']} episodes."]
    return "\n".join(lines) + "\n"


def plot(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.2), gridspec_kw={"width_ratios": [1, 2]})
    r = [res["overall"][p] for p in POLICIES]
    y = np.array([x["rate"] for x in r])
    err = np.array([[x["rate"] - x["ci95"][0], x["ci95"][1] - x["rate"]] for x in r]).T
    ax.bar(range(len(POLICIES)), 100 * y, yerr=100 * err, capsize=4, color="C0")
    ax.set_xticks(range(len(POLICIES)), [p.replace("_", "\n") for p in POLICIES], fontsize=8)
    ax.set_ylabel("success [%] (95 % Wilson)")
    ax.set_ylim(0, 105)
    ax.set_title(f"{res['test_episodes']} test episodes")
    kinds = list(res["by_kind"])
    w = 0.8 / len(POLICIES)
    for j, p in enumerate(POLICIES):
        bx.bar(np.arange(len(kinds)) + (j - len(POLICIES) / 2 + 0.5) * w,
               [100 * res["by_kind"][k][p] for k in kinds], w, label=p.replace("_", " "))
    bx.set_xticks(range(len(kinds)), [f"{k}\n({res['by_kind'][k]['episodes']})" for k in kinds], fontsize=8)
    bx.set_ylim(0, 122)
    bx.legend(fontsize=7, ncol=len(POLICIES), loc="upper center")
    bx.set_title("by object kind (episodes)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    cfg, out, run = start(E06Config, __file__, argv, __doc__, quiet=("graspsim",))
    total = Clock()
    db = experiment_database(cfg.db, out, cfg.map_config, threads=cfg.workers)  # before any worker starts
    db_start, given = database_record(db), cfg
    cfg = replace(cfg, db=str(db.root))  # the episodes' environments plan against it
    log.info("E06: %d training + %d test episodes, objects %s, K = %d, %d worker(s)",
             cfg.train, cfg.test, cfg.objects, cfg.k, cfg.workers)
    t0 = time.perf_counter()
    train = collect(cfg, 0, cfg.train)
    test = collect(cfg, 1, cfg.test)
    log.info("episodes logged in %.0f s", time.perf_counter() - t0)
    X, M, O = (stack(train, k) for k in ("features", "mask", "outcome"))
    M = M.astype(bool)
    Xv, yv = X[M].astype(float), (O[M] == 0).astype(float)
    learned = LogisticPolicy(l2=cfg.l2).fit(Xv, yv)
    map_only = LogisticPolicy(l2=cfg.l2).fit(Xv[:, MAP_ONLY], yv)
    pre_robust = LogisticPolicy(l2=cfg.l2).fit(stack(train, "features_map")[M].astype(float)[:, PRE_ROBUST], yv)
    pick = choices(test, learned, map_only, pre_robust, rng_for(cfg.seed, "choices"))
    res = evaluate(test, pick)
    res.update(test_episodes=len(test), train_episodes=len(train), train_candidates=int(len(yv)),
               train_success_rate=float(yv.mean()))
    cost = costs(train + test)
    write_json(out / "results.json", {
        "config": asdict(given), "env": {k: (v.to_dict() if hasattr(v, "to_dict") else v)
                                       for k, v in cfg.env_kwargs().items()},
        "results": res, "cost": cost,
        "learned": {"all_features": learned.to_dict(),
                    "map_only": {**map_only.to_dict(), "features": [FEATURE_NAMES[i] for i in MAP_ONLY]},
                    "pre_robust": {**pre_robust.to_dict(), "features": [FEATURE_NAMES[i] for i in PRE_ROBUST],
                                   "opening": "map"}},
        "wall_s": total.wall, "cpu_s": total.cpu, "load_avg_end": load_average()})
    np.savez_compressed(out / "episodes.npz", **{
        f"{name}_{k}": stack(eps, k) for name, eps in (("train", train), ("test", test))
        for k in ("features", "features_map", "candidates", "mask", "outcome", "cloud", "object_pose")},
        test_kind=np.array([e["kind"] for e in test]), feature_names=np.array(FEATURE_NAMES))
    run.write(out, {"config": asdict(given), "results": res, "cost": cost,
                    "database": {"start": db_start, "end": database_record(db)}},
              readme_section)
    table = write_table(cfg, res, cost)
    (out / "table.md").write_text("# E06 grasp-selection baselines (GraspSelect-v0)\n\n" + table)
    plot(res, out / "figure.png")
    log.info("%s\nwall %.0f s; results in %s", table, total.wall, out)
    return 0


NAMES = {"random": "random valid candidate", "highest_grade": "highest paper grade",
         "robust": "highest robust score (the planner's default ranking)",
         "learned": "learned (all features, the robust score included)",
         "learned_pre_robust": "learned (the features it had before the robust score: without it, "
                               "at the map's opening)",
         "learned_map_only": "learned (map columns only)",
         "oracle": "oracle (any candidate succeeds)"}
KIND_NAMES = {"random": "random", "highest_grade": "highest grade", "robust": "robust", "learned": "learned",
              "oracle": "oracle"}
SC_NAMES = {"highest_grade": "highest-grade", "robust": "robust"}


MAP_OPENING_NAMES = {"highest_grade_map": "highest paper grade, the map's opening (the paper)",
                     "robust_map": "highest robust score at the map's opening only",
                     "planner": "planner: the adapted map's robust best (any grasp, not only the K candidates)"}


def _map_opening_rows(r: dict, cfg: dict, err: str) -> list[str]:
    wide = [mm for mm in cfg.get("open_mm", (0.0,)) if mm > 0]
    L = ["", f"The paper's setting on the same episodes and candidates, every grasp at the map's opening "
         f"instead of the one its robust score chose (the map's, or {', '.join(f'{mm:g}' for mm in wide)} mm "
         "wider per side), and the planner's own robust best, with the error:", "",
         "| choice | success | START_COLLISION | robust choice above alone / this alone (McNemar p) |",
         "|---|---|---|---|"]
    for p, x in r["map_opening"].items():
        m = x["vs_robust"]
        none = f" ({x['no_grasp']} episodes without a scored grasp count as failures)" if x["no_grasp"] else ""
        L.append(f"| {MAP_OPENING_NAMES[p]}{none} | {rate_ci(x['successes'], x['n'], x['ci95'])} | "
                 f"{x['start_collision']} | {m['only_first']} / {m['only_second']} ({m['p_exact']:.2g}) |")
    return L


def _vs_pre_robust(r: dict) -> str:
    """The robust choice against the learned policy on its features from before the robust score."""
    m = r.get("robust_vs_learned_pre_robust")
    if m is None:  # summaries from before this comparison
        return ""
    return (f"; vs the learned policy on the features it had before the robust score: {m['only_first']} / "
            f"{m['only_second']} (p = {m['p_exact']:.2g})")


def readme_section(s: dict) -> str:
    """The README's E06 paragraph and tables (see ``experiments/report.py``)."""
    cfg, r, c = s["config"], s["results"], s["cost"]
    noisy = cfg["position_noise"] > 0 or cfg["rotation_noise_deg"] > 0
    err = (f"{1000 * cfg['position_noise']:g} mm / {cfg['rotation_noise_deg']:g}° execution error" if noisy
           else "no execution error")
    see = ("identified in its observed cloud" if cfg["perception"] == "cloud"
           else "given to the planner as its true primitives and pose (`plan_shape`)")
    wide = [mm for mm in cfg.get("open_mm", ()) if mm > 0]
    opening = (f", each candidate executed at the jaw opening its robust score chose (the map's, or "
               f"{', '.join(f'{mm:g}' for mm in wide)} mm wider per side; `EnvConfig.openings`)" if wide else "")
    L = [f"`{s['command']}`: {r['test_episodes']} test episodes (objects `{cfg['objects']}`, K = {cfg['k']} "
         f"candidates, the object {see}, {err}{opening}); the learned policies are trained on "
         f"{r['train_candidates']} logged candidates of {r['train_episodes']} other episodes." + database_note(s), ""]
    sc_err = "START_COLLISION of the chosen grasp" + (" (with / without the error)" if noisy else "")
    head = ["policy", f"success, {err}"] + (["the same choice without the error"] if noisy else []) + [sc_err]
    L += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    pols = [p for p in POLICIES if p in r["overall"]]  # summaries from before the robust ranking lack it
    names = {**NAMES, "learned": NAMES["learned"] if "robust" in pols else "learned (all features)"}
    if any(mm > 0 for mm in cfg.get("open_mm", ())):  # runs before the env executed chosen openings lack it
        names["robust"] = "highest robust score (its opening choice is the env's default)"
    for p in pols:
        o = r["overall"][p]
        row = [names[p], rate_ci(o["successes"], o["n"], o["ci95"])]
        if noisy:
            x = r["overall_exact"][p]
            row.append(rate_ci(x["successes"], x["n"], x["ci95"]))
        n_sc = r["chosen_outcomes"][p]["start_collision"]
        row.append(f"{n_sc} / {r['chosen_outcomes_exact'][p]['start_collision']}" if noisy else str(n_sc))
        L.append("| " + " | ".join(row) + " |")
    m = r["learned_vs_highest_grade"]
    kind_pols = [p for p in ("random", "highest_grade", "robust", "learned", "oracle") if p in pols]
    sc_pols = [p for p in ("highest_grade", "robust") if p in pols]
    L += ["", f"Random choice's expected success over the valid candidates: {pct(r['random_expected'])} %. "
          f"Learned vs highest grade on the same episodes: learned alone succeeds in {m['only_first']}, the "
          f"highest grade alone in {m['only_second']} (exact McNemar p = {m['p_exact']:.2g}). Per object kind:", "",
          "| kind | episodes | " + " | ".join(KIND_NAMES[p] for p in kind_pols) + " | learned alone / highest grade "
          "alone | " + sc_err.replace("of the chosen grasp", "of the " + " / ".join(SC_NAMES[p] for p in sc_pols)
                                      + " grasp") + " |",
          "|---|---|" + "---|" * (len(kind_pols) + 2)]
    for k, b in r["by_kind"].items():
        mk = b["learned_vs_highest_grade"]
        sc = " / ".join(str(b[key][p]) for p in sc_pols
                        for key in (("start_collision", "start_collision_exact") if noisy else ("start_collision",)))
        L.append(f"| {k} | {b['episodes']} | " + " | ".join(f"{pct(b[p], 0)} %" for p in kind_pols)
                 + f" | {mk['only_first']} / {mk['only_second']} | {sc} |")
    if "robust_vs_highest_grade" in r:
        mr, ml = r["robust_vs_highest_grade"], r["robust_vs_learned"]
        L += ["", f"Robust score vs highest grade on the same episodes: the robust choice alone succeeds in "
              f"{mr['only_first']}, the highest grade alone in {mr['only_second']} (exact McNemar p = "
              f"{mr['p_exact']:.2g}); vs the learned policy: {ml['only_first']} / {ml['only_second']} "
              f"(p = {ml['p_exact']:.2g})" + _vs_pre_robust(r) + "."]
    if r.get("map_opening"):
        L += _map_opening_rows(r, cfg, err)
    if r.get("ablation"):
        L += ["", "Ablations of the robust score (`graspsim.maps.robust.ABLATIONS`), each choosing among the "
              "same candidates:", "",
              "| robust score | " + f"success, {err}" + (" | without the error" if noisy else "") + f" | {sc_err} |",
              "|---|---|" + ("---|" if noisy else "") + "---|"]
        for a, x in r["ablation"].items():
            row = [ABLATION_LABELS.get(a, a), rate_ci(x["success"]["successes"], x["success"]["n"],
                                                     x["success"]["ci95"])]
            if noisy:
                row.append(rate_ci(x["success_exact"]["successes"], x["success_exact"]["n"],
                                   x["success_exact"]["ci95"]))
            row.append(f"{x['start_collision']} / {x['start_collision_exact']}" if noisy
                       else str(x["start_collision"]))
            L.append("| " + " | ".join(row) + " |")
    m = s["machine"]
    L += ["", f"Cost, mean CPU time: a reset (drawing the object, its cloud, planning) "
          f"{c['reset_cpu']['mean_ms']:.0f} ms, "
          f"a step (one trial) {c['step_cpu']['mean_ms']:.0f} ms (wall {c['reset']['mean_ms']:.0f} and "
          f"{c['step']['mean_ms']:.0f} ms on this {m['cpus']}-core machine shared at a load average of "
          f"{m['load_avg_start'][0]:g}–{m['load_avg_end'][0]:g})."]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
