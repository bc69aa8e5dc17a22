"""Support of a model by its cluster: extent ratios and surface coverage."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from graspsim.perception.mlesac import fit_model
from graspsim.perception.normals import estimate_local_surface
from graspsim.perception.support import extent_ratio, surface_coverage
from graspsim.primitives import Box, Cylinder, synthetic_cloud


def _cyl(h):
    return np.eye(3)[None], np.zeros((1, 3)), np.array([[0.03, h]])


def test_extent_ratio_and_coverage_of_a_cylinder(rng):
    c = synthetic_cloud(Cylinder(0.03, 0.10), rng, resolution=0.003, noise=0.0005)
    tree = cKDTree(c.points)
    assert extent_ratio("cylinder", *_cyl(0.10), c.points, 0.0005)[0] < 1.05
    assert extent_ratio("cylinder", *_cyl(0.30), c.points, 0.0005)[0] > 2.5
    cov = [surface_coverage("cylinder", *(a[0] for a in _cyl(h)), tree, radius=0.006) for h in (0.10, 0.30)]
    assert cov[0] > 0.95 and cov[1] < 0.45
    # one camera: about half of the surface
    v = synthetic_cloud(Cylinder(0.03, 0.10), rng, resolution=0.003, noise=0.0005,
                        camera=np.array([0.5, 0.0, 0.35]))
    half = surface_coverage("cylinder", *(a[0] for a in _cyl(0.10)), cKDTree(v.points), radius=0.006)
    assert 0.35 < half < 0.65


def test_a_model_much_larger_than_its_cluster_is_no_hypothesis(rng):
    """A half-toroid with R = 24 cm through a 4 x 4 x 30 cm cloud (the brush case): the
    size check makes it invalid; whatever half-toroid MLESAC keeps fits in the cluster."""
    c = synthetic_cloud(Box(0.04, 0.04, 0.30), rng, resolution=0.005, noise=0.001,
                        camera=np.array([0.4, 0.3, 0.2]))
    R = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])  # ring plane through the long edge
    t = np.array([[0.0, -0.24, 0.0]])
    assert extent_ratio("half_toroid", R, t, np.array([[0.24, 0.02]]), c.points, 0.001)[0] > 2.5
    n = estimate_local_surface(c.points).normals
    unchecked = [fit_model("half_toroid", c.points, n, np.random.default_rng(s), repetitions=30, sigma=0.001)
                 for s in range(3)]
    assert max(extent_ratio("half_toroid", f.R[None], f.t[None], f.dims[None], c.points, 0.001)[0]
               for f in unchecked) > 2.5  # what MLESAC picks without the check
    for seed in range(3):
        fit = fit_model("half_toroid", c.points, n, np.random.default_rng(seed), repetitions=30, sigma=0.001,
                        max_extent_ratio=2.5)
        if fit is not None:
            assert extent_ratio("half_toroid", fit.R[None], fit.t[None], fit.dims[None], c.points, 0.001)[0] <= 2.5
