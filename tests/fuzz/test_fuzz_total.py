"""Fuzz: how many generated inputs the suite ran (runs last: files run in name order)."""

import pytest

from .harness import COUNTS
from .registry import all_properties

pytestmark = pytest.mark.slow

#: The suite's size: generated bad or extreme inputs per CI run (issue 13: at least 500).
MIN_INPUTS = 500


def test_generated_input_count(request, capsys):
    """The suite's size; the count by category is printed with ``-v`` (``-q``'s dots stay
    one line) and is in the test's report either way (``record_property``)."""
    expected = {p.category for p in all_properties().values()}
    if not expected <= set(COUNTS):
        pytest.skip("part of the fuzz suite was deselected: nothing to count")
    request.node.user_properties += sorted(COUNTS.items())
    if request.config.get_verbosity() > 0:
        with capsys.disabled():
            print("\n  fuzz inputs by category:")
            for k, v in sorted(COUNTS.items()):
                print(f"    {v:5d}  {k}")
            print(f"    {sum(COUNTS.values()):5d}  in all")
    assert sum(COUNTS.values()) >= MIN_INPUTS, dict(COUNTS)
