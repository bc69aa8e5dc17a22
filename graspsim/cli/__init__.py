"""The ``graspsim`` command line: argparse subcommands, one module per group.

Every subcommand accepts ``--json`` and then prints one JSON summary object as the
last line of standard output. Errors print ``graspsim: error: ...`` on stderr and exit
with status 2; interrupted runs exit with 130.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from graspsim import __version__
from graspsim.errors import GraspsimError

__all__ = ["main", "build_parser"]

# Each module defines ``register(subparsers)``; its parsers set ``func`` returning a
# summary dict.
COMMAND_MODULES: tuple[str, ...] = (
    "graspsim.cli.demo",
    "graspsim.cli.maps",
    "graspsim.cli.identify",
    "graspsim.cli.adapt",
    "graspsim.cli.trial",
    "graspsim.cli.campaign",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="graspsim",
        description=(
            "Graspability maps from shape primitives for two-jaw grippers "
            "(Eizicovits & Berman 2018), validated in MuJoCo."
        ),
    )
    parser.add_argument("--version", action="version", version=f"graspsim {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except GraspsimError as err:
        print(f"graspsim: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("graspsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
