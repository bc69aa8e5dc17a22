"""``graspsim scene``: clutter removal on simulated table-top scenes seen by a depth camera.

    graspsim scene [--objects N] [--scenes S] [--kind pile|packed] [--object-set SET | --objects-dir DIR]
                   [--min-gap M] [--noise [--noise-pos M] [--noise-rot-deg DEG]] [--no-neighbours]
                   [--ground-truth] [--max-attempts M]
                   [--seed S] [--seeds N] [--planner NAME|module:function] [--db DIR]
                   [--gripper NAME|MODEL.xml|SPEC.json] [--robot none|panda [--robot-base X Y YAW]]
                   [--render DIR] [--save-scenes DIR] [--json]

Each scene is drawn and settled in MuJoCo, rendered by one D435-like depth camera, and
cleared grasp by grasp (:mod:`graspsim.tabletop.clutter`): segment, plan every object, execute
the best grasp, remove what was lifted, render again; until the table is clear, two
grasps in a row failed or no grasp is found. The JSON summary carries
``grasp_success_rate`` (lifts / grasps), ``cleared_rate`` (objects removed / placed),
the failure table per object (``per_object``: which object failed how often and why),
GSR and DR per seed with their mean and std (``seeds``: ``--seeds N``,
:mod:`graspsim.tabletop.clutter_stats`) and per-scene details. ``--planner`` swaps in
another grasp planner (:mod:`graspsim.tabletop.planners`). ``--robot panda`` clears the
table with the Franka Emika Panda arm standing beside it (``ClutterConfig.robot``): the
planner's grasps go through the arm's reachability check, the best it reaches is executed
by the arm's servos, and an episode whose grasps the arm reaches none of stops
``unreachable`` (docs/robots.md).

Objects: a named set (``household``, the default: the shipped real meshes; ``random``;
their ``-tuning`` / ``-heldout`` parts; ``primitives``, ``analogs``, ``mixed``) or any
folder of the user's mesh files (``--objects-dir DIR``, with an optional manifest
``objects.json`` / ``objects.toml`` for scale, mass or density, friction:
:mod:`graspsim.tabletop.mesh_objects`). Meshes are prepared (convex parts, cached) before the
first scene, with a progress bar.
"""

from __future__ import annotations

from graspsim.cli._common import (
    add_robot_flags,
    add_scene_planning_flags,
    command,
    emit,
    format_table,
    gripper_from_args,
    robot_base_from_args,
    scene_planning_from_args,
    whole_number,
)
from graspsim.cli.maps_cmd import _add_generation, _config
from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS

__all__ = ["register"]


#: The most scenes (``--scenes`` x ``--seeds``) one run takes, and the seconds a 5-object
#: scene takes on two cores (E10's per-scene time, rounded up), for the refusal's estimate.
MAX_SCENES = 2000
SCENE_SECONDS = 15


def _execution(args):
    """``--noise [--noise-pos M] [--noise-rot-deg DEG]`` as the execution error (None: no --noise)."""
    import math

    from graspsim.errors import InvalidParameterError
    from graspsim.maps.robust import POSITION_SIGMA, ROTATION_SIGMA
    from graspsim.sim.noise import ExecutionNoise

    if not args.noise:
        if args.noise_pos is not None or args.noise_rot_deg is not None:
            raise InvalidParameterError("--noise-pos / --noise-rot-deg set the execution error: give --noise too")
        return None
    pos = POSITION_SIGMA if args.noise_pos is None else args.noise_pos
    rot = math.degrees(ROTATION_SIGMA) if args.noise_rot_deg is None else args.noise_rot_deg
    if not (math.isfinite(pos) and 0 <= pos <= 0.05) or not (math.isfinite(rot) and 0 <= rot <= 45):
        raise InvalidParameterError(f"--noise-pos must be in [0, 0.05] m and --noise-rot-deg in [0, 45] deg, "
                                    f"got {pos!r} and {rot!r}")
    return ExecutionNoise(pos, math.radians(rot))


