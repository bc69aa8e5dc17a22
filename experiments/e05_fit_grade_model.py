"""Experiment E05a: fit the calibrated flat-pad contact grade on simulated trials.

Training objects only (``graspsim.calibration.objects.TRAIN_SHAPES``: the five paper
primitives at three sizes plus other proportions): FS maps with closing directions up
to 44 deg, grasps drawn evenly over ten paper-grade bins among the poses that clear the
table, lift-and-place under the default physics. A logistic model on the features of
``graspsim.grades.features`` is fitted and cross-validated by object (leave one object
out; and, stricter, leave one primitive kind out); its threshold is the one whose
out-of-fold population precision reaches 97 %. ``--install`` writes the model to
``graspsim/data/grade_model.json`` (the shipped ``pad_contact`` grade).

    python experiments/e05_fit_grade_model.py --out results/e05_fit [--install]
    python experiments/e05_fit_grade_model.py --quick --out results/e05_fit_quick
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from graspsim.calibration import SimCondition, TrialTable, draw_samples, simulate_samples, stats
from graspsim.calibration.markdown import fmt, md_table
from graspsim.calibration.objects import CALIBRATION_CONE, TRAIN_SHAPES
from graspsim.calibration.outputs import library_versions, write_json, write_text
from graspsim.calibration.plots import plot_roc
from graspsim.calibration.trials import fs_cases, table_features
from graspsim.grades.features import FEATURES
from graspsim.grades.fit import fit_grade
from graspsim.grades.models import default_model_path
from graspsim.maps.generate import MapConfig

log = logging.getLogger("e05_fit")


@dataclass(frozen=True)
class Config:
    out: str = "results/e05_fit"
    per_bin: int = 40
    seed: int = 0
    threads: int = 2
    l2: float = 1e-3
    target: float = 0.97
    features: tuple = FEATURES
    objects: tuple = tuple(TRAIN_SHAPES)
    closing_cone_deg: float = math.degrees(CALIBRATION_CONE)
    install: bool = False
    reuse: bool = True


def parse() -> Config:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=Config.out)
    p.add_argument("--per-bin", type=int, default=Config.per_bin)
    p.add_argument("--seed", type=int, default=Config.seed)
    p.add_argument("--threads", type=int, default=Config.threads)
    p.add_argument("--l2", type=float, default=Config.l2)
    p.add_argument("--install", action="store_true", help="write graspsim/data/grade_model.json")
    p.add_argument("--no-reuse", action="store_true", help="re-simulate even if trials.npz exists")
    p.add_argument("--quick", action="store_true", help="four objects, 5 grasps per bin (smoke run)")
    a = p.parse_args()
    objects = tuple(TRAIN_SHAPES)
    per_bin = a.per_bin
    if a.quick:
        objects, per_bin = ("box@1", "cylinder@1", "sphere@1", "cone@1"), 5
    return Config(out=a.out, per_bin=per_bin, seed=a.seed, threads=a.threads, l2=a.l2,
                  objects=objects, install=a.install, reuse=not a.no_reuse)


def collect(cfg: Config, out: Path) -> TrialTable:
    path = out / "trials.npz"
    if cfg.reuse and path.exists():
        table = TrialTable.load(path)
        if table.meta.get("config") == _jsonable(cfg, trials_only=True):
            log.info("reusing %s", path)
            return table
    shapes = {k: TRAIN_SHAPES[k] for k in cfg.objects}
    cases = fs_cases(shapes, config=MapConfig(closing_cone=math.radians(cfg.closing_cone_deg)),
                     threads=cfg.threads)
    samples = draw_samples(cases, cfg.per_bin, seed=cfg.seed)
    table = simulate_samples(samples, SimCondition(), seed=cfg.seed, threads=cfg.threads,
                             features=())
    table = TrialTable(table.columns, {**table.meta, "config": _jsonable(cfg, trials_only=True)})
    table.save(path)
    return table


def _jsonable(cfg: Config, trials_only: bool = False) -> dict:
    d = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(cfg).items()}
    if trials_only:
        d = {k: d[k] for k in ("per_bin", "seed", "objects", "closing_cone_deg")}
    return d


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    cfg = parse()
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    table = collect(cfg, out)
    t = table.select(table.feasible)
    kind_of = {c["group"]: c["object"]["primitive"] for c in table.meta["cases"]}
    kinds = np.array([kind_of[g] for g in t["group"]])
    feats = table_features(t, cfg.features)  # from the stored grasp geometry
    versions = library_versions()
    provenance = {"script": "experiments/e05_fit_grade_model.py", "seed": cfg.seed,
                  "per_bin": cfg.per_bin, "objects": list(cfg.objects),
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
    model = type(model).from_dict({**model.to_dict(), "provenance": {
        **provenance, "cv_auc": fit.auc, "cv_threshold": fit.threshold_oof,
        "paper_grade_auc": paper_auc}})
    model.save(out / "grade_model.json")
    if cfg.install:
        model.save(default_model_path())
        log.info("installed %s", default_model_path())
    p07 = stats.precision_recall(t["grade"], y, 0.7, t["weight"])
    pt = stats.precision_recall(fit.oof["object"], y, fit.threshold_oof, t["weight"])
    summary = {"config": _jsonable(cfg), "versions": versions, "seconds": time.perf_counter() - t0,
               "trials": len(table), "feasible": int(len(t)), "success_rate": float(y.mean()),
               "cv_auc": fit.auc, "cv_auc_by_object": fit.auc_by_group, "paper_auc": paper_auc,
               "paper_auc_by_object": {str(g): stats.roc_auc(t["grade"][t["group"] == g], y[t["group"] == g])
                                       for g in np.unique(t["group"])},
               "threshold_oof": fit.threshold_oof,
               "paper_at_0.7": dict(zip(("precision", "recall", "accepted"), p07)),
               "calibrated_at_threshold_oof": dict(zip(("precision", "recall", "accepted"), pt)),
               "model": model.to_dict()}
    write_json(out / "summary.json", summary)
    rows = [[g, summary["paper_auc_by_object"][g], fit.auc_by_group[g]] for g in fit.auc_by_group]
    md = [f"# E05a: calibrated grade fit ({len(t)} feasible trials, {len(fit.auc_by_group)} objects)", "",
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
    write_json(out / "config.json", _jsonable(cfg))
    print("\n".join(md))


if __name__ == "__main__":
    main()
