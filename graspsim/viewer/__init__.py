"""Interactive 3D viewer in the browser (viser): maps, clouds, meshes, trial replays, scenes.

    import graspsim.viewer
    server = graspsim.viewer.show("cyl.h5")            # or a GraspabilityMap
    print(server.get_port())                           # open http://localhost:PORT
    ...
    graspsim.viewer.stop(server)
    server = graspsim.viewer.show_scene("pile.json")   # a table-top scene, seen and planned
    server = graspsim.viewer.show_plan(plan_scene(cloud, ...), cloud)   # a scene cloud you planned

viser is an optional dependency (``pip install 'graspsim[viewer]'``); without it
:func:`show` raises :class:`~graspsim.errors.DependencyNotInstalled` saying so, and the
rest of graspsim is unaffected (nothing here is imported by ``import graspsim``).

May use: the base modules, geometry, primitives, grippers, grades, maps, plots,
perception, planning, sim and tabletop (never calibration, the envs, the apps or the CLI).
"""

from __future__ import annotations

import os
from pathlib import Path

from graspsim.errors import DependencyNotInstalled

__all__ = ["show", "show_scene", "show_plan", "stop", "require_viser", "INSTALL_HINT"]

INSTALL_HINT = "pip install 'graspsim[viewer]'"


def require_viser(*, load: bool = True):
    """The viser module (``load=False``: only check it is installed, without the
    import), or :class:`DependencyNotInstalled` naming what to install."""
    import importlib.util

    try:
        found = importlib.util.find_spec("viser") is not None
    except (ImportError, ValueError):  # e.g. sys.modules["viser"] is None
        found = False
    if not found:
        raise DependencyNotInstalled(f"the viewer needs viser, which is not installed: {INSTALL_HINT}")
    if not load:
        return None
    try:
        import viser
    except ImportError as err:
        raise DependencyNotInstalled(f"the viewer needs viser, which cannot be imported ({err}): "
                                     f"{INSTALL_HINT}") from err
    return viser


def _preload() -> None:
    """Import what the scene needs (viser, trimesh for the primitives' meshes) while
    the map is read: the two overlap, which shortens opening a large map."""
    import contextlib

    with contextlib.suppress(Exception):  # a real failure is reported by the import itself
        import trimesh  # noqa: F401
        import viser  # noqa: F401

        import graspsim.viewer.app  # noqa: F401


def show(map, cloud=None, mesh=None, *, recording=None, host: str = "127.0.0.1", port: int = 8080,
         max_drawn: int = 2000, min_grade: float = 0.0, colour: str = "grade", top_k: int = 0,
         pick: int | None = None, verbose: bool = False):
    """Serve a map in the browser and return the running ``viser.ViserServer``
    (``server.get_port()``; :func:`stop` ends it). Does not block.

    map: a map file (its simulation and robust-score columns are shown too), a
    third-party grasp file (ACRONYM, GraspGen, GraspNet: its own labels shown) or a
    :class:`~graspsim.maps.GraspabilityMap`. cloud: (N, 3) points or a cloud file, in
    the cloud's frame; mesh: a ``trimesh.Trimesh`` or a mesh file, in the cloud's
    frame (both placed by the map's ``T_cloud_obj``). recording: a
    :class:`~graspsim.sim.recording.TrialRecording` or its file, replayed with a
    timeline. port: the first port tried (the next free one is taken; 0: any).
    max_drawn, min_grade, colour, top_k: the GUI's initial settings; pick: a map row
    whose numbers and full gripper are shown at start.
    """
    import threading

    require_viser(load=False)
    warm = threading.Thread(target=_preload, name="graspsim-viewer-preload", daemon=True)
    warm.start()
    from graspsim.maps.graspmap import GraspabilityMap
    from graspsim.viewer.columns import Selection, ViewData

    if isinstance(map, GraspabilityMap):
        data = ViewData.from_map(map)
    else:
        from graspsim.maps.formats import is_foreign

        if is_foreign(map):  # a third-party grasp file: read, never written; its labels as columns
            data = ViewData.from_grasp_file(map)
        else:
            from graspsim.maps.io import load_map

            data = ViewData.from_map(load_map(map), map)
    warm.join()
    viser = require_viser()
    from graspsim.viewer.app import MapViewer

    cloud, mesh, recording = _read_inputs(cloud, mesh, recording)
    _check_min_grade(min_grade)
    sel = Selection(colour=colour, min_grade=min_grade, max_drawn=max_drawn, top_k=top_k)
    data.selected(sel)  # a bad colour name or limit fails before the server starts
    if pick is not None and not 0 <= pick < len(data.gmap):
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError(f"pick must be a row of the map (0..{len(data.gmap) - 1}), got {pick}")
    port = _check_host(host, port)
    server = _quietly(verbose, viser.ViserServer, host=host, port=port, verbose=verbose)
    try:
        server.gui.configure_theme(control_width="large", show_share_button=False)
        viewer = MapViewer(server, data, cloud=cloud, mesh=mesh, selection=sel)
        if pick is not None:
            viewer.g_row.value = int(pick)
        if recording is not None:
            from graspsim.viewer.replay import Replay

            server.graspsim_replay = Replay(server, recording, hide=viewer)
    except BaseException:
        server.stop()
        raise
    server.graspsim_viewer = viewer  # the scene and GUI state (tests, scripts)
    return server


