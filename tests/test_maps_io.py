import os

import h5py
import numpy as np
import pytest

from graspsim.errors import MapFileError
from graspsim.maps import load_map, read_sim_results, save_map, write_sim_results
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Cone


@pytest.fixture(scope="module")
def small_map():
    return generate_fs_map(Cone(0.03, 0.015, 0.06), config=MapConfig(surface_step=0.01))


def test_round_trip_is_exact(small_map, tmp_path):
    p = save_map(small_map, tmp_path / "m.h5")
    m = load_map(p)
    for k, v in small_map.columns().items():
        np.testing.assert_array_equal(getattr(m, k), v)
    assert m.meta == small_map.meta


def test_acronym_compatible_keys(small_map, tmp_path):
    p = save_map(small_map, tmp_path / "m.h5")
    with h5py.File(p) as f:
        T = f["grasps/transforms"][()]
        assert T.shape == (len(small_map), 4, 4)
        np.testing.assert_allclose(T[:, :3, 3], small_map.wrist_position, atol=1e-7)
        for k in ("grade", "fc_angle", "stability"):
            assert f[f"grasps/qualities/analytic/{k}"].shape == (len(small_map),)
        for k, shape in (("contacts", (2, 3)), ("normals", (2, 3)), ("grasp_point", (3,)), ("width", ())):
            assert f[f"graspability/{k}"].shape == (len(small_map), *shape)
        assert f["object/primitive"][()].decode() == "cone"
        assert f["object/com"].shape == (3,)
        assert float(f["object/mass"][()]) > 0
        assert f["gripper/type"][()].decode() == "festo_hgpl_25_60_a"
        assert b"stroke_per_jaw" in f["gripper/configuration"][()]


def test_missing_folder_and_missing_file(small_map, tmp_path):
    with pytest.raises(MapFileError, match="does not exist"):
        save_map(small_map, tmp_path / "nope" / "m.h5")
    with pytest.raises(MapFileError, match="does not exist"):
        load_map(tmp_path / "absent.h5")


def test_truncated_and_foreign_files(small_map, tmp_path):
    p = save_map(small_map, tmp_path / "m.h5")
    data = p.read_bytes()
    (tmp_path / "t.h5").write_bytes(data[: len(data) // 3])
    with pytest.raises(MapFileError, match="truncated|damaged"):
        load_map(tmp_path / "t.h5")
    (tmp_path / "x.h5").write_text("not hdf5")
    with pytest.raises(MapFileError):
        load_map(tmp_path / "x.h5")
    with h5py.File(tmp_path / "acronym.h5", "w") as f:
        f["grasps/transforms"] = np.tile(np.eye(4), (3, 1, 1))
        f["object/file"] = "mug.obj"
    with pytest.raises(MapFileError, match="ACRONYM.*missing"):
        load_map(tmp_path / "acronym.h5")


def test_failed_write_leaves_nothing_behind(small_map, tmp_path, monkeypatch):
    p = save_map(small_map, tmp_path / "m.h5")
    before = p.read_bytes()

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(h5py.Group, "create_dataset", boom)
    with pytest.raises(MapFileError, match="disk full"):
        save_map(small_map, p)
    assert p.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["m.h5"]


def test_sim_results_round_trip(small_map, tmp_path):
    p = save_map(small_map, tmp_path / "m.h5")
    n = len(small_map)
    write_sim_results(p, {"object_in_gripper": np.ones(n, np.int8)}, attrs_json={"protocol": "x"})
    r = read_sim_results(p)
    assert r["info"] == {"protocol": "x"} and r["object_in_gripper"].sum() == n
    with pytest.raises(MapFileError, match="rows"):
        write_sim_results(p, {"bad": np.ones(n + 1)})
    assert len(load_map(p)) == n
