"""``graspsim identify CLOUD``: identify the shape primitives of an object point cloud.

The JSON summary (``--json``, last stdout line)::

    {"status": "identified" | "partial" | "failed", "mode": "robust" | "paper",
     "parts": [{"primitive", "dims", "pose", "match", "fit_rate", "points", "approximate",
     "band_rate"}], "unidentified": [...], "uncovered": [{"points", "reason"}],
     "fit": {"explained", "outside", "mean", "p95", "max", "points", "band"}, "seconds", ...}

``fit`` says how well the parts explain the whole cloud
(:class:`~graspsim.perception.acceptance.FitQuality`): the share of points within the
inlier band of some part, the share outside every part, and the residuals [m].

``pose`` is ``T_world_obj`` (4x4, object frame of docs/design.md §3), ``dims`` in metres,
``match`` is "known" / "familiar" / null from the FS map database given with ``--db``,
else the default one (``$GRASPSIM_DB`` or ``~/.cache/graspsim/db``, the database
``adapt`` uses) when it exists -- identify never builds one; ``database`` says which.
Exit status 1 (the summary still printed) when nothing is identified, as ``adapt``.
"""

from __future__ import annotations

import argparse

from graspsim.cli._common import (
    add_gripper_flag,
    add_object_cloud_flags,
    command,
    dims_text,
    emit,
    format_table,
    gripper_from_args,
    stored_text,
    viewpoint_from_args,
)
from graspsim.errors import DependencyNotInstalled

__all__ = ["register", "run"]

def register(subparsers) -> None:

    with command(subparsers, "identify", run=run,
                 help="identify shape primitives in a point cloud (.pcd, .ply, .npy, .xyz)",
                 glossary=("known / familiar / build", "FS map")) as p:
        add_object_cloud_flags(p, "point cloud file: .pcd, .ply, .npy (N x 3), .xyz/.txt [m; see --units]")
        p.add_argument("--noise", type=float, default=None,
                       help="sensor noise sigma in metres (default: estimated)")
        p.add_argument("--db", metavar="DIR", default=None,
                       help="FS map database folder for the known/familiar decision (default: "
                       "$GRASPSIM_DB or ~/.cache/graspsim/db when it exists; never built here)")
        add_gripper_flag(p, help="whose maps --db's known / familiar decision reads: festo_hgpl_25_60_a "
                         "(default), franka_hand or a gripper spec .json")


def _lookup(db_dir: str | None, gripper=None):
    """(kind, dims) -> "known" / "familiar" / None, and the database folder used (None:
    no database). Without ``db_dir`` the default database is used only if it exists."""
    try:
        from graspsim.maps.database import MapDatabase, default_root
    except ImportError as err:
        raise DependencyNotInstalled(
            "--db needs graspsim.maps.database (the FS map database), which this "
            "installation does not have"
        ) from err
    if db_dir is None:
        root = default_root()
        if not (root / "index.json").is_file():  # nothing to ask; do not create it
            return (lambda kind, dims: (None, None)), None
        db_dir = root
    db = MapDatabase(db_dir, **({} if gripper is None else {"gripper": gripper}))

    def lookup(kind: str, dims: dict) -> tuple[str | None, dict | None]:
        m = db.lookup(kind, dims)
        if m.entry is None:  # BUILD: no map of the kind
            return None, None
        return m.match.value, {"key": m.entry.get("key"), "ratio": m.ratio, "max_diff": m.max_diff}

    return lookup, str(db.root)


def run(args: argparse.Namespace) -> int:
    """Identify the shape primitives (box, cylinder, sphere, cone, half-toroid) of an
    object point cloud by MLESAC fitting and splitting (paper section 4). Prints each
    part's primitive, dimensions, fit rate and whether the map database knows it (known:
    a map of that size is stored; familiar: same primitive, another size). Coordinates
    in metres. Exit status 1 when nothing is identified."""
    import numpy as np

    from graspsim.perception.cloud_input import read_point_cloud
    from graspsim.perception.identify import IdentifyConfig, identify

    config = IdentifyConfig.preset(args.mode, repetitions=args.repetitions, theta=args.theta, noise=args.noise)
    cloud = read_point_cloud(args.cloud, units=args.units)
    viewpoint = viewpoint_from_args(args)
    viewpoint = cloud.viewpoint if viewpoint is None else viewpoint
    lookup, db_root = _lookup(args.db, gripper_from_args(args))
    res = identify(cloud.points, rng=np.random.default_rng(args.seed), config=config)
    fit = res.fit_quality(cloud.points, config.band, viewpoint)
    parts = []
    for p in res.parts:
        match, stored = lookup(p.shape.value, p.dims)
        parts.append({"primitive": p.shape.value, "dims": p.dims, "pose": p.T_world_obj,
                      "match": match, "stored": stored, "fit_rate": p.fit_rate,
                      "points": p.n_points, "approximate": p.approximate, "band_rate": p.band_rate})
    summary = {
        "status": res.status.value,
        "mode": res.mode,
        "parts": parts,
        "unidentified": [{"points": p.n_points, "fit_rate": p.fit_rate, "pose": p.T_world_obj,
                          "reason": p.reason}
                         for p in res.unidentified],
        "uncovered": res.uncovered,
        "fit": fit.to_dict(),
        "seconds": res.seconds,
        "points": cloud.n_read,
        "units": cloud.units,
        "downsampling": None if res.downsampling is None else res.downsampling.to_dict(),
        "dropped_nonfinite": cloud.n_dropped,
        "outliers_removed": res.n_removed,
        "noise": res.noise,
        "repetitions": args.repetitions,
        "theta": args.theta,
        "seed": args.seed,
        "database": db_root,
        "viewpoint": None if viewpoint is None else [float(v) for v in viewpoint],
    }
    rows = [[i, p["primitive"], dims_text(p["dims"]),
             f"{p['fit_rate']:.3f}", p["points"], p["match"] or "-", stored_text(p)] for i, p in enumerate(parts)]
    rows += [[f"u{i}", "unidentified", "", f"{p.fit_rate:.3f}", p.n_points, "-", "-"]
             for i, p in enumerate(res.unidentified)]
    d = res.downsampling
    human = (f"{args.cloud}: {res.status.value} ({res.mode} mode) in {res.seconds * 1000:.0f} ms "
             f"({cloud.n_read} points, {cloud.n_dropped} NaN/inf dropped, "
             + (f"{d.used_points} used ({d.voxel * 1000:.2g} mm voxels), " if d else "") +
             f"{res.n_removed} outliers removed, noise {res.noise * 1000:.2f} mm)\n"
             + format_table(rows, ["part", "primitive", "dims", "fit rate", "points", "match",
                                   "stored map (size ratio)"])
             + (f"\n{fit.text()}" if res.parts else "")
             + ("" if viewpoint is None else f"\nviewpoint {' '.join(f'{v:g}' for v in viewpoint)} (recorded; "
                "identification does not use it)")
             + ("" if db_root else "\n(match: no map database yet -- `graspsim db build` or the "
                                   "first `graspsim adapt` makes one)"))
    emit(summary, args.json, human)
    if res.status.value == "failed":  # an honest no-op, as ``adapt``'s: a nonzero exit
        import sys

        reasons = sorted({p.reason for p in res.unidentified if p.reason})
        why = "; ".join(reasons[:2]) + ("; ..." if len(reasons) > 2 else "")
        print(f"graspsim: identify: nothing was identified in {cloud.n_read} points"
              + (f" ({why})" if why else ""), file=sys.stderr)
        return 1
    return 0
