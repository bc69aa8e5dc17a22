"""Subcommands for other grippers: ``adapt-gripper`` (a map made for one gripper
adapted to another, paper section 5) and ``design`` (a design parameter swept over the
paper's primitives, :mod:`graspsim.apps.design`)."""

from __future__ import annotations

import math
import time

from graspsim.cli._common import (
    VARIANT_HELP,
    add_gripper_flag,
    command,
    emit,
    format_table,
    gripper_from_args,
    seed_value,
)

__all__ = ["register"]

def _cmd_adapt_gripper(args) -> int:
    """Carry a map's accepted grasps to another gripper by Combined scaling: each
    contact keeps its place on the object and along the pad (else the wrist keeps its
    place), grasps wider than the new opening are dropped, the rest re-checked for
    collision with the new gripper. The map records the new gripper and its source
    gripper."""
    from graspsim._atomic import atomic_path
    from graspsim.errors import MapFileError
    from graspsim.maps.io import check_map_output, load_map, save_map
    from graspsim.maps.regrip import adapt_to_gripper

    out = check_map_output(args.output, others={"map": args.file})  # before the work
    gmap = load_map(args.file)
    target = gripper_from_args(args, flag="to_gripper", base=gmap.meta.gripper_spec)
    t0 = time.perf_counter()
    adapted = adapt_to_gripper(gmap, target, source_min_grade=args.source_min_grade)
    seconds = time.perf_counter() - t0
    info = adapted.meta.gripper_adaptation.to_dict()
    if not len(adapted):  # an empty map is no result: an existing -o is left as it was
        from graspsim.errors import NoFeasibleGraspError

        kept = f"{out} left as it was" if out.exists() else f"{out} not written"
        raise NoFeasibleGraspError(
            f"no grasp of the {gmap.meta.gripper_spec.name} map carried to {target.name}: of its "
            f"{info['source_grasps']} grasps with grade > {info['source_min_grade']:g}, {info['fit_opening']} fit "
            f"the new gripper's opening and none of them is left collision-free with a grade above the map's "
            f"threshold; nothing written ({kept})")
    with atomic_path(out, MapFileError) as tmp:
        save_map(adapted, tmp)
    summary = {"file": str(out), "source": args.file, "source_gripper": gmap.meta.gripper_spec.name,
               "gripper": target.name, "grasps": len(adapted), "accepted": int(adapted.accepted.sum()),
               **info, "seconds": seconds}
    emit(summary, args.json,
         f"{len(adapted)} of {info['source_grasps']} grasps (grade > {info['source_min_grade']:g}) of the "
         f"{summary['source_gripper']} map carried to {target.name} ({info['fit_opening']} fit its opening; "
         f"{info['quality_pose']} at the same pad place, {info['feasibility_pose']} with the wrist kept) "
         f"in {seconds:.3f} s -> {out}")
    return 0


