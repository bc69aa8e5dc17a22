"""Helpers shared by the subcommands: JSON summaries, tables, progress bars."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from graspsim._progress import progress

__all__ = ["command", "emit", "add_json_flag", "add_units_flag", "add_object_cloud_flags", "add_executor_flags",
           "seed_value", "whole_number",
           "executor_from_args", "format_table", "dims_text", "add_db_flag", "progress", "add_gripper_flag",
           "gripper_from_args", "VARIANT_HELP", "GLOSSARY", "glossary", "with_glossary"]


#: The words the commands print, defined once: the README's glossary says the same (a
#: test checks that every term is there), and the --help of each command that prints a
#: term ends with its definition (:func:`glossary`).
GLOSSARY = {
    "grade": "the paper's quality of a grasp, 0 to 1 (force closure and stability of its two contacts); "
             "'accepted' grasps have grade > 0.7",
    "FS map": "full-scale map: every collision-free grasp of the gripper on one shape primitive (a box, "
              "cylinder, sphere, cone or half-toroid of given size), graded; the FS map database stores them",
    "SR / VR": "surface rate / volume rate (the paper's eqs. 7-8): the share of the object's surface patches "
               "touched by some grasp, and of the voxels that can hold the wrist holding some grasp's wrist",
    "known / familiar / build": "how a primitive found in a cloud gets its map: known = a stored FS map of the "
                                "same size (within 3 % on every dimension), used as is; familiar = the nearest "
                                "stored map of the same primitive, scaled to its size; build = none near enough, "
                                "so an FS map is built (and stored)",
    "robust score": "the chance a grasp succeeds when the arm misses the pose by a typical error (3 mm / 2 deg): "
                    "the share of perturbed poses that stay clear of the observed points, the object and the "
                    "table with both contacts on the pads, times the calibrated success of the contacts; 0 when "
                    "the gripper touches the cloud; the default ranking",
    "feasible": "a pose whose gripper does not start in collision (with the object, or blocked by the table); "
                "success rates count feasible poses, start collisions are counted apart",
}


def glossary(*terms: str) -> str:
    """An epilog defining ``terms`` (keys of :data:`GLOSSARY`) for a command's --help."""
    import textwrap

    return "terms:\n" + "\n".join(textwrap.fill(f"{t}: {GLOSSARY[t]}", 88, initial_indent="  ",
                                                 subsequent_indent="      ") for t in terms)


def _help_formatter():
    import argparse

    class Formatter(argparse.HelpFormatter):
        """argparse's formatter, but a glossary epilog keeps its lines (one term a paragraph)."""

        def _fill_text(self, text, width, indent):
            return text if text.startswith("terms:\n") else super()._fill_text(text, width, indent)

    return Formatter


def with_glossary(p, *terms: str) -> None:
    """End ``p``'s --help with the definitions of ``terms`` (the words its output uses)."""
    p.epilog = glossary(*terms)
    p.formatter_class = _help_formatter()


def add_json_flag(p) -> None:
    p.add_argument(
        "--json", action="store_true", help="print one JSON summary object as the last line"
    )


@contextmanager
def command(sub, name: str, *, run, glossary: Iterable[str] = (), **parser_kw) -> Iterator:
    """A subcommand's parser (``sub.add_parser(name, **parser_kw)``), for the ``with``
    body to add the command's own options to; then what every command has: ``--json``
    (listed last in --help), the glossary of the words its output uses, and ``run``, the
    function the command runs (returning its exit status). The --help description is
    ``run``'s docstring unless ``description`` is given: what the command does is said
    once, beside the code that does it."""
    import inspect

    parser_kw.setdefault("description", inspect.getdoc(run))
    p = sub.add_parser(name, **parser_kw)
    yield p
    add_json_flag(p)
    if glossary:
        with_glossary(p, *glossary)
    p.set_defaults(func=run)


def add_units_flag(p, widest: str = "wider than 2 m") -> None:
    """``--units``; a cloud ``widest`` is refused (perception's check)."""
    p.add_argument("--units", choices=["m", "cm", "mm"], default="m",
                   help=f"unit of the cloud's coordinates, converted to metres (default m; a cloud "
                   f"{widest} is refused as probably mm or cm)")


