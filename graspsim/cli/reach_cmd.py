"""``graspsim reach``: mark which of a map's grasps an arm at a base reaches.

    graspsim reach MAP.h5 --robot panda [--robot-base X Y YAW] [--exact N] [--rank robust|paper] [--json]

Every grasp gets the arm's first cut (its capability map), the ``--exact`` best of those
it passes the exact check an arm trial plans (IK, approach, lift, move, collisions); the
verdicts go into the map file as its ``reachable`` column, atomically, with the arm and
its base in the map's metadata (:func:`graspsim.robots.mark_reach_file`). The map's
ranking then puts reachable grasps first: ``graspsim trial MAP --top N --robot panda``
runs the best ones the arm reaches.
"""

from __future__ import annotations

import sys

from graspsim.cli._common import add_robot_flags, command, emit, progress, robot_base_from_args, whole_number

__all__ = ["register", "run"]


def register(subparsers) -> None:
    with command(subparsers, "reach", run=run,
                 help="mark which of a map's grasps an arm at a base reaches (the map's ranking prefers them)",
                 glossary=("robust score", "grade")) as p:
        p.add_argument("map", metavar="MAP.h5", help="graspability map file (updated in place, atomically)")
        add_robot_flags(p, required=True, robot_help="the arm: panda (the Franka Emika Panda carrying the map's "
                        "gripper on its flange)")
        p.add_argument("--exact", type=whole_number(0), default=100, metavar="N",
                       help="how many of the best grasps the first cut passes get the exact check (100)")
        p.add_argument("--rank", choices=("robust", "paper"), default="robust",
                       help="the order choosing the --exact best (robust, default; paper: the grade)")


def run(args) -> int:
    """Judge every grasp of the map for the arm at its base -- the arm's capability map
    for all, the plan an arm trial makes for the --exact best -- and store the verdicts
    in the map (its reachable column: 1 planned, 0.5 first cut only, 0 unreachable),
    atomically: a bad option or a failure writes nothing."""
    from graspsim.maps.io import load_map

    base = robot_base_from_args(args)
    load_map(args.map, rows=slice(0, 0))  # a readable map before the arm is built
    from graspsim.robots import mark_reach_file

    bar = progress(None, "exact checks", enabled=not args.json and sys.stderr.isatty(), unit="grasp")
    try:
        record = mark_reach_file(args.map, robot=args.robot, base=base, exact=args.exact, rank=args.rank,
                                 on_progress=lambda k: bar.update(k - bar.n))
    finally:
        bar.close()
    c, e = record["counts"], record["exact"]
    summary = {"file": args.map, "robot": record["robot"], "robot_base": record["base"], "rank": args.rank,
               "grasps": record["first_cut"]["rows"], "first_cut_passed": record["first_cut"]["passed"],
               "exact_checked": e["rows"], "exact_reachable": e["planned"], "verdicts": e["reach"],
               "not_planned_at": e["not_executed_at"], "counts": c}
    human = (f"{args.map}: {record['robot']} at base {' '.join(f'{v:g}' for v in record['base'])} (x y [m], yaw "
             f"[deg]): first cut passed {record['first_cut']['passed']} of {record['first_cut']['rows']} grasps; "
             f"exact check planned {e['planned']} of the {e['rows']} best"
             + (f" (refused: {', '.join(f'{k} {v}' for k, v in e['reach'].items() if k != 'reachable')})"
                if e["rows"] > e["planned"] else "")
             + f"\nreachable column written: {c['exact']} exact, {c['first_cut']} first cut only, "
               f"{c['unreachable']} unreachable")
    emit(summary, args.json, human)
    return 0
