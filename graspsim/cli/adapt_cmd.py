"""``graspsim adapt``: point cloud -> adapted graspability map (the run-time planner)."""

from __future__ import annotations

from pathlib import Path

from graspsim.cli._common import (
    add_object_cloud_flags,
    add_robot_flags,
    add_unseen_margin_flag,
    command,
    dims_text,
    emit,
    format_table,
    gripper_from_args,
    robot_base_from_args,
    stored_text,
    unseen_margin_value,
    viewpoint_from_args,
)
from graspsim.cli.maps_cmd import _add_generation, _config

__all__ = ["register"]


def _cmd_adapt(args) -> int:
    """Identify the cloud's shape primitives, take their FS maps from the database
    (built on first use), scale familiar ones, combine several parts, and write the
    adapted map (object frame; object/T_cloud_obj maps it to the cloud's frame). Exit
    status 1, and no map written (an existing file is left as it was), when nothing is
    identified or no grasp is found. With --robot, every grasp is judged for the arm
    at its base before the map is written (its reachable column; graspsim reach)."""
    import sys

    from graspsim.maps.database import MapDatabase
    from graspsim.maps.io import check_map_output, save_map
    from graspsim.perception import read_point_cloud
    from graspsim.perception.acceptance import FitQuality
    from graspsim.planning.adapt import adapt_cloud, adapt_config

    # every option and the output path before the cloud is read or anything computed
    out = check_map_output(args.output, others={"input cloud": args.cloud})
    gripper = gripper_from_args(args)
    base = robot_base_from_args(args)
    if base is None and args.reach_exact != 100:
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError("--reach-exact needs --robot panda")
    cfg = adapt_config(mode=args.mode, table=None if args.table is None else (
        "auto" if args.table == "auto" else _height(args.table)), table_normal=args.table_normal,
        table_clearance=args.table_clearance, repetitions=args.repetitions, theta=args.theta,
        scaling=args.scaling, partial=not args.no_partial, low_profile=_low_profile(args.low_profile),
        unseen_margin=unseen_margin_value(args, none=True), restarts=args.restarts)
    viewpoint = viewpoint_from_args(args)
    map_cfg, quality = _config(args)
    if args.db is not None and Path(args.db).exists() and not Path(args.db).is_dir():
        from graspsim.errors import MapDatabaseError

        raise MapDatabaseError(f"--db {args.db} is not a folder (the FS map database is a folder of maps)")
    cloud = read_point_cloud(args.cloud, units=args.units)
    if args.unseen_margin not in (None, 0.0) and viewpoint is None and cloud.viewpoint is None:
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError("--unseen-margin needs the camera's place: give --viewpoint X Y Z (or a cloud "
                                    "with its camera record)")
    db = MapDatabase(args.db, gripper=gripper, quality=quality, config=map_cfg)
    result = adapt_cloud(cloud, db=db, config=cfg, seed=args.seed, source=str(Path(args.cloud).resolve()),
                         viewpoint=viewpoint)
    # only a map with grasps is written: a failed run leaves an existing file as it was
    why = ("nothing was identified" if result.status.value == "failed"
           else "the identified parts have no collision-free grasp" if not len(result.map) else None)
    reach = None
    if why is None:
        gmap = result.map
        if base is not None:
            from graspsim.robots import mark_reach

            gmap = mark_reach(gmap, robot=args.robot, base=base, exact=args.reach_exact, map_dir=out.parent)
            reach = gmap.meta.extra["reach"]
        save_map(gmap, out)
    s = result.summary()
    vp = result.map.meta.extra.get("viewpoint")
    s.update(file=str(out) if why is None else None, cloud=args.cloud, points=len(cloud.points),
             units=cloud.units, dropped=cloud.n_dropped, timing=result.timing, viewpoint=vp, seed=args.seed,
             unseen_margin=result.map.meta.extra.get("robust", {}).get("unseen_margin", 0.0))
    if reach is not None:
        s["reach"] = {"robot": reach["robot"], "robot_base": reach["base"], **reach["counts"],
                      "exact_checked": reach["exact"]["rows"]}
    rows = [(p["primitive"], dims_text(p["dims"]), p["match"], stored_text(p)) for p in s["parts"]]
    first = s["time_to_first_0.95"]
    human = (format_table(rows, ["part", "dims", "match", "stored map (size ratio)"]) +
             f"\n{s['status']}: {s['grasps']} grasps, {s['accepted']} > 0.7 in {s['seconds']:.3f} s"
             + (f"; first grasp > 0.95 after {first * 1e3:.1f} ms" if first is not None else "")
             + (f"; identified {result.attempts} times (the earlier maps held no grasp > 0.7)"
                if result.attempts > 1 else "")
             + (f"; {s['table']['dropped']} grasps below the table (height "
                f"{s['table']['height']:.4f} m) dropped" if s.get("table") and "dropped" in s["table"] else "")
             + (f", {s['table']['lifted']} lifted clear of it (contacts nearer the fingertip)"
                if s.get("table") and s["table"].get("lifted") else "")
             + (f"; viewpoint {' '.join(f'{v:g}' for v in vp)}" if vp is not None
                else "; seen all round (no viewpoint)")
             + (f", unseen margin {s['unseen_margin'] * 1e3:g} mm" if s["unseen_margin"] > 0 else "")
             + (f" -> {out}" if why is None else "")
             + (f"\n{FitQuality.from_dict(s['fit']).text()}" if s.get("fit") else "")
             + (f"\nreachable by {reach['robot']}: {reach['counts']['exact']} of the {reach['exact']['rows']} best "
                f"planned, {reach['counts']['first_cut']} more pass the first cut, {reach['counts']['unreachable']} "
                "unreachable" if reach is not None else ""))
    emit(s, args.json, human)
    if why is not None:
        kept = f"{out} left as it was" if out.exists() else f"{out} not written"
        print(f"graspsim: adapt: no map written: {why} ({kept})", file=sys.stderr)
        return 1
    return 0


