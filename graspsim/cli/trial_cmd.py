"""``graspsim trial``: simulate a map's grasps in MuJoCo and store the outcomes in the map.

    graspsim trial MAP.h5 [--protocol lift_place|tug] [--top N [--rank robust|paper] |
                   --sample N --min-grade G] [--threads T] [--render DIR]
                   [--mesh FILE [--mesh-scale S]]
                   [--seed S] [--noise] [--all] [--json]
                   [--robot none|panda [--robot-base X Y YAW]]

``--robot panda`` executes each grasp with the Franka Emika Panda arm standing beside the
table (:func:`graspsim.robots.simulate_map_arm`): reachability checked first (grasps it
refuses count as failures: unreachable, approach_collision), then a joint-space move, a
Cartesian approach, close, lift, place by the arm's joint servos.

MAP may also be a third-party grasp file -- ACRONYM (.h5), GraspGen (.json), GraspNet-1Billion
(GraspGroup .npy, with --mesh and --camera-pose) -- which is read into a graspsim map beside it
(``<stem>.graspsim.h5``, never touching the dataset file) that takes the results.

A selection that holds no grasp is an error (nonzero exit), not an empty table. Before
simulating, the command says how many trials will run and about how long they take;
more than :data:`MAX_TRIALS` need ``--all`` (an FS map holds up to ~1.7 M grasps: hours).
"""

from __future__ import annotations

import math
import sys

from graspsim.cli._common import (
    add_gripper_flag,
    add_robot_flags,
    command,
    emit,
    format_table,
    gripper_from_args,
    progress,
    robot_base_from_args,
)

__all__ = ["register", "run", "MAX_TRIALS", "TRIALS_PER_SECOND_PER_THREAD", "RENDER_SECONDS_PER_TRIAL"]

MAX_TRIALS = 10_000  # more than this many trials need --all
# Throughput of two-second lift_place trials that start clear, per thread, measured with
# `python experiments/bench_sim.py` on an idle machine (docs/results.md, bench_sim).
# Start collisions cost ~nothing; a busy machine is slower (62 trials/s on 2 threads at load 7).
TRIALS_PER_SECOND_PER_THREAD = 80.0
# --render: one rendered trial (offscreen 640 x 480, the key moments and a 25 frames/s GIF,
# ~100 frames; rendering runs on one core) took 5 s of CPU, measured by timing
# graspsim.sim.trial_render.render_trial on a cylinder map's trials (15 s of wall time each at
# load 10 on 2 cores): the estimate says "at least" and the bar shows the measured pace.
RENDER_SECONDS_PER_TRIAL = 5.0


