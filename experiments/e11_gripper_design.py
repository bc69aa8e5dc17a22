"""Experiment E11 (issue 18): gripper design analysis with graspability maps, and maps
adapted to a new gripper (paper section 5).

A. **Design sweeps.** Finger length, pad length and stroke are varied one at a time
   around the Festo HGPL-25-60-A defaults (``graspsim.apps.design.vary``: a longer stroke
   lengthens the housing just enough to carry it). Each design gets an FS map of the
   paper's five primitives at several sizes (scale factors of ``PAPER_SHAPES``) at the
   design resolution, and per map: SR and VR of the grasps with grade > 0.7 (VR over
   one voxel box per sweep, sized by its longest reach), the share of collision-free
   grasps above 0.7, and lift-and-place trials of accepted grasps drawn uniformly over
   the surface among those that clear the table (the gripper simulated from the spec).
   Each parameter's sweep is timed (wall, CPU, load average).
B. **Grippers compared**: the same numbers for named grippers (``--grippers``) over one
   voxel box.
C. **Adapted vs own**: the FS map of each primitive (paper size, library resolution)
   made for the Festo gripper, adapted to each ``--adapt-to`` gripper by Combined
   scaling (``graspsim.maps.regrip.adapt_to_gripper``), against that gripper's own FS
   map: SRN / VRN over grasps > 0.7, median time per adaptation, and lift-and-place
   success of accepted grasps of both.

    python experiments/e11_gripper_design.py
    python experiments/e11_gripper_design.py --quick --out results/e11-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    Clock,
    load_average,
    machine_load,
    map_config,
    md_table,
    opt,
    rate_ci,
    start,
    write_json,
)

from graspsim.apps.design import (
    DesignConfig,
    adapted_vs_own,
    common_reach,
    evaluate,
    param_value,
    resolve_design,
    sweep,
)
from graspsim.errors import GraspsimError
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps.database import PAPER_SHAPES, size_grid
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.plots import plot_design
from graspsim.stats import wilson_interval

log = logging.getLogger("e11")
KINDS = tuple(PAPER_SHAPES)


@dataclass(frozen=True)
class E11Config:
    seed: int = opt(0, "run seed")
    params: tuple[str, ...] = opt(("finger_length", "pad_length", "stroke"), "parameters to sweep",
                                  choices=("finger_length", "pad_length", "stroke"))
    finger_lengths: tuple[float, ...] = opt((0.05, 0.065, 0.08, 0.11), "finger lengths [m] (Festo: 0.08)")
    pad_lengths: tuple[float, ...] = opt((0.02, 0.03, 0.04, 0.06), "pad lengths [m] (Festo: 0.04)")
    strokes: tuple[float, ...] = opt((0.03, 0.045, 0.06, 0.08), "strokes per jaw [m] (Festo: 0.06)")
    kinds: tuple[str, ...] = opt(KINDS, "primitives", choices=KINDS)
    sizes: tuple[float, ...] = opt((0.75, 1.0, 1.25), "scale factors of the paper's primitives")
    sim_grasps: int = opt(12, "accepted grasps simulated per design x object")
    surface_step: float = opt(0.0075, "design maps' surface step [m]")
    rotation_step_deg: float = opt(16.5, "design maps' rotation step [deg]")
    grippers: tuple[str, ...] = opt((HGPL_25_60_A.name, "franka_hand"), "grippers compared (names or spec .json)")
    adapt_to: tuple[str, ...] = opt(("franka_hand", "finger_length=0.05", "stroke=0.04"),
                                    "grippers the Festo maps are adapted to (names, spec .json or "
                                    "param=value variants of the Festo gripper)")
    adapt_sim_grasps: int = opt(40, "accepted grasps simulated per adapted / own map")
    adapt_repeats: int = opt(3, "timed adaptations per map (median)")
    threads: int = opt(2, "map and simulation threads")
    quick: bool = opt(False, cli=False)
    QUICK: ClassVar[dict] = {"finger_lengths": (0.06, 0.08), "pad_lengths": (0.03, 0.04),
                             "strokes": (0.045, 0.06), "kinds": ("box", "sphere"), "sizes": (1.0,),
                             "sim_grasps": 2, "adapt_sim_grasps": 2, "adapt_repeats": 1, "quick": True}

    def __post_init__(self) -> None:
        if not self.sizes or min(self.sizes) <= 0:
            raise ValueError(f"--sizes must be positive scale factors, got {self.sizes}")
        if self.sim_grasps < 0 or self.adapt_sim_grasps < 0 or self.adapt_repeats < 1:
            raise ValueError("--sim-grasps and --adapt-sim-grasps must be >= 0, --adapt-repeats >= 1")

    def values(self, param: str) -> tuple[float, ...]:
        return {"finger_length": self.finger_lengths, "pad_length": self.pad_lengths,
                "stroke": self.strokes}[param]

    @property
    def design(self) -> DesignConfig:
        mc = map_config(True) if self.quick else MapConfig(
            surface_step=self.surface_step, rotation_step=math.radians(self.rotation_step_deg))
        return DesignConfig(map_config=mc, sim_grasps=self.sim_grasps, threads=self.threads, seed=self.seed)

    @property
    def adapt_config(self) -> MapConfig:
        return map_config(self.quick)

    def record(self) -> dict:
        return {**asdict(self), "design_map_config": self.design.map_config,
                "adapt_map_config": self.adapt_config}


def objects(cfg: E11Config) -> dict:
    """name -> primitive: each kind at each size factor."""
    return {f"{k}@{f:g}": s for k in cfg.kinds for f, s in zip(cfg.sizes, size_grid(PAPER_SHAPES[k], cfg.sizes))}


def run_sweeps(cfg: E11Config, out: Path) -> dict:
    objs = objects(cfg)
    sweeps = {}
    for param in cfg.params:
        c = Clock()
        rows = sweep(HGPL_25_60_A, param, cfg.values(param), objs, cfg.design, progress=_log_row)
        timing = {**c.record(), "load_avg_end": load_average()}
        base = param_value(HGPL_25_60_A, param)
        plot_design(rows, out / f"{param}.png", param=param, base_value=base,
                    title=f"{param.replace('_', ' ')} around the Festo HGPL-25-60-A ({1000 * base:g} mm, dotted)")
        sweeps[param] = {"values": list(cfg.values(param)), "base": base, "timing": timing,
                         "maps": len(rows), "rows": rows}
        log.info("%s: %d maps in %.1f s wall (%.1f s CPU), load %s -> %s", param, len(rows),
                 timing["wall_s"], timing["cpu_s"], timing["load_avg"], timing["load_avg_end"])
    return sweeps


def _log_row(r: dict) -> None:
    s = r.get("sim", {})
    log.info("  %s=%g %-16s accepted %6s SR %.3f VR %.4f sim %s/%s", r["param"], r["value"], r["object"],
             r.get("accepted"), r.get("SR", math.nan), r.get("VR", math.nan), s.get("success"), s.get("feasible"))


def run_grippers(cfg: E11Config) -> list[dict]:
    grippers = [resolve_design(g, HGPL_25_60_A) for g in cfg.grippers]
    box = common_reach(grippers)
    rows = []
    for g in grippers:
        for name, shape in objects(cfg).items():
            rows.append(evaluate(g, name, shape, cfg.design, box_gripper=box))
            _log_row({**rows[-1], "param": "gripper", "value": math.nan})
    return rows


def run_adapted(cfg: E11Config) -> list[dict]:
    rows = []
    targets = [(text, resolve_design(text, HGPL_25_60_A)) for text in cfg.adapt_to]
    for k in cfg.kinds:
        fs = generate_fs_map(PAPER_SHAPES[k], HGPL_25_60_A, config=cfg.adapt_config, threads=cfg.threads)
        for text, target in targets:
            try:
                r = adapted_vs_own(fs, k, target, repeats=cfg.adapt_repeats, sim_grasps=cfg.adapt_sim_grasps,
                                   seed=cfg.seed, threads=cfg.threads)
            except GraspsimError as err:  # e.g. the target cannot grasp the primitive at all
                r = {"object": k, "kind": k, "target": target.name, "error": str(err)}
            r["target_arg"] = text
            rows.append(r)
            log.info("  %s -> %s: SRN %s VRN %s adapt %.3f s (cold %.3f s) own %.2f s", k, target.name,
                     r.get("SRN"), r.get("VRN"), r.get("adapt_s", math.nan), r.get("adapt_cold_s", math.nan),
                     r.get("own_s", math.nan))
    return rows


def main(argv=None) -> int:
    cfg, out, run = start(E11Config, __file__, argv, __doc__)
    sweeps = run_sweeps(cfg, out)
    grippers = run_grippers(cfg)
    adapted = run_adapted(cfg)
    write_json(out / "results.json", {"config": cfg.record(), "sweeps": sweeps, "grippers": grippers,
                                      "adapted": adapted})
    text = run.write(out, {"config": cfg.record(), "sweeps": sweeps, "grippers": grippers,
                           "adapted": adapted}, readme_section)
    log.info("%s", text)
    return 0


# ------------------------------------------------------------------ the README block
def _pool(rows: list[dict], key: str = "sim") -> tuple[int, int]:
    """(successes, feasible trials) summed over rows."""
    sims = [r[key] for r in rows if key in r]
    return sum(s["success"] for s in sims), sum(s["feasible"] for s in sims)


def _rate(k: int, n: int) -> str:
    return rate_ci(k, n, wilson_interval(k, n) if n else None, digits=0)


def _mean(rows: list[dict], key: str) -> float:
    v = [r[key] for r in rows if key in r]
    return sum(v) / len(v) if v else math.nan


def _sweep_table(sw: dict, kinds: list[str]) -> str:
    head = ["value [mm]"] + [f"{k.replace('_', ' ')} VR / SR / > 0.7 [%]" for k in kinds] + ["success (feasible)"]
    body = []
    for v in sw["values"]:
        rs = [r for r in sw["rows"] if r["value"] == v]
        cells = [f"{1000 * v:g}" + (" (base)" if abs(v - sw["base"]) < 1e-12 else "")]
        for k in kinds:
            kr = [r for r in rs if r["kind"] == k]
            cells.append(f"{100 * _mean(kr, 'VR'):.1f} / {100 * _mean(kr, 'SR'):.0f} / "
                         f"{100 * _mean(kr, 'share_accepted'):.0f}")
        cells.append(_rate(*_pool(rs)))
        body.append(cells)
    return md_table(head, body)


def readme_section(s: dict) -> str:
    """The README's E11 block (see ``experiments/report.py``)."""
    cfg = s["config"]
    mc = cfg["design_map_config"]
    start, end = machine_load(s)
    L = [f"`{s['command']}` ({', '.join(cfg['kinds'])} at sizes x{', x'.join(f'{f:g}' for f in cfg['sizes'])} of the "
         f"paper's; design maps at {1000 * mc['surface_step']:g} mm / {math.degrees(mc['rotation_step']):.1f} deg; "
         f"VR / SR of grasps > 0.7 and the share of collision-free grasps > 0.7, means over the sizes; "
         f"success: lift-and-place of up to {cfg['sim_grasps']} accepted grasps per map clearing the table, "
         f"pooled, 95 % Wilson interval):", ""]
    kinds = list(cfg["kinds"])
    unsimulated = sorted({r["object"] for sw in s["sweeps"].values() for r in sw["rows"]
                          if r.get("accepted") and not r["sim"]["eligible"] and abs(r["value"] - sw["base"]) < 1e-12})
    if unsimulated:
        L += [f"Not simulated at the base design, since none of their grasps > 0.7 clears the table with the "
              f"object at rest: {', '.join(unsimulated)}.", ""]
    for param, sw in s["sweeps"].items():
        t = sw["timing"]
        L += [f"**{param.replace('_', ' ')}** ({sw['maps']} maps and their trials in {t['wall_s']:.0f} s wall, "
              f"{t['cpu_s']:.0f} s CPU, load average {t['load_avg'][0]:g} at its start, "
              f"{t.get('load_avg_end', [math.nan])[0]:g} at its end):", "",
              _sweep_table(sw, kinds), ""]
    if s["grippers"]:
        body = []
        for g in dict.fromkeys(r["gripper"] for r in s["grippers"]):
            rs = [r for r in s["grippers"] if r["gripper"] == g]
            body.append([g] + [f"{100 * _mean([r for r in rs if r['kind'] == k], 'VR'):.1f}" for k in kinds]
                        + [_rate(*_pool(rs))])
        L += ["**Grippers** (VR [%] of grasps > 0.7 over one voxel box):", "",
              md_table(["gripper"] + kinds + ["success (feasible)"], body), ""]
    if s["adapted"]:
        body = [[r["target"], r["object"]] + (
            [r.get("error", "")] * 7 if "error" in r else
            [f"{r.get('SRN', math.nan):.0f}", f"{r.get('VRN', math.nan):.0f}",
             f"{r.get('own_found', 0)}/{r['own_accepted']}", f"{r['adapt_s']:.3f} ({r['adapt_cpu_s']:.3f})",
             f"{r['adapt_cold_s']:.3f}", f"{r['own_s']:.2f}", _rate(*_pool([r], "sim_adapted")),
             _rate(*_pool([r], "sim_own"))]) for r in s["adapted"]]
        L += ["**Festo maps adapted to another gripper** (Combined scaling, paper section 5) against that "
              "gripper's own FS map at the library's resolution: SRN / VRN over grasps > 0.7; own found: the own "
              "map's grasps > 0.7 that the adapted map holds, pose by pose (1 um); adapt: wall (CPU) seconds, "
              f"median of {cfg['adapt_repeats']} runs with the object's collision samples cached, and one cold run; "
              "own FS map: one cold run; success: lift-and-place of up to "
              f"{cfg['adapt_sim_grasps']} accepted grasps of each map, both drawn from one random stream (where the "
              "maps hold the same grasps, the same grasps are simulated). A box map's wrists lie on the voxel grid's "
              "faces, so two maps of the same poses can differ in VR by last-bit rounding:", "",
              md_table(["gripper", "primitive", "SRN [%]", "VRN [%]", "own found", "adapt [s]", "adapt cold [s]",
                        "own FS map [s]", "success, adapted", "success, own"], body), ""]
        for target in dict.fromkeys(r["target"] for r in s["adapted"]):
            rs = [r for r in s["adapted"] if r["target"] == target and "error" not in r]
            (ka, na), (ko, no) = _pool(rs, "sim_adapted"), _pool(rs, "sim_own")
            gap = 100 * (ka / na - ko / no) if na and no else math.nan
            L.append(f"- {target}, pooled over the primitives: adapted {_rate(ka, na)}, own {_rate(ko, no)}: "
                     f"{gap:+.1f} points; own grasps > 0.7 found in the adapted maps "
                     f"{sum(r.get('own_found', 0) for r in rs)} of {sum(r['own_accepted'] for r in rs)}; "
                     f"adaptation {min(r['adapt_s'] for r in rs):.3f}–{max(r['adapt_s'] for r in rs):.3f} s wall, "
                     f"{min(r['adapt_cpu_s'] for r in rs):.3f}–{max(r['adapt_cpu_s'] for r in rs):.3f} s CPU.")
        L.append("")
    L.append(f"({s['machine']['cpus']} cores, load average {start[0]:g} at the start, {end[0]:g} at the end.)")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
