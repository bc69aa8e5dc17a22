"""Every ``graspsim`` command is declared the one way (``cli._common.command``): a
description in its --help, ``--json`` as its last option, and the function it runs."""

from __future__ import annotations

import argparse

from graspsim.cli import build_parser


def _leaves(parser: argparse.ArgumentParser, path=()):
    """(command path, parser) of every parser that runs something (has ``func``)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
    if not subs:
        yield path, parser
        return
    for name, p in subs[0].choices.items():
        yield from _leaves(p, (*path, name))


def test_every_command_has_a_description_json_last_and_a_function():
    leaves = dict(_leaves(build_parser()))
    assert {("adapt",), ("scene",), ("campaign", "run"), ("db", "build"), ("warmup",)} <= set(leaves)
    for path, p in leaves.items():
        where = " ".join(path)
        assert callable(p.get_default("func")), where
        assert p.description and len(p.description) > 20, where
        options = [a for a in p._actions if a.option_strings and a.dest != "help"]  # noqa: SLF001
        if path[0] != "db":  # db's actions add their own options after --json
            assert options[-1].option_strings == ["--json"], where
        else:
            assert any(a.option_strings == ["--json"] for a in options), where