def register(subparsers) -> None:
    from graspsim.cli._common import seed_value

    with command(subparsers, "trial", run=run,
                 help="simulate a map's grasps (lift-and-place or tug) and store the outcomes",
                 glossary=("feasible", "robust score", "grade")) as p:
        p.add_argument("map", metavar="FILE", help="graspability map file, or an ACRONYM .h5 / GraspGen "
                       ".json / GraspNet .npy grasp file (results go to <stem>.graspsim.h5 beside it)")
        add_robot_flags(p, robot_help="none: the floating gripper (default); panda: the Franka Emika Panda arm beside "
                        "the table carries the map's gripper (simulated as the floating gripper is), checks each "
                        "grasp's reachability and executes it with its joint servos (lift_place only); --top takes "
                        "the best grasps the map marks reachable first (graspsim reach)")
        p.add_argument("--protocol", choices=("lift_place", "tug"), default="lift_place",
                       help="lift_place: the paper's lift-and-place test (default); tug: "
                            "table-free pulls of 1 g x mass in six gripper directions")
        sel = p.add_mutually_exclusive_group()
        sel.add_argument("--top", type=int, metavar="N",
                         help="the N best grasps by --rank (the ones a robot would execute)")
        sel.add_argument("--sample", type=int, metavar="N",
                         help="N grasps spread uniformly over the object's surface")
        p.add_argument("--rank", choices=("robust", "paper"), default="robust",
                       help="order of --top: robust (default): the map's robust scores (expected success "
                            "under wrist pose error, clearance to the observed cloud; maps planned from a "
                            "cloud have them), then the grade; paper: the paper's grade")
        p.add_argument("--separation", type=float, nargs=2, metavar=("MM", "DEG"),
                       help="with --top: the N best at least MM mm apart (grasp points) or DEG deg "
                            "(wrist orientation, jaws swapped counted the same): non-maximum suppression")
        p.add_argument("--min-grade", type=float, metavar="G", help="only grasps with grade > G")
        p.add_argument("--threads", type=int, metavar="T", help="native threads (default: all cores)")
        p.add_argument("--seed", type=seed_value, default=0, help="seed of sampling and noise (default 0)")
        p.add_argument("--noise", action="store_true",
                       help="execution noise: wrist pose error sigma 3 mm / 2 deg per trial")
        p.add_argument("--mesh", metavar="FILE",
                       help="simulate against this mesh (the real object) instead of the map's "
                            "primitives, placed by the map's cloud->object transform")
        p.add_argument("--mesh-scale", type=float, default=None, metavar="S",
                       help="multiplies the mesh file's coordinates to give metres (0.001 for millimetres, "
                            "0.01 for centimetres; default 1, or a grasp file's own object/scale for its own "
                            "mesh). A mesh wider than 2 m or smaller than 5 mm is refused: its units are "
                            "probably not metres")
        p.add_argument("--mesh-model", choices=("parts", "surface"), default="parts",
                       help="the mesh's collision model: parts (default: CoACD's convex parts within 15 CPU "
                            "seconds, else its convex hull) or surface (the mesh's own surface, a 1.5 mm prism per "
                            "face: cavities and thin walls as the mesh has them; one geom per face: slower per "
                            "trial, about 8x on a 2334-face mug)")
        p.add_argument("--camera-pose", metavar="FILE.npy",
                       help="GraspNet files: the object's 4x4 pose in the camera frame (.npy or text)")
        p.add_argument("--object-id", type=int, help="GraspNet files: simulate this object's grasps only")
        p.add_argument("--mass", type=float, help="object mass [kg] (default: the map's, or density x volume; "
                       "with --mesh, density x the mesh's volume)")
        p.add_argument("--friction", type=float,
                       help="pad-object friction (default: the map's quality model mu)")
        p.add_argument("--grip-force", type=float, metavar="N", help="grip force per jaw [N]")
        p.add_argument("--render", metavar="DIR", help="write PNGs (and a GIF) of the first trials that start clear")
        p.add_argument("--render-count", type=int, default=3, metavar="K",
                       help="how many trials --render pictures (default 3)")
        p.add_argument("--record", metavar="FILE",
                       help="also save the trials' trajectories (25 frames/s, the first 2000 trials "
                            "that start clear) to FILE (.npz), for 'graspsim view MAP --replay FILE'")
        p.add_argument("--no-write", action="store_true", help="do not store results in the map")
        p.add_argument("--replace", action="store_true",
                       help="replace results the map already holds that these would overwrite (an earlier run "
                            "of the same grasps, or one with other settings: protocol, object, friction, noise); "
                            "without it such a run is refused before simulating. Results of other grasps made "
                            "with the same settings are always kept beside the new ones")
        p.add_argument("--all", action="store_true",
                       help=f"run the selection however large (without it, more than {MAX_TRIALS:,} "
                            "trials are refused with an estimate of their duration)")
        add_gripper_flag(p, help="the gripper the map was made for (default: the one it records; a "
                         "name or spec .json that differs from it is an error: the map's poses are that gripper's)")