def _cmd_scene(args) -> int:
    """Draw table-top scenes of several objects, settle them in MuJoCo, render them with
    a D435-like depth camera, and clear each table grasp by grasp: segment the cloud,
    plan every object (grasps checked against the whole scene), execute the best, remove
    what was lifted, render again. Reports the grasp success rate and the share of
    objects cleared."""
    import contextlib
    from pathlib import Path

    from graspsim._atomic import check_folder, staged_folder
    from graspsim.errors import InvalidParameterError, MapDatabaseError
    from graspsim.maps.database import MapDatabase
    from graspsim.perception.segment import gap_link
    from graspsim.planning.scene_config import SceneConfig
    from graspsim.sim.trial_scene import contact_settings
    from graspsim.tabletop.clutter import FAILURE_COLUMNS, ClutterConfig, failure_rows, run_benchmark, summarize
    from graspsim.tabletop.scene_objects import OBJECT_SETS, object_set_names, prepare_objects
    from graspsim.tabletop.table_scene import MAX_OBJECTS, known_gap

    if args.objects > MAX_OBJECTS:
        raise InvalidParameterError(f"--objects must be at most {MAX_OBJECTS}, got {args.objects}")
    if args.scenes * args.seeds > MAX_SCENES:  # a scene takes seconds to a minute: refuse days of work
        raise InvalidParameterError(
            f"--scenes x --seeds is {args.scenes * args.seeds} scenes, over the {MAX_SCENES} one run takes (about "
            f"{args.scenes * args.seeds * SCENE_SECONDS / 3600:.0f} h at {SCENE_SECONDS} s a scene); split the work "
            "over runs with different --seed values")
    if args.objects_dir is not None:
        if args.object_set is not None:
            raise InvalidParameterError("give --object-set or --objects-dir, not both")
        if not Path(args.objects_dir).is_dir():
            raise InvalidParameterError(f"--objects-dir {args.objects_dir} is not a folder (a folder of mesh files "
                                        "is expected)")
        object_set = str(Path(args.objects_dir).resolve())
    else:
        from graspsim.tabletop.mesh_objects import BENCHMARK_SET

        object_set = args.object_set or BENCHMARK_SET
        if object_set not in object_set_names():
            raise InvalidParameterError(f"--object-set {object_set!r} unknown; valid: {list(object_set_names())} "
                                        "(a folder of meshes: --objects-dir)")
    render = check_folder(args.render, "render folder") if args.render else None
    saves = check_folder(args.save_scenes, "scene folder") if args.save_scenes else None
    if args.db is not None and Path(args.db).exists() and not Path(args.db).is_dir():
        raise MapDatabaseError(f"--db {args.db} is not a folder (the FS map database is a folder of maps)")
    gap = known_gap(args.kind) if args.min_gap is None else (args.min_gap or None)
    try:
        gap_link(gap)
    except InvalidParameterError:
        raise InvalidParameterError(f"--min-gap must be in (0, 0.1] m, or 0 for none, got {args.min_gap!r}") from None
    scene = scene_planning_from_args(args, SceneConfig(neighbours=not args.no_neighbours, min_gap=gap))
    gripper = gripper_from_args(args)
    robot = None
    base = robot_base_from_args(args)
    if base is not None:
        from graspsim.tabletop.clutter import ClutterRobot

        robot = ClutterRobot(name=args.robot, base=base)
    planner = None
    if args.planner != "graspsim":
        from graspsim.tabletop.planners import load_planner

        planner = load_planner(args.planner)
    cfg = ClutterConfig(scene=scene,
                        execution=_execution(args), ground_truth=args.ground_truth,
                        max_attempts=args.max_attempts, planner=planner, planner_name=args.planner, robot=robot,
                        feel=not args.no_feel, **({"good_enough": None} if args.plan_all else {}),
                        sim=contact_settings(args.contacts))
    map_cfg, quality = _config(args)
    db = MapDatabase(args.db, gripper=gripper, quality=quality, config=map_cfg)
    drawn = prepare_objects(object_set, db.gripper, progress=not args.json)  # decompositions before scene 0
    from graspsim.tabletop.clutter_stats import benchmark_seeds, per_seed

    seeds = benchmark_seeds(args.seed, args.seeds)
    # files of one seed's scene i: scene{i:03d}..., of several seeds: seed{k}_scene{i:03d}... (no overwriting)
    prefix = ["" if len(seeds) == 1 else f"seed{k}_" for k in range(len(seeds))]
    current = {"prefix": ""}
    details = []
    by_seed = {}
    # figures and saved scenes are written while the scenes run, into staging folders that
    # reach --render / --save-scenes only when every scene has run (a failure leaves them as
    # they were)
    with contextlib.ExitStack() as stack:
        render_stage = None if render is None else stack.enter_context(staged_folder(render))
        saves_stage = None if saves is None else stack.enter_context(staged_folder(saves))
        on_step = None if render_stage is None else _figure_writer(render_stage, db.gripper, current)

        def on_scene(i, scene, result):
            if saves_stage is not None:  # for 'graspsim view --scene'
                from graspsim.tabletop.table_scene import save_scene

                save_scene(scene, saves_stage / f"{current['prefix']}scene{i:03d}.json")
            details.append({"scene": i, "seed": scene.seed, **result.to_dict(),
                            "poses": [_pose(o) for o in scene.objects]})

        for k, sd in enumerate(seeds):
            current["prefix"] = prefix[k]
            by_seed[sd] = run_benchmark(args.objects, args.kind, args.scenes, sd, db=db, config=cfg,
                                        object_set=object_set, on_step=on_step, on_scene=on_scene)
    results = [r for rs in by_seed.values() for r in rs]
    s = {"kind": args.kind, "objects": args.objects, "object_set": object_set,
         "meshes": drawn if object_set not in OBJECT_SETS else None, "seed": args.seed,
         "planner": args.planner, "good_enough": cfg.good_enough, "seeds": per_seed(by_seed),
         "gripper": db.gripper.name,
         "execution_noise": None if cfg.execution is None else cfg.execution.to_dict(),
         "planned_for": {"position_sigma": cfg.planning.planner.robust.position_sigma,
                         "rotation_sigma": cfg.planning.planner.robust.rotation_sigma},
         "unseen_margin": cfg.planning.planner.robust.unseen_margin,
         "seen_between": cfg.planning.planner.seen_between, "sparse_between": cfg.scene.sparse_between,
         "shadow_depth": cfg.scene.shadow_depth if cfg.scene.min_gap is None else 0.0,  # where objects may touch
         "feature_grasps": cfg.scene.feature_grasps,
         "neighbour_check": not args.no_neighbours, "ground_truth_segmentation": args.ground_truth,
         "felt_evidence": cfg.feel, "contacts": args.contacts, "min_gap": gap,
         "budget": cfg.scene.budget, "robot": args.robot,
         "robot_base": None if robot is None else (list(args.robot_base) if args.robot_base else [-0.5, 0.0, 0.0]),
         **summarize(results), "render": None if render is None else str(render), "details": details}
    rows = [(d["scene"], len(d["objects"]), d["removed"], d["attempts"], d["successes"], d["stop"],
             f"{d['first_one_cluster']}/{d['first_seen']}") for d in details]
    gsr = s["grasp_success_rate"]
    human = (format_table(rows, ["scene", "objects", "removed", "grasps", "lifted", "stop", "one cluster"])
             + "\n\nper object (failed grasps by cause; objects left by why):\n"
             + format_table(failure_rows(s["per_object"]), list(FAILURE_COLUMNS))
             + _sources_line(s["per_source"])
             + f"\ngrasp success {s['successes']}/{s['attempts']}"
             + ("" if gsr is None else f" ({100 * gsr:.1f} %)")
             + f", cleared {s['removed']}/{s['placed']} objects ({100 * s['cleared_rate']:.1f} %)"
             + ("" if robot is None
                else f" by the {args.robot} arm (base {' '.join(f'{v:g}' for v in s['robot_base'])})")
             + (f"; over {len(seeds)} seeds GSR {s['seeds']['gsr_text']}, DR {s['seeds']['dr_text']}"
                if len(seeds) > 1 else "")
             + (f", planning {s['planning_s']['median']:.2f} s per grasp (median)"
                if s["planning_s"]["median"] is not None else ""))
    emit(s, args.json, human)
    return 0


