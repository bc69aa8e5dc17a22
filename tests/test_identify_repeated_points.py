"""A fixed-size cloud sampled with replacement (GraspPose-v0's observation when the sensor
saw fewer points) repeats points: the spacing that links a continuous surface must count
each location once, or every repeat reads as zero spacing and a sphere is 'not one
continuous surface'."""

import numpy as np

from graspsim.geometry.spacing import median_spacing
from graspsim.perception import IdentifyConfig, identify
from graspsim.perception.identify import IdentificationStatus
from graspsim.primitives import Sphere, synthetic_cloud


def test_repeated_points_do_not_shrink_the_spacing():
    pts = synthetic_cloud(Sphere(0.03), np.random.default_rng(0), resolution=0.006, noise=0.0005).points
    rng = np.random.default_rng(1)
    resampled = np.concatenate([pts, pts[rng.choice(len(pts), 2 * len(pts), replace=True)]])
    assert median_spacing(resampled) == median_spacing(pts) > 0.002
    assert median_spacing(np.zeros((5, 3))) == 0.0


def test_a_sphere_sampled_with_replacement_is_identified():
    pts = synthetic_cloud(Sphere(0.03), np.random.default_rng(0), resolution=0.006, noise=0.0005).points
    assert len(pts) < 512
    cloud = pts[np.random.default_rng(2).choice(len(pts), 512, replace=True)]
    for mode in ("robust", "paper"):
        ident = identify(cloud, rng=np.random.default_rng(3), config=IdentifyConfig.preset(mode))
        assert ident.status is IdentificationStatus.IDENTIFIED, (mode, [p.reason for p in ident.unidentified])
        assert [p.primitive().kind for p in ident.parts] == ["sphere"]