def run(args) -> int:
    # mujoco loads only when the command runs (keeps `graspsim --help` fast)
    """Simulate grasps of a graspability map in MuJoCo; results go back into the file
    under grasps/qualities/mujoco (lift_place) or mujoco_tug (tug), beside the results
    of earlier runs of other grasps with the same settings; a run that would overwrite
    stored results (the same grasps again, or other settings) needs --replace. The
    success rate counts feasible poses: a pose whose gripper starts in collision (with
    the object, or blocked by the table) is excluded and counted apart."""
    from graspsim.errors import InvalidParameterError
    from graspsim.maps import load_map
    from graspsim.sim import ExecutionNoise, SimSettings, make_protocol, simulate_map

    if args.threads is not None and args.threads < 1:
        raise InvalidParameterError(f"--threads must be >= 1, got {args.threads}")
    for flag in ("top", "sample"):
        n = getattr(args, flag)
        if n is not None and n < 1:
            raise InvalidParameterError(f"nothing to simulate: --{flag} {n} selects no grasp "
                                        "(give N >= 1)")
    separation = None
    if args.separation is not None:
        mm, deg = args.separation
        if args.top is None or not (math.isfinite(mm) and mm >= 0 and math.isfinite(deg) and deg >= 0):
            raise InvalidParameterError(f"--separation {mm:g} {deg:g}: two numbers >= 0 (mm, deg), with --top")
        separation = (1e-3 * mm, math.radians(deg))
    if args.render:
        from graspsim._atomic import check_folder

        check_folder(args.render, "render folder")  # before the work, not after it
    recorder = None
    if args.record:
        from graspsim._atomic import check_output
        from graspsim.sim.recording import Recorder

        check_output(args.record, "trial recording")
        recorder = Recorder()
    if args.mesh is not None:
        from graspsim.sim.meshes import check_mesh_path

        check_mesh_path(args.mesh)
    dataset = _import_dataset(args)  # a third-party grasp file: args.map is its map now
    # the map's header (no rows) for the checks; simulate_map reads the map once in full
    header = load_map(args.map, rows=slice(0, 0)).meta if args.gripper is not None or (
        args.grip_force is not None and args.friction is None) else None
    if args.gripper is not None:
        _check_gripper(gripper_from_args(args), header.gripper_spec)
    mesh = _surface_mesh(args) if args.mesh_model == "surface" else (
        _prepared_mesh(args) if args.mesh is not None else None)
    settings = None
    if args.friction is not None or args.grip_force is not None:
        mu = args.friction
        if mu is None:
            mu = float(header.quality.get("friction", 0.5))
        settings = SimSettings(friction=mu, grip_force=args.grip_force)
    protocol = make_protocol(args.protocol)
    arm = _arm_args(args)
    bar = progress(None, "trials", enabled=not args.json and sys.stderr.isatty(), unit="trial")
    try:
        done = [0]

        def tick(k: int) -> None:
            bar.update(k - done[0])
            done[0] = k

        common = dict(top=args.top, sample=args.sample, min_grade=args.min_grade, threads=args.threads,
                      seed=args.seed, noise=ExecutionNoise() if args.noise else None, mesh=mesh,
                      mesh_scale=1.0 if args.mesh_scale is None else args.mesh_scale, mass=args.mass,
                      settings=settings, write=not args.no_write, replace_stored=args.replace, on_progress=tick,
                      on_selected=_selection_check(args, bar), rank=args.rank, separation=separation)
        if arm is None:
            out = simulate_map(args.map, protocol=protocol, on_record=recorder, **common)
        else:
            from graspsim.robots import simulate_map_arm

            protocol = arm["protocol"]
            out = simulate_map_arm(args.map, robot=args.robot, base=arm["base"], protocol=protocol, **common)
    finally:
        bar.close()
    res = out.results
    renders = _render(args, out, protocol) if args.render and len(out.index) else []
    if recorder is not None:
        recorder.recording(out.scene, out.index, res.outcome, res.protocol).save(args.record)
    counts = res.counts()
    blocked = res.start_collisions()
    summary = {
        "file": str(out.file), "dataset": dataset, "protocol": protocol.name, "trials": len(res),
        "feasible": res.feasible, "counts": counts, "start_collisions": blocked,
        "success": counts["success"], "success_rate": res.success_rate,
        "success_rate_all": counts["success"] / len(res) if len(res) else math.nan,
        "trials_per_second": res.trials_per_second, "wall_time_s": res.wall_time,
        "threads": res.threads, "seed": args.seed, "noise": res.noise, "rank": args.rank,
        "mesh": args.mesh, "mesh_model": None if mesh is None else mesh.describe(),
        "written_to": out.group, "kept_stored": out.kept, "replaced_stored": out.replaced,
        "renders": renders, "record": args.record,
        "separation": args.separation, "T_world_obj": out.scene.T_world_obj.tolist(),
        "viewpoint": out.viewpoint, "robot": args.robot,
    }
    if arm is not None:
        summary["robot_base"] = arm["base_args"]
        summary["plan"] = res.extra.get("plan")
    human = _report(res, counts, blocked, out, foreign=dataset is not None, robot=arm is not None)
    if mesh is not None:
        m = mesh.describe()
        human += (f"\nmesh {m['file']}: {m['parts']} convex part(s) ({m['method']}), mass from the "
                  f"{'closed mesh' if m['mass_from'] == 'mesh' else 'convex parts (the mesh is open)'}"
                  f"{', from the cache' if m['from_cache'] else ''}")
    emit(summary, args.json, human)
    return 0