def _sources_line(table: dict) -> str:
    """The grasps by what they were planned from, as one line ("" when none is known)."""
    if not table:
        return ""
    return "\ngrasps by source (lifted/grasps): " + ", ".join(f"{k} {v['lifted']}/{v['grasps']}"
                                                            for k, v in table.items())


def _pose(placed) -> dict:
    """An object's settled pose, in its mesh file's frame for meshes."""
    from graspsim.transforms import matrix_to_quat

    T = placed.T_world_file
    return {"name": placed.name, "pos": T[:3, 3].tolist(), "quat": matrix_to_quat(T[:3, :3]).tolist(),
            "frame": "file" if placed.spec.source == "mesh" else "object"}


def _figure_writer(folder, gripper, current: dict):
    """The per-step figure writer of ``--render``; ``current["prefix"]``: the running seed's
    file prefix."""
    from graspsim.tabletop.clutter_figure import save_step_figure

    def write(i, view, frame, plan, attempt):
        stem = f"{current['prefix']}scene{i:03d}"
        k = len(list(folder.glob(f"{stem}_step*.png")))
        save_step_figure(folder / f"{stem}_step{k:02d}.png", frame, plan, view.uv, gripper,
                         title=f"scene {i}, grasp {k + 1}: {attempt.cause} (score {attempt.score:.2f})")

    return write


