"""Scene planning speed (issue 17): robust identification on a bounded point count
(``IdentifyConfig.fit_points``; paper mode never downsamples), and a scene's segments
identified and planned on worker processes with the same result as in this process."""

import logging
import math
import os
import signal
import time
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.perception.identify import identify
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.planning import scene_segments
from graspsim.planning import scene_workers as workers_mod
from graspsim.planning.scene import plan_scene
from graspsim.planning.scene_config import SCENE_FIT_POINTS, SceneConfig
from graspsim.planning.scene_workers import (
    identify_segments,
    run_segments,
    scene_workers,
    shutdown_workers,
    start_workers,
    stream_segments,
)
from graspsim.primitives import Box, Cylinder, Sphere, synthetic_cloud
from graspsim.primitives.clouds import table_scene_cloud
from graspsim.transforms import make_transform

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


def _cloud(shape, seed: int, resolution: float = 0.0015) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = make_transform(np.eye(3), [0.1 * seed, 0.0, 0.05])
    return synthetic_cloud(shape, rng, resolution=resolution, noise=0.0005, T_world_obj=T).points


def test_robust_identification_fits_at_most_fit_points_and_paper_mode_never_downsamples():
    pts = _cloud(Cylinder(0.03, 0.12), 1)
    assert len(pts) > 3000
    r = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(fit_points=800))
    assert r.downsampling is not None and r.downsampling.used_points <= 800
    assert r.downsampling.input_points == len(pts) == r.n_points
    assert [p.shape.value for p in r.parts] == ["cylinder"]
    assert math.isclose(r.parts[0].dims["radius"], 0.03, abs_tol=0.002)
    idx = r.parts[0].indices  # still every input point of the part's voxels
    assert idx.max() < len(pts) and len(idx) > 0.9 * len(pts)
    off = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(fit_points=None))
    assert off.downsampling is None  # opted out: every point (below max_points)
    paper = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig.preset("paper", fit_points=800))
    assert paper.downsampling is None
    assert IdentifyConfig().point_limit == 20000 == IdentifyConfig.preset("paper", fit_points=800).point_limit
    # scenes identify their segments on at most SCENE_FIT_POINTS unless told otherwise
    assert SceneConfig().planner.identify.point_limit == SCENE_FIT_POINTS == 1000
    for bad in (100, 999.5, "many", True):
        with pytest.raises(InvalidParameterError, match="fit_points"):
            IdentifyConfig(fit_points=bad)


def test_segments_identified_on_workers_match_this_process():
    segs = [_cloud(Box(0.04, 0.05, 0.08), 2, 0.004), _cloud(Sphere(0.03), 3, 0.004),
            _cloud(Cylinder(0.02, 0.1), 4, 0.004), np.zeros((5, 3))]  # the last: too few points
    cfg = IdentifyConfig()

    def run(workers):
        rngs = np.random.default_rng(11).spawn(len(segs))
        return identify_segments(segs, rngs, cfg, workers)

    here, there = run(1), run(2)
    assert here[-1][0] is None and "points" in here[-1][1] and there[-1][1] == here[-1][1]
    for (a, _), (b, _) in zip(here[:-1], there[:-1]):
        assert a.status == b.status and len(a.parts) == len(b.parts)
        for p, q in zip(a.parts, b.parts):
            assert p.shape == q.shape and p.dims == q.dims
            np.testing.assert_array_equal(p.T_world_obj, q.T_world_obj)
            np.testing.assert_array_equal(p.indices, q.indices)
    assert [p.shape.value for p in here[1][0].parts] == ["sphere"]
    with pytest.raises(InvalidParameterError, match="one generator per segment"):
        identify_segments(segs, [np.random.default_rng(0)], cfg, 1)