def _percent(k: int, n: int) -> str:
    return f"{100 * k / n:5.1f} %" if n else "    - "


def _arm_args(args) -> dict | None:
    """``--robot`` / ``--robot-base`` checked before any work: None for the floating
    gripper, else the arm's protocol and base (x, y, yaw [rad])."""
    from graspsim.errors import InvalidParameterError

    base = robot_base_from_args(args)
    if base is None:
        return None
    for flag, bad in (("--protocol tug", args.protocol != "lift_place"), ("--render", args.render),
                      ("--record", args.record)):
        if bad:
            raise InvalidParameterError(f"{flag} is not available with --robot {args.robot} "
                                        "(the arm executes lift_place and is not rendered or recorded yet)")
    from graspsim.robots import ArmLiftPlace

    return {"protocol": ArmLiftPlace(), "base": base,
            "base_args": [-0.5, 0.0, 0.0] if args.robot_base is None else list(args.robot_base)}


_ARM_ONLY = ("unreachable", "approach_collision", "controller_error")


def _report(res, counts: dict, blocked: dict, out, foreign: bool = False, robot: bool = False) -> str:
    """The outcome table and the headline: every rate with its counts, the attempts and
    what was excluded from the feasible ones and why (and with an arm, what it did not
    execute, counted as failures)."""
    from graspsim.sim import TrialOutcome
    from graspsim.stats import wilson_interval

    n = len(res)
    rows = []
    for o in TrialOutcome:
        if o.label in _ARM_ONLY and not robot:
            continue
        if o is TrialOutcome.START_COLLISION:
            rows.append(("start_collision (object)", blocked["object"], _percent(blocked["object"], n)))
            rows.append(("start_collision (table only)", blocked["table"], _percent(blocked["table"], n)))
        else:
            rows.append((o.label, counts[o.label], _percent(counts[o.label], n)))
    ok, feasible = counts["success"], res.feasible
    excluded = n - feasible
    why = " and ".join(f"{k} {w}" for k, w in ((blocked["object"], "in collision with the object"),
                                                (blocked["table"], "blocked by the table")) if k)
    if feasible:
        lo, hi = wilson_interval(ok, feasible)
        head = (f"success rate: {ok} of {feasible} feasible poses = {100 * ok / feasible:.1f} % "
                f"(95 % CI {100 * lo:.0f}-{100 * hi:.0f} %)")
    else:
        head = "success rate: n/a (no feasible pose)"
    attempts = f"{n} attempt" + ("" if n == 1 else "s")
    head += (f"; {attempts}, {excluded} excluded as infeasible (the gripper starts in collision: {why})"
             if excluded else f"; {attempts}, none excluded")
    head += f"; of all {n} attempts {ok} succeeded ({100 * ok / n:.1f} %)" if excluded and n else ""
    if robot:
        plan = res.extra.get("plan", {})
        skipped = sum(plan.get("not_executed_at", {}).values()) - excluded
        head += (f"\nthe arm did not execute {skipped} feasible grasp(s) its reachability check refused "
                 f"(counted as failures: {counts['unreachable']} unreachable, "
                 f"{counts['approach_collision']} approach collision at planning or execution); "
                 f"reachability verdicts: {plan.get('reach', {})}")
    stored = ""
    if out.group:
        stored = (f"\nresults stored in {out.group}" + (f" of {out.file}" if foreign else "")
                  + (f" beside the {out.kept} stored before" if out.kept else "")
                  + (f", replacing the {out.replaced} stored before (--replace)" if out.replaced else ""))
    return (format_table(rows, ["outcome", "trials", "%"]) + "\n\n" + head
            + f"\n{res.trials_per_second:.1f} trials/s on {res.threads} thread(s)" + stored)


