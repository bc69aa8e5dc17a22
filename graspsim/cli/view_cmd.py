"""``graspsim view``: the interactive 3D viewer in the browser (viser).

    graspsim view MAP.h5 [--cloud CLOUD] [--mesh MESH [--mesh-scale S]] [--replay TRIALS.npz]
                  [--port P] [--host H] [--max-drawn N] [--screenshot PNG]
    graspsim view --scene SCENE.json [--db DIR] [--seed S] [--top K] [generation flags]

Prints the URL and serves until Ctrl-C (then stops the server and exits 0). A map
file the viewer cannot read is refused with the same error as ``graspsim info``;
without viser the command says how to install it. ``--screenshot`` opens the page in
headless Chromium, saves what it draws and exits (no serving). ``--scene`` shows a
table-top scene (a file of ``graspsim scene --save-scenes DIR``) as the depth camera saw it
and the planner planned it (:mod:`graspsim.viewer.scene_view`): the cloud coloured by
segment, the table, each object's top K grasps and the chosen one.
"""

from __future__ import annotations

import sys
import time

from graspsim.cli._common import command, emit, seed_value
from graspsim.cli.maps_cmd import _add_generation

__all__ = ["register", "run"]


def register(subparsers) -> None:
    with command(subparsers, "view", run=run,
                 help="interactive 3D viewer of a map (and cloud, mesh, trial replay) in the browser") as p:
        p.add_argument("map", metavar="MAP.h5", nargs="?", help="graspability map file, or an ACRONYM .h5 / "
                       "GraspGen .json / GraspNet .npy grasp file (its labels as colour columns) (or --scene)")
        p.add_argument("--scene", metavar="SCENE.json", help="show a table-top scene instead: rendered, "
                       "segmented and planned once (its top K grasps per object, default 3)")
        p.add_argument("--db", default=None, help="with --scene: the FS map database folder (default $GRASPSIM_DB or "
                       "~/.cache/graspsim/db)")
        p.add_argument("--seed", type=seed_value, default=0, help="with --scene: random seed of the render's noise "
                       "and the planning (0)")
        p.add_argument("--cloud", metavar="CLOUD", help="the observed cloud (.pcd/.ply/.npy/.xyz), cloud frame")
        p.add_argument("--mesh", metavar="MESH", help="the true mesh (.obj/.stl/.ply ...), cloud frame")
        p.add_argument("--mesh-scale", type=float, default=1.0, metavar="S",
                       help="multiplies the mesh file's coordinates to give metres (0.001 for millimetres; default 1)")
        p.add_argument("--replay", metavar="TRIALS.npz",
                       help="trials recorded by 'graspsim trial MAP --record TRIALS.npz', on a timeline")
        p.add_argument("--host", default="127.0.0.1",
                       help="address to serve on (default 127.0.0.1: this machine only; 0.0.0.0: all)")
        p.add_argument("--port", type=int, default=8080, help="first port tried (default 8080; the next free "
                       "one is taken)")
        p.add_argument("--colour", default="grade", help="initial colour column (default grade)")
        p.add_argument("--min-grade", type=float, default=0.0, help="initial min-grade filter (default 0)")
        p.add_argument("--top", type=int, default=0, metavar="K", help="initial top-K filter (default 0: all)")
        p.add_argument("--pick", type=int, metavar="ROW", help="show this grasp's numbers and full gripper at start")
        p.add_argument("--max-drawn", type=int, default=2000, metavar="N",
                       help="draw at most N grasps (default 2000; the filters use all)")
        p.add_argument("--screenshot", metavar="PNG",
                       help="save what headless Chromium draws to PNG and exit instead of serving")
        _add_generation(p)


