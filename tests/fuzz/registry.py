"""The fuzz properties by name: what each generates, what it checks, how many examples
the CI suite runs. ``tests/fuzz/test_fuzz.py`` and ``experiments/fuzz_long.py`` both
run them from here, so the nightly run checks exactly what CI checks, only more often.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass

from hypothesis import HealthCheck, given, settings
from hypothesis.configuration import set_hypothesis_home_dir

# Hypothesis keeps caches (source constants, unicode tables) in ./.hypothesis even with
# no example database: the fuzz runs keep theirs in a temporary folder, removed at exit,
# so they write nothing into the checkout.
_HOME = tempfile.mkdtemp(prefix="graspsim-hypothesis-")
set_hypothesis_home_dir(_HOME)
atexit.register(shutil.rmtree, _HOME, ignore_errors=True)


@dataclass(frozen=True)
class Property:
    """name; category: the input kind it counts under; strategy: () -> SearchStrategy
    of cases; check: case -> outcome label (raises on a violated property);
    examples: generated inputs per CI run; per_case: inputs one case counts for."""

    name: str
    category: str
    strategy: Callable
    check: Callable[[dict], str]
    examples: int
    per_case: int = 1


PROPERTIES: dict[str, Property] = {}


def register(name: str, category: str, strategy: Callable, examples: int, per_case: int = 1):
    def deco(check):
        PROPERTIES[name] = Property(name, category, strategy, check, examples, per_case)
        return check
    return deco


def all_properties() -> dict[str, Property]:
    from . import props_api, props_cli, props_db, props_memory, props_newer  # noqa: F401  (they register themselves)

    return PROPERTIES


def hypothesis_settings(examples: int, *, derandomize: bool = True) -> settings:
    """Settings of a fuzz run: no deadline (a loaded machine), no example database
    (deterministic: the same inputs every run), no health checks about slow strategies."""
    return settings(max_examples=examples, derandomize=derandomize, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck), print_blob=True)


def ci_test(name: str):
    """A pytest test running property ``name`` with its CI example count."""
    prop = all_properties()[name]

    @hypothesis_settings(prop.examples)
    @given(case=prop.strategy())
    def test(case):
        prop.check(case)

    test.__name__ = f"test_{name}"
    test.__doc__ = prop.check.__doc__
    return test
