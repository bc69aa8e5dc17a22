"""The viewer (`graspsim view`, `graspsim.viewer.show`): its data model without viser,
the server as a script uses it, the command as a person uses it (errors, Ctrl-C) and a
screenshot taken by headless Chromium."""

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.grippers.wireframe import gripper_wireframe
from graspsim.maps import load_map, save_map, write_sim_results
from graspsim.primitives import Cylinder
from graspsim.viewer import show, stop
from graspsim.viewer.app import OBJECT_COLOUR
from graspsim.viewer.columns import OUTCOME_PREFIX, Selection, ViewData
from graspsim.viewer.glyphs import colormap

ROBUST = "grasps/qualities/robust"


def _map_file(tmp_path, n=60, outcomes=True, robust=False):
    """A cylinder map of n side grasps (grades spread over [0.3, 1]); outcomes: a
    simulation group with a known outcome per row; robust: a robust-score group."""
    ang = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    z = np.linspace(-0.06, 0.06, n)
    T = np.stack([grasp_pose([0, 0, zi], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for a, zi in zip(ang, z)])
    grades = np.random.default_rng(0).uniform(0.3, 1.0, n)
    path = save_map(hand_made_map(Cylinder(0.02, 0.20), T, np.full(n, 0.04), grades=grades),
                    tmp_path / "cyl.h5")
    if outcomes:
        out = np.arange(n) % 5 - 1  # -1 (not simulated), 0 success, 1 start collision, 2, 3
        codes = {"success": 0, "start_collision": 1, "no_contact": 2, "slipped": 3, "dropped": 4,
                 "place_failed": 5, "sim_unstable": 6}
        write_sim_results(path, {"outcome": out.astype(np.int8), "simulated": out >= 0,
                                 "lift_height": np.where(out == 0, 0.12, np.nan)},
                          attrs_json={"outcome_codes": codes})
    if robust:
        write_sim_results(path, {"score": np.linspace(0.0, 0.5, n)}, group=f"{ROBUST}")
    return path


# ---------------------------------------------------------------- data model (no viser)
def test_filters_run_on_all_grasps_and_top_k_is_the_best(tmp_path):
    path = _map_file(tmp_path)
    m = load_map(path)
    d = ViewData.from_map(m, path)
    assert d.colour_names()[:2] == ["grade", OUTCOME_PREFIX + "grasps/qualities/mujoco"]
    assert np.array_equal(d.selected(Selection(min_grade=0.6)), np.flatnonzero(m.grade > 0.6))
    top = d.selected(Selection(top_k=7))
    assert np.array_equal(top, np.argsort(-m.grade, kind="stable")[:7])
    colour = OUTCOME_PREFIX + "grasps/qualities/mujoco"
    ok = d.selected(Selection(colour=colour, outcome="success"))
    assert len(ok) == 12 and np.all(np.arange(60)[ok] % 5 == 1)
    assert len(d.selected(Selection(colour=colour, outcome="not simulated"))) == 12
    both = d.selected(Selection(colour=colour, outcome="success", min_grade=0.6))
    assert set(both) == set(ok) & set(np.flatnonzero(m.grade > 0.6))
    rgb, _ = d.colours(ok, colour)
    assert np.all(rgb == (40, 170, 70))  # success green
    assert d.details(int(ok[0]))["grasps/qualities/mujoco outcome"] == "success"


def test_drawn_subset_is_bounded_and_stable_when_filters_loosen(tmp_path):
    path = _map_file(tmp_path, n=400, outcomes=False)
    d = ViewData.from_map(load_map(path), path)
    loose = d.drawn(d.selected(Selection(min_grade=0.3)), 50)
    strict_rows = d.selected(Selection(min_grade=0.8))
    strict = d.drawn(strict_rows, 50)
    assert len(loose) == len(strict) == 50 and set(strict) <= set(strict_rows)
    # a grasp drawn under the loose filter and passing the strict one stays drawn
    assert set(loose) & set(strict_rows) <= set(strict)
    assert np.array_equal(d.drawn(strict_rows[:10], 50), strict_rows[:10])


def test_robust_scores_are_a_colour_column_when_present(tmp_path):
    path = _map_file(tmp_path, outcomes=False, robust=True)
    d = ViewData.from_map(load_map(path), path)
    assert d.colour_names()[1] == f"{ROBUST}/score"
    top = d.selected(Selection(colour=f"{ROBUST}/score", top_k=3))
    assert top.tolist() == [59, 58, 57]  # ranked by the robust score, not the grade
    rgb, rng = d.colours(np.array([0, 59]), f"{ROBUST}/score")
    assert rng == (0.0, 0.5) and rgb[0].tolist() == [68, 1, 84] and rgb[1].tolist() == [253, 231, 37]
    without = ViewData.from_map(load_map(_map_file(tmp_path / "..", outcomes=False)))
    assert not any("robust" in c for c in without.colour_names())


def test_an_arms_reach_verdicts_are_a_colour_column_when_present(tmp_path):
    from graspsim.maps import write_reach
    from graspsim.viewer.columns import REACH
    from graspsim.viewer.glyphs import NOT_SIMULATED_COLOUR, REACH_COLOURS

    path = _map_file(tmp_path, outcomes=False)
    assert REACH not in ViewData.from_map(load_map(path), path).colour_names()
    verdicts = np.tile(np.array([1.0, 0.5, 0.0, np.nan], np.float32), 15)
    write_reach(path, verdicts, {"robot": "panda"})
    d = ViewData.from_map(load_map(path), path)
    assert d.colour_names()[1] == REACH and not any("qualities/reach" in c for c in d.colour_names())
    rgb, _ = d.colours(np.arange(4), REACH)
    assert [tuple(c) for c in rgb] == [REACH_COLOURS["reachable"], REACH_COLOURS["first cut only"],
                                       REACH_COLOURS["unreachable"], NOT_SIMULATED_COLOUR]
    top = d.selected(Selection(colour=REACH, top_k=15))
    assert np.all(verdicts[top] == 1.0)  # top-K by the column: the reachable ones
    assert d.details(2)["reachable by panda"] == "unreachable" and d.details(3)["reachable by panda"] == "unchecked"


def test_gripper_wireframe_and_colour_scale():
    seg = gripper_wireframe(HGPL_25_60_A, np.eye(4), 0.05)
    assert seg.shape == (12 * len(HGPL_25_60_A.collision_boxes().names), 2, 3)
    x = seg[..., 0]
    # the finger boxes' inner faces (the pads) lie at +-opening/2
    assert np.isclose(np.abs(x).min(), 0.025) and np.any(np.isclose(x, 0.025)) and np.any(np.isclose(x, -0.025))
    assert np.isclose(seg[..., 2].max(), HGPL_25_60_A.fingertip_z)
    c = colormap(np.array([0.0, 1.0, np.nan]), 0.0, 1.0)
    assert c[0].tolist() == [68, 1, 84] and c[1].tolist() == [253, 231, 37] and c[2].tolist() == [205, 205, 215]


# ---------------------------------------------------------------- the server (needs viser)
needs_viser = pytest.mark.skipif(importlib.util.find_spec("viser") is None,
                                 reason="viser is not installed (pip install -e '.[viewer]')")


def _get(url: str, timeout: float = 120.0) -> int:
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status


@needs_viser
def test_show_serves_the_page_and_its_gui_filters_and_picks(tmp_path):
    path = _map_file(tmp_path, n=120)
    server = show(str(path), port=0, max_drawn=40)
    try:
        port = server.get_port()
        assert port > 0 and _get(f"http://127.0.0.1:{port}/") == 200
        v = server.graspsim_viewer
        g = load_map(path).grade
        assert len(v.selected_rows) == 120 and len(v.rows) == 40
        v.g_min.value = 0.8  # as if the slider moved: the callback refilters all grasps
        assert np.array_equal(v.selected_rows, np.flatnonzero(g > 0.8))
        assert len(v.rows) == min(40, int((g > 0.8).sum())) and "showing" in v.g_status.content
        v.g_top.value = 5
        assert np.array_equal(v.rows, np.argsort(-g)[:5])  # best first
        v.g_row.value = int(v.rows[0])  # a click sets the row; the gripper and numbers appear
        assert v.picked == int(v.rows[0]) and f"{g[v.picked]:.4g}" in v.g_details.content
    finally:
        stop(server)
    with pytest.raises(urllib.error.URLError):
        _get(f"http://127.0.0.1:{port}/", timeout=5)


@needs_viser
def test_the_served_page_colours_by_reach_with_its_legend(tmp_path):
    from graspsim.maps import write_reach
    from graspsim.viewer.glyphs import REACH_COLOURS

    path = _map_file(tmp_path, outcomes=False)
    write_reach(path, np.tile(np.array([1.0, 0.0], np.float32), 30), {"robot": "panda"})
    server = show(str(path), port=0, colour="reachable", top_k=10)
    try:
        v = server.graspsim_viewer
        assert "reachable" in v.g_colour.options and "red: unreachable" in v.g_scale.content
        assert np.all(v.rows % 2 == 0)  # top 10 by the column: the reachable (even) rows
        v.g_row.value = 1
        assert "unreachable" in v.g_details.content
    finally:
        stop(server)
    assert REACH_COLOURS["reachable"] != REACH_COLOURS["unreachable"]


@needs_viser
def test_a_click_picks_the_instance_or_the_grasp_nearest_the_ray_and_wireframes_are_bounded(tmp_path):
    from types import SimpleNamespace

    from graspsim.viewer.app import MAX_WIREFRAMES

    path = _map_file(tmp_path, n=400, outcomes=False)
    server = show(str(path), port=0, max_drawn=1000)
    try:
        v = server.graspsim_viewer
        v._on_click(SimpleNamespace(instance_index=7, ray_origin=(0, 0, 0), ray_direction=(1, 0, 0)))
        assert v.picked == int(v.rows[7])
        target = int(v.rows[123])
        p = v.gmap.grasp_point[target].astype(float)
        origin = p + np.array([0.3, 0.2, 0.1])  # a ray from the camera's side through the grasp point
        d = (p - origin) / np.linalg.norm(p - origin)
        v._on_click(SimpleNamespace(instance_index=None, ray_origin=tuple(origin), ray_direction=tuple(d)))
        assert v.picked == target
        v.g_glyph.value = "gripper wireframe"
        assert len(v.rows) == MAX_WIREFRAMES and len(v.selected_rows) == 400
    finally:
        stop(server)


@needs_viser
def test_an_adapted_map_shows_its_table_cloud_and_mesh_in_the_object_frame(tmp_path):
    import trimesh

    from graspsim.maps.graspmap import Placement
    from graspsim.transforms import make_transform

    T_cloud_obj = make_transform(np.eye(3), [0.1, 0.0, 0.3])  # the object seen 30 cm up, 10 cm aside
    extra = Placement(T_cloud_obj, {"normal": [0.0, 0.0, 1.0], "height": 0.2, "dropped": 0}).to_extra()
    T = grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])[None]
    path = save_map(hand_made_map(Cylinder(0.02, 0.20), T, [0.04], extra=extra), tmp_path / "adapted.h5")
    cloud = np.array([[0.1, 0.0, 0.3], [0.12, 0.0, 0.3]] * 6)  # cloud frame
    mesh = trimesh.creation.box((0.04, 0.04, 0.2))
    mesh.apply_translation([0.1, 0.0, 0.3])
    server = show(str(path), cloud=cloud, mesh=mesh, port=0)
    try:
        v = server.graspsim_viewer
        # the plane z = 0.2 in the cloud frame is z = -0.1 in the object frame, under the origin
        assert np.allclose(v.table.position, [0.0, 0.0, -0.1], atol=1e-9)
        assert np.allclose(v.cloud.points, cloud - [0.1, 0.0, 0.3], atol=1e-3)  # float16 on the wire
        assert np.allclose(v.mesh.vertices.mean(axis=0), 0.0, atol=1e-6)
    finally:
        stop(server)


