import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.collide_fcl import FclChecker
from graspsim.maps.combine import combine_maps
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Compound, Cylinder, Sphere
from graspsim.transforms import make_transform

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def ball_tab():
    c = Compound.from_parts([Sphere(0.035), Box(0.02, 0.05, 0.06)],
                            [np.eye(4), make_transform(np.eye(3), [0.045, 0, 0])])
    maps = [generate_fs_map(p, config=FAST).filter(accepted=True) for p in c.parts]
    return c, maps, combine_maps(maps, c)


def test_part_ids_kept_and_contacts_on_the_compound_surface(ball_tab):
    c, maps, m = ball_tab
    assert set(np.unique(m.part)) <= {0, 1} and len(m) > 0
    assert np.abs(c.sdf(m.contacts.reshape(-1, 3).astype(float))).max() < 1e-6
    assert len(m) <= sum(len(x) for x in maps)


def test_no_kept_grasp_collides_with_another_part(ball_tab):
    c, _, m = ball_tab
    idx = np.random.default_rng(1).choice(len(m), 200, replace=False)
    assert not FclChecker(c, G).collides_many(m.T_obj_wrist[idx], m.width[idx] + 2 * G.approach_clearance).any()


def test_stability_is_reassessed_against_the_compound_com(ball_tab):
    c, _, m = ball_tab
    gp = m.grasp_point.astype(float)
    np.testing.assert_allclose(m.stability_distance, np.linalg.norm(gp, axis=1), atol=1e-6)
    assert m.meta.quality["d_ref"] == pytest.approx(c.circumradius)


def test_one_map_per_part():
    c = Compound.from_parts([Cylinder(0.02, 0.1)], [np.eye(4)])
    with pytest.raises(InvalidParameterError):
        combine_maps([], c)


def test_empty_part_batch(ball_tab):
    from graspsim.grades.paper import QualityModel
    from graspsim.maps.combine import combine_part

    c, maps, _ = ball_tab
    out = combine_part(maps[0].select(np.zeros(0, int)), 0, c, gripper=G, quality=QualityModel(), d_ref=0.05)
    assert len(out) == 0


def test_batch_with_every_contact_buried_in_another_part():
    """A batch none of whose contacts lies on the compound's surface gives an empty map
    (it failed in the line grouping's reshape once; the envs redrew such objects)."""
    from graspsim.grades.paper import QualityModel
    from graspsim.maps.combine import combine_part

    c = Compound((Sphere(0.02), Box(0.03, 0.03, 0.2)), np.stack([np.eye(4), make_transform(np.eye(3), [0.01, 0, 0])]))
    m = generate_fs_map(Sphere(0.02), config=FAST).filter(accepted=True)
    inside = c.parts[1].sdf(m.contacts.reshape(-1, 3).astype(float) - [0.01, 0, 0]).reshape(-1, 2) < -1e-4
    buried = m.select(np.flatnonzero(inside.all(axis=1)))  # both contacts inside the box
    assert len(buried) > 0
    out = combine_part(buried, 0, c, gripper=G, quality=QualityModel(), d_ref=0.05)
    assert len(out) == 0 and out.contacts.shape == (0, 2, 3)
