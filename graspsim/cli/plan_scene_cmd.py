"""``graspsim plan-scene``: grasps for every object of a table-top scene cloud of your own.

    graspsim plan-scene CLOUD -o GRASPS.json [--units m|cm|mm] [--viewpoint X Y Z] [--up NX NY NZ]
                        [--crop XMIN YMIN ZMIN XMAX YMAX ZMAX] [--min-gap M] [--labels LABELS.npy]
                        [--seed S] [--db DIR] [--gripper NAME|MODEL.xml|SPEC.json] [--view | --screenshot PNG] [--json]
    graspsim plan-scene DEPTH.png --camera d435 | --intrinsics FX FY CX CY [--depth-scale S] ...

The cloud a depth camera saw of a table with objects on it (``.pcd``, ``.ply``, ``.npy``,
``.xyz``; NaN rows for missing depth are dropped), or its depth image back-projected in the
camera's frame (:func:`~graspsim.perception.depth_image.read_depth_image`), is planned as ``graspsim scene`` plans
its simulated frames (:func:`~graspsim.planning.scene.plan_scene`): the table plane,
the objects segmented on it, each identified and given grasps scored against the whole
scene (its neighbours and the table). GRASPS.json holds the table, every segment (its
status, primitives, where it is) and the ranked grasps (wrist poses in the cloud's frame,
the jaw opening to approach with, the robust score). Exit status 1, and no file written
(an existing one is left as it was), when no grasp scores above 0.
"""

from __future__ import annotations

from graspsim.cli._common import (
    add_scene_planning_flags,
    command,
    emit,
    format_table,
    gripper_from_args,
    scene_planning_from_args,
)
from graspsim.cli.maps_cmd import _add_generation, _config

__all__ = ["register"]


def _cmd_plan_scene(args) -> int:
    """Fit the table of a scene cloud, segment the objects standing on it, identify each
    and plan grasps checked against the whole scene (neighbours and table), and write
    the table, the segments and the ranked grasps (poses in the cloud's frame) as JSON.
    Exit status 1, and nothing written (an existing file is left as it was), when no
    grasp scores above 0."""
    import sys
    from dataclasses import replace

    import numpy as np

    from graspsim.errors import InvalidParameterError
    from graspsim.maps.database import MapDatabase
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SceneConfig

    o = _options(args)  # every option and output path before the input is read or anything computed
    loaded = _depth_points(args, o["intrinsics"]) if o["depth"] else _cloud_points(args)
    pts, rows = loaded["points"], loaded["rows"]
    crop, viewpoint, up = o["crop"], o["viewpoint"], o["up"]
    if crop is not None:
        inside = np.all((pts >= crop[:3]) & (pts <= crop[3:]), axis=1)
        pts, rows = pts[inside], rows[inside]
    if viewpoint is None and loaded["viewpoint"] is not None:
        from graspsim.maps.occlusion import check_viewpoint

        viewpoint = check_viewpoint(loaded["viewpoint"])  # a file's camera record: checked as --viewpoint is
    if up is None and viewpoint is not None:  # the camera sees the table from above it
        up = viewpoint - np.median(pts, axis=0) if len(pts) else None
    if args.unseen_margin not in (None, 0.0) and viewpoint is None:
        raise InvalidParameterError("--unseen-margin needs the camera's place: give --viewpoint X Y Z (or a cloud "
                                    "with its camera record)")
    cfg = scene_planning_from_args(args, replace(SceneConfig(), min_gap=args.min_gap or None,
                                                 up=None if up is None else tuple(map(float, up))))
    cfg = _pose_error(args, cfg)
    db = MapDatabase(args.db, gripper=o["gripper"], quality=o["quality"], config=o["map_cfg"])
    plan = plan_scene(pts, db=db, rng=np.random.default_rng(args.seed), config=cfg, viewpoint=viewpoint)

    record = _record(args, plan, loaded, pts, viewpoint, cfg, crop, db.gripper.name)
    out, labels_out, best = o["out"], o["labels"], plan.best
    if best is not None:
        _write(out, labels_out, record, lambda: _file_labels(loaded, rows, pts, plan.perception, cfg))
    s = {k: record[k] for k in ("cloud", "input", "points", "used", "viewpoint", "up", "min_gap", "seed", "gripper",
                                "table", "best", "timing")}
    s.update(segments=plan.summary()["segments"], grasps=len(plan.grasps), file=None if best is None else str(out),
             labels=None if best is None or labels_out is None else str(labels_out))
    if args.view or o["shot"] is not None:
        s.update(_show(plan, pts, db.gripper, viewpoint, args, o["shot"]))
    emit(s, args.json, _human(plan, record["segments"], out))
    if best is None:
        kept = f"{out} left as it was" if out.exists() else f"{out} not written"
        print(f"graspsim: plan-scene: no grasp written: no grasp scores above 0 ({kept})", file=sys.stderr)
        return 1
    return 0


