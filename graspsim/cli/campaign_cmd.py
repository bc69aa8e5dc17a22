"""``graspsim campaign``: resumable trial campaigns over many map files."""

from __future__ import annotations

import math

from graspsim.cli._common import add_executor_flags, command, emit, executor_from_args, format_table, progress

__all__ = ["register"]


def _cmd_run(args) -> int:
    """Every map x seed is one task, stored in OUT/tasks as soon as it finishes; running
    the same command again skips finished tasks."""
    import sys

    from graspsim._atomic import check_folder
    from graspsim.apps.campaign import campaign_tasks, run_campaign
    from graspsim.errors import InvalidParameterError

    for flag in ("top", "sample", "seeds"):
        n = getattr(args, flag)
        if n is not None and n < 1:
            raise InvalidParameterError(f"nothing to simulate: --{flag} {n} (give N >= 1)")
    check_folder(args.out, "campaign folder")  # before the work, not after it
    from graspsim.sim import ExecutionNoise

    noise = ExecutionNoise(args.noise_pos, math.radians(args.noise_rot_deg)) if args.noise else None
    tasks = campaign_tasks(args.maps, protocol=args.protocol, top=args.top, sample=args.sample,
                           min_grade=args.min_grade, noise=noise, seeds=range(args.seeds),
                           threads=args.threads)
    with progress(len(tasks), "campaign", enabled=not args.json, unit="task") as bar, \
            executor_from_args(args) as ex:
        res = run_campaign(tasks, args.out, executor=ex, max_tasks=args.max_tasks,
                           progress=lambda i, n: bar.update(1))
    s = res.summary()
    rows = [(k, v) for k, v in res.counts.items()]
    lo, hi = res.interval
    emit(s, args.json, format_table(rows, ["outcome", "trials"]) +
         f"\nsuccess {res.success_rate:.3f} (95 % {lo:.3f}-{hi:.3f}) over feasible trials; "
         f"{res.ran} tasks run, {res.skipped} already done -> {args.out}")
    if not sum(res.counts.values()) and res.records:
        print(f"graspsim: campaign: no trials: no map had a grasp matching the selection "
              f"({len(res.records)} tasks)", file=sys.stderr)
        return 1
    return 0


def _cmd_status(args) -> int:
    """Count the finished and missing tasks of a campaign folder."""
    from graspsim.apps.campaign import load_campaign

    tasks, done = load_campaign(args.out)
    emit({"out": args.out, "tasks": len(tasks), "done": len(done),
          "missing": [t.task_id for t in tasks if t.task_id not in done]}, args.json,
         f"{len(done)} of {len(tasks)} tasks done in {args.out}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("campaign", help="resumable trial campaigns over many maps (local or Ray)",
                       description="Simulate grasps of many map files as a resumable campaign: "
                       "'run' starts or resumes one in a folder, 'status' says how far it is.")
    cs = p.add_subparsers(dest="campaign_command", metavar="ACTION")
    cs.required = True
    with command(cs, "run", run=_cmd_run, help="simulate grasps of many maps; rerun to resume") as q:
        q.add_argument("maps", nargs="+", help="map files (.h5)")
        q.add_argument("--out", required=True, help="campaign folder")
        q.add_argument("--protocol", choices=["lift_place", "tug"], default="lift_place")
        sel = q.add_mutually_exclusive_group()
        sel.add_argument("--top", type=int, default=None, help="simulate the N best grasps of each map")
        sel.add_argument("--sample", type=int, default=None, help="N grasps spread over the surface")
        q.add_argument("--min-grade", type=float, default=None, help="sample among grasps above this grade")
        q.add_argument("--seeds", type=int, default=1, help="repeat each map with seeds 0..K-1 (1)")
        q.add_argument("--noise", action="store_true", help="execution noise (wrist pose error)")
        q.add_argument("--noise-pos", type=float, default=0.003, help="position sigma [m] (0.003)")
        q.add_argument("--noise-rot-deg", type=float, default=2.0, help="rotation sigma [deg] (2)")
        q.add_argument("--threads", type=int, default=1, help="threads inside each task (1)")
        q.add_argument("--max-tasks", type=int, default=None, help="stop after N new tasks")
        add_executor_flags(q)
    with command(cs, "status", run=_cmd_status, help="how far a campaign folder is") as q:
        q.add_argument("out", help="campaign folder")
