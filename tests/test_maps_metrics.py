import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
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


def _turn(axes: np.ndarray, angle) -> np.ndarray:
    """Rotation matrices (N, 3, 3) turning by ``angle`` [rad] about unit ``axes`` (N, 3)."""
    return Rotation.from_rotvec(axes * np.reshape(angle, (-1, 1))).as_matrix()


def test_orientation_bins_are_stable_under_tiny_perturbation(rng):
    step = np.radians(11)
    R = random_rotation(rng, 500)
    q = matrix_to_quat(R)
    a = orientation_bins(q, step)
    assert a.shape == (500, 2)
    # a 1e-9 rad turn about a random axis moves no pose across a bin border (borders are
    # measure-zero: 500 poses land that close to one with probability ~1e-5)
    axes = rng.normal(size=(500, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    assert np.array_equal(orientation_bins(matrix_to_quat(_turn(axes, 1e-9) @ R), step), a)
    # q and -q are the same rotation
    assert np.array_equal(orientation_bins(-q, step), a)


def test_orientation_bins_are_step_sized(rng):
    """Turning the roll (about the approach axis) by 1.5 steps always changes the roll
    bin and never the approach bin; tilting the approach by 3 steps always changes the
    approach bin; turns of a tenth of a step keep most poses in their bins."""
    step = np.radians(11)
    R = random_rotation(rng, 300)
    a = orientation_bins(matrix_to_quat(R), step)
    rolled = orientation_bins(matrix_to_quat(R @ _turn(np.tile([0.0, 0, 1], (300, 1)), 1.5 * step)), step)
    assert np.array_equal(rolled[:, 0], a[:, 0]) and np.all(rolled[:, 1] != a[:, 1])
    tilted = orientation_bins(matrix_to_quat(_turn(R[:, :, 0], 3 * step) @ R), step)
    assert np.all(tilted[:, 0] != a[:, 0])
    small = orientation_bins(matrix_to_quat(R @ _turn(np.tile([0.0, 0, 1], (300, 1)), 0.1 * step)), step)
    assert np.mean(np.all(small == a, axis=1)) > 0.7


def test_voxel_keys_shape(cyl_map):
    k = voxel_keys(cyl_map.top_k(100))
    assert k.shape == (100, 5) and k.dtype == np.int64