def _options(args) -> dict:
    """The checked options: output paths (writable, none of them the input), the
    viewpoint, up and crop, the input's kind (a depth image with --intrinsics or
    --camera), the gripper and the map settings. Raises a one-line error."""
    from pathlib import Path

    import numpy as np

    from graspsim._atomic import check_output
    from graspsim.errors import InvalidParameterError, MapDatabaseError, OutputPathError
    from graspsim.maps.occlusion import check_viewpoint
    from graspsim.perception.segment import gap_link
    from graspsim.planning.scene_config import SceneConfig

    if args.view or args.screenshot:
        from graspsim.viewer import require_viser

        require_viser(load=False)
        if not 0 <= args.port <= 65535:
            raise InvalidParameterError(f"--port must be in 0..65535, got {args.port}")
    o = {"out": check_output(args.output, "grasps file", OutputPathError, others={"input cloud": args.cloud})}
    o["shot"] = None if args.screenshot is None else check_output(
        args.screenshot, "screenshot", OutputPathError, others={"input cloud": args.cloud, "grasps file": args.output})
    o["labels"] = None if args.labels is None else check_output(
        args.labels, "labels file", OutputPathError, others={"input cloud": args.cloud, "grasps file": args.output})
    if o["labels"] is not None and o["labels"].suffix.lower() != ".npy":
        raise InvalidParameterError(f"--labels writes a .npy file, got {o['labels'].name!r}")
    o["viewpoint"], o["up"], o["crop"] = (_finite(f, v) for f, v in (("--viewpoint", args.viewpoint),
                                                                      ("--up", args.up), ("--crop", args.crop)))
    try:
        check_viewpoint(o["viewpoint"])
    except InvalidParameterError as err:
        raise InvalidParameterError(f"--viewpoint: {err}") from None
    if o["up"] is not None and not np.linalg.norm(o["up"]) > 0:
        raise InvalidParameterError("--up must be a nonzero direction, got 0 0 0")
    if o["crop"] is not None and not np.all(o["crop"][:3] < o["crop"][3:]):
        raise InvalidParameterError("--crop takes XMIN YMIN ZMIN XMAX YMAX ZMAX with each minimum below its maximum")
    try:
        gap_link(args.min_gap or None)
    except InvalidParameterError:
        raise InvalidParameterError(f"--min-gap must be in (0, 0.1] m, or 0 for none, got {args.min_gap!r}") from None
    _pose_error(args, scene_planning_from_args(args, SceneConfig()))  # a bad --budget, --unseen-margin or
    # --pose-error: refused before the work
    if args.db is not None and Path(args.db).exists() and not Path(args.db).is_dir():
        raise MapDatabaseError(f"--db {args.db} is not a folder (the FS map database is a folder of maps)")
    o["depth"] = args.intrinsics is not None or args.camera is not None
    if o["depth"] and args.units != "m":
        raise InvalidParameterError("--units is for point clouds; a depth image's unit is --depth-scale")
    if not o["depth"] and args.depth_scale is not None:
        raise InvalidParameterError("--depth-scale is for depth images (given with --intrinsics or --camera)")
    o["intrinsics"] = _finite("--intrinsics", args.intrinsics)
    o["gripper"] = gripper_from_args(args)
    o["map_cfg"], o["quality"] = _config(args)
    return o


