"""Experiment E05: what the paper's 0.7 means in simulation, and how robust that is.

Held-out objects (``graspsim.calibration.study_shapes.HELD_OUT_SHAPES``: five primitives at
sizes and proportions not used to fit the calibrated grade, and two compounds with the
planner's combined maps), FS maps with closing directions up to 44 deg (default maps stop
at 22 deg: the subset a default map holds is reported apart), grasps drawn evenly over
ten paper-grade bins among the poses that clear the table (population weights kept),
lift-and-place, under two conditions (``graspsim.calibration.conditions``): ``default``
(250 N per jaw, the maps' light masses: nearly every feasible grasp holds, whatever its
grade) and ``friction_limited`` (8 N per jaw, 0.5 kg: grades decide). For the paper's
grade and the calibrated ``pad_contact`` grade: reliability, ROC/AUC, the threshold
reaching 97 % precision and the Youden threshold with bootstrap intervals, precision and
recall at 0.7 -- every precision beside the base rate (the success of all table-clear
grasps under the same condition), and per feasible trial and per attempt (a pose that
execution noise pushes into collision counts as a failed attempt). Then the sensitivity
to pad friction, grip force, object mass, execution noise (3 mm / 2 deg) and the
friction-limited condition, on a paired subsample (same grasps, same noise draws).
``--study`` also replays the feasibility study quoted in issue 6.

Success rates are MuJoCo's: an independent engine was reported (issue 12) to agree on
nearly all high-grade grasps but on far fewer low-grade ones.

Each simulated table is saved (trials_<name>.npz) and reused when its settings match.

    python experiments/e05_threshold_calibration.py [--publish]      # full configuration
    python experiments/e05_threshold_calibration.py --quick --out results/e05_quick
    python experiments/e05_threshold_calibration.py --report-only   # the report from saved trials
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
from dataclasses import astuple, dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, contacts_clause, derived_seed, fmt, map_config, md_table, opt, pct, start, write_text

from graspsim.calibration import TrialTable, calibrate, draw_samples, simulate_samples
from graspsim.calibration.conditions import SimCondition, condition
from graspsim.calibration.figures import plot_reliability, plot_roc, plot_threshold_sweep
from graspsim.calibration.study_shapes import CALIBRATION_CONE, HELD_OUT_SHAPES, paper_size_grid
from graspsim.calibration.trials import fs_cases
from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS
from graspsim.grades import get_grade
from graspsim.maps.map_config import MapConfig
from graspsim.sim import ExecutionNoise

log = logging.getLogger("e05")

COMPONENTS = ("q_fc", "q_st", "-fc_angle", "-stability_distance", "-f_alpha_min",
              "-f_pad_normal_angle", "-f_pad_residual_angle", "f_pad_edge_margin",
              "f_pad_log_area", "-f_place_tilt_ratio")


@dataclass(frozen=True)
class Config:
    per_bin: int = opt(40, "grasps per paper-grade bin and object (main sample)")
    sensitivity_per_bin: int = opt(20, "grasps per bin and object (sensitivity subsample)")
    seed: int = opt(1, "run seed")
    threads: int = opt(2, "simulation and map threads")
    target: float = opt(0.97, "precision the calibrated threshold reaches")
    n_boot: int = opt(500, "bootstrap resamples (main)")
    sensitivity_boot: int = opt(200, "bootstrap resamples (sensitivity)")
    objects: tuple[str, ...] = opt(tuple(HELD_OUT_SHAPES), "held-out objects", choices=tuple(HELD_OUT_SHAPES))
    main_conditions: tuple[str, ...] = opt(("default", "friction_limited"), cli=False)
    frictions: tuple[float, ...] = opt((0.4, 0.5, 0.6, 0.8, 1.0), "pad frictions of the sensitivity")
    forces: tuple[float, ...] = opt((30.0, 60.0, 100.0, 250.0, 300.0), "grip forces per jaw [N]")
    mass_scales: tuple[float, ...] = opt((0.5, 1.0, 2.0, 4.0), "object mass factors")
    noise: tuple[float, ...] = opt(astuple(ExecutionNoise()), cli=False)
    study: bool = opt(False, "replay the issue's feasibility study too")
    study_per_bin: int = opt(40, "grasps per bin of the study replay")
    closing_cone_deg: float = opt(math.degrees(CALIBRATION_CONE), cli=False)
    report_only: bool = opt(False, "recompute the report from the saved trials_*.npz (no maps, no simulation)")
    contacts: str = opt(DEFAULT_CONTACTS, "the simulation's contact model of every condition "
                        "(graspsim.sim.contact_model; SimCondition.contacts)", choices=CONTACT_MODELS)
    quick: bool = opt(False, "coarse maps (1 cm / 22 deg)", cli=False)
    QUICK: ClassVar[dict] = {"objects": ("box_5x7x9", "sphere_r40"), "per_bin": 4, "sensitivity_per_bin": 2,
                             "n_boot": 20, "sensitivity_boot": 10, "frictions": (0.5, 1.0), "forces": (30.0, 250.0),
                             "mass_scales": (1.0,), "study_per_bin": 2, "quick": True}

    def __post_init__(self) -> None:
        if min(self.per_bin, self.sensitivity_per_bin, self.study_per_bin, self.n_boot, self.sensitivity_boot) < 1:
            raise ValueError("--per-bin, --sensitivity-per-bin, --study-per-bin, --n-boot and --sensitivity-boot "
                             "must be >= 1")

    @property
    def map_config(self) -> MapConfig:
        return map_config(self.quick, closing_cone=math.radians(self.closing_cone_deg))


def conditions(cfg: Config) -> list[SimCondition]:
    """The sensitivity's conditions, each with the run's contact model."""
    return [replace(c, contacts=cfg.contacts) for c in _conditions(cfg)]


def _conditions(cfg: Config) -> list[SimCondition]:
    out = [SimCondition("default")]
    out += [SimCondition(f"mu_{m:g}", friction=m) for m in cfg.frictions if m != 0.5]
    out += [SimCondition(f"force_{f:g}", grip_force=f) for f in cfg.forces if f != 250.0]
    out += [SimCondition(f"mass_x{s:g}", mass_scale=s) for s in cfg.mass_scales if s != 1.0]
    out += [SimCondition("noise", noise=ExecutionNoise(*cfg.noise)),
            condition("friction_limited")]
    return out


def simulated(out: Path, name: str, samples, cond: SimCondition, cfg: Config, models) -> TrialTable:
    """The table of ``samples`` under ``cond``: loaded if saved with the same settings."""
    key = {"condition": cond.to_dict(), "seed": cfg.seed,
           "rows": {s.case.name: [int(r) for r in s.rows] for s in samples}}
    path = out / f"trials_{name}.npz"
    if path.exists():
        t = TrialTable.load(path)
        if t.meta.get("key") == key:
            return t
    t = simulate_samples(samples, cond, seed=cfg.seed, threads=cfg.threads, grade_models=models)
    t = TrialTable(t.columns, {**t.meta, "key": key})
    t.save(path)
    return t


SCORES = {"paper": "grade", "pad_contact": "grade_pad_contact"}


def run_tables(cfg: Config, out: Path) -> tuple[dict, dict, dict | None]:
    """(main reports per condition, sensitivity per condition, the study replay or None),
    with the figures written to ``out``."""
    pad = get_grade("pad_contact")
    # each grade at 0.7 and at its own acceptance threshold (paper 0.7; pad_contact's shipped one)
    ref = {"at_0.7": 0.7, "at_own_threshold": {"paper": 0.7, "pad_contact": pad.threshold}}
    mcfg = cfg.map_config
    lazy: dict = {}

    def table(name: str, what: str, cond: SimCondition) -> TrialTable:
        """Trials ``name``: the saved file with --report-only, else simulated (reused when
        saved with the same settings). what: main | sens | study (which grasp sample)."""
        if cfg.report_only:
            return TrialTable.load(out / f"trials_{name}.npz")
        if what not in lazy:
            if what == "study":
                cases = fs_cases(paper_size_grid(), config=mcfg, threads=cfg.threads)
                lazy[what] = draw_samples(cases, cfg.study_per_bin, seed=derived_seed(cfg.seed, "study"))
            else:
                if "cases" not in lazy:
                    lazy["cases"] = fs_cases({k: HELD_OUT_SHAPES[k] for k in cfg.objects}, config=mcfg,
                                             threads=cfg.threads)
                per_bin, seed = (cfg.per_bin, cfg.seed) if what == "main" else \
                    (cfg.sensitivity_per_bin, derived_seed(cfg.seed, "sensitivity"))
                lazy[what] = draw_samples(lazy["cases"], per_bin, seed=seed)
        return simulated(out, name, lazy[what], cond, cfg, [pad])

    main_reports = {}
    for cname in cfg.main_conditions:
        cond = condition(cname, contacts=cfg.contacts)
        t = table(f"main_{cname}", "main", cond)
        rep = calibrate(t, SCORES, target=cfg.target, reference=ref, n_boot=cfg.n_boot, seed=cfg.seed,
                        components=COMPONENTS)
        rep_22 = calibrate(t.select(t["in_default_cone"]), SCORES, target=cfg.target, reference=ref,
                           n_boot=cfg.n_boot, seed=cfg.seed)
        main_reports[cname] = {"condition": cond.to_dict(), "report": rep, "default_cone": rep_22}
        f = t.select(t.feasible)
        plot_reliability(rep.scores, out / f"reliability_{cname}.png", title=f"Held-out objects, {cname}")
        plot_roc({**{k: (f[c], f["success"], None) for k, c in SCORES.items()},
                  **{c: (f[c], f["success"], None) for c in ("q_fc", "q_st")}},
                 out / f"roc_{cname}.png", title=f"Held-out objects, {cname} (sample)")

    sens = {}  # paired subsample, every condition
    for cond in conditions(cfg):
        t = table(f"sens_{cond.name}", "sens", cond)
        r = calibrate(t, SCORES, target=cfg.target, reference=ref, n_boot=cfg.sensitivity_boot, seed=cfg.seed)
        sens[cond.name] = {"condition": cond.to_dict(), "summary": r.summary,
                           "scores": {k: _brief(v) for k, v in r.scores.items()}}
        log.info("%s: %s", cond.name, {k: round(v.auc, 3) for k, v in r.scores.items()})
    _sweep_plot(sens, "mu_", 0.5, "pad friction mu (planner assumes 0.5)", out / "threshold_vs_mu.png")
    _sweep_plot(sens, "force_", 250.0, "grip force per jaw [N]", out / "threshold_vs_force.png")

    study = None
    if cfg.study:
        study = {}
        for cond in (SimCondition("default", contacts=cfg.contacts),
                     SimCondition("study_100N_mu0.6", friction=0.6, grip_force=100.0, contacts=cfg.contacts)):
            t = table(f"study_{cond.name}", "study", cond)
            r = calibrate(t, SCORES, target=cfg.target, reference=ref, n_boot=cfg.sensitivity_boot,
                          seed=cfg.seed)
            study[cond.name] = {"summary": r.summary, "scores": {k: v.to_dict() for k, v in r.scores.items()}}
    return main_reports, sens, study


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=NAMED, quiet=("graspsim.sim.batch",))
    main_reports, sens, study = run_tables(cfg, out)
    pad = get_grade("pad_contact")
    data = {
        "script": f"experiments/{run.stem}.py", "config": cfg, "reduced": _reduced(cfg),
        "pad_contact_model": {k: v for k, v in pad.to_dict().items() if k != "provenance"},
        "closing_cone_deg": cfg.closing_cone_deg, "default_closing_cone_deg": math.degrees(MapConfig().closing_cone),
        "headline": {c: {"all_closing_directions": _headline(m["report"]),
                         "default_cone_only": _headline(m["default_cone"])} for c, m in main_reports.items()},
        "main": {c: {"condition": m["condition"], "report": m["report"].to_dict(),
                     "default_cone": m["default_cone"].to_dict()} for c, m in main_reports.items()},
        "sensitivity": sens, "study": study}
    run.write(out, data, readme_section)
    md = _markdown(cfg, main_reports, sens, study)
    write_text(out / "summary.md", md)
    print(md)
    return 0


def _reduced(cfg: Config) -> str | None:
    """What this run left out of the full configuration (None: nothing); the contact model is
    no reduction (the block names it apart)."""
    full = Config()
    diff = {f: getattr(cfg, f) for f in cfg.__dataclass_fields__
            if getattr(cfg, f) != getattr(full, f) and f not in ("threads", "report_only", "contacts")}
    return None if not diff else "reduced configuration: " + ", ".join(f"{k}={v}" for k, v in diff.items())


def _headline(rep) -> dict:
    """The numbers the README quotes, each with its denominator."""
    s = rep.summary
    out = {"trials": s["trials"], "feasible": s["feasible"], "start_collision": s["start_collision"],
           "base_rate": s["base_rate"], "base_rate_attempts": s["base_rate_attempts"],
           "sample_success": s["success_rate"], "objects": s["groups"]}
    for name, r in rep.scores.items():
        pts = {}
        for label in ("at_0.7", "at_own_threshold", "target"):
            op = r.at.get(label)
            if op is None:
                continue
            pts[label] = {k: op.get(k) for k in ("threshold", "precision", "precision_ci", "precision_attempts",
                                                 "recall", "successes_accepted", "trials_accepted",
                                                 "successes_accepted_attempts", "trials_accepted_attempts")}
        out[name] = {"auc": r.auc, "auc_ci": r.auc_ci, "auc_population": r.auc_population,
                     "threshold_97": r.threshold, "threshold_97_ci": r.threshold_ci, "at": pts}
    return out


def _brief(r) -> dict:
    at = {k: {kk: v.get(kk) for kk in ("threshold", "precision", "precision_attempts", "recall",
                                       "accepted_fraction")}
          for k, v in r.at.items()}
    return {"auc": r.auc, "auc_ci": r.auc_ci, "auc_population": r.auc_population,
            "threshold": r.threshold, "threshold_ci": r.threshold_ci, "youden": r.youden,
            "youden_ci": r.youden_ci, "at": at}


def _sweep_plot(sens: dict, prefix: str, default: float, xlabel: str, path: Path) -> None:
    pts = sorted([(float(k[len(prefix):]), v) for k, v in sens.items() if k.startswith(prefix)]
                 + [(default, sens["default"])], key=lambda p: p[0])
    x = [p[0] for p in pts]
    series = {}
    for name in SCORES:
        v = [p[1]["scores"][name]["threshold"] for p in pts]
        lo = [p[1]["scores"][name]["threshold_ci"][0] for p in pts]
        hi = [p[1]["scores"][name]["threshold_ci"][1] for p in pts]
        series[f"{name}: threshold for 97 % precision"] = (
            [np.nan if a is None else a for a in v], [np.nan if a is None else a for a in lo],
            [np.nan if a is None else a for a in hi])
    plot_threshold_sweep(x, series, path, xlabel=xlabel, title="Calibrated threshold vs " + xlabel)


def _markdown(cfg, main_reports, sens, study) -> str:
    lines = ["# E05: calibration of the grade threshold in simulation", "",
             f"Held-out objects: {', '.join(cfg.objects)}. Maps with closing directions up to "
             f"{cfg.closing_cone_deg:g} deg (default maps: 22 deg)."]
    for cname, m in main_reports.items():
        lines += ["", f"## Condition {cname}: {m['condition']}", "", m["report"].markdown(), "",
                  "Restricted to grasps a default (22 deg) map contains:", "", m["default_cone"].markdown()]
    lines += ["", "## Sensitivity (paired subsample)", "",
              "Base rate: success of all table-clear grasps (population estimate), per feasible trial / "
              "per attempt (START_COLLISION a failure); precision likewise.", ""]
    rows = []
    for name, d in sens.items():
        s = d["summary"]
        for k, v in d["scores"].items():
            a = v["at"]
            rows.append([name, k, s["start_collision"], s["base_rate"], s["base_rate_attempts"], v["auc"],
                         v["threshold"], v["threshold_ci"], a["at_0.7"]["precision"],
                         a["at_0.7"]["precision_attempts"], a["at_0.7"]["recall"],
                         a["at_own_threshold"]["precision"], a["at_own_threshold"]["recall"]])
    lines.append(md_table(["condition", "score", "START_COLLISION", "base rate", "base (attempts)", "AUC",
                           "t(97 %)", "CI", "prec@0.7", "prec@0.7 (attempts)", "rec@0.7", "prec@own t",
                           "rec@own t"], rows))
    if study:
        lines += ["", "## Feasibility study replay (paper primitives, 3 sizes)", "",
                  "The paper primitives at three sizes are training objects of the calibrated grade: "
                  "its numbers here are in-sample.", ""]
        rows = []
        for name, d in study.items():
            for k, v in d["scores"].items():
                a = v["at"]["at_0.7"]
                rows.append([name, k, d["summary"]["feasible"], d["summary"]["base_rate"], v["auc"],
                             v["auc_population"], a["precision"], a["recall"], v["threshold"]])
        lines.append(md_table(["condition", "score", "feasible", "base rate", "AUC", "AUC (pop.)",
                               "prec@0.7", "rec@0.7", "t(97 %)"], rows))
    return "\n".join(lines)


def _pct(v) -> str:
    return pct(v, missing="–") + ("" if v is None else " %")


def readme_section(summary: dict) -> str:
    """The README's block for E05, from a summary.json."""
    rows = []
    for cname, h in summary["headline"].items():
        for subset, d in (("all", h["all_closing_directions"]), ("≤ 22°", h["default_cone_only"])):
            p07, own = d["paper"]["at"]["at_0.7"], d["pad_contact"]["at"]["at_own_threshold"]
            rows.append(f"| {cname} | {subset} | {d['feasible']} ({d['start_collision']}) | "
                        f"{_pct(d['base_rate'])} | {_pct(p07['precision'])} "
                        f"({p07['successes_accepted']}/{p07['trials_accepted']}) | {_pct(p07['recall'])} | "
                        f"{fmt(d['paper']['auc'], 2)} | {fmt(own['threshold'], 2)}: {_pct(own['precision'])}, "
                        f"recall {_pct(own['recall'])} | {fmt(d['pad_contact']['auc'], 2)} |")
    noise = summary["sensitivity"].get("noise")
    lines = [
        f"`{summary['command']}`" + (f" ({summary['reduced']})" if summary.get("reduced") else "")
        + contacts_clause(summary.get("config", {}), lead=" with "),
        "",
        "Held-out objects (sizes and shapes the calibrated grade was not fitted on), grasps drawn evenly over "
        "ten paper-grade bins among the poses that clear the table, lift-and-place in MuJoCo. Rates are "
        "population estimates (sampling weights); the base rate is the success of *all* table-clear grasps "
        "under the same condition. `default`: 250 N per jaw and the maps' light masses (pad friction holds "
        "the weight a hundred times over); `friction_limited`: 8 N per jaw, 0.5 kg (friction barely "
        f"exceeds weight plus lift acceleration). The calibration maps include closing directions up to "
        f"{summary['closing_cone_deg']:.0f}° "
        f"(default maps stop at {summary['default_closing_cone_deg']:.0f}°); the ≤ 22° rows are the grasps a "
        "default map holds.", "",
        "| condition | closing dirs | feasible (START_COLLISION) | base rate | paper > 0.7: precision (sample) "
        "| recall | paper AUC | pad_contact at its threshold | pad_contact AUC |",
        "|---|---|---|---|---|---|---|---|---|", *rows]
    if noise:
        s, p = noise["summary"], noise["scores"]["paper"]["at"]["at_0.7"]
        lines += ["", f"With execution noise (3 mm / 2°, paired subsample of {s['trials']} grasps): "
                  f"{s['start_collision']} poses start in collision; base rate {_pct(s['base_rate'])} per "
                  f"feasible trial, {_pct(s['base_rate_attempts'])} per attempt; paper > 0.7 precision "
                  f"{_pct(p['precision'])} per feasible trial, {_pct(p['precision_attempts'])} per attempt."]
    lines += ["", "Success is MuJoCo's: an independent engine (PyBullet) was reported to agree on nearly all "
              "high-grade grasps in the friction-limited condition but on far fewer low-grade ones (MuJoCo "
              "the stricter on edge and corner contacts)."]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