def add_budget_flag(p) -> None:
    """``--budget ENOUGH:PER_SEGMENT``, a scene's planning effort per object (read with
    :func:`budget_from_args`)."""
    p.add_argument("--budget", default="", metavar="ENOUGH:PER_SEGMENT",
                   help="planning effort per object: its planning stops once ENOUGH grasps score above 0 or "
                   "PER_SEGMENT grasps per part are scored (default: SceneConfig's, 32:200); a smaller budget plans "
                   "faster and chooses from fewer grasps (the planning-effort study in docs/results.md measures both)")


def budget_from_args(args) -> dict:
    """The ``SceneConfig`` fields ``--budget`` sets ({}: the defaults); a malformed budget
    is an :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.errors import InvalidParameterError
    from graspsim.planning.scene_config import budget_fields

    try:
        return budget_fields(args.budget)
    except InvalidParameterError as err:
        raise InvalidParameterError(f"--budget: {err}") from None


def add_unseen_margin_flag(p, help: str | None = None) -> None:
    """``--unseen-margin [M]``, the robust score's margin against an object's unseen back
    (read with :func:`unseen_margin_value`); ``help``:
    the command's own text (default: the scene commands')."""
    p.add_argument("--unseen-margin", type=float, nargs="?", const=True, default=None, metavar="M",
                   help=help or "with the camera's place known: a grasp whose far finger comes within M [m] of the "
                   "object's own fitted back, in space the camera did not see, scores less (by the distance's share "
                   "of M) and wider openings are tried for it (default and alone: the measured 0.02 m; 0: none; "
                   "RobustConfig.unseen_margin); fewer start collisions with an object's unseen back "
                   "(docs/scenes.md)")


def unseen_margin_value(args, *, none: bool = False) -> float | None:
    """``--unseen-margin`` as metres (the flag alone: the measured
    :data:`~graspsim.maps.robust.UNSEEN_MARGIN`), None when not given; a margin outside
    (0, 0.1] m -- [0, 0.1] with ``none`` (a command whose default has a margin: 0 turns it
    off) -- is an :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.errors import InvalidParameterError

    m = getattr(args, "unseen_margin", None)
    if m is None:
        return None
    if m is True:  # the flag alone (argparse's const: not a string, so not converted)
        from graspsim.maps.robust import UNSEEN_MARGIN

        m = UNSEEN_MARGIN
    from graspsim.planning.scene_config import MAX_UNSEEN_MARGIN

    if not (math.isfinite(m) and (0 <= m if none else 0 < m) and m <= MAX_UNSEEN_MARGIN):
        raise InvalidParameterError(f"--unseen-margin must be in {'[0' if none else '(0'}, {MAX_UNSEEN_MARGIN:g}] m "
                                    f"(alone: the measured 0.02{'; 0: none' if none else ''}), got {m!r}")
    return float(m)


def add_seen_between_flag(p) -> None:
    """``--seen-between N``, the points of its own segment a scene grasp must close on
    (read with :func:`scene_planning_from_args`); its help names the measured
    :data:`~graspsim.planning.observed.SEEN_BETWEEN` (not imported: building the parser
    stays light)."""
    p.add_argument("--seen-between", default=None, metavar="N",
                   help="a grasp must have at least N of its object's seen points between its pads, so that it "
                   "closes on what the camera saw and not on a fitted part's extrapolation (default: the measured "
                   "5; 0: off; PlannerConfig.seen_between, docs/scenes.md)")


def add_sparse_between_flag(p) -> None:
    """``--sparse-between N``: a scene grasp closing on fewer of its own segment's points
    keeps a share of its score (read with :func:`scene_planning_from_args`; the measured
    :data:`~graspsim.planning.scene_config.SPARSE_BETWEEN` written out: building the parser
    stays light)."""
    p.add_argument("--sparse-between", default=None, metavar="N",
                   help="a grasp with fewer than N of its object's seen points between its pads ranks after "
                   "better-seen grasps (its score times SPARSE_SHARE; default: the measured 30; 0: off; "
                   "SceneConfig.sparse_between, docs/scenes.md)")


def add_shadow_depth_flag(p) -> None:
    """``--shadow-depth M``: the depth behind each neighbour's seen points kept clear
    (``SceneConfig.shadow_depth``, read with :func:`scene_planning_from_args`)."""
    p.add_argument("--shadow-depth", type=float, default=None, metavar="M",
                   help="where objects may touch (no --min-gap) and the camera's place is known: the space up to M [m] "
                   "behind each other object's seen points, along the camera's rays, is kept clear like the object "
                   "itself -- an object goes on behind its seen front (default: the measured 0.03; 0: off; "
                   "SceneConfig.shadow_depth, docs/scenes.md)")


