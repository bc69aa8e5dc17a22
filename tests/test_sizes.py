"""Sizes, reported: modules of graspsim/ and experiments/ over ~400 lines and functions
over ~80 are listed (``pytest -rP tests/test_sizes.py`` shows the list) so a reviewer
sees them, but nothing fails on a size: size follows the concept, and a module is split
where its concepts part, not to meet a number."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODULE_GOAL = 420
FUNCTION_GOAL = 85


def _sources():
    return sorted([*(ROOT / "graspsim").rglob("*.py"), *(ROOT / "experiments").glob("*.py")])


def over_goal() -> tuple[list[str], list[str]]:
    """(modules over the goal, functions over the goal), as ``path: N lines`` lines."""
    long_modules, long_functions = [], []
    for path in _sources():
        text = path.read_text()
        rel = path.relative_to(ROOT).as_posix()
        if len(text.splitlines()) > MODULE_GOAL:
            long_modules.append(f"{rel}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > FUNCTION_GOAL:
                    long_functions.append(f"{rel}:{node.lineno} {node.name}: {n} lines")
    return long_modules, long_functions


def test_report_module_and_function_sizes():
    long_modules, long_functions = over_goal()
    print(f"modules over {MODULE_GOAL} lines: {len(long_modules)}", *long_modules, sep="\n  ")
    print(f"functions over {FUNCTION_GOAL} lines: {len(long_functions)}", *long_functions, sep="\n  ")
    assert len(_sources()) > 0  # the report ran over the sources
