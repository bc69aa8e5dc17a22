"""Subcommands for full-scale maps: ``map``, ``db``, ``show``, ``info``."""

from __future__ import annotations

import math
import time

from graspsim.cli._common import (
    add_db_flag,
    add_executor_flags,
    add_gripper_flag,
    add_json_flag,
    command,
    dims_text,
    emit,
    executor_from_args,
    format_table,
    gripper_from_args,
    progress,
    with_glossary,
)

__all__ = ["register"]

_DIM_HELP = {
    "x": "box edge along x [m]", "y": "box edge along y [m]", "z": "box edge along z [m]",
    "radius": "cylinder/sphere radius [m]", "height": "cylinder/cone height [m]",
    "bottom_radius": "cone base radius [m]", "top_radius": "cone top radius [m] (0: full cone)",
    "major_radius": "half-toroid ring radius [m]", "minor_radius": "half-toroid tube radius [m]",
}


def _add_dims(p) -> None:
    g = p.add_argument_group("dimensions (metres; the ones the primitive takes)")
    for name, text in _DIM_HELP.items():
        g.add_argument(f"--{name.replace('_', '-')}", dest=f"dim_{name}", type=float, metavar="M",
                       help=text)


def _shape_from_args(args):
    from graspsim.primitives import make_primitive

    dims = {k[4:]: v for k, v in vars(args).items() if k.startswith("dim_") and v is not None}
    return make_primitive(args.primitive, **dims)


def _add_generation(p) -> None:
    g = p.add_argument_group("generation")
    g.add_argument("--surface-step", type=float, default=0.005, help="contact spacing [m] (0.005)")
    g.add_argument("--rotation-step-deg", type=float, default=11.0, help="rotation step [deg] (11)")
    g.add_argument("--closing-cone-deg", type=float, default=22.0,
                   help="closing directions up to this angle from the inward normal [deg] (22)")
    g.add_argument("--depth-step", type=float, default=0.01, help="contact depths along the pad [m] (0.01)")
    g.add_argument("--tolerance", type=float, default=0.00025,
                   help="poses closer than this to touching count as colliding [m] (0.00025)")
    g.add_argument("--mu", type=float, default=0.5, help="friction coefficient of the grade (0.5)")
    g.add_argument("--threads", type=int, default=None, help="CPU threads (default: all cores)")
    add_gripper_flag(g)


def _config(args):
    from graspsim.errors import InvalidParameterError
    from graspsim.grades.paper import QualityModel
    from graspsim.maps.map_config import MapConfig

    if args.threads is not None and args.threads < 1:
        raise InvalidParameterError(f"--threads must be >= 1, got {args.threads}")
    cfg = MapConfig(surface_step=args.surface_step, rotation_step=math.radians(args.rotation_step_deg),
                    closing_cone=math.radians(args.closing_cone_deg), depth_step=args.depth_step,
                    collision_tolerance=args.tolerance)
    return cfg, QualityModel(friction=args.mu)


def _cmd_map(args) -> int:
    """Surface-to-voxel FS map of a shape primitive for a two-jaw gripper (default the
    Festo HGPL-25-60-A style; --gripper); writes an HDF5 map file."""
    from graspsim._atomic import atomic_paths, check_output
    from graspsim.errors import MapFileError
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.io import check_map_output, save_map
    from graspsim.maps.metrics import map_rates

    gripper = gripper_from_args(args)
    shape = _shape_from_args(args)
    cfg, quality = _config(args)
    out = check_map_output(args.output)  # before the work, not after it
    plot = fmt = None
    if args.plot:
        from graspsim.plots import image_format

        plot, fmt = check_output(args.plot, "plot", others={"map (-o)": out}), image_format(args.plot)
    t0 = time.perf_counter()
    with progress(100, f"map {shape.kind}", enabled=not args.json, unit="%") as bar:
        def report(frac: float) -> None:
            bar.n = int(100 * frac)
            bar.refresh()

        gmap = generate_fs_map(shape, gripper, quality, cfg, mass=args.mass,
                               threads=args.threads, progress=report)
    seconds = time.perf_counter() - t0
    rates = map_rates(gmap)
    with atomic_paths([out] + ([plot] if plot else []), MapFileError) as tmps:  # both or neither
        save_map(gmap, tmps[0])
        if plot:
            from graspsim.plots import plot_map

            plot_map(gmap, tmps[1], format=fmt)
    summary = {"file": str(out), "object": gmap.meta.object, "grasps": len(gmap),
               "accepted": int(gmap.accepted.sum()), "SR": rates.sr, "VR": rates.vr,
               "seconds": seconds, "timing": gmap.meta.timing, "plot": args.plot, "gripper": gripper.name}
    human = (f"{shape} ({gripper.name}): {len(gmap)} collision-free grasps, {summary['accepted']} with grade > "
             f"{gmap.threshold:g}; SR {rates.sr:.3f}, VR {rates.vr:.3f}; {seconds:.2f} s -> {out}"
             + (f" (plot: {plot})" if plot else ""))
    emit(summary, args.json, human)
    return 0