@needs_viser
def test_a_mesh_object_is_drawn_from_its_file_beside_the_map(tmp_path):
    import trimesh

    box = trimesh.creation.box((0.04, 0.06, 0.1))
    box.export(tmp_path / "part.stl")
    T = grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])[None]
    m = hand_made_map(Cylinder(0.02, 0.20), T, [0.04])
    m = m.with_meta(object={"primitive": "mesh", "file": "part.stl", "scale": 1.0, "com": [0, 0, 0], "mass": 0.1})
    path = save_map(m, tmp_path / "mesh.h5")
    server = show(str(path), port=0)
    try:
        v = server.graspsim_viewer
        assert np.allclose(v.extent, 0.5 * np.linalg.norm([0.04, 0.06, 0.1]))  # the box's half diagonal
    finally:
        stop(server)


def _chromium_or_skip():
    from graspsim.viewer.snapshot import find_browser

    if find_browser() is None:
        pytest.skip("no Chromium on this machine (Debian: apt-get install chromium; .ci/run installs it)")


def _hue_share(img: np.ndarray, rgb, tol_deg: float = 12.0) -> float:
    """Fraction of saturated pixels whose hue is within ``tol_deg`` of ``rgb``'s (shading
    changes brightness, not hue)."""
    def hue(a):
        a = np.asarray(a, float).reshape(-1, 3)
        r, g, b = a.T
        return np.degrees(np.arctan2(np.sqrt(3) * (g - b), 2 * r - g - b)) % 360

    px = img.reshape(-1, 3).astype(float)
    sat = (px.max(axis=1) - px.min(axis=1)) / np.maximum(px.max(axis=1), 1)
    d = np.abs((hue(px) - hue(rgb)[0] + 180) % 360 - 180)
    return float(np.mean((sat > 0.35) & (d < tol_deg)))


