"""Bad input to the commands added since issue 13 (issue 35): adapt-gripper, view,
plan-scene, db check, --gripper SPEC.json and the scene planner's API. Each case: one
``graspsim: error:`` line and a nonzero exit (CLI) or a GraspsimError (API), never a
traceback or a hang, and no existing output replaced."""

from __future__ import annotations

import io
import json
import os
import shutil
import socket

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.errors import GripperError, InvalidParameterError, PointCloudError
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps import save_map
from graspsim.primitives import Cylinder

FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


def _fails(capsys, argv, *needles, code=2) -> str:
    assert main([str(a) for a in argv]) == code
    out, err = capsys.readouterr()
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("[graspsim]")]
    assert len(lines) == 1 and lines[0].startswith("graspsim: error: "), err
    assert "Traceback" not in err + out
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


@pytest.fixture
def cyl_map(tmp_path):
    ang = np.linspace(0.0, np.pi, 6)
    T = np.stack([grasp_pose([0, 0, 0.02 * k], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for k, a in enumerate(ang)])
    return save_map(hand_made_map(Cylinder(0.02, 0.20), T, np.full(6, 0.04), grades=np.linspace(0.75, 0.95, 6)),
                    tmp_path / "cyl.h5")


# ---------------------------------------------------------------- adapt-gripper: no empty map over -o
@pytest.mark.parametrize("how", ["stroke 1 mm", "source grade 2", "source grade nan"])
def test_adapt_gripper_never_replaces_an_output_with_an_empty_map(cyl_map, tmp_path, capsys, how):
    spec = tmp_path / "tiny.json"
    spec.write_text(json.dumps({**HGPL_25_60_A.to_dict(), "name": "tiny", "stroke_per_jaw": 0.001}))
    existing = shutil.copyfile(cyl_map, tmp_path / "existing.h5")
    before = existing.read_bytes()
    extra = {"stroke 1 mm": ["--to-gripper", spec], "source grade 2": ["--to-gripper", "franka_hand",
             "--source-min-grade", "2"], "source grade nan": ["--to-gripper", "franka_hand", "--source-min-grade",
                                                              "nan"]}[how]
    _fails(capsys, ["adapt-gripper", cyl_map, "-o", existing, *extra])
    assert existing.read_bytes() == before


def test_adapt_to_gripper_refuses_grades_outside_0_1():
    from graspsim.grippers import get_gripper
    from graspsim.maps.regrip import adapt_to_gripper

    ang = np.linspace(0.0, np.pi, 3)
    T = np.stack([grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0]) for a in ang])
    gmap = hand_made_map(Cylinder(0.02, 0.20), T, np.full(3, 0.04), grades=np.full(3, 0.9))
    for bad in (2, float("nan"), -0.5, 1.0, "0.5"):
        with pytest.raises(InvalidParameterError, match="grade in"):
            adapt_to_gripper(gmap, get_gripper("franka_hand"), source_min_grade=bad)


# ---------------------------------------------------------------- view: no hang, no slider traceback
def test_view_port_taken_up_to_65535_is_an_error_not_a_hang(cyl_map, capsys):
    from graspsim.viewer import _check_host

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        taken = s.getsockname()[1]
        assert _check_host("127.0.0.1", taken) > taken  # the next free one above it
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", 65535))
            s.listen()
        except OSError:
            pass  # someone else holds it: the same case
        with pytest.raises(InvalidParameterError, match="no free port"):
            _check_host("127.0.0.1", 65535)
        if _has_viser():  # the command: one line at once (it waited for ever on viser's failed thread)
            _fails(capsys, ["view", cyl_map, "--port", "65535"], "no free port")
    for bad in (-1, 65536, 1.5, True):
        with pytest.raises(InvalidParameterError, match="0..65535"):
            _check_host("127.0.0.1", bad)


def _has_viser() -> bool:
    import importlib.util

    return importlib.util.find_spec("viser") is not None


def test_view_min_grade_outside_0_1_is_refused(cyl_map, capsys):
    from graspsim.viewer import _check_min_grade

    for bad in (float("nan"), -0.1, 1.5, float("inf")):
        with pytest.raises(InvalidParameterError, match=r"\[0, 1\]"):
            _check_min_grade(bad)
    pytest.importorskip("viser")
    _fails(capsys, ["view", cyl_map, "--min-grade", "nan", "--port", "0"], "min-grade")


# ---------------------------------------------------------------- plan-scene and its API
def _claiming(png: bytes, w: int, h: int) -> bytes:
    """The PNG ``png`` with a header claiming ``w`` x ``h`` pixels (IHDR and its CRC rewritten):
    a decompression bomb's size at no cost to make."""
    import struct
    import zlib

    ihdr = bytearray(png[12:29])
    ihdr[4:12] = struct.pack(">II", w, h)
    return png[:12] + bytes(ihdr) + struct.pack(">I", zlib.crc32(bytes(ihdr))) + png[33:]