def _cmd_show(args) -> int:
    """Draw a map's grasp points (or wrist positions) as a 3-D scatter coloured by grade
    over a translucent mesh of the object, and save the image (PNG, PDF, SVG ... by the
    file's extension)."""
    from graspsim._atomic import check_output
    from graspsim.errors import InvalidParameterError
    from graspsim.maps.io import load_map
    from graspsim.plots import PLOT_POINTS, image_format, plot_map

    check_output(args.output, "image", others={"map": args.file})
    fmt = image_format(args.output)
    from graspsim.maps.imported import load_any

    gmap = load_any(args.file) if args.file.lower().endswith((".json", ".npy")) else load_map(args.file)
    shown = int(gmap.above(args.min_grade).sum())
    if not shown and len(gmap) and not (gmap.grade == gmap.grade).any():
        raise InvalidParameterError(f"nothing to plot: {args.file}'s {len(gmap)} grasps have no grades (a "
                                    "third-party grasp file); 'graspsim view' shows them by their own labels")
    if not shown:
        raise InvalidParameterError(f"nothing to plot: none of the map's {len(gmap)} grasps has "
                                    f"grade > {args.min_grade:g} (max {_max_grade(gmap)})")
    plot_map(gmap, args.output, what=args.what, min_grade=args.min_grade, format=fmt)
    drawn = min(shown, PLOT_POINTS)
    emit({"file": args.file, "image": args.output, "grasps": len(gmap), "plotted": shown, "drawn": drawn,
          "plotted_min_grade": args.min_grade}, args.json,
         f"wrote {args.output} ({shown} of {len(gmap)} grasps with grade > {args.min_grade:g}"
         + (f"; a uniform sample of {drawn} of them drawn" if drawn < shown else "") + ")")
    return 0


def _max_grade(gmap) -> str:
    return f"{float(gmap.grade.max()):.3f}" if len(gmap) else "no grasps"


def _describe_object(obj: dict) -> str:
    """One readable line for a map's object description (primitive, compound or mesh)."""
    mass = obj.get("mass")
    tail = f", mass {1000 * mass:.4g} g" if isinstance(mass, (int, float)) and math.isfinite(mass) else ""
    if obj.get("file"):
        return f"mesh {obj['file']} (scale {obj.get('scale', 1.0):g}){tail}"
    try:
        from graspsim.primitives import shape_from_dict

        return f"{shape_from_dict(obj)}{tail}"
    except Exception:  # noqa: BLE001 - e.g. an unidentified object: show what is recorded
        return ", ".join(f"{k} {v}" for k, v in obj.items() if k not in ("com", "mass")) + tail


