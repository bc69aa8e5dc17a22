import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps import GraspabilityMap, MapMeta
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box


@pytest.fixture(scope="module")
def box_map():
    return generate_fs_map(Box(0.04, 0.05, 0.08), config=MapConfig(surface_step=0.01))


def test_filter_top_k_and_select(box_map):
    m = box_map
    top = m.top_k(50)
    assert len(top) == 50 and np.all(np.diff(top.grade) <= 0)
    assert top.grade[0] == m.grade.max()
    acc = m.filter(accepted=True)
    assert np.all(acc.grade > 0.7) and len(acc) == int(m.accepted.sum())
    assert len(m.filter(min_grade=2.0)) == 0


def test_select_gives_the_rows_indexing_gives(box_map):
    """select() takes rows with np.take (a mask turned into indices once): every column
    as indexing it gives, for masks, index arrays (negative and repeated ones), lists and
    an empty selection; a mask of the wrong length is refused as indexing refuses it."""
    m = box_map
    rng = np.random.default_rng(0)
    mask = rng.random(len(m)) < 0.3
    for index in (mask, np.flatnonzero(mask)[::-1], np.array([-1, 0, 0, 5]), [3, 1], np.zeros(0, int),
                  np.zeros(len(m), bool), np.array([2, 4], np.uint32)):
        got = m.select(index)
        for k, v in m.columns().items():
            want = v[np.asarray(index)]
            assert getattr(got, k).dtype == want.dtype and getattr(got, k).tobytes() == want.tobytes(), k
    with pytest.raises(IndexError):
        m.select(mask[:-1])
    with pytest.raises(IndexError):
        m.select(np.array([len(m)]))


def test_uniform_surface_sample_spreads_and_is_seeded(box_map):
    a = box_map.sample_uniform_surface(30, np.random.default_rng(1))
    b = box_map.sample_uniform_surface(30, np.random.default_rng(1))
    np.testing.assert_array_equal(a.wrist_position, b.wrist_position)
    cells = {tuple(np.floor(c / 0.01).astype(int)) for c in a.contacts[:, 0]}
    assert len(cells) == 30


def test_concat_and_shape_checks(box_map):
    two = GraspabilityMap.concat([box_map.top_k(5), box_map.top_k(7)])
    assert len(two) == 12
    cols = box_map.top_k(3).columns()
    cols["grade"] = cols["grade"][:2]
    with pytest.raises(InvalidParameterError, match="grade"):
        GraspabilityMap(**cols, meta=box_map.meta)


def test_T_obj_wrist_matches_columns(box_map):
    m = box_map.top_k(20)
    T = m.T_obj_wrist
    np.testing.assert_allclose(T[:, :3, 3], m.wrist_position, atol=1e-7)
    np.testing.assert_allclose(np.linalg.det(T[:, :3, :3]), 1.0, atol=1e-5)
    np.testing.assert_allclose(m.approach, T[:, :3, 2], atol=1e-7)


def test_empty_map():
    meta = MapMeta(object={"primitive": "box"}, gripper={}, quality={}, resolution={}, method="x")
    e = GraspabilityMap.empty(meta)
    assert len(e) == 0 and len(e.top_k(3)) == 0


def test_meta_typed_views_parse_once_and_round_trip(box_map):
    from graspsim.errors import InvalidMapError
    from graspsim.grades.paper import QualityModel
    from graspsim.grippers.spec import HGPL_25_60_A

    meta = box_map.meta
    assert meta.gripper_spec == HGPL_25_60_A and meta.gripper_spec is meta.gripper_spec
    assert meta.quality_model == QualityModel()
    assert meta.map_config == MapConfig(surface_step=0.01)
    assert meta.shape == Box(0.04, 0.05, 0.08)
    assert meta.threshold == 0.7 and meta.surface_step == 0.01
    assert meta.placement is None
    bare = MapMeta(object={}, gripper={}, quality={}, resolution={}, method="x")
    assert bare.threshold == QualityModel().threshold and bare.surface_step == MapConfig().surface_step
    with pytest.raises(InvalidMapError, match="no gripper"):
        _ = bare.gripper_spec


def test_placement_is_what_extra_records():
    from graspsim.maps.graspmap import Placement

    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # object x = cloud y
    table = {"normal": [0.0, 1.0, 0.0], "height": -0.1, "clearance": 0.0}
    extra = Placement(T, table).to_extra()
    assert extra == {"T_cloud_obj": T.tolist(), "table": table}
    meta = MapMeta(object={}, gripper={}, quality={}, resolution={}, method="adapted", extra=extra)
    p = meta.placement
    np.testing.assert_array_equal(p.T_cloud_obj, T)
    np.testing.assert_allclose(p.up, [1.0, 0.0, 0.0])  # cloud y in the object frame
    assert Placement.from_extra({"T_cloud_obj": T.tolist(), "table": {}}).up is None
