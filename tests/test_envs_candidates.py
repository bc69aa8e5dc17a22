"""The selection environment's pooled map database: its pool is drawn by the seed rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspsim.envs.candidates import PooledDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Sphere

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    root = tmp_path_factory.mktemp("pooldb")
    PooledDatabase(root, config=FAST).build([Sphere(0.03)])
    return root


def _pool(root, seed: int, size: int = 40) -> np.ndarray:
    db = PooledDatabase(root, config=FAST, pool_size=size, seed=seed)
    (entry,) = db.entries()
    return db.load_entry(entry, accepted_only=True).wrist_position


def test_pool_is_stable_for_a_seed_and_changes_with_it(root):
    full = PooledDatabase(root, config=FAST).load_entry(PooledDatabase(root, config=FAST).entries()[0],
                                                        accepted_only=True)
    assert len(full) > 40
    a, b, c = _pool(root, 0), _pool(root, 0), _pool(root, 1)
    assert len(a) == 40
    np.testing.assert_array_equal(a, b)           # the same pool in every database (and process)
    assert not np.array_equal(np.sort(a, axis=0), np.sort(c, axis=0))  # another seed, another pool
    # the pool is a subset of the map's accepted grasps
    assert {tuple(r) for r in a} <= {tuple(r) for r in full.wrist_position}
