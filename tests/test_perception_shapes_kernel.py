"""The compiled signed distances of the fitters' models
(:mod:`graspsim.primitives.sdf_kernel`) equal the numpy formulas of
:mod:`graspsim.primitives.sdf` -- NaN and the points on a model's edges included --
so identification does not change with which one runs. They agree to the bit on the
builds this was written on; the test allows a few units in the last place, because
numpy's SIMD paths (and so its last bits) differ between CPUs and versions."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graspsim.primitives import sdf as shapes
from graspsim.primitives.sdf import DIM_NAMES, sdf_local, to_local
from graspsim.primitives.sdf_kernel import model_sdf as compiled

DIMS = {"sphere": [0.03], "cylinder": [0.025, 0.1], "box": [0.03, 0.05, 0.08], "cone": [0.04, 0.015, 0.09],
        "half_toroid": [0.04, 0.012]}


def _inputs(kind: str, seed: int):
    rng = np.random.default_rng(seed)
    H = 7
    R = Rotation.random(H, random_state=seed).as_matrix()
    R[0] = np.eye(3)  # axis-aligned: points exactly on faces, axes and planes of symmetry
    t = rng.normal(size=(H, 3)) * 0.01
    t[0] = 0.0
    dims = np.asarray(DIMS[kind]) * rng.uniform(0.5, 1.5, size=(H, len(DIMS[kind])))
    dims[1, :] = 0.0  # degenerate models
    dims[2, -1] = dims[2, 0]  # a cone with equal radii, a ring with r = R
    pts = rng.normal(size=(400, 3)) * 0.05
    grid = np.array([-0.05, -0.02, -0.0, 0.0, 0.0125, 0.02, 0.04, 0.045])
    pts = np.concatenate([pts, np.stack(np.meshgrid(grid, grid, grid), -1).reshape(-1, 3),
                          [[np.nan, 0.0, 0.0], [np.inf, 0.0, 1.0]]])
    return R, t, dims, pts


@pytest.mark.parametrize("kind", list(DIM_NAMES))
def test_compiled_distances_equal_numpys(kind):
    for seed in range(3):
        R, t, dims, pts = _inputs(kind, seed)
        with np.errstate(invalid="ignore"):
            want = sdf_local(kind, to_local(R, t, pts), dims)
            got = compiled(kind, R, t, dims, pts)
        assert np.isnan(want).any() and np.isfinite(want).sum() > 0.9 * want.size
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        ok = ~np.isnan(want)
        np.testing.assert_allclose(got[ok], want[ok], rtol=1e-13, atol=1e-16)


def test_model_sdf_takes_the_compiled_path_only_for_what_it_fits():
    R, t, dims, pts = _inputs("box", 0)
    assert shapes._kernel_fits("box", R, t, dims, pts)
    assert not shapes._kernel_fits("box", R, t, dims[:, :2], pts)  # wrong dims count: numpy's path
    assert not shapes._kernel_fits("box", R.astype(np.float32), t, dims, pts)
    assert not shapes._kernel_fits("blob", R, t, dims, pts)
    with pytest.raises(ValueError, match="unknown model kind"), np.errstate(invalid="ignore"):
        shapes.model_sdf("blob", R, t, dims, pts)