def test_depth_image_too_large_is_refused_before_its_pixels_are_read(tmp_path, capsys):
    from PIL import Image

    from graspsim.perception.depth_image import MAX_PIXELS, read_depth_image

    small = io.BytesIO()
    Image.new("I;16", (2, 2)).save(small, format="PNG")
    (tmp_path / "bomb.png").write_bytes(_claiming(small.getvalue(), 20000, 20000))  # 400 M pixels, says its header
    (tmp_path / "big.png").write_bytes(_claiming(small.getvalue(), 5000, 4000))  # under PIL's limit, over ours
    for name in ("bomb.png", "big.png"):
        with pytest.raises(PointCloudError, match="depth camera"):
            read_depth_image(tmp_path / name)
    assert 5000 * 4000 > MAX_PIXELS
    out = tmp_path / "g.json"
    _fails(capsys, ["plan-scene", tmp_path / "bomb.png", "--camera", "d435", "-o", out], "bomb.png", "pixels")
    assert not out.exists()


def test_plan_scene_viewpoint_far_away_is_one_error_without_warnings(tmp_path, capsys):
    import warnings

    np.save(tmp_path / "pts.npy", np.random.default_rng(0).uniform(-0.2, 0.2, (500, 3)) * [1, 1, 0.01])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _fails(capsys, ["plan-scene", tmp_path / "pts.npy", "--viewpoint", "1e300", "1e300", "1e300", "-o",
                        tmp_path / "g.json"], "--viewpoint", "100 m")


@pytest.mark.parametrize("kw", [{"rng": 42}, {"viewpoint": np.zeros(2)}, {"viewpoint": [np.nan, 0, 1]},
                                {"viewpoint": "abc"}, {"viewpoint": [1e300, 0, 0]}], ids=str)
def test_plan_scene_api_bad_rng_or_viewpoint_is_a_graspsim_error(tmp_path, kw):
    from graspsim.maps.database import MapDatabase
    from graspsim.planning.planner import plan
    from graspsim.planning.scene import plan_scene

    pts = np.random.default_rng(0).uniform(-0.2, 0.2, (500, 3)) * [1, 1, 0.01]
    db = MapDatabase(tmp_path / "db")
    args = {"rng": np.random.default_rng(0), **kw}
    for fn in (plan_scene, plan):
        with pytest.raises(InvalidParameterError):
            fn(pts, db=db, **args)
    assert not any((tmp_path / "db").rglob("*.h5"))


# ---------------------------------------------------------------- db check
@pytest.fixture
def small_db(tmp_path):
    db = tmp_path / "db"
    assert main(["db", "build", "--primitives", "sphere", "--db", str(db), *FAST_FLAGS, "--json"]) == 0
    return db


def test_db_check_of_link_loops_reports_and_repairs_them(small_db, capsys):
    capsys.readouterr()
    os.symlink("loop.h5", small_db / "sphere" / "loop.h5")  # a loop in the folder
    index = json.loads((small_db / "index.json").read_text())
    rec = dict(index["maps"][0], file="sphere/loop2.h5", key="loop2")
    index["maps"].append(rec)  # a record naming a loop
    (small_db / "index.json").write_text(json.dumps(index))
    os.symlink("loop2.h5", small_db / "sphere" / "loop2.h5")
    assert main(["db", "check", "--db", str(small_db)]) == 1
    out, err = capsys.readouterr()
    assert "Traceback" not in err and out.count("symbolic links") == 2, out
    assert main(["db", "check", "--db", str(small_db), "--repair"]) == 0
    assert main(["db", "check", "--db", str(small_db)]) == 0
    assert not os.path.lexists(small_db / "sphere" / "loop.h5")


def test_db_check_of_a_missing_folder_is_an_error_and_creates_nothing(tmp_path, capsys):
    missing = tmp_path / "missing"
    _fails(capsys, ["db", "check", "--db", missing], "no map database", "does not exist")
    _fails(capsys, ["db", "list", "--db", missing], "no map database")
    assert not missing.exists()


# ---------------------------------------------------------------- --gripper SPEC.json
def test_gripper_spec_without_a_name_or_with_a_registered_name_is_refused(tmp_path, capsys):
    from graspsim.grippers import load_gripper_json

    spec = {**HGPL_25_60_A.to_dict(), "stroke_per_jaw": 0.03}
    spec.pop("name")
    (tmp_path / "nameless.json").write_text(json.dumps(spec))
    (tmp_path / "impostor.json").write_text(json.dumps({**spec, "name": HGPL_25_60_A.name}))
    (tmp_path / "mine.json").write_text(json.dumps({**spec, "name": "mine"}))
    for name, why in (("nameless.json", "no \"name\""), ("impostor.json", "registered gripper")):
        with pytest.raises(GripperError, match=why):
            load_gripper_json(tmp_path / name)
        _fails(capsys, ["map", "sphere", "--radius", "0.02", "-o", tmp_path / "s.h5", "--gripper",
                        tmp_path / name], why)
    assert load_gripper_json(tmp_path / "mine.json").name == "mine"
    assert not (tmp_path / "s.h5").exists()


def test_small_json_inputs_from_a_fifo_or_a_device_fail_at_once(tmp_path):
    from graspsim.grippers import get_gripper
    from graspsim.tabletop.table_scene import load_scene

    os.mkfifo(tmp_path / "fifo.json")  # reading it would block for ever
    os.symlink("/dev/zero", tmp_path / "zero.json")  # reading it would never end
    for name in ("fifo.json", "zero.json"):
        with pytest.raises(InvalidParameterError, match="not a regular file"):
            load_scene(tmp_path / name)
        with pytest.raises(GripperError, match="not a regular file"):
            get_gripper(str(tmp_path / name))