def _low_profile(text: str) -> float | str:
    from graspsim.errors import InvalidParameterError

    if text == "off":
        return "off"
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (v >= 0 and v < float("inf")):
        raise InvalidParameterError(f"--low-profile takes 'off' or a contact depth >= 0 m, got {text!r}")
    return v


def _height(text: str) -> float:
    from graspsim.errors import InvalidParameterError

    try:
        return float(text)
    except ValueError:
        raise InvalidParameterError(f"--table takes 'auto' or a height in metres, got {text!r}") from None


def register(sub) -> None:

    with command(sub, "adapt", run=_cmd_adapt, help="adapted graspability map of an object's point cloud",
                 glossary=("known / familiar / build", "FS map", "grade", "robust score")) as p:
        add_object_cloud_flags(p, "point cloud file: .pcd, .ply, .npy (N x 3), .xyz/.txt [m; see --units]")
        p.add_argument("-o", "--output", required=True, help="map file to write (.h5)")
        p.add_argument("--scaling", choices=["combined", "quality", "feasibility"], default="combined",
                       help="map scaling for familiar objects (combined)")
        p.add_argument("--db", default=None, help="FS map database folder (default $GRASPSIM_DB or "
                       "~/.cache/graspsim/db)")
        p.add_argument("--no-partial", action="store_true",
                       help="no map at all when clustering fails (default: map of the identified parts)")
        p.add_argument("--table", default=None, metavar="auto|HEIGHT",
                       help="drop grasps that would take the gripper below the table the object "
                       "stands on: 'auto' puts the table at the cloud's lowest point along "
                       "--table-normal (a single view's lowest visible point lies a few mm above the "
                       "real table: safe), a number is its height along the "
                       "normal [m] in the cloud's frame (default: no table, as the paper's maps)")
        p.add_argument("--table-normal", type=float, nargs=3, default=(0.0, 0.0, 1.0),
                       metavar=("NX", "NY", "NZ"), help="the table's upward normal in the cloud's frame (0 0 1)")
        p.add_argument("--table-clearance", type=float, default=0.002,
                       help="gripper clearance above the table [m] (0.002)")
        p.add_argument("--low-profile", default="0.001", metavar="DEPTH|off",
                       help="with --table: a grasp that would take the gripper under the table is lifted clear "
                       "of it along its approach, its contacts held nearer the fingertip, where they stay at "
                       "least DEPTH [m] from it (low objects lying on the table: a domino, a lid); 'off': "
                       "dropped (0.001; --mode paper never lifts)")
        add_unseen_margin_flag(p, help="with a viewpoint, robust mode: a grasp whose far finger comes within M [m] of "
                               "the fitted back, in space the camera did not see, scores less (by the distance's share "
                               "of M) and wider openings are tried for it (default and alone: the measured 0.02 m; 0: "
                               "none; paper mode: none unless given); needs the camera's place")
        add_robot_flags(p, robot_help="mark each grasp reachable or not for this arm at --robot-base (the map's "
                        "reachable column; its ranking then puts reachable grasps first; see graspsim reach)")
        from graspsim.cli._common import whole_number

        p.add_argument("--restarts", type=whole_number(0), default=None, metavar="N",
                       help="robust mode: when the map holds no accepted grasp, identify the cloud again, up to N "
                       "more times (identification is a randomised search; the same --seed gives the same "
                       "answer; default 2, at most 10; 0: once)")
        p.add_argument("--reach-exact", type=whole_number(0), default=100, metavar="N",
                       help="with --robot: how many of the best grasps get the exact reach check (100)")
        _add_generation(p)