def _settings_rows(meta) -> list[tuple[str, str]]:
    """The settings a map was made with, in words (quality model, resolution, gripper)."""
    q, r = meta.quality, meta.resolution
    grade = (f"{q.get('name', '?')}: friction mu {q.get('friction', '?')}, force-closure weight "
             f"{q.get('fc_weight', '?')}, stability at the {q.get('stability_mode', '?')}"
             + (f" (d_ref {100 * q['d_ref']:.2f} cm)" if isinstance(q.get("d_ref"), (int, float)) else ""))
    parts = []
    for key, label, unit, scale in (("surface_step", "surface step", "mm", 1000),
                                    ("rotation_step", "rotation step", "deg", 180 / math.pi),
                                    ("depth_step", "depth step", "mm", 1000),
                                    ("closing_cone", "closing cone", "deg", 180 / math.pi),
                                    ("collision_tolerance", "collision tolerance", "mm", 1000)):
        if isinstance(r.get(key), (int, float)):
            parts.append(f"{label} {r[key] * scale:.3g} {unit}")
    g = meta.gripper
    grip = g.get("name", "unknown") + (f" (stroke {1000 * g['stroke_per_jaw']:.3g} mm per jaw)"
                                       if isinstance(g.get("stroke_per_jaw"), (int, float)) else "")
    rows = [("grade", grade), ("resolution", ", ".join(parts) or "-"), ("gripper", grip)]
    if meta.timing.get("total") is not None:
        rows.append(("generated", f"{meta.timing['total']:.2f} s" + (f" by graspsim {meta.version}"
                                                                        if meta.version else "")))
    return rows


def _cmd_info(args) -> int:
    """Check a map file and print what it holds: the object, grasp counts, grades, SR /
    VR, the settings it was made with (grade, resolution, gripper), an adapted map's
    source and table, and which grasps were simulated."""
    from graspsim.maps.formats import is_foreign
    from graspsim.maps.io import load_map, read_sim_results
    from graspsim.maps.metrics import map_rates

    if is_foreign(args.file):
        from graspsim.cli.export_cmd import info_dataset

        return info_dataset(args, _describe_object)
    gmap = load_map(args.file)
    s = gmap.summary()
    if not s["graded"]:  # an imported third-party file's map: no grades, no contacts
        from graspsim.cli.export_cmd import info_imported

        return info_imported(args, gmap, s, _describe_object)
    rates = map_rates(gmap)
    sim = read_sim_results(args.file)
    s.update(file=args.file, SR=rates.sr, VR=rates.vr, quality=gmap.meta.quality,
             resolution=gmap.meta.resolution, timing=gmap.meta.timing, gripper=gmap.meta.gripper["name"],
             simulated=sorted(k for k in sim if k != "info"))
    rows = [("object", _describe_object(gmap.meta.object)), ("method", s["method"]),
            ("grasps", s["grasps"]), ("accepted", f"{s['accepted']} (grade > {s['threshold']:g})"),
            ("grade mean / max", "-" if s["grade_mean"] is None else
             f"{s['grade_mean']:.3f} / {s['grade_max']:.3f}"),
            ("parts", s["parts"]), ("SR / VR", f"{rates.sr:.3f} / {rates.vr:.3f}")]
    rows += _settings_rows(gmap.meta)
    extra, placement = gmap.meta.extra, gmap.meta.placement
    if placement is not None:  # an adapted map: where it came from and what it assumed
        s.update(source=extra.get("source"), T_cloud_obj=placement.T_cloud_obj.tolist(), table=placement.table)
        rows += [("source", extra.get("source")), ("status", extra.get("status"))]
        t = placement.table
        rows.append(("table", "none (the map ignores it)" if not t else
                     f"normal {t['normal']}, height {t['height']:.4f} m, {t.get('dropped', 0)} poses dropped"))
    if gmap.has_reach:  # an arm's verdicts (graspsim reach)
        from graspsim.maps.graspmap import REACH_EXACT, REACH_FIRST_CUT, REACH_NONE

        r, rec = gmap.reachable, extra.get("reach", {})
        counts = {k: int((r == v).sum()) for k, v in (("exact", REACH_EXACT), ("first_cut", REACH_FIRST_CUT),
                                                      ("unreachable", REACH_NONE))}
        base = rec.get("base")
        s["reach"] = {"robot": rec.get("robot"), "robot_base": base, **counts}
        rows.append(("reachable", f"by {rec.get('robot')} at base "
                     + (" ".join(f"{v:g}" for v in base) if base else "(a pose)")
                     + f": {counts['exact']} planned, {counts['first_cut']} first cut only, "
                       f"{counts['unreachable']} unreachable"))
    if "simulated" in sim:
        rows.append(("simulated", f"{int(sim['simulated'].sum())} of {len(gmap)} grasps "
                                  "(grasps/qualities/mujoco)"))
    human = f"{args.file}\n" + format_table(rows, ["field", "value"])
    emit(s, args.json, human)
    return 0