def _pose_error(args, scene):
    """``scene`` planned for ``--pose-error M DEG`` (the robot's accuracy:
    :func:`~graspsim.planning.scene_config.with_pose_error`); a bad value is refused naming the flag."""
    if args.pose_error is None:
        return scene
    from graspsim.errors import InvalidParameterError
    from graspsim.planning.scene_config import with_pose_error

    try:
        return with_pose_error(scene, *args.pose_error)
    except InvalidParameterError as err:
        raise InvalidParameterError(f"--pose-error: {err}") from None


def _record(args, plan, loaded, pts, viewpoint, cfg, crop, gripper: str) -> dict:
    """What the grasps file holds: the input, the settings, the table, every segment
    (where it is) and the ranked grasps."""
    from pathlib import Path

    from graspsim._version import __version__

    per = plan.perception
    segments = []
    for seg in plan.segments:
        p = per.segment_points(seg.segment)
        segments.append({**seg.to_dict(), "centroid": p.mean(axis=0), "lower": p.min(axis=0), "upper": p.max(axis=0)})
    best = plan.best
    return {"graspsim": __version__, "cloud": str(Path(args.cloud).resolve()), **loaded["source"],
            "points": int(loaded["n_read"]), "used": int(len(pts)), "viewpoint": viewpoint, "up": cfg.up,
            "crop": crop, "min_gap": cfg.min_gap, "budget": cfg.budget,
            "unseen_margin": cfg.planner.robust.unseen_margin if viewpoint is not None else 0.0,  # applied with a view
            "seen_between": cfg.planner.seen_between, "sparse_between": cfg.sparse_between,
            "shadow_depth": cfg.shadow_depth if viewpoint is not None and cfg.min_gap is None else 0.0,  # applied:
            # with a view, where objects may touch
            "feature_grasps": cfg.feature_grasps,
            "planned_for": {"position_sigma": cfg.planner.robust.position_sigma,
                            "rotation_sigma": cfg.planner.robust.rotation_sigma},
            "seed": args.seed, "gripper": gripper,
            "table": per.plane.to_dict(), "segments": segments, "grasps": [g.to_dict() for g in plan.grasps],
            "best": None if best is None else best.to_dict(), "timing": plan.timing}


def _write(out, labels_out, record: dict, labels) -> None:
    """The grasps file and, if asked, the labels (``labels()``): both or neither."""
    import json

    import numpy as np

    from graspsim._atomic import atomic_paths
    from graspsim._jsonable import to_jsonable
    from graspsim.errors import OutputPathError

    with atomic_paths([out] + ([] if labels_out is None else [labels_out]), OutputPathError) as tmps:
        tmps[0].write_text(json.dumps(to_jsonable(record), indent=1) + "\n")
        if labels_out is not None:
            with open(tmps[1], "wb") as f:
                np.save(f, labels())


def _file_labels(loaded: dict, rows, points, per, cfg):
    """Each input row's (or pixel's: (H, W)) segment; -1: table, cropped, no depth, noise."""
    import numpy as np

    labels = np.full(loaded["n_read"], -1, np.int64)
    labels[rows] = _every_point(points, per, cfg)
    return labels.reshape(loaded["shape"])


def _human(plan, segments: list, out) -> str:
    import numpy as np

    per, best = plan.perception, plan.best
    rows = [(d["segment"], d["points"], d["status"], "+".join(d["primitives"]) or "-",
             max((g.score for g in plan.grasps if g.segment == d["segment"]), default=0.0)) for d in segments]
    return (f"table: normal {np.round(per.plane.normal, 3).tolist()}, {per.plane.share * 100:.0f} % of the points\n"
            + format_table(rows, ["segment", "points", "status", "primitives", "best score"])
            + f"\n{len(segments)} objects, {len(plan.grasps)} grasps in {plan.timing['total']:.2f} s"
            + ("" if best is None else f"; best: segment {best.segment}, score {best.score:.2f} -> {out}"))