@needs_viser
def test_screenshot_in_headless_chromium_shows_the_object(tmp_path):
    _chromium_or_skip()
    from graspsim.viewer.snapshot import browser_render

    path = _map_file(tmp_path, n=30)
    server = show(str(path), port=0, max_drawn=30, min_grade=0.9)
    try:
        img = browser_render(server, size=(300, 400), camera=server.graspsim_viewer.camera, timeout=120)
    finally:
        stop(server)
    assert img.shape == (300, 400, 3)
    assert img.std() > 10  # not blank
    assert _hue_share(img, OBJECT_COLOUR) > 0.02  # the object's colour is there
    assert np.mean(np.all(img > 245, axis=-1)) > 0.3  # and the background around it


_HELD_BROWSER = """
import viser
from graspsim.viewer.snapshot import browser_render
server = viser.ViserServer(port=0, verbose=False)
server.scene.add_box("b", dimensions=(0.1, 0.1, 0.1))
browser_render(server, size=(100, 100), timeout=120, settle=120)  # holds the browser open
"""


def _procs() -> list[tuple[int, int, int, str]]:
    """(pid, parent, session, state) of every process (Linux's /proc)."""
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                rest = f.read().rsplit(")", 1)[1].split()
            out.append((int(d), int(rest[1]), int(rest[3]), rest[0]))
        except (OSError, ValueError, IndexError):
            continue
    return out