def _cmd_db(args) -> int:
    from graspsim.maps.database import PAPER_SHAPES, MapDatabase, size_grid

    gripper = gripper_from_args(args)  # the maps of one gripper (its spec keys them)
    if args.db_command == "list":  # every stored map, whatever its settings
        db = MapDatabase(args.db, gripper=gripper, create=False)
        ents = db.entries(all_settings=True)
        rows = [(e["primitive"], dims_text(e["dims"]), e["grasps"], e.get("gripper", "?"), e.get("settings", "?")
                 + (" (default)" if e.get("settings") == db.settings_digest else ""), e["file"])
                for e in ents]
        emit({"root": str(db.root), "maps": ents, "default_settings": db.settings_digest}, args.json,
             format_table(rows, ["primitive", "dims", "grasps", "gripper", "settings", "file"])
             + f"\n{len(ents)} maps in {db.root}")
        return 0
    if args.db_command == "check":  # every stored map, whatever its settings
        return _db_check(MapDatabase(args.db, create=False), args)
    cfg, quality = _config(args)
    db = MapDatabase(args.db, gripper=gripper, quality=quality, config=cfg)
    if args.db_command == "build":
        from graspsim._atomic import check_folder

        check_folder(db.root, "database folder")
        kinds = args.primitives or list(PAPER_SHAPES)
        shapes = []
        for k in kinds:
            base = PAPER_SHAPES.get(k.replace("-", "_"))
            if base is None:
                from graspsim.errors import MapDatabaseError

                raise MapDatabaseError(f"unknown primitive {k!r}; valid: {sorted(PAPER_SHAPES)}")
            shapes += size_grid(base, args.grid) if args.grid else [base]
        t0 = time.perf_counter()
        with progress(len(shapes), "FS database", enabled=not args.json, unit="map", tick=1.0) as bar, \
                executor_from_args(args) as ex:
            records = db.build(shapes, threads=args.threads, executor=ex,
                               progress=lambda i, n, s: bar.update(1))
        rows = [(e["primitive"], dims_text(e["dims"]), e["grasps"], e["accepted"], e["seconds"])
                for e in records]
        emit({"root": str(db.root), "maps": records, "seconds": time.perf_counter() - t0}, args.json,
             format_table(rows, ["primitive", "dims", "grasps", "accepted", "build s"]))
    else:  # lookup
        shape = _shape_from_args(args)
        m = db.lookup(shape.kind, shape.dims)
        match = m.match.value if m.entry is not None else None  # BUILD: no map of the kind
        emit({"primitive": shape.kind, "dims": shape.dims, "match": match,
              "nearest": m.entry, "max_diff": m.max_diff}, args.json,
             f"{shape}: {match or 'no map of this primitive'}"
             + (f" (nearest stored: {dims_text(m.entry['dims'])}, {m.max_diff * 100:.2f} cm off)"
                if m.entry else ""))
    return 0


