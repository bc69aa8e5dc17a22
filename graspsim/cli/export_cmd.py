"""``graspsim export`` (a map in a third-party grasp format) and ``graspsim info`` of such files.

    graspsim export MAP.h5 --format acronym|graspgen|graspnet -o FILE [--label auto|mujoco|tug|source|grade]

The output loads with the format's own reader (ACRONYM's ``load_grasps``, GraspGen's JSON
loader, graspnetAPI's ``GraspGroup().from_npy``); see :mod:`graspsim.maps.export`.
"""

from __future__ import annotations

from graspsim.cli._common import command, emit, format_table

__all__ = ["register", "run", "info_dataset", "info_imported"]

_SUFFIX = {"acronym": ".h5", "graspgen": ".json", "graspnet": ".npy"}


def register(subparsers) -> None:
    with command(subparsers, "export", run=run,
                 help="write a map as an ACRONYM .h5, GraspGen .json or GraspNet .npy grasp file") as p:
        p.add_argument("map", metavar="MAP.h5", help="graspsim map file (or another format's grasp file: converted)")
        p.add_argument("--format", required=True, choices=tuple(_SUFFIX), help="the format to write")
        p.add_argument("-o", "--output", required=True, metavar="FILE",
                       help="output file (.h5 for acronym, .json for graspgen, .npy for graspnet)")
        p.add_argument("--label", default="auto", choices=("auto", "mujoco", "tug", "source", "grade"),
                       help="per-grasp label: auto (default): the MuJoCo lift-and-place outcome when the "
                            "map holds one, else an imported dataset's own labels, else grade > threshold")


def run(args) -> int:
    """Write a graspsim map in a third-party grasp format, the poses converted to the
    format's gripper frame and the labels named honestly (the file says which simulator
    produced them)."""
    import numpy as np

    from graspsim._atomic import check_output
    from graspsim.errors import InvalidParameterError
    from graspsim.maps.export import export_map, map_labels
    from graspsim.maps.io import load_map

    want = _SUFFIX[args.format]
    if not args.output.lower().endswith(want):
        raise InvalidParameterError(f"--format {args.format} writes a {want} file; got -o {args.output}")
    check_output(args.output, f"{args.format} grasp file", others={"map": args.map})
    from graspsim.maps.formats import is_foreign, read_grasp_file

    if is_foreign(args.map):  # another dataset file: converted, with its own labels
        gf = read_grasp_file(args.map)
        gmap, given = gf.gmap, (gf.labels.get("object_in_gripper", gf.labels.get("score")), gf.label_source)
        if given[0] is None or args.label not in ("auto", "source"):
            raise InvalidParameterError(f"{args.map} is a {gf.format} file: it can be exported with its own "
                                        "labels only (--label auto or source)")
    else:
        gmap, given = load_map(args.map), None
    files = export_map(gmap, args.format, args.output, map_path=args.map, label=args.label, labels=given)
    labels, source = given if given is not None else map_labels(gmap, args.map, args.label)
    labels = np.asarray(labels)
    summary = {"map": args.map, "format": args.format, "files": [str(f) for f in files],
               "grasps": len(gmap), "label_source": source,
               "labels": {"held": int((labels == 1).sum()), "not_held": int((labels == 0).sum()),
                          "unlabelled": int((labels < 0).sum())}}
    emit(summary, args.json, f"wrote {', '.join(map(str, files))}: {len(gmap)} grasps, labels from {source}")
    return 0


def _label_rows(labels: dict, source: str) -> list[tuple[str, str]]:
    """One row per per-grasp label: its mean over the grasps that have one."""
    import numpy as np

    rows = []
    for k, v in labels.items():
        v = np.asarray(v, float)
        if v.ndim != 1:
            continue
        known = v[v >= 0] if k in ("object_in_gripper", "outcome") else v[np.isfinite(v)]
        rows.append((f"label {k}", f"mean {known.mean():.3f} over {len(known)} grasps ({source})"
                     if len(known) else f"none ({source})"))
    return rows


def info_dataset(args, describe) -> int:
    """``graspsim info`` of a third-party grasp file (ACRONYM, GraspGen, GraspNet)."""
    from graspsim.maps.formats import read_grasp_file
    from graspsim.maps.imported import imported_path

    gf = read_grasp_file(args.file)
    m = gf.gmap.meta
    beside = imported_path(args.file)
    s = {"file": args.file, "format": gf.format, "grasps": len(gf.gmap), "gripper": m.gripper["name"],
         "object": m.object, "labels": sorted(gf.labels),
         "label_source": gf.label_source, "frame": m.extra["import"]["T_grasp_wrist"],
         "imported_map": str(beside) if beside.is_file() else None}
    rows = [("format", gf.format), ("object", describe(m.object)), ("grasps", len(gf.gmap)),
            ("gripper", m.gripper["name"]), ("grades", "none (a dataset file: its own labels below)")]
    rows += _label_rows(gf.labels, gf.label_source)
    rows.append(("simulated", f"see {beside}" if beside.is_file() else "not yet (graspsim trial FILE)"))
    emit(s, args.json, f"{args.file}\n" + format_table(rows, ["field", "value"]))
    return 0


def info_imported(args, gmap, s: dict, describe) -> int:
    """``graspsim info`` of a map imported from a third-party file: its labels and trials."""
    import numpy as np

    from graspsim.maps.imported import SOURCE_GROUP
    from graspsim.maps.io import read_sim_results

    rec = gmap.meta.extra.get("import", {})
    source = read_sim_results(args.file, SOURCE_GROUP)
    sim = read_sim_results(args.file)
    s.update(file=args.file, gripper=gmap.meta.gripper["name"], imported_from=rec.get("file"),
             format=rec.get("format"), label_source=rec.get("label_source"),
             simulated=sorted(k for k in sim if k != "info"))
    rows = [("object", describe(gmap.meta.object)), ("method", s["method"]),
            ("imported from", f"{rec.get('file')} ({rec.get('format')})"), ("grasps", s["grasps"]),
            ("grades", "none (imported)"), ("gripper", gmap.meta.gripper["name"])]
    rows += _label_rows({k: v for k, v in source.items() if k != "info"}, rec.get("label_source", ""))
    if "simulated" in sim:
        done = np.asarray(sim["simulated"], bool)
        held = np.asarray(sim["object_in_gripper"])[done]
        rows.append(("simulated", f"{int(done.sum())} of {len(gmap)} grasps, {int((held == 1).sum())} held "
                                  "(grasps/qualities/mujoco)"))
    emit(s, args.json, f"{args.file}\n" + format_table(rows, ["field", "value"]))
    return 0