@needs_viser
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the tie to the caller is Linux's (prctl)")
def test_the_browser_ends_with_a_caller_killed_by_sigkill():
    """A caller killed outright never reaches the finally that ends its browser, and the
    browser runs in its own session: the kernel ends it with the caller."""
    _chromium_or_skip()
    caller = subprocess.Popen([sys.executable, "-c", _HELD_BROWSER], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        browser = []
        while not browser and time.monotonic() < deadline and caller.poll() is None:
            time.sleep(0.2)
            browser = [p for p, parent, _, _ in _procs() if parent == caller.pid]
        assert browser, "the browser never started"
        session = browser[0]  # the browser leads its own session, helpers included
        while len([p for p, _, sid, _ in _procs() if sid == session]) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)  # let it start its helpers (a loaded machine's browser may still have none: then
            # the leader alone must end with the caller)
    finally:
        caller.kill()
        caller.wait(30)

    def alive():  # what is left of the browser's session (zombies have ended)
        return [p for p, _, sid, state in _procs() if sid == session and state != "Z"]
    deadline = time.monotonic() + 30
    while alive() and time.monotonic() < deadline:
        time.sleep(0.2)
    left = alive()
    if left:  # do not leave it spinning when the test fails
        os.killpg(session, signal.SIGKILL)
    assert not left
    import tempfile

    from graspsim.viewer.snapshot import _sweep_profiles

    profile = f"graspsim-chromium-{caller.pid}-*"
    assert list(Path(tempfile.gettempdir()).glob(profile))  # the killed caller could not remove it
    _sweep_profiles()  # the next snapshot's sweep does
    assert not list(Path(tempfile.gettempdir()).glob(profile))