def _run_parallel_pad_kernel():
    from graspsim.grades.pad_kernel import SERIAL_BELOW, run_pad_patches

    n = 2 * SERIAL_BELOW  # enough grasps for the parallel path
    R = np.repeat(np.eye(3)[None], n, axis=0)
    pts = np.random.default_rng(0).normal(size=(50, 3)) * 0.01
    run_pad_patches(pts, np.tile([0.0, 0.0, 1.0], (50, 1)), np.full(50, 1e-6), R, np.zeros((n, 3)), 0.01, 0.0,
                    0.02, 0.001)


def test_workers_forked_after_the_parallel_kernels_ran_still_identify():
    """The pad-contact grade's kernel runs on numba's OpenMP pool; a child forked after it
    ran dies if it runs such a kernel too. Identification never does: a pool forked after
    the kernel ran identifies as one forked before it."""
    _run_parallel_pad_kernel()
    shutdown_workers()  # the next call forks new workers, after the kernel ran
    segs = [_cloud(Sphere(0.03), 5, 0.004), _cloud(Cylinder(0.02, 0.1), 6, 0.004)]
    here = identify_segments(segs, np.random.default_rng(1).spawn(2), IdentifyConfig(), 1)
    there = identify_segments(segs, np.random.default_rng(1).spawn(2), IdentifyConfig(), 2)
    assert [[p.dims for p in a.parts] for a, _ in here] == [[p.dims for p in b.parts] for b, _ in there]


def test_worker_count_is_validated():
    assert scene_workers(1) == 1 and scene_workers(3) == 3 and scene_workers(None) >= 1
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InvalidParameterError, match="workers"):
            scene_workers(bad)
        with pytest.raises(InvalidParameterError, match="workers"):
            SceneConfig(workers=bad)


def test_serial_pad_kernel_gives_the_parallel_kernels_results_bit_for_bit():
    from scipy.spatial.transform import Rotation

    from graspsim.grades.pad_kernel import pad_patches, pad_patches_serial

    rng = np.random.default_rng(3)
    P, N = rng.normal(size=(2000, 3)) * 0.03, rng.normal(size=(2000, 3))
    A = rng.random(2000) * 1e-5
    R, p = Rotation.random(300, random_state=4).as_matrix(), rng.normal(size=(300, 3)) * 0.01
    a, b = np.zeros((300, 2, 7)), np.zeros((300, 2, 7))
    pad_patches(P, N, A, R, p, 0.01, 0.02, 0.03, 0.002, a)
    pad_patches_serial(P, N, A, R, p, 0.01, 0.02, 0.03, 0.002, b)
    assert np.count_nonzero(a[:, :, 6]) > 50  # patches found, not all empty
    np.testing.assert_array_equal(a, b)


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.2), Sphere(0.035)])
    return d


def _scene(shapes, seed: int, gap: float = 0.015) -> np.ndarray:
    """Shapes standing in a row ``gap`` [m] apart (close enough to block grasps)."""
    widths = [s.aabb[1, 0] - s.aabb[0, 0] for s in shapes]
    x = np.cumsum([0.0] + [0.5 * (a + b) + gap for a, b in zip(widths[:-1], widths[1:])])
    xy = np.column_stack([x - x.mean(), np.zeros(len(x))])
    return table_scene_cloud(shapes, xy, np.random.default_rng(seed), noise=0.0005)[0]


def _plan_record(sp) -> list:
    return [(s.segment, s.status, s.primitives, s.scored) for s in sp.segments] + [
        (g.segment, g.T_world_wrist.tobytes(), g.opening, g.score, g.grade, g.clearance) for g in sp.grasps]


def _spy_workers(monkeypatch) -> list:
    """The worker counts the scene's segment planning asked for (one per batch planned:
    1 where the batch was planned in this process)."""
    asked = []

    def spy(fn, groups, workers=1):
        stream = stream_segments(fn, groups, workers)
        try:
            for (_, _, parallel), out in zip(groups, stream):
                asked.append(workers if parallel else 1)
                yield out
        finally:
            stream.close()

    monkeypatch.setattr(scene_segments, "stream_segments", spy)
    return asked