def _prepared_mesh(args):
    """``--mesh`` prepared for simulation (checked, decomposed within its time limit or
    read from the cache), with a progress bar on a terminal once it takes over 2 s."""
    from graspsim.cli._common import progress
    from graspsim.sim.meshes import prepare_mesh

    with progress(100, "preparing the mesh", enabled=not args.json, unit="%", delay=2.0) as bar:
        def report(stage: str, fraction: float) -> None:
            bar.set_description(f"{stage} the mesh (time limit)", refresh=False)
            bar.update(int(100 * fraction) - bar.n)

        return prepare_mesh(args.mesh, scale=1.0 if args.mesh_scale is None else args.mesh_scale,
                            progress=report)


def _surface_mesh(args):
    """``--mesh-model surface``: the surface model of ``--mesh``, else of the map's own mesh
    file (a grasp file's ``object/file``, at its scale)."""
    from pathlib import Path

    from graspsim.errors import InvalidParameterError
    from graspsim.maps import load_map
    from graspsim.sim.meshes import surface_model

    if args.mesh is not None:
        return surface_model(args.mesh, scale=1.0 if args.mesh_scale is None else args.mesh_scale)
    obj = load_map(args.map, rows=slice(0, 0)).meta.object or {}
    if not obj.get("file"):
        raise InvalidParameterError("--mesh-model surface needs a mesh: give --mesh FILE (the map's object is "
                                    "not a mesh)")
    path = Path(obj["file"])
    return surface_model(path if path.is_absolute() else Path(args.map).parent / path,
                         scale=float(obj.get("scale", 1.0)))


def _render(args, out, protocol) -> list[str]:
    """Pictures and GIFs of the first ``--render-count`` trials that started (not in
    collision) into ``--render``; their paths."""
    from graspsim.sim import TrialOutcome
    from graspsim.sim.trial_render import render_trial

    res = out.results
    clear = [j for j in range(len(out.index)) if res.outcome[j] != TrialOutcome.START_COLLISION]
    renders = []
    with progress(min(len(clear), args.render_count), "rendering", enabled=not args.json, unit="trial") as bar:
        for j in clear[:args.render_count]:
            i = int(out.index[j])
            paths = render_trial(out.scene, None, float(out.width[j]), args.render, protocol,
                                 name=f"grasp{i:06d}", gif=True, T_world_wrist=res.T_world_wrist[j])
            renders += [str(p) for p in paths]
            bar.update(1)
    return renders


def _import_dataset(args) -> str | None:
    """For a third-party grasp file: import it beside itself (graspsim.maps.formats),
    point ``args.map`` at that map and hand it the mesh, gripper, camera pose and object
    id; returns the dataset file (None for a graspsim map)."""
    from graspsim.errors import InvalidParameterError
    from graspsim.maps.formats import is_foreign
    from graspsim.maps.imported import import_beside

    if not is_foreign(args.map):
        if args.camera_pose is not None or args.object_id is not None:
            raise InvalidParameterError("--camera-pose and --object-id apply to GraspNet grasp files only")
        return None
    kw = _dataset_args(args)
    if args.mesh is not None:
        kw.update(mesh=args.mesh, mesh_scale=args.mesh_scale)
    dataset, args.map = args.map, str(import_beside(args.map, **kw))
    args.mesh = args.gripper = None
    args.mesh_scale = None
    return dataset


