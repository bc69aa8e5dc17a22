"""``graspsim adapt``: point cloud -> adapted graspability map (the run-time planner)."""

from __future__ import annotations

from pathlib import Path

from graspsim.cli._common import add_json_flag, emit, format_table
from graspsim.cli.maps import _add_generation, _config

__all__ = ["register"]


def _cmd_adapt(args) -> int:
    import numpy as np

    from graspsim.errors import MapFileError
    from graspsim.maps.database import MapDatabase
    from graspsim.maps.io import save_map
    from graspsim.maps.scaling import ScalingConfig
    from graspsim.perception import IdentifyConfig, read_point_cloud
    from graspsim.planner import PlannerConfig, plan

    out = Path(args.output)
    if not out.parent.is_dir():
        raise MapFileError(f"cannot write {out}: folder {out.parent} does not exist")
    cloud = read_point_cloud(args.cloud)
    cfg = PlannerConfig(identify=IdentifyConfig(repetitions=args.repetitions, theta=args.theta),
                        scaling=ScalingConfig(method=args.scaling), partial=not args.no_partial)
    map_cfg, quality = _config(args)
    db = MapDatabase(args.db, quality=quality, config=map_cfg)
    result = plan(cloud.points, db=db, rng=np.random.default_rng(args.seed), config=cfg,
                  source=str(Path(args.cloud).resolve()))
    save_map(result.map, out)
    s = result.summary()
    s.update(file=str(out), cloud=args.cloud, points=len(cloud.points), dropped=cloud.n_dropped,
             timing=result.timing)
    rows = [(p["primitive"], {k: round(v, 4) for k, v in p["dims"].items()}, p["match"]) for p in s["parts"]]
    first = s["time_to_first_0.95"]
    human = (format_table(rows, ["part", "dims [m]", "match"]) +
             f"\n{s['status']}: {s['grasps']} grasps, {s['accepted']} > 0.7 in {s['seconds']:.3f} s"
             + (f"; first grasp > 0.95 after {first * 1e3:.1f} ms" if first is not None else "")
             + f" -> {out}")
    emit(s, args.json, human)
    return 0 if result.status.value != "failed" else 1


def register(sub) -> None:
    p = sub.add_parser(
        "adapt", help="adapted graspability map of an object's point cloud",
        description="Identify the cloud's shape primitives, take their FS maps from the "
        "database (built on first use), scale familiar ones, combine several parts, and "
        "write the adapted map (object frame; object/T_cloud_obj maps it to the cloud's "
        "frame). Exit status 1 when identification fails completely.")
    p.add_argument("cloud", help="point cloud file: .pcd, .ply, .npy (N x 3), .xyz/.txt [m]")
    p.add_argument("-o", "--output", required=True, help="map file to write (.h5)")
    p.add_argument("--scaling", choices=["combined", "quality", "feasibility"], default="combined",
                   help="map scaling for familiar objects (combined)")
    p.add_argument("--db", default=None, help="FS map database folder (default $GRASPSIM_DB or "
                   "~/.cache/graspsim/db)")
    p.add_argument("--repetitions", type=int, default=10, help="MLESAC repetitions (10)")
    p.add_argument("--theta", type=float, default=0.5, help="split threshold theta_th (0.5)")
    p.add_argument("--seed", type=int, default=0, help="random seed (0)")
    p.add_argument("--no-partial", action="store_true",
                   help="no map at all when clustering fails (default: map of identified parts)")
    _add_generation(p)
    add_json_flag(p)
    p.set_defaults(func=_cmd_adapt)