def show_scene(scene, *, db=None, look=None, seed: int = 0, config=None, top_k: int = 3,
               host: str = "127.0.0.1", port: int = 8080, verbose: bool = False):
    """Serve a table-top scene as the robot's depth camera saw and planned it, and
    return the running ``viser.ViserServer`` (:mod:`graspsim.viewer.scene_view`: the
    cloud coloured by segment, the table plane, each object's top-K grasps and the chosen
    one). Does not block.

    scene: a :class:`~graspsim.tabletop.table_scene.TableScene` or its JSON file
    (``save_scene``); it is rendered and planned once, as the clutter-removal protocol's
    first look (:class:`~graspsim.tabletop.clutter.ClutterEpisode`, ``config`` a
    ``ClutterConfig``, draws from ``rng_for(seed)``) against the map database ``db``
    (None: the default folder), unless ``look`` (a ``ClutterFrame`` of it) is given.
    top_k: grasps drawn per object at start."""
    require_viser(load=False)
    _check_top_k(top_k)
    if look is None:
        look, gripper = _scene_look(scene, db, seed, config)
    else:
        gripper = db.gripper if db is not None else _default_gripper()
    return show_plan(look.plan, look.view.world(), gripper=gripper, eye=look.frame.camera.T_world_camera[:3, 3],
                     best=look.best, top_k=top_k, host=host, port=port, verbose=verbose)


def show_plan(plan, cloud, *, gripper=None, eye=None, best=None, top_k: int = 3, host: str = "127.0.0.1",
              port: int = 8080, verbose: bool = False):
    """Serve a planned scene -- ``plan``, a :class:`~graspsim.planning.scene.ScenePlan`
    of the points ``cloud`` (N, 3) (e.g. ``plan_scene``'s of a user's own cloud, as
    ``graspsim plan-scene --view`` shows it) -- and return the running
    ``viser.ViserServer`` without blocking (:mod:`graspsim.viewer.scene_view`). gripper:
    the GripperSpec that planned it (default the Festo); eye (3,): where the camera was
    (None: unknown); best: the grasp shown as chosen (default the plan's best); top_k:
    grasps drawn per object at start."""
    require_viser(load=False)
    _check_top_k(top_k)
    viser = require_viser()
    from graspsim.viewer.scene_view import SceneViewer

    port = _check_host(host, port)
    server = _quietly(verbose, viser.ViserServer, host=host, port=port, verbose=verbose)
    try:
        server.gui.configure_theme(control_width="large", show_share_button=False)
        server.graspsim_viewer = SceneViewer(server, plan, cloud, gripper or _default_gripper(), eye=eye, best=best,
                                             top_k=top_k)
    except BaseException:
        server.stop()
        raise
    return server