def test_profile_folders_of_callers_that_no_longer_run_are_swept(tmp_path, monkeypatch):
    import tempfile

    from graspsim.viewer.snapshot import _sweep_profiles

    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = int(done.stdout)  # a process that has ended
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    names = [f"graspsim-chromium-{dead}-ab12", f"graspsim-chromium-{os.getpid()}-cd34", "graspsim-chromium-ef56",
             "something-else"]
    for n in names:
        (tmp_path / n).mkdir()
        (tmp_path / n / "Default").mkdir()
    _sweep_profiles()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names[1:])  # only the dead caller's went


# ---------------------------------------------------------------- the command
@needs_viser
def test_view_refuses_what_info_refuses(tmp_path, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5 at all")
    for argv in (["info", str(bad)], ["view", str(bad)], ["view", str(tmp_path / "missing.h5")]):
        assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == err[1] and "not a readable HDF5 map file" in err[0]
    assert "does not exist" in err[2] and not any("Traceback" in e for e in err)


@needs_viser
@pytest.mark.parametrize("args, words", [
    (["--host", "10.255.255.1"], "cannot serve on host"),
    (["--colour", "nope"], "unknown colour column 'nope'"),
    (["--replay", "MAP"], "not a graspsim trial recording"),
    (["--pick", "60"], "pick must be a row of the map"),
    (["--cloud", "missing.pcd"], "does not exist"),
])
def test_view_refuses_bad_options_in_one_line_before_serving(tmp_path, capsys, args, words):
    path = _map_file(tmp_path)
    args = [str(path) if a == "MAP" else a for a in args]
    assert main(["view", str(path), "--port", "0", *args]) == 2
    out, err = capsys.readouterr()
    assert len(err.strip().splitlines()) == 1 and words in err and "http" not in out


def test_view_without_viser_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser now fails
    assert main(["view", str(_map_file(tmp_path))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'graspsim[viewer]'" in err


@needs_viser
def test_ctrl_c_stops_the_server_and_leaves_no_process(tmp_path):
    path = _map_file(tmp_path)
    # PYTHONFAULTHANDLER: a server that does not stop is sent SIGABRT, and every thread's
    # stack is in the failure message
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), os.environ.get("PYTHONPATH", "")]),
           "PYTHONFAULTHANDLER": "1"}
    # SIGINT at its default in the child: a shell starts background jobs (a suite run with
    # `&`) with SIGINT ignored, a child inherits that, and Python then never raises
    # KeyboardInterrupt -- the cause of this test's earlier 300 s timeouts
    p = subprocess.Popen([sys.executable, "-m", "graspsim", "view", str(path), "--port", "0", "--json"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = p.stderr.readline()  # "graspsim view: http://localhost:PORT" once serving
        assert line.startswith("graspsim view: http://"), line + p.stderr.read()
        url = line.split()[-1]
        assert _get(url) == 200
        p.send_signal(signal.SIGINT)
        try:
            out, err = p.communicate(timeout=300)  # generous: a loaded CI machine
        except subprocess.TimeoutExpired:
            p.send_signal(signal.SIGABRT)
            pytest.fail("graspsim view did not stop 300 s after Ctrl-C; its threads:\n"
                        + p.communicate(timeout=60)[1])
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["url"] == url and summary["grasps"] == 60
    assert "Traceback" not in err
    with pytest.raises(urllib.error.URLError):
        _get(url, timeout=5)
    time.sleep(0)


@needs_viser
def test_replay_moves_the_recorded_gripper_and_object_on_its_timeline(tmp_path):
    from graspsim.sim.recording import load_recording
    from graspsim.transforms import make_transform, quat_to_matrix

    path = _map_file(tmp_path, outcomes=False)
    rec_path = tmp_path / "trials.npz"
    assert main(["trial", str(path), "--top", "2", "--threads", "1", "--record", str(rec_path)]) == 0
    rec = load_recording(rec_path)
    server = show(str(path), port=0, recording=rec_path)
    try:
        r, v = server.graspsim_replay, server.graspsim_viewer
        r.g_play.value = False
        assert not v.root.visible and r.root.visible  # replaying hides the map's glyphs
        r.g_trial.value = r.g_trial.options[1]
        lifted = int(np.argmax(rec.obj_pos[1, :, 2]))
        r.g_frame.value = lifted
        assert r.trial == 1 and np.allclose(r.obj.position, rec.obj_pos[1, lifted], atol=1e-6)
        # the replay's frame puts the object's first recorded pose on the map's object frame
        T_root = make_transform(quat_to_matrix(np.asarray(r.root.wxyz)), np.asarray(r.root.position))
        T0 = make_transform(quat_to_matrix(rec.obj_quat[1, 0].astype(float)), rec.obj_pos[1, 0])
        assert np.allclose(T_root @ T0, np.eye(4), atol=1e-5)
        assert f"{rec.time[lifted]:.2f} s" in r.g_time.content
        r.g_on.value = False
        assert v.root.visible and not r.root.visible
    finally:
        stop(server)
    assert not server.graspsim_replay._thread.is_alive()


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@needs_viser
@pytest.mark.slow
def test_clicking_a_glyph_in_chromium_picks_that_grasp(tmp_path):
    """A real mouse click (Chrome DevTools Protocol) on a glyph's bridge, at the pixel
    the viewer's camera projects it to, shows that grasp; a click on empty space none."""
    _chromium_or_skip()
    import tempfile

    from websockets.sync.client import connect

    from graspsim.transforms import quat_to_matrix
    from graspsim.viewer.snapshot import _end, camera_wxyz, find_browser

    a = np.array([-1.0, 1.0, 0.0]) / np.sqrt(2)  # approaching from the camera's side
    T = grasp_pose([0, 0, 0], a, [1 / np.sqrt(2), 1 / np.sqrt(2), 0])[None]
    path = save_map(hand_made_map(Cylinder(0.02, 0.20), T, [0.04]), tmp_path / "one.h5")
    server = show(str(path), port=0)
    v = server.graspsim_viewer
    v.g_size.value = 2.0
    position, look_at = (np.asarray(x, float) for x in v.camera)
    bridge = -0.02 * 2.0 * a  # the fork's bridge: prong length x glyph size back along the approach
    debug = _free_port()
    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.Popen(
            [find_browser(), "--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
             "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--window-size=1600,1100",
             f"--remote-debugging-port={debug}", f"http://127.0.0.1:{server.get_port()}/"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            deadline = time.monotonic() + 120
            while not server.get_clients() and time.monotonic() < deadline:
                time.sleep(0.1)
            client = next(iter(server.get_clients().values()))
            while not np.allclose(client.camera.position, position, atol=1e-3) and time.monotonic() < deadline:
                time.sleep(0.1)
            with urllib.request.urlopen(f"http://127.0.0.1:{debug}/json/list", timeout=30) as r:
                ws_url = next(p["webSocketDebuggerUrl"] for p in json.load(r) if p["type"] == "page")
            with connect(ws_url, max_size=None) as ws:
                calls = iter(range(1, 10_000))

                def cdp(method, **params):
                    i = next(calls)
                    ws.send(json.dumps({"id": i, "method": method, "params": params}))
                    while True:
                        m = json.loads(ws.recv(timeout=60))
                        if m.get("id") == i:
                            return m.get("result", {})

                def click(x, y):
                    for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
                        cdp("Input.dispatchMouseEvent", type=kind, x=float(x), y=float(y), button="left",
                            clickCount=1)

                size = cdp("Runtime.evaluate", expression="[innerWidth, innerHeight].join()", returnByValue=True)
                w, h = (int(x) for x in size["result"]["value"].split(","))
                p = quat_to_matrix(camera_wxyz(position, look_at)).T @ (bridge - position)  # camera frame
                f = 0.5 * h / np.tan(0.5 * client.camera.fov)
                u, y = 0.5 * w + f * p[0] / p[2], 0.5 * h + f * p[1] / p[2]
                click(0.1 * w, 0.9 * h)  # empty space
                time.sleep(1.0)
                assert v.picked is None
                while v.picked is None and time.monotonic() < deadline:  # until the glyph is drawn
                    click(u, y)
                    t = time.monotonic()
                    while v.picked is None and time.monotonic() < t + 3:
                        time.sleep(0.05)
        finally:
            _end(proc)
            stop(server)
    assert v.picked == 0 and "**grade**" in v.g_details.content


# ---------------------------------------------------------------- scene mode
@pytest.fixture(scope="module")
def scene_db(tmp_path_factory):
    import math

    from graspsim.maps.database import MapDatabase
    from graspsim.maps.map_config import MapConfig
    from graspsim.primitives import Box, Sphere

    db = MapDatabase(tmp_path_factory.mktemp("scenedb"),
                     config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
    db.build([Box(0.06, 0.06, 0.06), Sphere(0.035)])
    return db


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    from graspsim.tabletop.table_scene import make_scene, save_scene

    path = tmp_path_factory.mktemp("scene") / "packed.json"
    save_scene(make_scene(3, "packed", 1, object_set="primitives"), path)
    return path


SCENE_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


@needs_viser
def test_scene_mode_colours_segments_and_draws_each_objects_top_k_and_the_chosen_grasp(scene_file, scene_db):
    from graspsim.viewer import show_scene
    from graspsim.viewer.scene_view import SEGMENT_COLOURS

    server = show_scene(scene_file, db=scene_db, port=0, top_k=2)
    try:
        v = server.graspsim_viewer
        per, plan = v.per, v.plan
        assert per.n_segments == 3 and len(v.segments.points) == len(per.points)
        colours = v.point_colours()
        for k in range(per.n_segments):  # every segment's points in its own colour
            assert np.all(colours[per.segment == k] == SEGMENT_COLOURS[k])
        # the table plate lies on the fitted plane (z = 0 up to the fit) and faces up
        assert abs(v.table.position[2]) < 0.005
        drawn = v.drawn
        assert all(sum(g.segment == k for g in drawn) == min(2, sum(g.segment == k for g in plan.grasps))
                   for k in range(per.n_segments))
        best = v.best
        assert best is not None and best in drawn and best.score == max(g.score for g in plan.grasps)
        v.g_top.value = 1  # the slider: one grasp per object, each the object's best
        assert [g.segment for g in v.drawn] == sorted({g.segment for g in plan.grasps}, key=[
            g.segment for g in plan.grasps].index)
        assert "| 0 |" in v.segment_table() and "planned" in v.segment_table()
    finally:
        stop(server)


@needs_viser
def test_screenshot_of_a_scene_shows_its_segments_in_their_colours(scene_file, scene_db):
    _chromium_or_skip()
    from graspsim.viewer import show_scene
    from graspsim.viewer.scene_view import SEGMENT_COLOURS
    from graspsim.viewer.snapshot import browser_render

    server = show_scene(scene_file, db=scene_db, port=0)
    try:
        img = browser_render(server, size=(300, 400), camera=server.graspsim_viewer.camera, timeout=120)
    finally:
        stop(server)
    assert img.shape == (300, 400, 3) and img.std() > 10
    for k in range(3):  # each object's points, coloured by its segment
        assert _hue_share(img, SEGMENT_COLOURS[k]) > 0.002, k


@needs_viser
def test_view_scene_command_screenshot_and_one_line_errors(scene_file, scene_db, tmp_path, capsys):
    base = ["view", "--scene", str(scene_file), "--db", str(scene_db.root), *SCENE_FLAGS, "--port", "0"]
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    for argv, words in ((["view"], "one of them"), (["view", "x.h5", "--scene", str(scene_file)], "one of them"),
                        ([*base, "--cloud", "c.pcd"], "--cloud belong to a map"),
                        (["view", "--scene", str(bad)], "not a table scene")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and words in err, err
    from graspsim.viewer.snapshot import find_browser

    if find_browser() is None:
        return
    png = tmp_path / "scene.png"
    assert main([*base, "--screenshot", str(png), "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert png.stat().st_size > 0 and s["segments"] == 3 and s["objects"] == 3 and s["chosen"]["score"] > 0
