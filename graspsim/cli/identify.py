"""``graspsim identify CLOUD``: identify the shape primitives of an object point cloud.

The JSON summary (``--json``, last stdout line)::

    {"status": "identified" | "failed", "parts": [{"primitive", "dims", "pose",
     "match", "fit_rate", "points"}], "unidentified": [...], "seconds", ...}

``pose`` is ``T_world_obj`` (4x4, object frame of DESIGN.md §3), ``dims`` in metres,
``match`` is "known" / "familiar" / null from the FS map database given with ``--db``
(null without one).
"""

from __future__ import annotations

import argparse

from graspsim.cli._common import add_json_flag, emit, format_table
from graspsim.errors import DependencyNotInstalled

__all__ = ["register", "run"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "identify",
        help="identify shape primitives in a point cloud (.pcd, .ply, .npy, .xyz)",
        description=__doc__.split("\n\n")[0],
    )
    p.add_argument("cloud", help="point cloud file, coordinates in metres")
    p.add_argument("--repetitions", type=int, default=10,
                   help="MLESAC samples per model (default 10)")
    p.add_argument("--theta", type=float, default=0.5,
                   help="split threshold theta_th of eq. (1), in (0, 1] (default 0.5)")
    p.add_argument("--noise", type=float, default=None,
                   help="sensor noise sigma in metres (default: estimated)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--db", metavar="DIR", default=None,
                   help="FS map database folder for the known/familiar decision")
    add_json_flag(p)
    p.set_defaults(func=run)


def _lookup(db_dir: str | None):
    if db_dir is None:
        return lambda kind, dims: None
    try:
        from graspsim.maps.database import MapDatabase
    except ImportError as err:
        raise DependencyNotInstalled(
            "--db needs graspsim.maps.database (the FS map database), which this "
            "installation does not have"
        ) from err
    db = MapDatabase(db_dir)

    def lookup(kind: str, dims: dict) -> str | None:
        m = db.lookup(kind, dims).match
        return None if m is None else str(getattr(m, "value", m))

    return lookup


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from graspsim.perception.identify import IdentifyConfig, identify
    from graspsim.perception.io import read_point_cloud

    cloud = read_point_cloud(args.cloud)
    config = IdentifyConfig(repetitions=args.repetitions, theta=args.theta, noise=args.noise)
    lookup = _lookup(args.db)
    res = identify(cloud.points, rng=np.random.default_rng(args.seed), config=config)
    parts = []
    for p in res.parts:
        parts.append({"primitive": p.shape.value, "dims": p.dims, "pose": p.T_world_obj,
                      "match": lookup(p.shape.value, p.dims), "fit_rate": p.fit_rate,
                      "points": p.n_points})
    summary = {
        "status": res.status.value,
        "parts": parts,
        "unidentified": [{"points": p.n_points, "fit_rate": p.fit_rate, "pose": p.T_world_obj,
                          "reason": p.reason}
                         for p in res.unidentified],
        "seconds": res.seconds,
        "points": cloud.n_read,
        "dropped_nonfinite": cloud.n_dropped,
        "outliers_removed": res.n_removed,
        "noise": res.noise,
        "repetitions": args.repetitions,
        "theta": args.theta,
        "seed": args.seed,
    }
    rows = [[i, p["primitive"], ", ".join(f"{k}={v * 100:.2f} cm" for k, v in p["dims"].items()),
             f"{p['fit_rate']:.3f}", p["points"], p["match"] or "-"] for i, p in enumerate(parts)]
    rows += [[f"u{i}", "unidentified", "", f"{p.fit_rate:.3f}", p.n_points, "-"]
             for i, p in enumerate(res.unidentified)]
    human = (f"{args.cloud}: {res.status.value} in {res.seconds * 1000:.0f} ms "
             f"({cloud.n_read} points, {cloud.n_dropped} NaN/inf dropped, "
             f"{res.n_removed} outliers removed, noise {res.noise * 1000:.2f} mm)\n"
             + format_table(rows, ["part", "primitive", "dims", "fit rate", "points", "match"]))
    emit(summary, args.json, human)
    return 0