def shadow_depth_value(args) -> float | None:
    """``--shadow-depth`` in metres, None when not given; outside [0, MAX_SHADOW_DEPTH] m an
    :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.errors import InvalidParameterError
    from graspsim.planning.scene_config import MAX_SHADOW_DEPTH

    m = getattr(args, "shadow_depth", None)
    if m is None:
        return None
    if not (math.isfinite(m) and 0 <= m <= MAX_SHADOW_DEPTH):
        raise InvalidParameterError(f"--shadow-depth must be in [0, {MAX_SHADOW_DEPTH:g}] m (0: off), got {m!r}")
    return float(m)


def seen_between_value(args) -> int | None:
    """``--seen-between`` as a whole number of points, None when not given; anything else
    is an :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.planning.observed import SEEN_BETWEEN

    return _points_value(args, "seen_between", SEEN_BETWEEN)


def sparse_between_value(args) -> int | None:
    """``--sparse-between`` as a whole number of points, None when not given; anything else
    is an :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.planning.scene_config import SPARSE_BETWEEN

    return _points_value(args, "sparse_between", SPARSE_BETWEEN)


def _points_value(args, name: str, measured: int) -> int | None:
    """Flag ``--NAME`` (attribute ``name``) as a whole number of points, None when not given;
    anything else is an :class:`~graspsim.errors.InvalidParameterError` naming the flag."""
    from graspsim.errors import InvalidParameterError

    v = getattr(args, name, None)
    if v is None:
        return None
    try:
        n = int(str(v).strip())
    except ValueError:
        n = -1
    if n < 0:
        raise InvalidParameterError(f"--{name.replace('_', '-')} must be a whole number of points >= 0 (the "
                                    f"measured {measured}; 0: off), got {v!r}")
    return n


def add_feature_grasps_flag(p) -> None:
    """``--feature-grasps {apart,fallback,always,never}``, where a scene segment's planning adds
    grasps on its cloud's own features (``SceneConfig.feature_grasps``, read with
    :func:`scene_planning_from_args`; the choices are
    :data:`~graspsim.planning.scene_config.FEATURE_GRASPS`, written out: building the
    parser stays light)."""
    p.add_argument("--feature-grasps", choices=["apart", "fallback", "always", "never"], default=None,
                   help="where an object whose fitted parts give too few grasps (a bowl seen as one sphere, a blob "
                   "seen as a plate) also gets grasps on its cloud's own features: fallback (default) where "
                   "objects are known to stand apart (--min-gap, or a packed scene) and elsewhere when no object "
                   "gets a grasp otherwise, apart only where they stand apart, always, or never "
                   "(SceneConfig.feature_grasps, docs/scenes.md)")


def add_scene_planning_flags(p) -> None:
    """The planning flags the scene commands (``scene``, ``plan-scene``) share:
    ``--budget``, ``--unseen-margin``, ``--seen-between``, ``--sparse-between``,
    ``--shadow-depth`` and ``--feature-grasps`` (read with :func:`scene_planning_from_args`)."""
    add_budget_flag(p)
    add_unseen_margin_flag(p)
    add_seen_between_flag(p)
    add_sparse_between_flag(p)
    add_shadow_depth_flag(p)
    add_feature_grasps_flag(p)


def scene_planning_from_args(args, scene):
    """``scene`` (a ``SceneConfig``) with ``--budget``, ``--unseen-margin``, ``--seen-between``,
    ``--sparse-between``, ``--shadow-depth`` and ``--feature-grasps`` applied
    (:func:`graspsim.planning.scene_config.with_unseen_margin`,
    :func:`~graspsim.planning.scene_config.with_seen_between`,
    :func:`~graspsim.planning.scene_config.with_sparse_between`,
    :func:`~graspsim.planning.scene_config.with_shadow_depth`,
    :func:`~graspsim.planning.scene_config.with_feature_grasps`, E10's path too); a bad
    value is an :class:`~graspsim.errors.InvalidParameterError` naming its flag."""
    from dataclasses import replace

    from graspsim.planning.scene_config import (
        with_feature_grasps,
        with_seen_between,
        with_shadow_depth,
        with_sparse_between,
        with_unseen_margin,
    )

    scene = replace(scene, **budget_from_args(args))
    scene = with_unseen_margin(scene, unseen_margin_value(args, none=True))  # the value checked, naming the flag
    scene = with_seen_between(scene, seen_between_value(args))
    scene = with_sparse_between(scene, sparse_between_value(args))
    scene = with_shadow_depth(scene, shadow_depth_value(args))
    return with_feature_grasps(scene, getattr(args, "feature_grasps", None))


class _DeprecatedAlias:
    """argparse action of an old flag name kept working: stores like the new one and says
    once on stderr that the new name is the one to use."""

    def __new__(cls, new: str):
        import argparse

        class Action(argparse.Action):
            def __call__(self, parser, namespace, values, option_string=None):
                print(f"[graspsim] note: {option_string} is deprecated (it still works); use {new}", file=sys.stderr)
                setattr(namespace, self.dest, values)

        return Action


def add_db_flag(p, help: str = "FS map database folder (default $GRASPSIM_DB or ~/.cache/graspsim/db)") -> None:
    """``--db DIR``, the database folder as every command names it (``args.db``); the
    ``db`` subcommands' old ``--root`` still works, with a deprecation note."""
    import argparse

    p.add_argument("--db", metavar="DIR", default=None, help=help)
    p.add_argument("--root", dest="db", metavar="DIR", action=_DeprecatedAlias("--db"), help=argparse.SUPPRESS)


GRIPPER_HELP = ("the gripper: festo_hgpl_25_60_a (default), franka_hand, robotiq_2f85, rethink_gripper, "
                "your gripper's model file (MJCF .xml or .urdf: measured and simulated as authored; options in "
                "a <model>.gripper.json beside it), or a JSON file of GripperSpec fields (see docs/grippers.md)")


#: The help of a gripper flag that also takes a variant of a base design.
VARIANT_HELP = ("a registered gripper (festo_hgpl_25_60_a, franka_hand, robotiq_2f85, rethink_gripper), a model "
                "file (MJCF .xml or .urdf), a spec .json, or "
                "param=value [m] varying the base gripper (e.g. finger_length=0.05)")


def add_gripper_flag(p, help: str = GRIPPER_HELP, *, flag: str = "--gripper", required: bool = False,
                     variants: bool = False) -> None:
    """The one gripper flag of every command: ``--gripper NAME|MODEL.xml|MODEL.urdf|SPEC.json``
    (or ``flag``, e.g. ``--to-gripper``), resolved by :func:`gripper_from_args` (a bad name
    or file is a one-line error, exit 2). ``variants``: it also takes ``param=value``, a
    variant of the base design that :func:`gripper_from_args` is given."""
    p.add_argument(flag, default=None, required=required, help=help,
                   metavar="NAME|MODEL.xml|SPEC.json|PARAM=M" if variants else "NAME|MODEL.xml|SPEC.json")


def gripper_from_args(args, *, flag: str = "gripper", base=None):
    """The :class:`~graspsim.grippers.spec.GripperSpec` of the gripper flag ``flag`` (the
    argparse dest; default: the Festo), resolved once. ``base``: the spec a ``param=value``
    varies (flags added with ``variants=True``; :func:`graspsim.apps.design.resolve_design`)."""
    text = getattr(args, flag, None)
    if base is not None and text is not None:
        from graspsim.apps.design import resolve_design

        return resolve_design(text, base)
    from graspsim.grippers import get_gripper

    return get_gripper(text)


ROBOTS = ("none", "panda")


def add_robot_flags(p, *, required: bool = False, robot_help: str | None = None) -> None:
    """The arm flags: ``--robot none|panda`` and ``--robot-base X Y YAW``, checked by
    :func:`robot_base_from_args` (one line, exit 2, before any work)."""
    p.add_argument("--robot", choices=ROBOTS[1:] if required else ROBOTS, default=None if required else "none",
                   required=required, help=robot_help or "the arm (panda: the Franka Emika Panda)")
    p.add_argument("--robot-base", type=float, nargs=3, metavar=("X", "Y", "YAW"),
                   help="with --robot: the arm's base on the table top, x and y [m] from the object "
                        "(which stands over the origin) and yaw [deg] (default -0.5 0 0: 0.5 m away, facing it)")


def robot_base_from_args(args) -> tuple[float, float, float] | None:
    """The arm's base (x [m], y [m], yaw [rad]) of ``--robot`` / ``--robot-base``; None for
    ``--robot none`` (a base given without an arm is an error). Bad values: one line
    naming what is valid."""
    from graspsim.errors import InvalidParameterError

    if args.robot in (None, "none"):
        if args.robot_base is not None:
            raise InvalidParameterError("--robot-base needs --robot panda")
        return None
    base = (-0.5, 0.0, 0.0) if args.robot_base is None else tuple(args.robot_base)
    if not all(math.isfinite(v) for v in base) or math.hypot(base[0], base[1]) > 2.0:
        raise InvalidParameterError(f"--robot-base {' '.join(f'{v:g}' for v in base)}: x and y [m] within 2 m of "
                                    "the object, a finite yaw [deg]")
    return (base[0], base[1], math.radians(base[2]))


def whole_number(minimum: int):
    """argparse type: a whole number >= ``minimum``."""

    def parse(text: str) -> int:
        import argparse

        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {minimum}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {minimum}, got {text!r}")
        return value

    return parse


#: argparse type of ``--seed``: a whole number >= 0 (numpy's generators take no other).
seed_value = whole_number(0)


def add_object_cloud_flags(p, cloud_help: str) -> None:
    """The object cloud and its identification, as ``identify`` and ``adapt`` take them: the
    cloud file, ``--units``, ``--viewpoint``, ``--mode``, ``--repetitions``, ``--theta`` and
    ``--seed``."""
    p.add_argument("cloud", help=cloud_help)
    add_units_flag(p)
    add_viewpoint_flag(p)
    add_mode_flag(p)
    p.add_argument("--repetitions", type=int, default=10, help="MLESAC samples per model (default 10)")
    p.add_argument("--theta", type=float, default=0.5,
                   help="split threshold theta_th of eq. (1), in (0, 1] (default 0.5)")
    p.add_argument("--seed", type=seed_value, default=0, help="random seed (default 0)")


def add_mode_flag(p) -> None:
    p.add_argument("--mode", choices=["robust", "paper"], default="robust",
                   help="identification: 'paper' applies the paper's rules alone (theta_th, 85 %% "
                   "explained); 'robust' (default) then keeps decomposing what they leave")


def add_executor_flags(p) -> None:
    g = p.add_argument_group("scale-out")
    g.add_argument("--executor", choices=["local", "ray", "serial"], default="local",
                   help="where tasks run: local processes (default), a Ray cluster, or serially")
    g.add_argument("--workers", type=int, default=None, help="local worker processes (default: cores)")
    g.add_argument("--address", default=None,
                   help="Ray cluster address ('auto', 'ray://host:10001'); default: a local Ray instance")


def executor_from_args(args):
    from graspsim.executors import make_executor

    return make_executor(args.executor, workers=args.workers, address=args.address)


def emit(summary: dict, as_json: bool, human: str | None = None) -> None:
    """Print the human-readable text, or the JSON summary as the last line."""
    from graspsim._jsonable import to_jsonable

    if as_json:
        sys.stdout.write(json.dumps(to_jsonable(summary), sort_keys=False) + "\n")
    elif human is not None:
        sys.stdout.write(human.rstrip("\n") + "\n")


def format_table(rows: Iterable[Iterable[Any]], header: Iterable[str]) -> str:
    rows = [[_fmt(c) for c in r] for r in rows]
    header = list(header)
    widths = [max(len(str(h)), *(len(r[i]) for r in rows)) if rows else len(str(h))
              for i, h in enumerate(header)]
    line = "  ".join(str(h).ljust(w) for h, w in zip(header, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(ln.rstrip() for ln in out)


def dims_text(dims: dict) -> str:
    """A primitive's dimensions as every command prints them: ``radius=3.49 cm, height=10 cm``."""
    return ", ".join(f"{k}={v * 100:.3g} cm" for k, v in dims.items())


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def add_viewpoint_flag(p) -> None:
    p.add_argument("--viewpoint", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="where a single-view cloud was seen from, in the cloud's frame [m] (the robust "
                        "score's occluded-space term; default: the cloud's own record -- a PCD VIEWPOINT "
                        "header or a camera record beside the file -- else seen all round)")


def viewpoint_from_args(args):
    """``--viewpoint`` as a (3,) array, None when not given; checked by the one viewpoint
    check every planner entry point uses (:func:`graspsim.maps.occlusion.check_viewpoint`)."""
    from graspsim.errors import InvalidParameterError
    from graspsim.maps.occlusion import check_viewpoint

    try:
        return check_viewpoint(getattr(args, "viewpoint", None))
    except InvalidParameterError as err:
        raise InvalidParameterError(f"--viewpoint: {err}") from None


def stored_text(part: dict) -> str:
    """A plan part's stored FS map and its size ratio (``PartPlan.to_dict()``), for tables."""
    s = part.get("stored")
    if not s:
        return "-"
    return f"{s['key']} (x{s['ratio']:.3f})"
