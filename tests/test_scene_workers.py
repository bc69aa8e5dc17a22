"""Scene identification speed (issue 17): robust identification on a bounded point
count (``IdentifyConfig.fit_points``; paper mode never downsamples), and a scene's
segments identified on worker processes with the same result as in this process."""

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.perception.identify import identify
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.scene import SCENE_FIT_POINTS, SceneConfig
from graspsim.perception.scene_workers import identify_segments, scene_workers
from graspsim.primitives import Box, Cylinder, Sphere, synthetic_cloud
from graspsim.transforms import make_transform


def _cloud(shape, seed: int, resolution: float = 0.0015) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = make_transform(np.eye(3), [0.1 * seed, 0.0, 0.05])
    return synthetic_cloud(shape, rng, resolution=resolution, noise=0.0005, T_world_obj=T).points


def test_robust_identification_fits_at_most_fit_points_and_paper_mode_never_downsamples():
    pts = _cloud(Cylinder(0.03, 0.12), 1)
    assert len(pts) > 3000
    r = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(fit_points=800))
    assert r.downsampling is not None and r.downsampling.used_points <= 800
    assert r.downsampling.input_points == len(pts) == r.n_points
    assert [p.shape.value for p in r.parts] == ["cylinder"]
    assert math.isclose(r.parts[0].dims["radius"], 0.03, abs_tol=0.002)
    idx = r.parts[0].indices  # still every input point of the part's voxels
    assert idx.max() < len(pts) and len(idx) > 0.9 * len(pts)
    off = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(fit_points=None))
    assert off.downsampling is None  # opted out: every point (below max_points)
    paper = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig.preset("paper", fit_points=800))
    assert paper.downsampling is None
    assert IdentifyConfig().point_limit == 20000 == IdentifyConfig.preset("paper", fit_points=800).point_limit
    # scenes identify their segments on at most SCENE_FIT_POINTS unless told otherwise
    assert SceneConfig().planner.identify.point_limit == SCENE_FIT_POINTS == 1000
    for bad in (100, 999.5, "many", True):
        with pytest.raises(InvalidParameterError, match="fit_points"):
            IdentifyConfig(fit_points=bad)


def test_segments_identified_on_workers_match_this_process():
    segs = [_cloud(Box(0.04, 0.05, 0.08), 2, 0.004), _cloud(Sphere(0.03), 3, 0.004),
            _cloud(Cylinder(0.02, 0.1), 4, 0.004), np.zeros((5, 3))]  # the last: too few points
    cfg = IdentifyConfig()

    def run(workers):
        rngs = np.random.default_rng(11).spawn(len(segs))
        return identify_segments(segs, rngs, cfg, workers)

    here, there = run(1), run(2)
    assert here[-1][0] is None and "points" in here[-1][1] and there[-1][1] == here[-1][1]
    for (a, _), (b, _) in zip(here[:-1], there[:-1]):
        assert a.status == b.status and len(a.parts) == len(b.parts)
        for p, q in zip(a.parts, b.parts):
            assert p.shape == q.shape and p.dims == q.dims
            np.testing.assert_array_equal(p.T_world_obj, q.T_world_obj)
            np.testing.assert_array_equal(p.indices, q.indices)
    assert [p.shape.value for p in here[1][0].parts] == ["sphere"]
    with pytest.raises(InvalidParameterError, match="one generator per segment"):
        identify_segments(segs, [np.random.default_rng(0)], cfg, 1)


def test_worker_count_is_validated():
    assert scene_workers(1) == 1 and scene_workers(3) == 3 and scene_workers(None) >= 1
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InvalidParameterError, match="workers"):
            scene_workers(bad)
        with pytest.raises(InvalidParameterError, match="workers"):
            SceneConfig(workers=bad)