def _db_check(db, args) -> int:
    from graspsim.maps.dbcheck import check_database

    rep = check_database(db, repair=args.repair)
    n = len(rep.problems)
    state = ("no problems" if not n else f"{_count(n, 'problem')}, "
             + ("all repaired" if rep.repaired else "NOT repaired (run with --repair)"))
    human = (format_table(rep.problems, ["file", "problem"]) + "\n" if rep.problems else "") + (
        f"{db.root}: {_count(rep.maps, 'map')} listed, {rep.valid} valid; {state}"
        + (f"; removed {_count(len(rep.removed), 'file')}, indexed {len(rep.reindexed)}" if rep.repaired else ""))
    emit(rep.to_dict(), args.json, human)
    return 0 if rep.ok else 1


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def register(sub) -> None:
    with command(sub, "map", run=_cmd_map, help="generate a full-scale graspability map of a primitive",
                 glossary=("FS map", "grade", "SR / VR")) as p:
        p.add_argument("primitive", help="box, cylinder, sphere, cone or half_toroid")
        _add_dims(p)
        p.add_argument("-o", "--output", required=True, help="map file to write (.h5)")
        p.add_argument("--mass", type=float, default=None, help="object mass [kg] (default: 500 kg/m^3)")
        p.add_argument("--plot", default=None, help="also save a PNG of the map")
        _add_generation(p)

    with command(sub, "show", run=_cmd_show, help="plot a map file as a 3-D scatter coloured by grade",
                 glossary=("grade",)) as p:
        p.add_argument("file", help="map file (.h5)")
        p.add_argument("-o", "--output", required=True, help="image to write (.png)")
        p.add_argument("--what", choices=["grasp_point", "wrist"], default="grasp_point",
                       help="plot grasp points (default) or wrist positions")
        p.add_argument("--min-grade", type=float, default=0.0, help="plot grasps above this grade")

    with command(sub, "info", run=_cmd_info, help="summarise a map file",
                 glossary=("grade", "SR / VR", "robust score")) as p:
        p.add_argument("file", help="map file (.h5)")

    p = sub.add_parser("db", help="the full-scale map database (build, list, lookup, check)",
                       description="The FS map database that adapt takes its maps from "
                       "($GRASPSIM_DB or ~/.cache/graspsim/db): build it, list it, or ask it "
                       "whether a primitive is known or familiar, or check it.")
    dbs = p.add_subparsers(dest="db_command", metavar="ACTION")
    dbs.required = True
    for name, text, desc in (
            ("build", "build the paper's five primitives (and a size grid)",
             "Generate and store FS maps of the paper's five reference primitives (or "
             "--primitives), optionally at several sizes (--grid); maps already stored with the "
             "same settings are kept."),
            ("list", "list stored maps",
             "List every map stored in the database folder with its gripper and settings digest; "
             "'(default)' marks the maps of the default generation settings (for --gripper)."),
            ("lookup", "known / familiar decision",
             "Say whether a primitive of the given dimensions is known (a stored map of the same "
             "size), familiar (same primitive, another size: its map is scaled) or absent, for "
             "the maps of the given generation settings."),
            ("check", "verify every stored map (exit 1 on problems; --repair fixes them)",
             "Verify every map the index lists (file present, readable, valid, record "
             "consistent), maps the index misses and stale temporary files; --repair removes "
             "invalid files and records and indexes valid unlisted maps. Exit status 1 on "
             "problems left unrepaired.")):
        q = dbs.add_parser(name, help=text, description=desc)
        with_glossary(q, *{"build": ("FS map", "grade"), "lookup": ("FS map", "known / familiar / build")}.get(
            name, ("FS map",)))
        add_db_flag(q, help="database folder (default $GRASPSIM_DB or ~/.cache/graspsim/db; --root, "
                    "its old name, still works)")
        if name not in ("list", "check"):
            _add_generation(q)
        elif name == "list":
            add_gripper_flag(q)
        add_json_flag(q)
        if name == "build":
            q.add_argument("--primitives", nargs="+", default=None, help="subset of the five")
            add_executor_flags(q)
            q.add_argument("--grid", type=float, nargs="+", default=None,
                           help="size scale factors, e.g. 0.5 0.75 1 1.5 2")
        if name == "lookup":
            q.add_argument("primitive")
            _add_dims(q)
        if name == "check":
            q.add_argument("--repair", action="store_true",
                           help="remove invalid maps and records, index valid unlisted maps, delete "
                           "stale temporary files")
        q.set_defaults(func=_cmd_db)
