import numpy as np
import pytest

from graspsim.maps.generate import MapConfig, generate_fs_map
from graspsim.maps.metrics import map_rates, orientation_bins, relative_rates, voxel_keys
from graspsim.primitives import Cylinder
from graspsim.transforms import matrix_to_quat, random_rotation


@pytest.fixture(scope="module")
def cyl_map():
    return generate_fs_map(Cylinder(0.02, 0.12), config=MapConfig(surface_step=0.008))


def test_rates_are_fractions_and_shrink_with_filtering(cyl_map):
    full = map_rates(cyl_map)
    acc = map_rates(cyl_map, min_grade=0.7)
    assert 0 < acc.sr <= full.sr <= 1 and 0 < acc.vr <= full.vr <= 1
    assert full.hit_pixels <= full.pixels


def test_relative_rates_of_a_map_against_itself_are_100(cyl_map):
    r = relative_rates(cyl_map, cyl_map)
    assert r["SRN"] == pytest.approx(100) and r["VRN"] == pytest.approx(100)
    half = cyl_map.select(np.arange(0, len(cyl_map), 2))
    r = relative_rates(half, cyl_map)
    assert r["SRN"] <= 100 and r["VRN"] < 100


def test_orientation_bins_are_stable_under_tiny_perturbation(rng):
    R = random_rotation(rng, 200)
    q = matrix_to_quat(R)
    a = orientation_bins(q, np.radians(11))
    assert a.shape == (200, 2)
    assert np.array_equal(a, orientation_bins(q, np.radians(11)))


def test_voxel_keys_shape(cyl_map):
    k = voxel_keys(cyl_map.top_k(100))
    assert k.shape == (100, 5) and k.dtype == np.int64