def test_segments_planned_on_workers_match_this_process_after_the_parallel_kernel_ran(db, monkeypatch, caplog):
    """Maps, collision samples and robust scores against the neighbours, computed on two
    forked workers (forked after this process ran numba's OpenMP kernel, which the
    workers must then not start), give every grasp as this process does, in the same order."""
    asked = _spy_workers(monkeypatch)
    caplog.set_level(logging.WARNING, logger="graspsim.planning.scene_workers")
    pts = _scene([Box(0.05, 0.06, 0.07), Cylinder(0.025, 0.12), Sphere(0.03)], 5)
    cfg = SceneConfig(enough=10**6, per_segment=400, keep=400)  # batches big enough for the parallel kernel
    here = plan_scene(pts, db=db, rng=np.random.default_rng(9), config=replace(cfg, workers=1))
    _run_parallel_pad_kernel()
    shutdown_workers()  # the next pool is forked after the kernel ran
    there = plan_scene(pts, db=db, rng=np.random.default_rng(9), config=replace(cfg, workers=2))
    assert asked == [1, 2]  # planned here, then on the workers (no map had to be built)
    assert not caplog.records  # and the workers lived (none died for running the OpenMP kernel)
    assert sum(s.status == "planned" for s in here.segments) == 3 and sum(g.score > 0 for g in here.grasps) > 10
    assert any(g.score == 0 for g in here.grasps)  # some blocked by a neighbour
    assert _plan_record(there) == _plan_record(here)


def test_a_scene_whose_plan_builds_a_map_is_planned_in_this_process(tmp_path, monkeypatch):
    """A part with no stored map in scaling range makes its plan build and store one,
    which later plans match against: such a scene is planned in this process, segment
    after segment, as before."""
    asked = _spy_workers(monkeypatch)
    small = MapDatabase(tmp_path, config=FAST)
    small.build([Sphere(0.035)])
    pts = _scene([Sphere(0.03), Box(0.05, 0.06, 0.07)], 6)
    sp = plan_scene(pts, db=small, rng=np.random.default_rng(9), config=SceneConfig(workers=2))
    assert asked == [1]
    assert len(small.entries()) > 1  # the box's map was built
    assert [s.status for s in sp.segments] == ["planned", "planned"]


def _die_in_a_worker(x):
    if os.getpid() != x:  # in a worker: killed, as by the kernel's OOM killer
        os.kill(os.getpid(), signal.SIGKILL)
    return x


def test_a_dead_worker_leaves_the_segments_to_this_process(caplog):
    caplog.set_level(logging.WARNING, logger="graspsim.planning.scene_workers")
    me = os.getpid()
    assert run_segments(_die_in_a_worker, [(me,), (me,), (me,)], [1, 2, 3], 2) == [me, me, me]
    assert "died" in caplog.text
    assert run_segments(abs, [(-1,), (-2,)], [1, 1], 2) == [1, 2]  # a new pool serves the next call


class _OwnDatabase(MapDatabase):
    """A database subclass with state of its own (as E10's maps built in memory)."""


def test_a_database_subclass_is_planned_in_this_process(db, monkeypatch):
    asked = _spy_workers(monkeypatch)
    own = _OwnDatabase(db.root, config=db.config)
    pts = _scene([Box(0.05, 0.06, 0.07), Sphere(0.03)], 7)
    sp = plan_scene(pts, db=own, rng=np.random.default_rng(9), config=SceneConfig(workers=2))
    assert asked == [1] and [s.status for s in sp.segments] == ["planned", "planned"]


class _AlikeDatabase(MapDatabase):
    """A database subclass whose copies plan alike (as E10's RunDatabase says of itself)."""

    copies_plan_alike = True


