"""Experiment E12: fit the calibrated flat-pad contact grade on simulated trials.

Training objects only (``graspsim.calibration.study_shapes.TRAIN_SHAPES``: the five paper
primitives at three sizes plus other proportions): FS maps with closing directions up
to 44 deg, grasps drawn evenly over ten paper-grade bins among the poses that clear the
table, lift-and-place under the default physics. A logistic model on the features of
``graspsim.grades.grade_features`` is fitted and cross-validated by object (leave one object
out; and, stricter, leave one primitive kind out); its threshold is the one whose
out-of-fold population precision reaches 97 %. ``--install`` writes the model to
``graspsim/data/grade_model.json`` (the shipped ``pad_contact`` grade).

The model is the gripper's (``--gripper``, default the Festo HGPL-25-60-A): its maps,
its simulated model and grip force; the model records the gripper, and ``--install``
writes it where ``get_grade("pad_contact", gripper=...)`` finds it
(``graspsim.grades.model_path``). A training object the gripper cannot take at all
(no collision-free grasp: wider than it opens) is left out and listed.

    python experiments/e12_fit_grade_model.py [--install]
    python experiments/e12_fit_grade_model.py --gripper franka_hand --out results/e12_fit_grade_model.franka_hand \
        [--install]
    python experiments/e12_fit_grade_model.py --quick --out results/e12_quick
    python experiments/e12_fit_grade_model.py --gripper path/to/my_gripper.xml --out results/e12_mine

Per gripper, at a size a loaded 2-core machine runs in minutes (the published blocks of
docs/results.md; ``--publish`` writes ``experiments/reported/e12_fit_grade_model.<name>.json``
when ``--out`` is ``results/e12_fit_grade_model.<name>``):

    python experiments/e12_fit_grade_model.py --gripper robotiq_2f85 --per-bin 20 \
        --out results/e12_fit_grade_model.robotiq_2f85 --install --publish

The summary records which model the package ships for the gripper (its provenance:
trials, per-bin, cross-validated AUC) and whether this run installed its own.

(It was E05a, ``e05_fit_grade_model.py``; E05 is the threshold calibration on held-out
objects that uses the model this script installs.)
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, fmt, map_config, md_table, opt, pct, start, write_text

from graspsim import stats
from graspsim.calibration import SimCondition, TrialTable, draw_samples, simulate_samples
from graspsim.calibration.figures import plot_roc
from graspsim.calibration.study_shapes import CALIBRATION_CONE, TRAIN_SHAPES
from graspsim.calibration.trials import fs_cases, table_features
from graspsim.errors import NoFeasibleGraspError
from graspsim.grades.fit import fit_grade
from graspsim.grades.grade_features import FEATURES
from graspsim.grades.models import FESTO, gripper_identity, model_path
from graspsim.grippers import get_gripper
from graspsim.maps.map_config import MapConfig

log = logging.getLogger("e12_fit")


@dataclass(frozen=True)
class Config:
    gripper: str = opt(FESTO, "gripper: a registered name, a model file (.xml, .urdf) or a spec .json")
    per_bin: int = opt(40, "grasps drawn per paper-grade bin and object")
    seed: int = opt(0, "run seed")
    threads: int = opt(2, "simulation and map threads")
    l2: float = opt(1e-3, "L2 penalty of the logistic fit")
    target: float = opt(0.97, "out-of-fold precision the threshold reaches")
    features: tuple[str, ...] = opt(FEATURES, cli=False)
    objects: tuple[str, ...] = opt(tuple(TRAIN_SHAPES), "training objects", choices=tuple(TRAIN_SHAPES))
    closing_cone_deg: float = opt(math.degrees(CALIBRATION_CONE), "closing directions kept [deg]")
    install: bool = opt(False, "write graspsim/data/grade_model.json")
    reuse: bool = opt(True, "reuse OUT/trials.npz if it holds this configuration's trials")
    quick: bool = opt(False, "coarse maps (1 cm / 22 deg)", cli=False)
    QUICK: ClassVar[dict] = {"objects": ("box@1", "cylinder@1", "sphere@1"), "per_bin": 3, "quick": True}

    def __post_init__(self) -> None:
        if self.per_bin < 1 or len(self.objects) < 2:
            raise ValueError(f"--per-bin must be >= 1 and --objects two or more; got {self.per_bin}, {self.objects}")
        get_gripper(self.gripper)  # a bad name or spec file: one line, exit 2

    @property
    def map_config(self) -> MapConfig:
        return map_config(self.quick, closing_cone=math.radians(self.closing_cone_deg))


def collect(cfg: Config, out: Path) -> TrialTable:
    path = out / "trials.npz"
    if cfg.reuse and path.exists():
        table = TrialTable.load(path)
        if table.meta.get("config") == _jsonable(cfg, trials_only=True):
            log.info("reusing %s", path)
            return table
    gripper, cases, skipped = get_gripper(cfg.gripper), [], []
    for k in cfg.objects:
        try:
            cases += fs_cases({k: TRAIN_SHAPES[k]}, config=cfg.map_config, gripper=gripper, threads=cfg.threads)
        except NoFeasibleGraspError as err:  # wider than this gripper opens, everywhere
            log.warning("%s left out: %s", k, err)
            skipped.append(k)
    samples = draw_samples(cases, cfg.per_bin, seed=cfg.seed)
    table = simulate_samples(samples, SimCondition(), seed=cfg.seed, threads=cfg.threads,
                             features=())
    table = TrialTable(table.columns, {**table.meta, "config": _jsonable(cfg, trials_only=True),
                                       "objects_left_out": skipped})
    table.save(path)
    return table


def _jsonable(cfg: Config, trials_only: bool = False) -> dict:
    """The configuration the stored trials depend on (a rerun reuses them if equal)."""
    d = {"per_bin": cfg.per_bin, "seed": cfg.seed, "objects": list(cfg.objects),
         "closing_cone_deg": cfg.closing_cone_deg}
    if cfg.gripper != FESTO:  # (the Festo's stored trials predate the field)
        d["gripper"] = gripper_identity(get_gripper(cfg.gripper))
    return {**d, "quick": True} if cfg.quick else d


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=NAMED)
    table = collect(cfg, out)
    t = table.select(table.feasible)
    kind_of = {c["group"]: c["object"]["primitive"] for c in table.meta["cases"]}
    kinds = np.array([kind_of[g] for g in t["group"]])
    feats = table_features(t, cfg.features)  # from the stored grasp geometry
    versions = run.versions
    gripper = gripper_identity(get_gripper(cfg.gripper))
    left_out = table.meta.get("objects_left_out", [])
    provenance = {"script": "experiments/e12_fit_grade_model.py", "command": run.command, "seed": cfg.seed,
                  "per_bin": cfg.per_bin, "gripper": gripper,
                  "objects": [k for k in cfg.objects if k not in left_out], "objects_left_out": left_out,
                  "trials": int(len(table)), "feasible_trials": int(len(t)),
                  "protocol": table.meta.get("protocol"), "condition": table.meta.get("condition"),
                  "mujoco_version": table.meta.get("mujoco_version"),
                  "git_commit": versions.get("git_commit"), "date": versions["date"]}
    fit = fit_grade(feats, t["success"], t["group"], kinds, weights=t["weight"], names=cfg.features,
                    l2=cfg.l2, target=cfg.target, provenance=provenance)
    y = t["success"].astype(bool)
    paper_auc = {"object": stats.roc_auc(t["grade"], y),
                 "object_population": stats.roc_auc(t["grade"], y, t["weight"])}
    model = fit.model
    model = type(model).from_dict({**model.to_dict(), "gripper": gripper, "provenance": {
        **provenance, "cv_auc": fit.auc, "cv_threshold": fit.threshold_oof,
        "paper_grade_auc": paper_auc}})
    model.save(out / "grade_model.json")
    shipped = _shipped(gripper)  # before --install replaces it
    if cfg.install:
        model.save(model_path(gripper["name"]))
        log.info("installed %s", model_path(gripper["name"]))
    p07 = stats.precision_recall(t["grade"], y, 0.7, t["weight"])
    pt = stats.precision_recall(fit.oof["object"], y, fit.threshold_oof, t["weight"])
    summary = {"config": cfg, "gripper": gripper, "objects_left_out": left_out,
               "trials": len(table), "feasible": int(len(t)), "success_rate": float(y.mean()),
               "cv_auc": fit.auc, "cv_auc_by_object": fit.auc_by_group, "paper_auc": paper_auc,
               "paper_auc_by_object": {str(g): stats.roc_auc(t["grade"][t["group"] == g], y[t["group"] == g])
                                       for g in np.unique(t["group"])},
               "threshold_oof": fit.threshold_oof,
               "paper_at_0.7": dict(zip(("precision", "recall", "accepted"), p07)),
               "calibrated_at_threshold_oof": dict(zip(("precision", "recall", "accepted"), pt)),
               "model": model.to_dict(), "installed": bool(cfg.install), "shipped_before": shipped}
    run.write(out, summary)
    rows = [[g, summary["paper_auc_by_object"][g], fit.auc_by_group[g]] for g in fit.auc_by_group]
    md = [f"# E12: calibrated grade fit for {gripper['name']} ({len(t)} feasible trials, "
          f"{len(fit.auc_by_group)} objects" + (f"; left out: {', '.join(left_out)}" if left_out else "") + ")", "",
          md_table(["", "paper grade", "calibrated (out of fold)"],
                   [["pooled AUC, leave one object out", paper_auc["object"], fit.auc["object"]],
                    ["pooled AUC, leave one kind out", paper_auc["object"], fit.auc.get("kind")],
                    ["population AUC, leave one object out", paper_auc["object_population"],
                     fit.auc["object_population"]]]), "",
          f"Out-of-fold threshold for {cfg.target:.0%} precision: {fmt(fit.threshold_oof)} "
          f"(precision {fmt(pt[0])}, recall {fmt(pt[1])}); paper grade at 0.7: precision "
          f"{fmt(p07[0])}, recall {fmt(p07[1])}.", "",
          md_table(["object", "paper AUC", "calibrated AUC (held out)"], rows), "",
          md_table(["feature", "coef (standardised)", "mean", "scale"],
                   [[k, c, m, s] for k, c, m, s in zip(model.features, model.coef, model.mean, model.scale)]),
          "", f"Intercept {fmt(model.intercept)}."]
    write_text(out / "summary.md", "\n".join(md))
    plot_roc({"paper grade": (t["grade"], y, None),
              "calibrated, leave-one-object-out": (fit.oof["object"], y, None),
              "calibrated, leave-one-kind-out": (fit.oof["kind"], y, None)},
             out / "roc_fit.png", title="Training objects (out-of-fold)")
    print("\n".join(md))
    return 0


def _shipped(gripper: dict) -> dict | None:
    """The provenance of the model the package ships for ``gripper`` (None: none)."""
    import json

    path = model_path(gripper["name"])
    if not path.is_file():
        return None
    d = json.loads(path.read_text())
    p = d.get("provenance") or {}
    return {"file": f"graspsim/data/{path.name}", "gripper": d.get("gripper"),
            **{k: p.get(k) for k in ("command", "per_bin", "trials", "feasible_trials", "cv_auc", "cv_threshold",
                                     "git_commit", "date")}}


def readme_section(s: dict) -> str:
    """docs/results.md's block of one gripper's fit (see ``experiments/report.py``)."""
    c, g, m = s["config"], s["gripper"], s["model"]
    objs, left = [k for k in c["objects"] if k not in s["objects_left_out"]], s["objects_left_out"]
    pr, cal = s["paper_at_0.7"], s["calibrated_at_threshold_oof"]
    L = [f"`{s['command']}`: gripper `{g['name']}` (spec digest `{g['digest']}`); {len(objs)} training objects"
         + (f" ({len(left)} it cannot take at all left out: {', '.join(left)})" if left else "")
         + (f", {len(s['paper_auc_by_object'])} of them with trials"
            if len(s["paper_auc_by_object"]) < len(objs) else "")
         + f", {c['per_bin']} grasps per paper-grade bin (ten bins) and object drawn among the poses clear of "
         f"the table, lift-and-place with the gripper's own model; {s['trials']} trials, "
         f"{s['trials'] - s['feasible']} of them starting in collision, {s['feasible']} feasible (the denominator: "
         f"the fit predicts the success of an executed grasp), {pct(s['success_rate'])} % of them succeed. "
         "Cross-validated by object:", ""]
    au, pa = s["cv_auc"], s["paper_auc"]
    L += [md_table(["", "paper grade", "pad_contact fitted here (out of fold)"],
                   [["AUC, leave one object out", pa["object"], au["object"]],
                    ["AUC, leave one primitive kind out", pa["object"], au.get("kind")],
                    ["population AUC (sampling weights), leave one object out", pa["object_population"],
                     au["object_population"]]]), ""]
    thr = s["threshold_oof"]
    L.append(f"Out of fold, the threshold reaching {pct(c['target'], 0)} % precision is "
             + (f"{fmt(thr)}: precision {pct(cal['precision'])} %, recall {pct(cal['recall'])} % "
                if thr is not None and math.isfinite(thr) else "not reached ")
             + f"(population); the paper's grade at 0.7: precision {pct(pr['precision'])} %, recall "
             f"{pct(pr['recall'])} %.")
    sh = s.get("shipped_before")
    if s.get("installed"):
        L.append(f"This fit is the model shipped for `{g['name']}` (`{model_path_name(g['name'])}`, "
                 f"threshold {fmt(m['threshold'])})"
                 + (f"; it replaced one fitted on {sh['trials']} trials" if sh else "") + ".")
    elif sh:
        auc = (sh.get("cv_auc") or {}).get("object")
        L.append(f"Not installed: the model shipped for `{g['name']}` (`{sh['file']}`) was fitted on "
                 f"{sh['trials']} trials at {sh['per_bin']} per bin (AUC leave one object out {fmt(auc)}) "
                 "and is kept; this block shows the fit at this run's size.")
    else:
        L.append(f"Not installed: no model is shipped for `{g['name']}` (it takes the paper's grade).")
    return "\n".join(L)


def model_path_name(name: str) -> str:
    """The shipped model's path relative to the repository (``graspsim/data/...``)."""
    return f"graspsim/data/{model_path(name).name}"


if __name__ == "__main__":
    sys.exit(main())
