"""Size goals (STYLE.md 1, issue 14): no module of graspsim/ or experiments/ over ~400
lines, no function over ~80. The limits allow the "~"; a file that outgrows them is
split by concept, not squeezed."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE_LINES = 420
MAX_FUNCTION_LINES = 85
#: none: the robust kernel (graspsim/maps/_robust_kernel.py) is split into its passes now
EXEMPT_FUNCTIONS: set[str] = set()


def _sources():
    return sorted([*(ROOT / "graspsim").rglob("*.py"), *(ROOT / "experiments").glob("*.py")])


def test_modules_and_functions_stay_small():
    long_modules, long_functions = [], []
    for path in _sources():
        text = path.read_text()
        rel = path.relative_to(ROOT).as_posix()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            long_modules.append(f"{rel}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES and f"{rel}:{node.name}" not in EXEMPT_FUNCTIONS:
                    long_functions.append(f"{rel}:{node.lineno} {node.name}: {n} lines")
    assert not long_modules, "modules over the size goal:\n" + "\n".join(long_modules)
    assert not long_functions, "functions over the size goal:\n" + "\n".join(long_functions)