def test_a_database_subclass_whose_copies_plan_alike_is_planned_on_the_workers(db, monkeypatch):
    """A subclass that says its copies plan alike has its segments planned side by side on
    the workers, with every grasp as a plain database planned here gives; one that does
    not say so (or says so with anything but True) is planned here."""
    asked = _spy_workers(monkeypatch)
    pts = _scene([Box(0.05, 0.06, 0.07), Sphere(0.03)], 7)
    here = plan_scene(pts, db=db, rng=np.random.default_rng(9), config=SceneConfig(workers=1))
    alike = _AlikeDatabase(db.root, config=db.config)
    there = plan_scene(pts, db=alike, rng=np.random.default_rng(9), config=SceneConfig(workers=2))
    assert asked == [1, 2] and _plan_record(there) == _plan_record(here)
    assert scene_segments.copies_plan_alike(db) and scene_segments.copies_plan_alike(alike)
    assert not scene_segments.copies_plan_alike(_OwnDatabase(db.root, config=db.config))
    monkeypatch.setattr(_AlikeDatabase, "copies_plan_alike", "yes")
    assert not scene_segments.copies_plan_alike(alike)


def _resident_is_given(db) -> bool:
    from graspsim.planning.scene_workers import resident_database

    return resident_database(db) is db


def test_only_scene_workers_keep_the_database_sent_to_them(db):
    """An experiment's own child process (not a scene worker) plans against the database
    it is given, every time -- never one kept from an earlier call."""
    import multiprocessing as mp

    assert _resident_is_given(db)
    with mp.get_context("fork").Pool(1) as pool:  # a child process that is no scene worker
        assert pool.apply(_resident_is_given, (db,)) and pool.apply(_resident_is_given, (db,))


def _loaded_here(names):
    import sys

    return [n in sys.modules for n in names], os.getpid()


