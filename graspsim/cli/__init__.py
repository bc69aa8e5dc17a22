"""The ``graspsim`` command line: argparse subcommands, one module per group
(``<command>_cmd.py``, so that no name repeats a library module's).

Every subcommand accepts ``--json`` and then prints one JSON summary object as the
last line of standard output. Errors print ``graspsim: error: ...`` on stderr and exit
with status 2; interrupted runs exit with 130.

Subcommand modules import nothing heavy at module level (numpy, scipy, numba, h5py,
mujoco load inside the command functions), so ``graspsim --help`` and
``graspsim COMMAND --help`` answer at once.

May use: every other part of graspsim (the top of the layer map); each command imports
its work only when it runs, so that ``graspsim --help`` stays light.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from graspsim._version import __version__
from graspsim.errors import GraspsimError

__all__ = ["main", "build_parser"]

# Each module defines ``register(subparsers)``, declaring its commands with
# ``_common.command`` (the parser, its options, --json and ``func``, the function run).
COMMAND_MODULES: tuple[str, ...] = (
    "graspsim.cli.demo_cmd",
    "graspsim.cli.maps_cmd",
    "graspsim.cli.identify_cmd",
    "graspsim.cli.adapt_cmd",
    "graspsim.cli.trial_cmd",
    "graspsim.cli.reach_cmd",
    "graspsim.cli.export_cmd",
    "graspsim.cli.campaign_cmd",
    "graspsim.cli.calibrate_cmd",
    "graspsim.cli.warmup_cmd",
    "graspsim.cli.view_cmd",
    "graspsim.cli.design_cmd",
    "graspsim.cli.scene_cmd",
    "graspsim.cli.plan_scene_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="graspsim",
        description=(
            "Graspability maps from shape primitives for two-jaw grippers "
            "(Eizicovits & Berman 2018), validated in MuJoCo. Lengths in metres; every "
            "subcommand takes --json (one JSON summary object as the last output line)."
        ),
        epilog=(
            "examples:\n"
            "  graspsim demo                                   # the whole pipeline\n"
            "  graspsim map cylinder --radius 0.02 --height 0.2 -o cyl.h5 --plot cyl.png\n"
            "  graspsim adapt cloud.pcd -o adapted.h5          # cloud -> adapted map\n"
            "  graspsim trial adapted.h5 --sample 15 --min-grade 0.7\n"
            "  graspsim campaign run maps/*.h5 --out camp --top 100 --executor ray\n"
            "  graspsim scene --objects 5 --scenes 5 --kind packed --json   # clutter removal\n"
            "  graspsim plan-scene table.pcd --viewpoint 0 0 0 -o grasps.json   # your own scene\n"
            "run 'graspsim COMMAND --help' for a command's options."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"graspsim {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    _mark_subparsers(parser)
    return parser


def _mark_subparsers(parser: argparse.ArgumentParser) -> None:
    """Each subcommand's parser records itself in the namespace (``_parser``: the
    innermost one parsed), so that an unknown option is reported with its usage."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                sub.set_defaults(_parser=sub)
                _mark_subparsers(sub)


def _parse(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """``parser.parse_args``, but an unknown option (a typo) is reported by the
    subcommand it was given to: its usage, not the top-level one."""
    args, extra = parser.parse_known_args(argv)
    if extra:
        (getattr(args, "_parser", None) or parser).error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = _parse(parser, argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    _show_compile_progress()
    try:
        if not getattr(args, "json", False):
            _show_build_progress()
        return int(args.func(args) or 0)
    except GraspsimError as err:
        print(f"graspsim: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("graspsim: interrupted", file=sys.stderr)
        return 130


def _show_build_progress() -> None:
    """A progress bar (on a terminal) for FS maps the database builds on demand (the
    planner's build case, e.g. the demo's sixth map): ``BUILD_PROGRESS``."""
    from graspsim._progress import map_build_bar
    from graspsim.maps.database import BUILD_PROGRESS

    BUILD_PROGRESS.set(map_build_bar)


class _ProgressLineHandler(logging.StreamHandler):
    """Log lines on stderr that do not break a tqdm progress bar drawn there."""

    def emit(self, record: logging.LogRecord) -> None:
        tqdm = sys.modules.get("tqdm.auto")
        if tqdm is None:
            super().emit(record)
        else:
            tqdm.tqdm.write(self.format(record), file=sys.stderr)


def _show_compile_progress() -> None:
    """The map kernels' first-run compile notice and per-kernel progress, as
    ``graspsim: ...`` lines on stderr (the library logs them; see graspsim.maps.kernels)."""
    log = logging.getLogger("graspsim.maps.kernels")
    if not any(isinstance(h, _ProgressLineHandler) for h in log.handlers):
        handler = _ProgressLineHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("graspsim: %(message)s"))
        log.addHandler(handler)
    log.setLevel(logging.INFO)
    log.propagate = False


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
