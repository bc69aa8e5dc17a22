"""``graspsim demo``: the project's main job, end to end."""

from __future__ import annotations

import sys

from graspsim.cli._common import add_gripper_flag, add_robot_flags, command, emit, format_table, robot_base_from_args

__all__ = ["register"]


def _cmd_demo(args) -> int:
    """The paper's case study in one run: a glue-bottle analog seen as a noisy cloud is
    identified, its adapted map is built from the FS database (built on first use in
    ~/.cache/graspsim/db or $GRASPSIM_DB), and grasps drawn uniformly over the map are
    lift-and-placed in MuJoCo against the true geometry. Writes the map, its plot, trial
    renders and summary.json to --out."""
    from graspsim.apps.demo import DemoConfig, run_demo

    cfg = DemoConfig(out=args.out, cloud=args.cloud, db=args.db, quick=args.quick,
                     trials=args.trials, renders=args.renders, noise=args.noise, seed=args.seed,
                     threads=args.threads, gripper=args.gripper, robot=args.robot,
                     robot_base=robot_base_from_args(args))

    def step(msg: str) -> None:
        if not args.json:
            print(f"[graspsim] {msg}", file=sys.stderr, flush=True)

    s = run_demo(cfg, step=step)
    lines = [f"object: {s['source']} -> {s['status']}: "
             + ", ".join(f"{p['primitive']} ({p['match']})" for p in s["parts"]),
             f"adapted map: {s['grasps']} grasps, {s['accepted']} with grade > 0.7"
             + (f" ({s['clear_of_table']} of them with the gripper clear of the table)"
                if "clear_of_table" in s else "")
             + f", built in {s['plan_seconds']:.2f} s from the cloud"]
    if s["trials"]:
        rows = [(i, t["part"], f"{t['grade']:.3f}", "-" if t.get("robust") is None else f"{t['robust']:.3f}",
                 t["outcome"], f"{100 * t['lift_height']:.1f}", f"{1000 * t['hold_slip']:.1f}")
                for i, t in enumerate(s["trials"])]
        lines.append("trial 0: the best grasp by the robust ranking; the others drawn over the object")
        lines.append(format_table(rows, ["#", "part", "grade", "robust", "outcome", "lift cm", "hold slip mm"]))
        lo, hi = s["interval_95"]
        if s.get("robot"):
            lines.append(f"executed by the {s['robot']} arm: reachability {s['plan']['reach']}")
        lines.append(f"success {s['success']}/{s['feasible']} feasible trials "
                     f"({100 * s['success_rate']:.0f} %, 95 % CI {100 * lo:.0f}-{100 * hi:.0f} %)")
    lines.append(f"outputs in {args.out}/ ({s['seconds']:.1f} s in all)")
    emit(s, args.json, "\n".join(lines))
    return 0 if s["status"] != "failed" else 1


def register(sub) -> None:
    from graspsim.cli._common import seed_value

    with command(sub, "demo", run=_cmd_demo, help="end to end: cloud -> identification -> adapted map -> MuJoCo trials",
                 glossary=("FS map", "known / familiar / build", "grade", "robust score", "feasible")) as p:
        p.add_argument("--out", default="graspsim-demo", help="output folder (graspsim-demo)")
        p.add_argument("--cloud", default=None, help="use this cloud file instead of the synthetic analog")
        p.add_argument("--db", default=None, help="FS database folder")
        p.add_argument("--trials", type=int, default=15, help="grasps to simulate (15, as the paper)")
        p.add_argument("--renders", type=int, default=3, help="trials to render as PNG (3; 0: none)")
        p.add_argument("--noise", action="store_true", help="execution noise (3 mm / 2 deg) in the trials")
        p.add_argument("--seed", type=seed_value, default=0)
        p.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
        p.add_argument("--quick", action="store_true",
                       help="coarse database in OUT/db and fewer trials: a fast smoke run (CI)")
        add_gripper_flag(p)
        add_robot_flags(p, robot_help="none: the floating gripper (default); panda: the Franka Emika Panda arm beside "
                        "the table plans and executes the trials (with --gripper on its flange)")