def register(sub) -> None:
    from graspsim.cli._common import seed_value

    with command(sub, "scene", run=_cmd_scene,
                 help="clutter removal on simulated table-top scenes seen by a depth camera",
                 glossary=("robust score", "known / familiar / build")) as p:
        p.add_argument("--objects", type=whole_number(1), default=5, help="objects per scene (5)")
        p.add_argument("--scenes", type=whole_number(1), default=1, help="scenes (1)")
        p.add_argument("--kind", choices=["pile", "packed"], default="pile",
                       help="pile: dropped and settled; packed: upright side by side, >= 1 cm apart (pile)")
        p.add_argument("--min-gap", type=float, default=None, metavar="M",
                       help="least gap [m] between any two objects, which segmentation may rely on (0: none; default: "
                       "the kind's: packed 0.01, pile none)")
        p.add_argument("--object-set", default=None, metavar="SET",
                       help="objects drawn from this set: household (the default: shipped real meshes), random, "
                       "household-tuning, household-heldout, random-tuning, random-heldout, primitives, analogs, "
                       "meshes, mixed")
        p.add_argument("--objects-dir", default=None, metavar="DIR",
                       help="objects drawn from a folder of your mesh files (.stl .obj .ply .off .glb .gltf; an "
                       "optional objects.json or objects.toml gives per-file scale, mass or density, friction)")
        p.add_argument("--noise", action="store_true", help="execution error: the arm misses each pose by Gaussian "
                       "errors at the TCP (sigmas: --noise-pos, --noise-rot-deg); the planner's robust score assumes "
                       "the same error")
        p.add_argument("--noise-pos", type=float, default=None, metavar="M",
                       help="the execution error's position sigma [m] (0.003)")
        p.add_argument("--noise-rot-deg", type=float, default=None, metavar="DEG",
                       help="the execution error's rotation sigma [deg] (2)")
        p.add_argument("--no-neighbours", action="store_true",
                       help="ablation: check grasps against the object's own points only")
        p.add_argument("--ground-truth", action="store_true",
                       help="ablation: segment by the simulator's object labels instead of clustering")
        p.add_argument("--no-feel", action="store_true",
                       help="ablation: a grasp that started in collision with an object tells the next plans nothing "
                            "but its contacts (default: its finger volume the camera did not see is kept clear of "
                            "until an attempt changes the scene; ClutterConfig.feel)")
        p.add_argument("--contacts", choices=CONTACT_MODELS, default=DEFAULT_CONTACTS,
                       help="the simulation's contact model: stiff (default: 1 ms steps, stiff pads that hold an "
                            "object of a few grams as a heavy one), or soft (2 ms steps, softer pads: the results "
                            "published before stiff became the default; graspsim.sim.contact_model)")
        p.add_argument("--max-attempts", type=whole_number(1), default=None,
                       help="grasps per scene at most (default 2 x objects + 2)")
        add_scene_planning_flags(p)
        p.add_argument("--seed", type=seed_value, default=0, help="random seed (0)")
        p.add_argument("--plan-all", action="store_true",
                       help="plan every object at every look (default: the highest objects first, until one has a "
                            "grasp whose robust score reaches 0.9, ClutterConfig.good_enough; the others when a later "
                            "look needs them)")
        p.add_argument("--seeds", type=whole_number(1), default=1,
                       help="repeat the benchmark over this many seeds (derived from --seed; 1: --seed itself) and "
                       "report GSR / DR per seed and their mean and std (the field's way)")
        add_robot_flags(p, robot_help="none: the floating gripper (default); panda: the Franka Emika Panda arm beside "
                        "the table executes each grasp, the best the arm reaches (with --gripper on its flange, "
                        "simulated as the floating gripper is)")
        p.add_argument("--planner", default="graspsim", metavar="NAME|module:function",
                       help="the grasp planner: graspsim (default: its scene planner, plans reused between "
                       "frames), graspsim-interface (the same through the planner interface), antipodal (a "
                       "geometric baseline), or module:function of your own (graspsim.tabletop.planners)")
        p.add_argument("--db", default=None, help="FS map database folder (default $GRASPSIM_DB or "
                       "~/.cache/graspsim/db)")
        p.add_argument("--render", default=None, metavar="DIR",
                       help="write a picture of every grasp (colour, depth, segments, the grasp) into DIR")
        p.add_argument("--save-scenes", default=None, metavar="DIR",
                       help="write every scene as DIR/sceneNNN.json, with --seeds > 1 as DIR/seedK_sceneNNN.json "
                        "(for 'graspsim view --scene')")
        _add_generation(p)
