"""The package's layer map, held: which part of graspsim may import which, checked on the
imports of every module (module level, inside functions and under ``TYPE_CHECKING``
alike, parsed with :mod:`ast`, nothing imported), no circle between modules, and every
package's docstring saying what it holds and what it may use.

A part is a subpackage (``graspsim.maps``) or a top-level module (``graspsim.stats``).
Lower parts never import higher ones; a new dependency between parts is a change of
this map, made here on purpose.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "graspsim"

#: The base: small modules every part may use (errors, settings checks, version, atomic writes, small
#: input files, JSON, installed files, the cache folders, the GL backend, progress bars, seeds, frames, executors,
#: statistics, the contact models' names).
BASE = frozenset({"errors", "checks", "_version", "_atomic", "_files", "_jsonable", "_resources", "_cache", "_gl",
                  "_blas", "_progress", "seeding", "transforms", "executors", "stats", "contacts"})


def _above(*parts: str) -> frozenset[str]:
    return BASE | frozenset(parts)


_GEOMETRY = _above("geometry", "primitives")
_GRIPPERS = _GEOMETRY | {"grippers", "grades"}
_MAPS = _GRIPPERS | {"maps", "plots"}

#: part -> the parts it may import (besides itself). Lowest first.
LAYERS: dict[str, frozenset[str]] = {
    **dict.fromkeys(BASE, BASE),
    "geometry": BASE,                                        # point spacing, the table plane, cameras, boxes
    "primitives": _above("geometry"),                        # shapes, their samples and signed distance
    "grippers": _above("geometry"),                          # the gripper spec and the registry
    "grades": _above("geometry", "primitives", "grippers"),  # the paper's grade and the fitted ones
    "maps": _GRIPPERS,                                       # graspability maps: generate, store, score
    "plots": _GRIPPERS | {"maps"},                           # figures of maps and designs
    "perception": _GEOMETRY,                                 # cloud input and identification
    "planning": _GRIPPERS | {"maps", "perception"},          # cloud -> ranked grasps, scenes
    "sim": _MAPS,                                            # MuJoCo trials of one object
    "robots": _MAPS | {"sim"},                               # an arm: reachability, execution
    "tabletop": _MAPS | {"perception", "planning", "sim", "robots"},  # table-top scenes, camera, clutter
    "calibration": _MAPS | {"perception", "planning", "sim"},  # grades against simulated trials
    "viewer": _MAPS | {"perception", "planning", "sim", "robots", "tabletop"},
    "envs": _MAPS | {"perception", "planning", "sim", "robots", "tabletop"},
    "apps": _MAPS | {"perception", "planning", "sim", "robots", "tabletop", "calibration"},  # demo, design, campaign
    "cli": _MAPS | {"perception", "planning", "sim", "robots", "tabletop", "calibration", "viewer", "envs", "apps",
                    "graspsim"},
    "__main__": frozenset({"cli"}),
    # the package face: names resolved lazily; it registers the envs
    "graspsim": BASE | {"envs"},
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in PKG.rglob("*.py"):
        parts = ["graspsim", *p.relative_to(PKG).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        if ".".join(parts[:i]) in MODULES:
            return ".".join(parts[:i])
    return None


def imports_of(module: str, source: str) -> set[str]:
    """The graspsim modules ``module`` imports anywhere in ``source``."""
    is_pkg = MODULES[module].name == "__init__.py" if module in MODULES else False
    out = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                here = module.split(".") if is_pkg else module.split(".")[:-1]
                here = here[:len(here) - (node.level - 1)]
                base = ".".join(here + ([node.module] if node.module else []))
            subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES]
            names = subs if len(subs) == len(node.names) else [base, *subs]
        else:
            continue
        for n in names:
            r = _resolve(n) if n.split(".")[0] == "graspsim" else None
            if r is not None and r != module:
                out.add(r)
    return out


def part(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "graspsim"


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    bad = []
    for mod, deps in graph.items():
        mine = part(mod)
        allowed = LAYERS.get(mine)
        if allowed is None:
            bad.append(f"{mod}: part {mine!r} is not in the layer map")
            continue
        bad += [f"{mod} imports {dep} ({part(dep)!r} is not below {mine!r})"
                for dep in sorted(deps) if part(dep) != mine and part(dep) not in allowed]
    return bad


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return {m: imports_of(m, p.read_text()) for m, p in MODULES.items()}


def test_no_module_imports_a_part_above_its_own(graph):
    assert layer_violations(graph) == []


def test_no_import_circles(graph):
    assert circles(graph) == []


def test_the_checks_trip():
    """A forbidden import and a circle are found, whether at module level or in a function."""
    g = {"graspsim.maps.graspmap": imports_of("graspsim.maps.graspmap",
                                             "def f():\n    from graspsim.planning.planner import plan\n"),
         "graspsim.planning.planner": {"graspsim.maps.graspmap"}}
    assert layer_violations(g) == ["graspsim.maps.graspmap imports graspsim.planning.planner "
                                   "('planning' is not below 'maps')"]
    assert circles(g) == [["graspsim.maps.graspmap", "graspsim.planning.planner"]]


def test_every_package_says_what_it_holds_and_may_use():
    for init in sorted(PKG.rglob("__init__.py")):
        if init.parent == PKG:
            continue
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        assert "May use" in doc, f"{init.relative_to(PKG.parent)}: its docstring must say what it may use"


def test_docs_architecture_states_this_map():
    """docs/architecture.md's layer table says what LAYERS says: one row per part, its
    last cell the parts it may import besides the base (and the base's own list)."""
    text = (PKG.parent / "docs" / "architecture.md").read_text()
    layers = text[text.index("## The layers"):text.index("## Where is X decided?")]
    rows = {}
    for line in layers.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| `") and len(cells) == 3:
            rows[cells[0].strip("`")] = set(re.findall(r"`(\w+)`", cells[2]))
    base_line = layers[layers.index("**The base**"):layers.index("Lowest first")]
    assert set(re.findall(r"`(\w+)`", base_line)) == BASE
    higher = {p: allowed - BASE - {p} for p, allowed in LAYERS.items() if p not in BASE}
    assert rows == higher


#: Base names more than one module may have: a package's ``__init__`` and ``__main__``
#: (Python's own names for a package's face and its ``-m`` entry), nothing else.
SHARED_BASE_NAMES = frozenset({"__init__", "__main__"})


def shared_base_names(paths) -> dict[str, list[str]]:
    """Base names (``camera`` of ``graspsim/geometry/camera.py``) that several modules
    have, each with its modules, outside :data:`SHARED_BASE_NAMES`."""
    by_name: dict[str, list[str]] = {}
    for p in paths:
        by_name.setdefault(Path(p).stem, []).append(str(p))
    return {n: sorted(ps) for n, ps in sorted(by_name.items()) if len(ps) > 1 and n not in SHARED_BASE_NAMES}


def test_no_two_modules_share_a_base_name():
    """A base name says what a module is about wherever it is read (a traceback, a
    ``git log --stat``, an editor tab): two modules with one name in two packages (a
    viewer's camera and the pinhole camera, a trial's scene and a table-top scene)
    are two concepts a reader confuses."""
    assert shared_base_names(p.relative_to(PKG.parent) for p in MODULES.values()) == {}


def private_imports(graph: dict[str, set[str]]) -> list[str]:
    """Imports of another part's private module (a ``_name`` module inside a package):
    what a package offers other parts is its public modules. The base's own private
    modules (``graspsim._atomic``) are parts in themselves, open to all."""
    bad = []
    for mod, deps in graph.items():
        for dep in sorted(deps):
            names = dep.split(".")
            if len(names) > 2 and names[-1].startswith("_") and part(dep) != part(mod):
                bad.append(f"{mod} imports {dep}, a private module of {part(dep)!r}")
    return bad


def _module_strings(module: str, source: str) -> set[str]:
    """graspsim modules a module names in a string (``importlib.import_module(name)``)."""
    return {n.value for n in ast.walk(ast.parse(source))
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in MODULES
            and n.value != module}


def test_no_module_imports_another_parts_private_module(graph):
    named = {m: graph[m] | _module_strings(m, p.read_text()) for m, p in MODULES.items()}
    assert private_imports(named) == []


def test_the_name_and_privacy_checks_trip():
    assert shared_base_names(["graspsim/viewer/camera.py", "graspsim/geometry/camera.py",
                              "graspsim/a/__init__.py", "graspsim/b/__init__.py"]) == {
        "camera": ["graspsim/geometry/camera.py", "graspsim/viewer/camera.py"]}
    g = {"graspsim.maps.warmup": {"graspsim.grades._pads", "graspsim.maps._kernel", "graspsim._atomic"}}
    assert private_imports(g) == ["graspsim.maps.warmup imports graspsim.grades._pads, a private module of 'grades'"]
    assert _module_strings("graspsim.maps.warmup", 'K = ("graspsim.maps.kernels", "x")') == {"graspsim.maps.kernels"}