def run(args) -> int:
    """Serve a map in the browser (viser): the object's primitives coloured by part, the
    table, the cloud and mesh when given, and the grasps as glyphs coloured by grade,
    robust score or simulated outcome, with filters; click a grasp for its numbers and
    the full gripper. Ctrl-C stops it. Needs the 'viewer' extra: pip install
    'graspsim[viewer]'."""
    t0 = time.perf_counter()
    from graspsim.errors import InvalidParameterError
    from graspsim.viewer import require_viser, show

    require_viser(load=False)  # before reading anything
    if not 0 <= args.port <= 65535:
        raise InvalidParameterError(f"--port must be in 0..65535, got {args.port}")
    if args.max_drawn < 1 or args.top < 0:
        raise InvalidParameterError(f"--max-drawn must be >= 1 and --top >= 0, got {args.max_drawn}, {args.top}")
    if (args.map is None) == (args.scene is None):
        raise InvalidParameterError("give a map file or --scene SCENE.json, one of them")
    mapped = [f for f, v in (("--cloud", args.cloud), ("--mesh", args.mesh), ("--replay", args.replay),
                              ("--pick", args.pick)) if v is not None]
    if args.scene is not None and mapped:
        raise InvalidParameterError(f"{', '.join(mapped)} belong to a map, not to --scene")
    if args.screenshot:
        from graspsim._atomic import check_output

        check_output(args.screenshot, "screenshot")
    mesh = args.mesh
    if mesh is not None:
        from graspsim.sim.meshes import load_mesh

        mesh = load_mesh(mesh, scale=args.mesh_scale)  # checked before the server starts
    _quiet_server_logs()
    if args.scene is not None:
        server, summary, banner = _show_scene(args)
    else:
        server = show(args.map, cloud=args.cloud, mesh=mesh, recording=args.replay, host=args.host,
                      port=args.port, max_drawn=args.max_drawn, min_grade=args.min_grade, colour=args.colour,
                      top_k=args.top, pick=args.pick)
        viewer = server.graspsim_viewer
        summary = {"file": args.map, "grasps": len(viewer.gmap), "drawn": len(viewer.rows),
                   "selected": len(viewer.selected_rows)}
        banner = f"{len(viewer.rows):,} of {len(viewer.gmap):,} grasps drawn"
    url = f"http://{'localhost' if args.host in ('0.0.0.0', '127.0.0.1') else args.host}:{server.get_port()}"
    viewer = server.graspsim_viewer
    summary = {**summary, "url": url, "ready_s": time.perf_counter() - t0}
    try:
        if args.screenshot:
            from graspsim.viewer.snapshot import browser_render, save_png

            browser: dict = {}
            save_png(browser_render(server, camera=viewer.camera, settle=0.5 if args.replay else 0.0,
                                    timings=browser), args.screenshot)
            summary.update(screenshot=args.screenshot, frame_s=time.perf_counter() - t0,
                           browser_connect_s=browser.get("connect_s"), browser_frame_s=browser.get("frame_s"))
        else:
            _serve(url, banner, args.json)
    finally:
        _stop_uninterrupted(server)
    emit(summary, args.json, f"wrote {args.screenshot}" if args.screenshot else "graspsim view: stopped")
    return 0


def _show_scene(args):
    """The scene viewer's server, its summary and banner."""
    from graspsim.cli._common import gripper_from_args
    from graspsim.cli.maps_cmd import _config
    from graspsim.maps.database import MapDatabase
    from graspsim.tabletop.table_scene import load_scene
    from graspsim.viewer import show_scene

    scene = load_scene(args.scene)  # a bad file fails before the database is touched
    map_cfg, quality = _config(args)
    db = MapDatabase(args.db, gripper=gripper_from_args(args), quality=quality, config=map_cfg)
    server = show_scene(scene, db=db, seed=args.seed, top_k=args.top or 3, host=args.host, port=args.port)
    v = server.graspsim_viewer
    best = v.best
    summary = {"scene": args.scene, "objects": len(scene.objects), "segments": v.per.n_segments,
               "grasps": len(v.plan.grasps), "drawn": len(v.drawn), "chosen": None if best is None else
               {"segment": best.segment, "score": best.score, "grade": best.grade}}
    return server, summary, f"{v.per.n_segments} segments, {len(v.drawn)} grasps drawn"


def _serve(url: str, banner: str, as_json: bool) -> None:
    """Print the URL (stdout, or stderr under --json) and serve until Ctrl-C."""
    try:
        if as_json:
            print(f"graspsim view: {url}", file=sys.stderr, flush=True)
        else:
            print(f"graspsim view: {url}  ({banner}; Ctrl-C stops)", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass


def _stop_uninterrupted(server) -> None:
    """Stop the server; a second Ctrl-C meanwhile does not cut the shutdown short."""
    import signal
    import threading

    from graspsim.viewer import stop

    if threading.current_thread() is not threading.main_thread():
        stop(server)
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        stop(server)
    finally:
        signal.signal(signal.SIGINT, old)


def _quiet_server_logs() -> None:
    """A browser closing a half-open connection is not an error worth a traceback."""
    import logging

    for name in ("websockets.server", "websockets"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
