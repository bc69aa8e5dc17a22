"""The row helpers of perception.prepare are numpy's row-wise unique, faster: the same
rows in the same order (median spacing, voxel thinning and the MVBB depend on them)."""

import numpy as np

from graspsim.geometry.spacing import median_spacing
from graspsim.perception.prepare import distinct_rows, first_of_each_row


def test_distinct_rows_is_numpys_unique_rows():
    rng = np.random.default_rng(0)
    p = np.round(rng.normal(0, 0.05, (600, 3)), 3)
    p = np.concatenate([p, p[:150], p[::7]])[rng.permutation(600 + 150 + 86)]
    assert distinct_rows(p).tobytes() == np.unique(p, axis=0).tobytes()
    assert len(distinct_rows(p)) == len(np.unique(p, axis=0)) < len(p)
    assert distinct_rows(np.zeros((0, 3))).shape == (0, 3)


def test_first_of_each_row_is_numpys_first_occurrences():
    rng = np.random.default_rng(1)
    keys = np.floor(rng.normal(0, 0.05, (900, 3)) / 0.01).astype(np.int64)
    want = np.sort(np.unique(keys, axis=0, return_index=True)[1])
    assert np.array_equal(first_of_each_row(keys), want)
    wide = keys * np.int64(10**6)  # ranges too large to pack into one integer
    assert np.array_equal(first_of_each_row(wide), want)
    assert first_of_each_row(np.zeros((0, 3), np.int64)).shape == (0,)


def test_median_spacing_counts_repeated_points_once():
    g = np.stack(np.meshgrid(*[np.arange(6) * 0.01] * 3), -1).reshape(-1, 3)
    assert abs(median_spacing(np.concatenate([g, g, g[:50]])) - 0.01) < 1e-12