def _cmd_design(args) -> int:
    from graspsim._atomic import check_output
    from graspsim.apps.design import DesignConfig, param_value, sweep
    from graspsim.calibration.outputs import write_json
    from graspsim.errors import InvalidParameterError
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.database import PAPER_SHAPES, size_grid
    from graspsim.maps.map_config import MapConfig

    out = check_output(args.output, "results") if args.output else None
    plot = check_output(args.plot, "plot", others={"results (-o)": out} if out else None) if args.plot else None
    if plot is not None:
        from graspsim.plots import image_format

        image_format(plot)
    base = gripper_from_args(args, base=HGPL_25_60_A)
    bad = sorted(set(args.primitives) - set(PAPER_SHAPES))
    if bad or any(not s > 0 for s in args.sizes):
        raise InvalidParameterError(f"--primitives from {sorted(PAPER_SHAPES)} and --sizes > 0, got "
                                    f"{args.primitives} and {args.sizes}")
    objects = {f"{k}@{f:g}": s for k in args.primitives
               for f, s in zip(args.sizes, size_grid(PAPER_SHAPES[k], args.sizes))}
    cfg = DesignConfig(map_config=MapConfig(surface_step=args.surface_step,
                                            rotation_step=math.radians(args.rotation_step_deg)),
                       sim_grasps=args.sim_grasps, threads=args.threads, seed=args.seed)
    t0 = time.perf_counter()
    rows = sweep(base, args.param, args.values, objects, cfg)
    seconds = time.perf_counter() - t0
    summary = {"gripper": base.name, "param": args.param, "values": args.values, "objects": list(objects),
               "map_config": cfg.map_config.to_dict(), "sim_grasps": args.sim_grasps, "seed": args.seed,
               "seconds": seconds, "rows": rows}
    if out is not None:
        write_json(out, summary)
    if plot is not None:
        from graspsim.plots import plot_design

        plot_design(rows, plot, param=args.param, base_value=param_value(base, args.param))
    table = format_table(
        [[f"{1000 * r['value']:g}", r["object"], r.get("accepted", "-"), 100 * r.get("SR", math.nan),
          100 * r.get("VR", math.nan), 100 * r.get("share_accepted", math.nan),
          f"{r['sim']['success']}/{r['sim']['feasible']}" if "sim" in r else r.get("error", "")]
         for r in rows],
        [f"{args.param} [mm]", "object", "grasps > 0.7", "SR %", "VR %", "> 0.7 %", "lift-and-place"])
    emit(summary, args.json, f"{table}\n{len(rows)} designs x objects in {seconds:.1f} s"
         + (f" -> {out}" if out else "") + (f" (plot: {plot})" if plot else ""))
    return 0


#: graspsim.apps.design.PARAMS, spelt out here so that ``graspsim --help`` imports nothing heavy
#: (a test checks they agree)
PARAMS = {
    "finger_length": "the finger's length below the jaw",
    "pad_length": "the contact region from the fingertip",
    "stroke": "the stroke per jaw (the housing grows if it could not carry the jaws)",
}


def register(sub) -> None:
    with command(sub, "adapt-gripper", run=_cmd_adapt_gripper, help="adapt a map to another gripper (paper section 5)",
                 glossary=("grade",)) as p:
        p.add_argument("file", help="map file (.h5) of a primitive or compound")
        add_gripper_flag(p, VARIANT_HELP, flag="--to-gripper", required=True, variants=True)
        p.add_argument("-o", "--output", required=True, help="adapted map to write (.h5)")
        p.add_argument("--source-min-grade", type=float, default=None,
                       help="carry grasps above this grade (default: the map's threshold, 0.7)")

    with command(sub, "design", help="sweep a gripper design parameter over the paper's primitives",
                 description="FS maps of the paper's primitives (at --sizes) for each value of one "
                 "design parameter of --gripper: SR and VR of grasps > 0.7 (VR over one voxel box "
                 "for all values), the share of grasps > 0.7, and lift-and-place trials of "
                 "accepted grasps. " + "; ".join(f"{k}: {v}" for k, v in PARAMS.items()) + ".",
                 run=_cmd_design, glossary=("FS map", "SR / VR", "grade", "feasible")) as p:
        p.add_argument("--param", required=True, choices=sorted(PARAMS), help="the parameter to vary")
        p.add_argument("--values", required=True, type=float, nargs="+", metavar="M", help="its values [m]")
        add_gripper_flag(p, "the base design (default: festo_hgpl_25_60_a): " + VARIANT_HELP, variants=True)
        p.add_argument("--primitives", nargs="+", default=["box", "cylinder", "sphere", "cone", "half_toroid"],
                       help="which of the paper's primitives (default: all five)")
        p.add_argument("--sizes", type=float, nargs="+", default=[1.0], help="scale factors of their sizes (1)")
        p.add_argument("--sim-grasps", type=int, default=12, help="accepted grasps simulated per map (12; 0: none)")
        p.add_argument("--surface-step", type=float, default=0.0075, help="map surface step [m] (0.0075)")
        p.add_argument("--rotation-step-deg", type=float, default=16.5, help="map rotation step [deg] (16.5)")
        p.add_argument("--threads", type=int, default=None, help="map and simulation threads (default: all cores)")
        p.add_argument("--seed", type=seed_value, default=0, help="seed of the simulated draws (0)")
        p.add_argument("-o", "--output", default=None, help="write every number to this .json")
        p.add_argument("--plot", default=None, help="write the design plot (VR, SR, share, success) here")