def test_warm_loads_what_planning_uses_in_a_fresh_process():
    import subprocess
    import sys

    names = ["numba", "h5py", "graspsim.maps._kernel", "graspsim.maps._robust_kernel",
             "graspsim.primitives.sdf_kernel", "graspsim.maps._hierarchy_kernel", "graspsim.grades.models", "trimesh"]
    code = ("import sys; from graspsim.planning.scene_workers import _warm; "
            f"before = [n in sys.modules for n in {names!r}]; _warm(); "
            f"print(sum(before), all(n in sys.modules for n in {names!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.split() == ["0", "True"]


@pytest.mark.skipif(scene_workers(2) < 2, reason="no fork here: segments are planned in this process")
def test_started_workers_warm_up_and_are_the_pool_scenes_use(tmp_path, monkeypatch):
    """start_workers forks the pool that scenes of any segment count then use (one pool
    per size asked for), and each worker warms up (``_warm``) before its first task."""
    def mark():  # runs in each forked worker (the fork carries the patch)
        (tmp_path / str(os.getpid())).touch()

    monkeypatch.setattr(workers_mod, "_warm", mark)
    shutdown_workers()
    assert start_workers(1) == 1 and not workers_mod._pools  # one worker: none started
    assert start_workers(3) == 3
    pool = workers_mod._pools[3][1]
    pids = {r[1] for r in run_segments(_loaded_here, [([],)] * 6, [1] * 6, 3)}
    assert os.getpid() not in pids and {int(p.name) for p in tmp_path.iterdir()} >= pids  # warmed, then tasks
    deadline = time.monotonic() + 60  # a worker that took no task may still be starting
    while len(list(tmp_path.iterdir())) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(list(tmp_path.iterdir())) == 3  # every worker warmed up, once
    run_segments(_loaded_here, [([],)] * 2, [1, 1], 3)  # fewer segments than workers
    assert list(workers_mod._pools) == [3] and workers_mod._pools[3][1] is pool  # no pool per task count
    shutdown_workers()
    assert not workers_mod._pools


def _await_file(path, seconds):
    """Wait for ``path`` to exist (at most ``seconds``): whether it came."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if os.path.exists(path):
            return True
        time.sleep(0.01)
    return False


def _touch(path):
    open(path, "w").close()
    return os.getpid()


def _until_given_up(started, path, seconds):
    """Mark ``started``, then spin until the caller gives this task up (then mark
    ``path``) or ``seconds`` pass."""
    open(started, "w").close()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if workers_mod.cancelled():
            open(path, "w").close()
            return "given up"
        time.sleep(0.01)
    return "ran out"


def test_streamed_groups_give_each_groups_results_in_order_here_and_on_workers():
    groups = [([(-1,), (-2,), (-3,)], [1, 3, 2], True), ([(-4,)], [1], False), ([(-5,), (-6,)], [1, 1], True)]
    for workers in (1, 2):
        assert list(stream_segments(abs, groups, workers)) == [[1, 2, 3], [4], [5, 6]]
    assert list(stream_segments(abs, [], 2)) == [] and list(stream_segments(abs, [([], [], True)], 2)) == [[]]


@pytest.mark.skipif(scene_workers(2) < 2, reason="no fork here: segments are planned in this process")
def test_a_free_worker_starts_the_next_group_ahead_and_a_closed_stream_gives_it_up(tmp_path):
    """While the first group's task waits for a file that only the second group's task
    writes, that task starts on the free worker (without it the wait runs out); a third
    group's task started ahead is given up when the caller closes the stream, and the
    worker is free again at once."""
    mark, started, gone = (str(tmp_path / n) for n in ("second ran", "third started", "given up"))
    groups = [([(mark, 60)], [1], True), ([(mark,)], [1], True), ([(started, gone, 120)], [1], True)]
    fns = {0: _await_file, 1: _touch, 2: _until_given_up}
    stream = stream_segments(_dispatch, [([(fns[g], *t) for t in tasks], s, p) for g, (tasks, s, p)
                                         in enumerate(groups)], 2)
    assert next(stream) == [True]  # the second group's task ran while the first group's waited
    assert next(stream)[0] != os.getpid()
    assert _await_file(started, 60)  # the third group's task began ahead, on the free worker
    t0 = time.monotonic()
    stream.close()  # the third group's task (started ahead on the free worker) is given up
    assert run_segments(abs, [(-1,), (-2,)], [1, 1], 2) == [1, 2]
    assert _await_file(gone, 60) and time.monotonic() - t0 < 60  # it saw it was given up


def _dispatch(fn, *args):
    return fn(*args)


def test_a_group_planned_here_waits_for_every_group_before_it_and_none_after_it_starts_first(tmp_path):
    """A group that is not parallel (its plans may store a map later ones match against)
    runs in this process after the groups before it, and no later group's task starts
    before it has run: the later task marks a file the moment it starts, which the group
    run here watches for a second."""
    later = str(tmp_path / "later started")
    groups = [([(_touch, str(tmp_path / "a"))], [1], True), ([(_where_and_whether, later, 1.0)], [1], False),
              ([(_touch, later)], [1], True)]
    out = list(stream_segments(_dispatch, groups, 2))
    assert out[1] == [(os.getpid(), False)] and os.path.exists(later)


def _where_and_whether(path, seconds):
    return os.getpid(), _await_file(path, seconds)


@pytest.mark.skipif(scene_workers(2) < 2, reason="no fork here: segments are planned in this process")
def test_a_stream_gives_up_only_its_own_tasks(tmp_path):
    """Another stream ending (another thread's scene, say) leaves this stream's task
    started ahead running; this stream's close gives it up."""
    started, gone = str(tmp_path / "started"), str(tmp_path / "given up")
    mine = stream_segments(_dispatch, [([(_await_file, started, 60)], [1], True),
                                       ([(_until_given_up, started, gone, 60)], [1], True)], 2)
    assert next(mine) == [True]  # its second group's task runs ahead, on the other worker
    assert list(stream_segments(abs, [([(-1,)], [1], True)], 2)) == [[1]]  # another stream, run to its end
    assert not _await_file(gone, 1.0)  # this stream's task was not given up by it
    mine.close()
    assert _await_file(gone, 60)
