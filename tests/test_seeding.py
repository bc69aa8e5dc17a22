"""The one seed rule (graspsim.seeding): stable, keyed by names and indices."""

import subprocess
import sys

import numpy as np
import pytest

from graspsim.calibration import case_seed
from graspsim.errors import InvalidParameterError
from graspsim.seeding import derived_seed, name_key, rng_for, seed_sequence


def test_names_key_streams_and_anagrams_differ():
    assert name_key("duck_toy") != name_key("toy_duck")  # a sum of character codes would tie them
    assert rng_for(0, "duck_toy").random() != rng_for(0, "toy_duck").random()
    assert rng_for(0, "a").random() != rng_for(1, "a").random()
    assert rng_for(7, "a", 2).random() == rng_for(7, "a", 2).random()


def test_integer_keys_are_numpys_list_seeding():
    # rng_for(seed, k) is np.random.default_rng([seed, k]), and rng_for(seed) default_rng(seed)
    assert rng_for(3, 15).random() == np.random.default_rng([3, 15]).random()
    assert rng_for(20180101).random() == np.random.default_rng(20180101).random()
    assert seed_sequence(1, "x").entropy == [1, name_key("x")]


def test_stable_across_processes_and_the_calibration_case_seed():
    code = "from graspsim.seeding import derived_seed; print(derived_seed(5, 'glue_bottle/adapted'))"
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert int(other) == derived_seed(5, "glue_bottle/adapted") == case_seed(5, "glue_bottle/adapted")
    assert 0 <= derived_seed(0, "a") < 2**32


def test_negative_seeds_are_refused():
    with pytest.raises(InvalidParameterError, match="seeds and keys must be >= 0"):
        rng_for(-1, "a")


def test_no_second_seed_rule_in_the_tree():
    """Seeds are derived only by graspsim.seeding: no offsets (``seed + 1``), sums of
    character codes, hashes or SeedSequence lists spelled out elsewhere."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    bad = re.compile(r"sum\(map\(ord|default_rng\(\[|\.generate_state\(|SeedSequence\(\[?[a-z_.]*seed"
                     r"|seed\s*[-+*^%]\s*\d|hashlib\.\w+\((seed|key|name)\b")
    found = [f"{p.relative_to(root)}:{i}: {line.strip()}"
             for p in sorted([*(root / "graspsim").rglob("*.py"), *(root / "experiments").glob("*.py")])
             if p.name != "seeding.py"
             for i, line in enumerate(p.read_text().splitlines(), 1) if bad.search(line)]
    assert not found, "seeds derived outside graspsim.seeding:\n" + "\n".join(found)