def _dataset_args(args) -> dict:
    """read_grasp_file's arguments from the command line (gripper, camera pose, object id)."""
    import numpy as np

    from graspsim.errors import InvalidParameterError

    out = {}
    if args.gripper is not None:
        out["gripper"] = gripper_from_args(args)
    if args.object_id is not None:
        out["object_id"] = args.object_id
    if args.camera_pose is not None:
        try:
            T = (np.load(args.camera_pose) if args.camera_pose.endswith(".npy")
                 else np.loadtxt(args.camera_pose))
        except (OSError, ValueError) as err:
            raise InvalidParameterError(f"cannot read --camera-pose {args.camera_pose}: {err}") from err
        out["T_camera_obj"] = np.asarray(T, float).reshape(-1)[:16].reshape(4, 4) if np.size(T) == 16 else T
    return out


def _check_gripper(asked, recorded) -> None:
    from graspsim.errors import GripperError

    if asked != recorded:
        raise GripperError(f"the map was made for gripper {recorded.name!r}, not {asked.name!r} (its "
                           "poses are that gripper's); build the map with --gripper to simulate another")


def _duration(seconds: float) -> str:
    if seconds < 1:
        return "1 s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _selection_check(args, bar):
    """The ``on_selected`` hook: refuse an empty selection, or a huge one without
    ``--all``; otherwise say how many trials will run and about how long they take (from
    the benchmark's rate; the progress bar then shows the time left at the measured one)."""
    import os

    import numpy as np

    from graspsim.errors import InvalidParameterError

    threads = args.threads or os.cpu_count() or 1

    def check(gmap, index) -> None:
        n = len(index)
        among = (f"grasps with grade > {args.min_grade:g}" if args.min_grade is not None
                 else "grasps")
        if n == 0:
            graded = np.isfinite(gmap.grade)
            best = (f"; its best grade is {float(gmap.grade[graded].max()):.3f}" if graded.any()
                    else "; it has no grades (a third-party grasp file)" if len(gmap) else "")
            raise InvalidParameterError(f"nothing to simulate: the map ({len(gmap)} grasps) holds "
                                        f"no {among}{best}")
        eta = _duration(n / (TRIALS_PER_SECOND_PER_THREAD * threads))
        if n > MAX_TRIALS and not args.all:
            asked = (f"--top {args.top}" if args.top else f"--sample {args.sample}" if args.sample
                     else "no --top/--sample (all grasps)")
            raise InvalidParameterError(
                f"{asked} selects {n:,} trials, about {eta} on {threads} thread(s) at "
                f"~{TRIALS_PER_SECOND_PER_THREAD:g} trials/s each (longer on a busy machine); pass "
                f"--all to run them, or select at most {MAX_TRIALS:,} with --top/--sample")
        if not args.json:
            short = (f" (the map holds only {n} {among})" if (args.sample or args.top or 0) > n
                     else "")
            shots = min(n, args.render_count) if args.render else 0
            render = (f"; then rendering up to {shots} of them: at least {_duration(shots * RENDER_SECONDS_PER_TRIAL)}"
                      f" (~{RENDER_SECONDS_PER_TRIAL:g} s each on one core)" if shots else "")
            print(f"[graspsim] simulating {n:,} trials{short}: about {eta} on {threads} "
                  f"thread(s) at ~{TRIALS_PER_SECOND_PER_THREAD:g} trials/s each{render}", file=sys.stderr,
                  flush=True)
        bar.total = n  # the bar's time left comes from the measured rate
        bar.refresh()

    return check
