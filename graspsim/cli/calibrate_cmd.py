"""``graspsim calibrate``: how well a grade predicts simulated success, on any map files.

    graspsim calibrate MAP.h5 [MAP.h5 ...] [--per-bin N] [--grade NAME|FILE ...]
                       [--target P] [--friction MU] [--grip-force N] [--mass-scale S]
                       [--noise] [--seed S] [--threads T] [--boot B] [-o DIR] [--json]

Grasps are drawn evenly over ten grade bins among each map's poses that clear the table,
simulated with lift-and-place, and every grade is calibrated: ROC AUC, the threshold for
the target precision and the Youden threshold (bootstrap intervals), precision and
recall at 0.7, and the binned reliability curve.

A calibrated grade is a gripper's: ``pad_contact`` is the model fitted for the maps'
gripper (skipped, with a note, when none was fitted for it), and a model fitted for
another gripper than a map's is refused before anything is simulated.
"""

from __future__ import annotations

import sys
from pathlib import Path

from graspsim.cli._common import add_executor_flags, command, emit, executor_from_args, format_table, progress

__all__ = ["register", "run"]


def register(subparsers) -> None:
    from graspsim.cli._common import seed_value

    with command(subparsers, "calibrate", run=run,
                 help="calibrate grades against simulated lift-and-place trials") as p:
        p.add_argument("maps", nargs="+", metavar="FILE.h5", help="graspability map files")
        p.add_argument("--per-bin", type=int, default=20, metavar="N",
                       help="grasps per grade bin (ten bins) per map (default 20)")
        p.add_argument("--grade", action="append", metavar="NAME|FILE",
                       help="extra grade beside the map's own: pad_contact (the model fitted for the "
                            "maps' gripper) or a model .json (repeatable; default: pad_contact)")
        p.add_argument("--target", type=float, default=0.97, help="target precision (default 0.97)")
        p.add_argument("--friction", type=float, default=0.5, help="pad friction mu (default 0.5)")
        p.add_argument("--grip-force", type=float, metavar="N", help="grip force per jaw [N] (default: spec)")
        p.add_argument("--mass-scale", type=float, default=1.0, help="object mass x this (default 1)")
        p.add_argument("--noise", action="store_true", help="execution noise sigma 3 mm / 2 deg")
        p.add_argument("--seed", type=seed_value, default=0, help="seed of sampling and noise (default 0)")
        p.add_argument("--threads", type=int, metavar="T", help="native threads (default: all cores)")
        p.add_argument("--boot", type=int, default=500, metavar="B", help="bootstrap replicates (default 500)")
        p.add_argument("-o", "--out", metavar="DIR", help="write trials.npz, report.json/.md and PNGs here")
        add_executor_flags(p)