def _show(plan, points, gripper, viewpoint, args, shot) -> dict:
    """The planned scene in the viewer: a screenshot to ``shot`` (then stop), else
    served until Ctrl-C. Returns what to add to the summary."""
    import time

    from graspsim.cli.view_cmd import _quiet_server_logs, _serve, _stop_uninterrupted
    from graspsim.viewer import show_plan

    _quiet_server_logs()
    server = show_plan(plan, points, gripper=gripper, eye=viewpoint, top_k=3, port=args.port)
    url = f"http://localhost:{server.get_port()}"
    try:
        if shot is not None:
            from graspsim.viewer.snapshot import browser_render, save_png

            t = time.perf_counter()
            save_png(browser_render(server, camera=server.graspsim_viewer.camera), shot)
            return {"screenshot": str(shot), "screenshot_s": time.perf_counter() - t}
        _serve(url, f"{plan.perception.n_segments} segments, {len(plan.grasps)} grasps", args.json)
        return {"url": url}
    finally:
        _stop_uninterrupted(server)


def _cloud_points(args) -> dict:
    """The points of a cloud file, each one's file row, where it was seen from (its
    camera record, if any) and what was read."""
    import numpy as np

    from graspsim.perception import read_point_cloud
    from graspsim.planning.scene_config import MAX_SCENE_EXTENT

    cloud = read_point_cloud(args.cloud, units=args.units, min_points=100, max_extent=MAX_SCENE_EXTENT,
                             what="a table-top scene")
    rows = np.arange(cloud.n_read) if cloud.rows is None else cloud.rows
    return {"points": cloud.points, "rows": rows, "n_read": cloud.n_read, "shape": (cloud.n_read,),
            "viewpoint": cloud.viewpoint,
            "source": {"input": "point cloud", "units": cloud.units,
                       "frame": "the cloud's (file coordinates, metres)"}}


def _depth_points(args, intrinsics) -> dict:
    """The camera-frame points of a depth image's valid pixels (``--intrinsics`` or the
    ``--camera`` preset), each one's pixel (row-major index), the camera at the origin."""
    import numpy as np

    from graspsim.errors import InvalidParameterError
    from graspsim.geometry.camera import Camera, DepthFrame, Intrinsics, backproject
    from graspsim.perception.depth_image import read_depth_image

    if intrinsics is not None and args.camera is not None:
        raise InvalidParameterError("give --intrinsics or --camera, not both")
    depth, scale = read_depth_image(args.cloud, scale=args.depth_scale)
    h, w = depth.shape
    if args.camera is not None:
        k = Intrinsics.preset(args.camera)
        if (k.width, k.height) != (w, h):
            raise InvalidParameterError(f"the depth image is {w} x {h} pixels; the {args.camera} preset is "
                                        f"{k.width} x {k.height} (give its --intrinsics FX FY CX CY instead)")
    else:
        k = Intrinsics(w, h, *map(float, intrinsics))
    view = backproject(DepthFrame(depth, Camera(k, np.eye(4))))
    return {"points": view.points, "rows": view.uv[:, 1] * w + view.uv[:, 0], "n_read": h * w, "shape": (h, w),
            "viewpoint": np.zeros(3),
            "source": {"input": "depth image", "intrinsics": k.to_dict(), "depth_scale": scale,
                       "frame": "the camera's (OpenCV: x right, y down, z forward; metres)"}}


def _every_point(points, per, cfg):
    """Each point's segment (-1: none): the thinned points' own, and for a point thinning
    left out, above the table as they are, the segment of the thinned point nearest it
    within a voxel's diagonal."""
    import math

    import numpy as np
    from scipy.spatial import cKDTree

    labels = per.labels.copy()
    h = per.plane.heights(points)
    todo = np.flatnonzero((labels < 0) & (h > cfg.table_band) & (h < cfg.max_height))
    if len(todo) and len(per.points):
        d, j = cKDTree(per.points).query(points[todo], distance_upper_bound=math.sqrt(3) * cfg.voxel)
        near = np.isfinite(d)
        labels[todo[near]] = per.segment[j[near]]
    return labels


