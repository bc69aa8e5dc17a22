"""Experiment E13: lift-and-place success of a gripper's grasps > 0.7, with its own model.

For a gripper (default the vendored Franka hand: its MuJoCo model as authored, attached
under the harness's wrist, with its rated grip force), the five paper primitives at
several sizes: the gripper's own FS map of each; ``--per-case`` grasps with paper grade
> 0.7 drawn uniformly over the surface among the poses that keep the gripper clear of
the table; each lifted and placed (``LiftPlace``) without execution error. A drawn
pose that starts in collision (START_COLLISION) is not a trial; the feasible poses are
the denominator (95 % Wilson intervals). A size with no grasp > 0.7 clear of the table
is reported as impossible, with the widest chord the gripper could take.

    python experiments/e13_gripper_validation.py                      # the Franka hand
    python experiments/e13_gripper_validation.py --gripper festo_hgpl_25_60_a
    python experiments/e13_gripper_validation.py --gripper experiments/grippers/franka_hand_slow_fingers.json \
        --out results/e13_gripper_validation.slow_fingers      # the hand at 0.05 m/s per finger
    python experiments/e13_gripper_validation.py --quick --out results/e13-quick
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RunRecord, map_config, md_table, opt, parse_config, rate_ci, rng_for, write_text

from graspsim.calibration import CalibrationCase, SimCondition, simulate_samples, wilson_interval
from graspsim.calibration.trials import CaseSample, case_clears_table
from graspsim.errors import NoFeasibleGraspError
from graspsim.grippers import get_gripper
from graspsim.maps.database import PAPER_SHAPES, size_grid
from graspsim.maps.generate import MapConfig, generate_fs_map
from graspsim.sim import select_grasps
from graspsim.sim.outcomes import TrialOutcome

log = logging.getLogger("e13")


@dataclass(frozen=True)
class Config:
    gripper: str = opt("franka_hand", "gripper: a registered name or a spec .json")
    seed: int = opt(0, "run seed")
    per_case: int = opt(100, "grasps > 0.7 drawn per map")
    sizes: tuple[float, ...] = opt((0.8, 1.0, 1.25), "sizes relative to the paper's")
    primitives: tuple[str, ...] = opt(tuple(PAPER_SHAPES), choices=tuple(PAPER_SHAPES))
    threads: int = opt(2, "simulation and map threads")
    quick: bool = opt(False, "coarse maps (1 cm / 22 deg)", cli=False)
    QUICK: ClassVar[dict] = {"per_case": 6, "sizes": (1.0,), "primitives": ("box", "sphere"), "quick": True}

    def __post_init__(self) -> None:
        if self.per_case < 1 or not self.sizes:
            raise ValueError(f"--per-case must be >= 1 and --sizes non-empty, got {self.per_case}, {self.sizes}")
        get_gripper(self.gripper)  # a bad name or spec file: one line, exit 2

    @property
    def map_config(self) -> MapConfig:
        return map_config(self.quick)


def _rate(k: int, n: int) -> dict:
    lo, hi = wilson_interval(k, n)
    return {"success": int(k), "of": int(n), "rate": k / n if n else None, "ci": [float(lo), float(hi)]}


def cases(cfg: Config, gripper) -> tuple[list[CaseSample], list[dict]]:
    """Each primitive and size: its FS map and the drawn rows (grade > 0.7, clear of the table)."""
    samples, info = [], []
    for name in cfg.primitives:
        for s, shape in zip(cfg.sizes, size_grid(PAPER_SHAPES[name], cfg.sizes)):
            try:
                fs = generate_fs_map(shape, gripper, config=cfg.map_config, threads=cfg.threads)
            except NoFeasibleGraspError as err:  # wider than the gripper opens, everywhere
                info.append({"case": f"{name}@{s:g}", "primitive": name, "size": s, "shape": shape.to_dict(),
                             "map_grasps": 0, "accepted": 0, "accepted_clear_of_table": 0, "drawn": 0,
                             "why_none": str(err)})
                continue
            case = CalibrationCase(f"{name}@{s:g}", fs, group=name, kind="fs")
            eligible = np.flatnonzero((fs.grade > 0.7) & case_clears_table(case))
            rng = rng_for(cfg.seed, case.name)
            rows = eligible[select_grasps(fs.select(eligible), sample=cfg.per_case, rng=rng)] if len(eligible) \
                else eligible
            info.append({"case": case.name, "primitive": name, "size": s, "shape": shape.to_dict(),
                         "map_grasps": len(fs), "accepted": int(np.sum(fs.grade > 0.7)),
                         "accepted_clear_of_table": len(eligible), "drawn": len(rows)})
            if len(rows):
                samples.append(CaseSample(case, rows, np.ones(len(rows)), len(eligible), len(fs)))
    return samples, info


def outcome_rates(outcomes: np.ndarray) -> dict:
    """Success of the feasible poses and the failures by outcome."""
    feas = outcomes != TrialOutcome.START_COLLISION
    fails = {o.label: int(np.sum(outcomes[feas] == o)) for o in TrialOutcome
             if o not in (TrialOutcome.SUCCESS, TrialOutcome.START_COLLISION)}
    return {"drawn": int(len(outcomes)), "start_collision": int(np.sum(~feas)),
            **_rate(int(np.sum(outcomes == TrialOutcome.SUCCESS)), int(feas.sum())), "failures": fails}


def main(argv=None) -> int:
    cfg, opts = parse_config(Config, __file__, argv, __doc__)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("graspsim.sim.batch").setLevel(logging.WARNING)
    run = RunRecord(__file__, argv)
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    gripper = get_gripper(cfg.gripper)
    samples, info = cases(cfg, gripper)
    table = simulate_samples(samples, SimCondition("exact"), seed=cfg.seed, threads=cfg.threads, features=())
    table.save(out / "trials.npz")
    oc = np.asarray(table["outcome"]) if len(table) else np.zeros(0, np.int8)
    case_col = np.asarray(table["case"]) if len(table) else np.zeros(0, str)
    for row in info:
        row.update(outcome_rates(oc[case_col == row["case"]]))
    prim = np.array([c.split("@")[0] for c in case_col])
    data = {"config": cfg, "gripper": gripper.to_dict(), "grip_force": gripper.grip_force,
            "widest_chord": gripper.max_opening - 2 * gripper.approach_clearance,
            "pooled": outcome_rates(oc), "per_primitive": {p: outcome_rates(oc[prim == p]) for p in cfg.primitives},
            "per_case": info, "impossible": [r["case"] for r in info if not r["drawn"]]}
    md = run.write(out, data, readme_section, publish=opts.publish)
    write_text(out / "summary.md", md)
    print(md)
    return 0


def _fails(f: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in f.items() if v) or "none"


def readme_section(s: dict) -> str:
    """The README's E13 paragraph and table (see ``experiments/report.py``)."""
    g, c = s["gripper"], s["config"]
    L = [f"`{s['command']}` (gripper `{g['name']}`"
         + (f", simulated with its vendored model `mjcf/{g['model']}`" if g.get("model") else "")
         + f", grip force {s['grip_force']:g} N per finger, fingers closing at {g['closing_speed']:g} m/s; the "
         "primitives at "
         f"{', '.join(f'{x:g}' for x in c['sizes'])}× the paper's size; {c['per_case']} grasps > 0.7 per map "
         "drawn uniformly over the surface among the poses clear of the table; lift-and-place without "
         "execution error; the feasible poses are the denominator):", ""]
    rows = [[p, r["drawn"], r["start_collision"], rate_ci(r["success"], r["of"], r["ci"]), _fails(r["failures"])]
            for p, r in s["per_primitive"].items()]
    p = s["pooled"]
    rows.append(["all", p["drawn"], p["start_collision"], rate_ci(p["success"], p["of"], p["ci"]),
                 _fails(p["failures"])])
    L += [md_table(["primitive (all sizes)", "drawn", "start in collision", "success of feasible",
                    "failures"], rows), ""]
    per = [[r["case"], r["accepted"], r["accepted_clear_of_table"],
            rate_ci(r["success"], r["of"], r["ci"]) if r["of"] else "–"] for r in s["per_case"]]
    L += ["Per size:", "", md_table(["map", "grasps > 0.7", "of them clear of the table", "success of feasible"],
                                    per), ""]
    for r in s["per_case"]:
        if not r["drawn"]:
            why = r.get("why_none") or (
                f"{r['map_grasps']} collision-free grasps, none > 0.7 (the widest chord the gripper takes is "
                f"{1000 * s['widest_chord']:g} mm: its opening minus the approach clearance)" if not r["accepted"]
                else f"none of its {r['accepted']} grasps > 0.7 keeps the gripper clear of the table")
            L.append(f"- {r['case']}: impossible: {why}")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