def run(args) -> int:
    """Draw grasps across the whole grade range of map files, simulate them
    (lift-and-place) and report what each grade predicts: AUC, thresholds for a target
    precision and Youden's J, precision/recall at 0.7."""
    from graspsim.calibration import CalibrationCase, SimCondition, calibrate, draw_samples, simulate_samples
    from graspsim.errors import InvalidParameterError
    from graspsim.maps import load_map

    if args.per_bin < 1:
        raise InvalidParameterError(f"--per-bin must be >= 1, got {args.per_bin}")
    if args.threads is not None and args.threads < 1:
        raise InvalidParameterError(f"--threads must be >= 1, got {args.threads}")
    if args.out:
        from graspsim._atomic import check_folder

        check_folder(args.out, "output folder")  # before the work, not after it
    names = [Path(m).stem for m in args.maps]
    if len(set(names)) != len(names):
        raise InvalidParameterError("map files must have distinct names")
    cases = []
    for path, name in zip(args.maps, names):
        gmap = load_map(path)
        cases.append(CalibrationCase(name, gmap, group=name, kind=gmap.meta.method))
    models = _grade_models(args.grade, [c.gmap for c in cases], quiet=args.json)
    from graspsim.sim import ExecutionNoise

    cond = SimCondition("cli", friction=args.friction, grip_force=args.grip_force,
                        mass_scale=args.mass_scale, noise=ExecutionNoise() if args.noise else None)
    samples = draw_samples(cases, args.per_bin, seed=args.seed)
    if not sum(len(s.rows) for s in samples):
        raise InvalidParameterError("nothing to calibrate: the maps hold no grasp that clears the table")
    bar = progress(sum(len(s.rows) for s in samples), "trials", enabled=not args.json, unit="trial")
    try:
        with executor_from_args(args) as ex:
            table = simulate_samples(samples, cond, seed=args.seed, threads=args.threads, features=(),
                                     grade_models=models, on_case=lambda _, n: bar.update(n),
                                     executor=ex)
    finally:
        bar.close()
    scores = {cases[0].gmap.meta.quality.get("name", "map grade"): "grade",
              **{m.name: f"grade_{m.name}" for m in models}}
    ref = {"at_0.7": 0.7, "at_own_threshold": {**{k: 0.7 for k in scores},
                                               **{m.name: m.threshold for m in models}}}
    rep = calibrate(table, scores, target=args.target, reference=ref, n_boot=args.boot, seed=args.seed)
    files = []
    if args.out:
        files = _write(Path(args.out), table, rep, scores)
    summary = {"maps": list(args.maps), "trials": rep.summary["trials"], "feasible": rep.summary["feasible"],
               "counts": rep.summary["counts"], "success_rate": rep.summary["success_rate"],
               "condition": cond.to_dict(), "seed": args.seed, "files": files,
               "grades": {k: {"auc": v.auc, "auc_ci": v.auc_ci, "auc_population": v.auc_population,
                              "threshold": v.threshold, "threshold_ci": v.threshold_ci,
                              "youden": v.youden, "youden_ci": v.youden_ci,
                              "at": {label: {kk: op[kk] for kk in ("threshold", "precision", "recall")}
                                     for label, op in v.at.items()}}
                          for k, v in rep.scores.items()}}
    rows = []
    for k, v in rep.scores.items():
        a = v.at["at_0.7"]
        rows.append((k, v.auc, v.threshold, v.youden, a["precision"], a["recall"]))
    human = (format_table(rows, ["grade", "AUC", f"t({args.target:g})", "Youden t", "prec@0.7", "rec@0.7"])
             + f"\n\n{rep.summary['feasible']} feasible of {rep.summary['trials']} trials, success "
             f"{100 * rep.summary['success_rate']:.1f} %" + (f"; files in {args.out}" if args.out else ""))
    emit(summary, args.json, human)
    return 0


def _grade_models(grades, maps, *, quiet: bool) -> list:
    """The extra grade models, each checked against every map's gripper (GripperError:
    a model fitted for another gripper). The default ``pad_contact`` is the maps'
    gripper's model, left out with a note when none was fitted for it."""
    from graspsim.errors import GripperError, InvalidParameterError
    from graspsim.grades import get_grade
    from graspsim.grades.models import check_gripper

    grippers = sorted({str(g.meta.gripper.get("name")) for g in maps})
    models = []
    for g in grades or ["pad_contact"]:
        if g == "pad_contact" and len(grippers) > 1:
            raise InvalidParameterError(f"pad_contact is one gripper's model; the maps are of {grippers}")
        try:
            model = get_grade(g, gripper=grippers[0]) if g == "pad_contact" else get_grade(g)
        except GripperError as err:
            if grades:  # asked for by name: an error
                raise
            if not quiet:
                print(f"note: {err}; only the maps' own grade is calibrated", file=sys.stderr)
            continue
        for gmap in maps:
            check_gripper(model, gmap.meta.gripper)
        models.append(model)
    return models


def _write(out: Path, table, rep, scores: dict) -> list[str]:
    """All five files, or none: each is written to a temporary and renamed at the end."""
    from graspsim._atomic import atomic_paths
    from graspsim.calibration.figures import plot_reliability, plot_roc
    from graspsim.calibration.outputs import library_versions, write_json, write_text
    from graspsim.errors import OutputPathError

    out.mkdir(parents=True, exist_ok=True)
    f = table.select(table.feasible)
    names = ["trials.npz", "report.json", "report.md", "reliability.png", "roc.png"]
    with atomic_paths([out / n for n in names], OutputPathError) as tmp:
        table.save(tmp[0])
        write_json(tmp[1], {**rep.to_dict(), "versions": library_versions(), "argv": sys.argv})
        write_text(tmp[2], rep.markdown())
        plot_reliability(rep.scores, tmp[3])
        plot_roc({k: (f[c], f["success"], None) for k, c in scores.items()}, tmp[4])
    return [str(out / n) for n in names]