def _check_top_k(top_k) -> None:
    from graspsim.errors import InvalidParameterError

    if isinstance(top_k, bool) or not isinstance(top_k, int) or top_k < 0:
        raise InvalidParameterError(f"top_k must be a whole number >= 0, got {top_k!r}")


def _default_gripper():
    from graspsim.grippers.spec import HGPL_25_60_A

    return HGPL_25_60_A


def _scene_look(scene, db, seed: int, config):
    """The first look of ``scene`` (a TableScene or its file): render and plan once."""
    from graspsim.maps.database import MapDatabase
    from graspsim.seeding import rng_for
    from graspsim.tabletop.clutter import ClutterEpisode
    from graspsim.tabletop.table_scene import load_scene

    if isinstance(scene, (str, os.PathLike)):
        scene = load_scene(scene)
    db = db if db is not None else MapDatabase()
    ep = ClutterEpisode(scene, db=db, rng=rng_for(seed), config=config)
    try:
        ep.observe()
    finally:
        ep.close()
    return ep.last, db.gripper


def stop(server) -> None:
    """Stop a server started by :func:`show` (and its replay's playback thread)."""
    replay = getattr(server, "graspsim_replay", None)
    if replay is not None:
        replay.stop()
    _quietly(False, server.stop)


def _read_inputs(cloud, mesh, recording):
    """Files among the cloud, mesh and recording read (their own clear errors), the
    rest passed through."""
    if isinstance(cloud, (str, os.PathLike)):
        from graspsim.perception.cloud_input import read_point_cloud

        cloud = read_point_cloud(cloud).points
    if isinstance(mesh, (str, os.PathLike)):
        from graspsim.sim.meshes import load_mesh

        mesh = load_mesh(Path(mesh))
    if isinstance(recording, (str, os.PathLike)):
        from graspsim.sim.recording import load_recording

        recording = load_recording(recording)
    return cloud, mesh, recording


def _check_host(host: str, port: int = 0) -> int:
    """The port to serve on: ``port`` if free on ``host``, else the next free one above it
    (0: any, chosen by the server). An address this machine cannot serve on, a port
    outside 0..65535 or no free port up to 65535 is an error now (viser would wait on it
    for ever: its server thread fails past 65535)."""
    import socket

    from graspsim.errors import InvalidParameterError

    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InvalidParameterError(f"port must be a whole number in 0..65535 (0: any free one), got {port!r}")
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
        with socket.socket(infos[0][0], socket.SOCK_STREAM) as sock:
            sock.bind(infos[0][4][:2])
    except OSError as err:
        raise InvalidParameterError(f"cannot serve on host {host!r}: {err.strerror or err} (use 127.0.0.1 for this "
                                    "machine, 0.0.0.0 for all its addresses)") from err
    if port == 0:
        return 0
    last = min(65535, port + 999)
    for p in range(port, last + 1):
        with socket.socket(infos[0][0], socket.SOCK_STREAM) as sock:
            try:
                sock.bind((infos[0][4][0], p))
            except OSError:
                continue
        return p
    raise InvalidParameterError(f"no free port on {host} from {port} to {last}; give another port (--port), "
                                "or 0 for any free one")


def _check_min_grade(min_grade) -> None:
    from graspsim.errors import InvalidParameterError

    if isinstance(min_grade, bool) or not isinstance(min_grade, (int, float)) or not 0 <= min_grade <= 1:
        raise InvalidParameterError(f"min_grade (--min-grade) must be a grade in [0, 1], got {min_grade!r}")


def _quietly(loud: bool, fn, *args, **kwargs):
    """Call ``fn`` with viser's banner lines ("HTTP ...", "Server stopped") kept off
    standard output unless ``loud``."""
    import contextlib
    import io

    if loud:
        return fn(*args, **kwargs)
    with contextlib.redirect_stdout(io.StringIO()):
        return fn(*args, **kwargs)
