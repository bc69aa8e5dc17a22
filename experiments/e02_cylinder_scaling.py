"""Experiment E02 (paper 3.3 / 4.2, table 2, figure 5): map scaling for familiar objects.

The FS map of the paper's cylinder (r = 2 cm, h = 20 cm) is scaled to ten size
variants -- five larger, five smaller; of the smaller ones two change only the height
and three the radius or both, as the paper's discussion says -- by the three
algorithms (grasp Quality, grasp Feasibility, Combined), and compared with an FS map
generated for each variant:

* SRN, VRN [%] (eqs. 7-8) over the accepted grasps (grade > 0.7) of both maps; the
  scaled maps keep only grasps above 0.7, as the paper's do;
* TR = 1 - t_scaled / t_FS [%] (wall time; also on process CPU time, which is less
  sensitive to other load on a shared machine);
* time to the first and to the tenth grasp with grade > 0.95 in the best-first stream.

Timings are the median of ``--repeats`` runs; before every timed run the collision
sample cache of the target is emptied (a new object at run time has none), while the FS
map's line structure is prepared once beforehand (a-priori work on a stored map).
Statistics: mean (SD) per algorithm x direction, a mixed ANOVA (algorithm within,
direction between, variants as subjects) and Bonferroni-adjusted paired post-hoc tests
of the algorithms. Writes summary.json, results.json, table.md, figure5.png and
config.json to ``--out``.

    python experiments/e02_cylinder_scaling.py
    python experiments/e02_cylinder_scaling.py --quick --out results/e02-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import gc
import logging
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    Clock,
    load_average,
    machine_load,
    map_config,
    mean_sd_text,
    opt,
    start,
    write_json,
)
from _map_timing import time_fs, time_scaled
from _stats import mean_sd, mixed_anova, p_text, paired_posthoc, tests_markdown

from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.map_config import MapConfig
from graspsim.maps.metrics import map_rates, relative_rates
from graspsim.maps.scaling import ScalingConfig, scale_stream
from graspsim.plots import plot_maps
from graspsim.primitives import Cylinder

log = logging.getLogger("e02")

BASE = {"radius": 0.02, "height": 0.20}
METHODS = ("quality", "feasibility", "combined")
LABELS = {"quality": "GQ", "feasibility": "GF", "combined": "C"}

# (name, radius [m], height [m], direction, what changes). Larger: radius only, height
# only, both. Smaller: two height-only (the paper's discussion), three radius or both.
# Every ratio lies within 0.6-1.5 of the base, well inside the scaling limit of 3.
VARIANTS: tuple[tuple[str, float, float, str, str], ...] = (
    ("L1", 0.025, 0.20, "larger", "radius"),
    ("L2", 0.020, 0.25, "larger", "height"),
    ("L3", 0.025, 0.25, "larger", "both"),
    ("L4", 0.030, 0.24, "larger", "both"),
    ("L5", 0.030, 0.30, "larger", "both"),
    ("S1", 0.020, 0.15, "smaller", "height"),
    ("S2", 0.020, 0.12, "smaller", "height"),
    ("S3", 0.015, 0.20, "smaller", "radius"),
    ("S4", 0.015, 0.15, "smaller", "both"),
    ("S5", 0.012, 0.12, "smaller", "both"),
)
NAMES = tuple(v[0] for v in VARIANTS)


@dataclass(frozen=True)
class E02Config:
    variants: tuple[str, ...] = opt(NAMES, "size variants", choices=NAMES)
    max_ratio: float = opt(3.0, "scaling limit per dimension")
    repeats: int = opt(3, "timed runs per map (median)")
    hi_grade: float = opt(0.95, cli=False)
    figure_variant: str = opt("", "variant shown in figure5.png (default L3, else the first)")
    quick: bool = opt(False, cli=False)
    QUICK: ClassVar[dict] = {"variants": ("L1", "L3", "S2", "S4"), "repeats": 1, "quick": True}

    def __post_init__(self) -> None:
        if {"larger", "smaller"} - {v[3] for v in self.sizes}:
            raise ValueError("choose at least one larger and one smaller variant")
        if self.figure_variant and self.figure_variant not in self.variants:
            raise ValueError(f"--figure-variant {self.figure_variant} is not among the variants {self.variants}")
        if self.repeats < 1:
            raise ValueError(f"--repeats must be >= 1, got {self.repeats}")

    @property
    def sizes(self) -> tuple[tuple[str, float, float, str, str], ...]:
        """The chosen rows of VARIANTS."""
        return tuple(v for v in VARIANTS if v[0] in self.variants)

    @property
    def figure(self) -> str:
        return self.figure_variant or ("L3" if "L3" in self.variants else self.sizes[0][0])

    @property
    def map_config(self) -> MapConfig:
        return map_config(self.quick)

    def record(self) -> dict:
        """The config as summaries hold it (the variants' sizes and the map settings spelt out)."""
        return {**asdict(self), "variants": self.sizes, "map_config": self.map_config,
                "figure_variant": self.figure}


def run_variant(fs_base: GraspabilityMap, v, cfg: E02Config):
    name, r, h, direction, change = v
    shape = Cylinder(r, h)
    log.info("%s: cylinder r %.1f cm, h %.1f cm (%s, %s); load %s", name, 100 * r, 100 * h,
             direction, change, load_average())
    # scaled maps first, then the variant's FS map (timings do not depend on the order:
    # every timed run starts cold)
    scaled, scaled_t = {}, {}
    for m in METHODS:
        scaled[m], scaled_t[m] = time_scaled(fs_base, shape, ScalingConfig(method=m, max_ratio=cfg.max_ratio),
                                             cfg.repeats, cfg.hi_grade)
    fs, fs_t = time_fs(shape, cfg.map_config, cfg.repeats)
    coarse = 2.0 * cfg.map_config.surface_step  # bins twice the map's step: less sensitive to
    ref2 = map_rates(fs, shape=shape, min_grade=fs.threshold, resolution=coarse)  # sampling density
    row = {"variant": name, "radius": r, "height": h, "direction": direction, "change": change,
           "ratio_radius": r / BASE["radius"], "ratio_height": h / BASE["height"],
           "fs": {"grasps": len(fs), "accepted": int(fs.accepted.sum()),
                  **{k: fs_t[k] for k in ("wall_s", "cpu_s", "load_avg", "runs")}},
           "methods": {}}
    for m in METHODS:
        sm, t = scaled[m], scaled_t[m]
        if sm is None or len(sm) == 0:
            rates = {"SRN": 0.0, "VRN": 0.0}
            srn2 = vrn2 = 0.0
            n = 0
        else:
            rates = relative_rates(sm, fs, min_grade=fs.threshold)
            r2 = map_rates(sm, shape=shape, min_grade=fs.threshold, resolution=coarse)
            srn2, vrn2 = 100.0 * r2.sr / ref2.sr, 100.0 * r2.vr / ref2.vr
            n = len(sm)
        row["methods"][m] = {
            "grasps": n, "SRN": rates["SRN"], "VRN": rates["VRN"], "SRN_2x": srn2, "VRN_2x": vrn2,
            "TR": 100.0 * (1.0 - t["wall_s"] / fs_t["wall_s"]),
            "TR_cpu": 100.0 * (1.0 - t["cpu_s"] / fs_t["cpu_s"]),
            "first_ms": None if t["first_s"] is None else 1000 * t["first_s"],
            "tenth_ms": None if t["tenth_s"] is None else 1000 * t["tenth_s"],
            "wall_s": t["wall_s"], "cpu_s": t["cpu_s"], "load_avg": t["load_avg"], "runs": t["runs"]}
        log.info("  %-11s %7d grasps  SRN %5.1f  VRN %5.1f  TR %5.1f %%  %.3f s (FS %.2f s)  "
                 "first %s ms  tenth %s ms", m, n, rates["SRN"], rates["VRN"],
                 row["methods"][m]["TR"], t["wall_s"], fs_t["wall_s"],
                 _ms(row["methods"][m]["first_ms"]), _ms(row["methods"][m]["tenth_ms"]))
    figure = (fs, scaled["combined"]) if name == cfg.figure else None
    return row, figure


def _ms(x):
    return "n/a" if x is None else f"{x:.1f}"


METRICS = (("SRN", "SRN [%]", 0), ("VRN", "VRN [%]", 0), ("SRN_2x", "SRN, 2x bins [%]", 0),
           ("VRN_2x", "VRN, 2x bins [%]", 0), ("TR", "TR [%]", 0),
           ("TR_cpu", "TR, CPU [%]", 0), ("first_ms", "first > 0.95 [ms]", 1),
           ("tenth_ms", "tenth > 0.95 [ms]", 1), ("wall_s", "scaled map [s]", 3))


def summarise(rows: list[dict]) -> dict:
    cells = {}
    for m in METHODS:
        for d in ("larger", "smaller"):
            rs = [r["methods"][m] for r in rows if r["direction"] == d]
            cells[f"{m}/{d}"] = {"n": len(rs), **{
                k: dict(zip(("mean", "sd"), mean_sd([x[k] for x in rs])), missing=sum(x[k] is None for x in rs))
                for k, _, _ in METRICS}}
    fs = {d: dict(zip(("mean", "sd"), mean_sd([r["fs"]["wall_s"] for r in rows if r["direction"] == d])))
          for d in ("larger", "smaller")}
    tests = {}
    group = np.array([r["direction"] for r in rows])
    for k, _, _ in METRICS[:-1]:
        y = np.array([[np.nan if r["methods"][m][k] is None else r["methods"][m][k] for m in METHODS]
                      for r in rows], float)
        if not np.all(np.isfinite(y)):
            tests[k] = {"skipped": "some variants have no value (no grasp above the grade) for "
                                   "some algorithm: the repeated-measures test needs complete data"}
            continue
        if len(set(group)) < 2 or min(np.sum(group == g) for g in set(group)) < 2:
            tests[k] = {"skipped": "needs at least two variants per direction"}
            continue
        tests[k] = {"anova": mixed_anova(y, group),
                    "posthoc": paired_posthoc(y, [LABELS[m] for m in METHODS])}
    return {"cells": cells, "fs_wall_s": fs, "tests": tests}


def write_table(rows: list[dict], summary: dict, cfg: E02Config) -> str:
    L = ["## Table 2: scaled map quality, time reduction and initial grasps (mean (SD))", "",
         "SRN / VRN over the accepted grasps (grade > 0.7) of both maps; the scaled maps keep "
         "only grasps above 0.7, as the paper's do; SR / VR bins at the map's surface step "
         f"({1000 * cfg.map_config.surface_step:g} mm), and at twice it (2x bins: less sensitive to the "
         "scaled map's contact spacing, which grows / shrinks with the scale factor). "
         "TR = 1 - t_scaled / t_FS on wall time "
         "(TR, CPU: on process CPU time). Times to the first / tenth grasp with grade > 0.95 "
         "in the best-first stream; n/a counts variants where no (or fewer than ten) such "
         f"grasps exist. Median of {cfg.repeats} timed run(s) each.", "",
         "| algorithm | direction | " + " | ".join(lbl for _, lbl, _ in METRICS) + " |",
         "|---|---|" + "---|" * len(METRICS)]
    for m in METHODS:
        for d in ("larger", "smaller"):
            c = summary["cells"][f"{m}/{d}"]
            vals = []
            for k, _, dig in METRICS:
                s = mean_sd_text(c[k]["mean"], c[k]["sd"], dig)
                if c[k]["missing"]:
                    s += f" [{c[k]['missing']}/{c['n']} n/a]"
                vals.append(s)
            L.append(f"| {LABELS[m]} | {d} | " + " | ".join(vals) + " |")
    f = summary["fs_wall_s"]
    L += ["", f"FS map of a variant: {mean_sd_text(f['larger']['mean'], f['larger']['sd'], 2)} s (larger), "
          f"{mean_sd_text(f['smaller']['mean'], f['smaller']['sd'], 2)} s (smaller).",
          *tests_markdown(summary["tests"], [(k, lbl) for k, lbl, _ in METRICS[:-1]])]
    L += ["", "## Per variant", "",
          "| variant | r [cm] | h [cm] | changes | FS grasps (> 0.7) | FS [s] | "
          + " | ".join(f"{LABELS[m]} SRN / VRN / TR / first / tenth / s" for m in METHODS) + " |",
          "|---|---|---|---|---|---|" + "---|" * len(METHODS)]
    for r in rows:
        cells = []
        for m in METHODS:
            x = r["methods"][m]
            cells.append(f"{x['SRN']:.0f} / {x['VRN']:.0f} / {x['TR']:.0f} / {_ms(x['first_ms'])} / "
                         f"{_ms(x['tenth_ms'])} / {x['wall_s']:.3f}")
        L.append(f"| {r['variant']} ({r['direction']}) | {100 * r['radius']:.1f} | {100 * r['height']:.1f} | "
                 f"{r['change']} | {r['fs']['grasps']} ({r['fs']['accepted']}) | {r['fs']['wall_s']:.2f} | "
                 + " | ".join(cells) + " |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    cfg, out, run = start(E02Config, __file__, argv, __doc__)
    total = Clock()
    base = Cylinder(BASE["radius"], BASE["height"])
    c = Clock()
    fs_base = generate_fs_map(base, HGPL_25_60_A, QualityModel(), cfg.map_config)
    base_t = c.record()
    # a-priori preparation of the stored map (its line structure) and compiled kernels
    for _ in scale_stream(fs_base, Cylinder(0.021, 0.21), scaling=ScalingConfig(max_ratio=cfg.max_ratio)):
        break
    log.info("E02: base FS map %d grasps (%d > 0.7) in %.2f s; %d variants x %d algorithms, %d repeat(s)",
             len(fs_base), int(fs_base.accepted.sum()), base_t["wall_s"], len(cfg.sizes), len(METHODS),
             cfg.repeats)
    rows = []
    for v in cfg.sizes:
        row, figure = run_variant(fs_base, v, cfg)
        rows.append(row)
        if figure is not None:
            fs_v, comb = figure
            plot_maps([fs_v, comb], out / "figure5.png", what="wrist", titles=[
                f"FS map, cylinder r {100 * v[1]:.1f} cm h {100 * v[2]:.1f} cm:\n"
                f"{len(fs_v)} wrist poses, {int(fs_v.accepted.sum())} > 0.7",
                f"Combined-scaled from r 2 h 20 cm:\n{len(comb)} wrist poses (all > 0.7)"])
            del figure, fs_v, comb
        gc.collect()
    summary = summarise(rows)
    base_info = {**BASE, "grasps": len(fs_base), "accepted": int(fs_base.accepted.sum())}
    write_json(out / "results.json", {
        "config": cfg.record(), "base": {**base_info, **base_t},
        "note": "SRN/VRN over grasps with grade > 0.7 in both maps; scaled maps keep only grasps > 0.7",
        "summary": summary, "variants": rows, "wall_s": total.wall, "cpu_s": total.cpu})
    brief = [{k: v for k, v in r.items() if k not in ("fs", "methods")}
             | {"fs": {k: r["fs"][k] for k in ("grasps", "accepted", "wall_s", "cpu_s")},
                "methods": {m: {k: v for k, v in x.items() if k != "runs"} for m, x in r["methods"].items()}}
             for r in rows]
    run.write(out, {"config": cfg.record(), "base": base_info, "summary": summary, "variants": brief},
              readme_section)
    table = write_table(rows, summary, cfg)
    (out / "table.md").write_text("# E02 cylinder map scaling (paper table 2)\n\n" + table)
    log.info("%s\nwall %.0f s, CPU %.0f s; results in %s", table, total.wall, total.cpu, out)
    return 0


def _cell(c: dict, k: str, digits: int, unit: str) -> str:
    m = c[k]["mean"]
    if m is None or not math.isfinite(m):
        return "none"
    s = f"{m:.{digits}f}"
    return s + (f" ({c[k]['missing']} of {c['n']} none)" if c[k]["missing"] else "") + unit


#: paper 4.2 on table 2's time reduction
PAPER_TR = "The paper's scaled maps saved 96–97 % of its FS maps' time."


def _p_rel(p: float) -> str:
    """"< .0001" or "= 0.0123"."""
    t = p_text(p)
    return t if t.startswith("<") else f"= {t}"


def readme_section(s: dict) -> str:
    """The README's E02 table and paragraph (see ``experiments/report.py``)."""
    cells, tests, rows = s["summary"]["cells"], s["summary"]["tests"], s["variants"]
    cfg = s["config"]
    step = 1000 * cfg["map_config"]["surface_step"]
    n = {d: sum(r["direction"] == d for r in rows) for d in ("larger", "smaller")}
    L = [f"`{s['command']}` ({n['larger']} larger and {n['smaller']} smaller variants of the r 2 cm, h 20 cm "
         f"cylinder; SRN / VRN over grasps > 0.7, at {step:g} mm bins and at {2 * step:g} mm bins, which are less "
         f"sensitive to contact spacing; means over the variants, larger / smaller; times are medians of "
         f"{cfg['repeats']} cold runs):", "",
         f"| algorithm | SRN | VRN | SRN, {2 * step:g} mm | VRN, {2 * step:g} mm | first > 0.95 | tenth > 0.95 |",
         "|---|---|---|---|---|---|---|"]
    for m in METHODS:
        c = [cells[f"{m}/{d}"] for d in ("larger", "smaller")]
        row = [" / ".join(_cell(x, k, 0, "") for x in c) + " %" for k in ("SRN", "VRN", "SRN_2x", "VRN_2x")]
        row += [" / ".join(_cell(x, k, 1, "") for x in c) + " ms" for k in ("first_ms", "tenth_ms")]
        L.append(f"| {m.capitalize()} | " + " | ".join(row) + " |")
    L.append("")
    for k in ("VRN", "SRN"):
        t = tests[k]
        if "skipped" in t:
            L.append(f"Algorithm effect on {k}: not tested ({t['skipped']}).")
            continue
        e = t["anova"]["within"]
        sig = [f"{ph['a']}–{ph['b']} p {_p_rel(ph['p_bonferroni'])}" for ph in t["posthoc"]
               if ph["p_bonferroni"] < 0.05]
        L.append(f"Algorithm effect on {k} (mixed ANOVA, variants as subjects): F({e['df']:g},{e['df_error']:g}) = "
                 f"{e['F']:.2f}, p {_p_rel(e['p'])}; Bonferroni post-hoc pairs below .05: "
                 f"{', '.join(sig) or 'none'} (GQ Quality, GF Feasibility, C Combined).")
    L.append("")
    for d in ("smaller", "larger"):
        rs = [r for r in rows if r["direction"] == d]
        comb = [r["methods"]["combined"]["wall_s"] for r in rs]
        fs = [r["fs"]["wall_s"] for r in rs]
        tr = [r["methods"]["combined"]["TR"] for r in rs]
        L.append(f"{d.capitalize()} variants: a Combined-scaled map takes {min(comb):.2f}–{max(comb):.2f} s of wall "
                 f"time, an FS map of the same variant {min(fs):.2f}–{max(fs):.2f} s: scaling saves "
                 f"{min(tr):.0f}–{max(tr):.0f} %.")
    start, end = machine_load(s)
    L.append(f"(Wall times on {s['machine']['cpus']} cores, load average {start[0]:g} at the start, "
             f"{end[0]:g} at the end. {PAPER_TR})")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