def _finite(flag: str, values):
    import numpy as np

    from graspsim.errors import InvalidParameterError

    if values is None:
        return None
    v = np.asarray(values, float)
    if not np.all(np.isfinite(v)):
        raise InvalidParameterError(f"{flag} takes finite numbers, got {' '.join(map(str, values))}")
    return v


def register(sub) -> None:
    from graspsim.cli._common import add_units_flag, seed_value

    with command(sub, "plan-scene", run=_cmd_plan_scene,
                 help="grasps for every object of a table-top scene cloud (a depth camera's view)",
                 glossary=("robust score", "grade", "known / familiar / build")) as p:
        p.add_argument("cloud", help="scene cloud file: .pcd, .ply, .npy (N x 3), .xyz/.txt [m; see --units]; "
                       "NaN rows (no depth) are dropped; or, with --intrinsics or --camera, a depth image: a "
                       "one-channel 16-bit .png/.tif or an (H, W) .npy")
        add_units_flag(p, widest="too wide for a table-top scene")
        p.add_argument("-o", "--output", required=True, help="grasps file to write (.json)")
        p.add_argument("--intrinsics", type=float, nargs=4, default=None, metavar=("FX", "FY", "CX", "CY"),
                       help="the input is a depth image from a camera with these pinhole intrinsics [px] (OpenCV "
                       "convention); the points are planned in the camera's frame")
        p.add_argument("--camera", default=None, metavar="NAME",
                       help="the input is a depth image from this camera preset (d435: 640 x 480, 87 deg)")
        p.add_argument("--depth-scale", type=float, default=None, metavar="S",
                       help="metres per depth image unit (default 0.001 for integer images: millimetres; 1 for "
                       "float arrays)")
        p.add_argument("--viewpoint", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                       help="where the camera was, in the cloud's frame [m] (0 0 0 for a cloud in the camera's "
                       "frame): the robust score then counts finger volume in the space behind what the camera saw, "
                       "and the table's up is towards it (default: the camera record beside the cloud, written by "
                       "graspsim's save_cloud, else unknown)")
        p.add_argument("--up", type=float, nargs=3, default=None, metavar=("NX", "NY", "NZ"),
                       help="the table's upward direction in the cloud's frame (default: towards the viewpoint, "
                       "else the side of the table with more points)")
        p.add_argument("--crop", type=float, nargs=6, default=None,
                       metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
                       help="keep only the points in this box of the cloud's frame [m] (e.g. the table and "
                       "what stands on it, without the floor or the walls)")
        p.add_argument("--min-gap", type=float, default=0.0, metavar="M",
                       help="least gap [m] between any two objects, if known (segments closer than 0.8 x it are "
                       "joined into one object; 0: unknown, default)")
        p.add_argument("--labels", default=None, metavar="LABELS.npy",
                       help="also write each file point's segment (-1: table, cropped, no depth or noise) as .npy")
        add_scene_planning_flags(p)
        p.add_argument("--pose-error", type=float, nargs=2, default=None, metavar=("M", "DEG"),
                       help="your robot's accuracy at the TCP: position and rotation sigmas [m] [deg]; the robust "
                       "score ranks grasps by how often they still hold under that error (default 0.003 2: a "
                       "typical arm with hand-eye calibration; RobustConfig.position_sigma / rotation_sigma)")
        p.add_argument("--seed", type=seed_value, default=0, help="random seed (0)")
        p.add_argument("--db", default=None, help="FS map database folder (default $GRASPSIM_DB or "
                       "~/.cache/graspsim/db; maps of new sizes are built on first use)")
        p.add_argument("--view", action="store_true",
                       help="then show the planned scene in the browser (the viewer extra: the points coloured by "
                       "segment, the table, each object's best grasps, the chosen one) until Ctrl-C")
        p.add_argument("--port", type=int, default=8080, help="with --view: first port tried (8080)")
        p.add_argument("--screenshot", default=None, metavar="PNG",
                       help="save what headless Chromium draws of the planned scene to PNG (instead of serving)")
        _add_generation(p)
