"""Bad input never crashes, never loses data (issue 13 items 3-5): outputs are all or
nothing and checked before the work, map files are validated on load, no-ops say so.

Every CLI case asserts a nonzero exit, one line on stderr and no traceback."""

from __future__ import annotations

import json
import shutil
import warnings

import h5py
import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.errors import MapFileError
from graspsim.maps import load_map, read_sim_results, save_map
from graspsim.maps.io import SCHEMA_VERSION
from graspsim.maps.validate import map_problems
from graspsim.primitives import Cylinder


def _small_map(n: int = 4):
    ang = np.linspace(0.0, np.pi / 2, n)
    T = np.stack([grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for a in ang])
    return hand_made_map(Cylinder(0.02, 0.20), T, np.full(n, 0.04), grades=np.linspace(0.5, 0.9, n))


@pytest.fixture
def map_file(tmp_path):
    return save_map(_small_map(), tmp_path / "cyl.h5")


def _fails(capsys, argv, code=2) -> str:
    """Run the CLI; assert exit ``code``, exactly one stderr line, no traceback. Returns it."""
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert rc == code, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("graspsim"), err
    return lines[0]


def _no_temps(folder) -> bool:
    return not [p for p in folder.iterdir() if p.name.startswith(".") and ".tmp" in p.name]


@pytest.fixture
def no_work(monkeypatch):
    """Generation and simulation raise if reached: a check must fail before the work."""
    def boom(*a, **k):
        raise AssertionError("the work started before the check")

    monkeypatch.setattr("graspsim.maps.generate.generate_fs_map", boom)
    monkeypatch.setattr("graspsim.sim.mapsim.run_trials", boom)


# ------------------------------------------------------------------ A: all-or-nothing outputs
def _blob(tmp_path):
    path = tmp_path / "blob.npy"
    np.save(path, np.random.default_rng(0).normal(size=(500, 3)) * 0.03)  # identifies as nothing
    return path


@pytest.mark.parametrize("flags", [[], ["--no-partial"]])
def test_adapt_failure_leaves_an_existing_output_untouched(tmp_path, map_file, capsys, flags):
    # was: replaced by an empty map (also with --no-partial) that `graspsim info` rejected
    before = map_file.read_bytes()
    line = _fails(capsys, ["adapt", _blob(tmp_path), "-o", map_file, "--db", tmp_path / "db", *flags], code=1)
    assert "no map written" in line and "left as it was" in line
    assert map_file.read_bytes() == before and _no_temps(tmp_path)
    assert len(load_map(map_file)) == 4


def test_adapt_no_partial_writes_no_file_at_all(tmp_path, capsys):
    out = tmp_path / "new.h5"
    _fails(capsys, ["adapt", _blob(tmp_path), "-o", out, "--no-partial", "--db", tmp_path / "db",
                    "--json"], code=1)
    assert not out.exists() and _no_temps(tmp_path)


def test_identify_of_nothing_exits_1_with_its_summary(tmp_path, capsys):
    # an honest no-op, as adapt's: was exit 0 with status "failed"
    rc = main(["identify", str(_blob(tmp_path)), "--json", "--db", str(tmp_path / "db")])
    out, err = capsys.readouterr()
    assert rc == 1 and "Traceback" not in err
    assert json.loads(out.strip().splitlines()[-1])["status"] == "failed"  # the summary still printed
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("graspsim: identify: nothing was identified in 500 points")


def test_map_output_that_is_a_directory_fails_before_the_work(tmp_path, capsys, no_work):
    (tmp_path / "outdir").mkdir()
    line = _fails(capsys, ["map", "box", "--x", "0.05", "--y", "0.05", "--z", "0.05",
                           "-o", tmp_path / "outdir"])
    assert "is a directory" in line


def test_adapt_output_in_a_missing_folder_fails_before_the_work(tmp_path, capsys, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("read the cloud before checking -o")

    monkeypatch.setattr("graspsim.perception.read_point_cloud", boom)
    line = _fails(capsys, ["adapt", _blob(tmp_path), "-o", tmp_path / "nodir" / "m.h5"])
    assert "does not exist" in line


def test_map_missing_plot_folder_fails_before_the_work_and_keeps_the_map(tmp_path, map_file,
                                                                          capsys, no_work):
    before = map_file.read_bytes()
    line = _fails(capsys, ["map", "cylinder", "--radius", "0.02", "--height", "0.2", "-o", map_file,
                           "--plot", tmp_path / "nodir" / "x.png"])
    assert "nodir" in line and "does not exist" in line
    assert map_file.read_bytes() == before


def test_map_and_plot_are_written_together_or_not_at_all(tmp_path, map_file, capsys, monkeypatch):
    from graspsim.errors import GraspsimError

    monkeypatch.setattr("graspsim.maps.generate.generate_fs_map", lambda *a, **k: _small_map(6))

    def broken_plot(*a, **k):
        raise GraspsimError("the plot failed")

    monkeypatch.setattr("graspsim.plots.plot_map", broken_plot)
    before = map_file.read_bytes()
    png = tmp_path / "x.png"
    _fails(capsys, ["map", "cylinder", "--radius", "0.02", "--height", "0.2", "-o", map_file,
                    "--plot", png])
    assert map_file.read_bytes() == before and not png.exists() and _no_temps(tmp_path)
    monkeypatch.undo()
    monkeypatch.setattr("graspsim.maps.generate.generate_fs_map", lambda *a, **k: _small_map(6))
    assert main(["map", "cylinder", "--radius", "0.02", "--height", "0.2", "-o", str(map_file),
                 "--plot", str(png)]) == 0
    assert len(load_map(map_file)) == 6 and png.read_bytes()[:4] == b"\x89PNG"


def test_show_to_a_missing_folder_or_unknown_format_fails_before_loading(tmp_path, capsys,
                                                                         monkeypatch):
    def boom(*a, **k):
        raise AssertionError("loaded the map before checking -o")

    monkeypatch.setattr("graspsim.maps.io.load_map", boom)
    assert "does not exist" in _fails(capsys, ["show", tmp_path / "any.h5", "-o",
                                               tmp_path / "nodir" / "x.png"])
    assert "unknown extension .h5" in _fails(capsys, ["show", tmp_path / "any.h5", "-o",
                                                      tmp_path / "x.h5"])


def test_trial_render_folder_that_is_a_file_fails_before_simulating(tmp_path, map_file, capsys,
                                                                     no_work):
    (tmp_path / "renders").write_text("a file")
    line = _fails(capsys, ["trial", map_file, "--top", "1", "--render", tmp_path / "renders"])
    assert "not a folder" in line and read_sim_results(map_file) == {}


def test_campaign_and_calibrate_outputs_are_checked_before_the_work(tmp_path, map_file, capsys,
                                                                     no_work):
    (tmp_path / "taken").write_text("a file")
    assert "not a folder" in _fails(capsys, ["campaign", "run", map_file, "--out",
                                             tmp_path / "taken", "--top", "1"])
    assert "not a folder" in _fails(capsys, ["calibrate", map_file, "-o", tmp_path / "taken"])


def test_demo_output_that_is_a_file_fails_before_the_work(tmp_path, capsys, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("built the database before checking --out")

    monkeypatch.setattr("graspsim.apps.demo._database", boom)
    (tmp_path / "demo").write_text("a file")
    assert "not a folder" in _fails(capsys, ["demo", "--out", tmp_path / "demo"])


# ------------------------------------------------------------------ B: maps validated on load
def _damaged(map_file, edit):
    with h5py.File(map_file, "r+") as f:
        edit(f)
    return map_file


def _set(dataset, index, value):
    def edit(f):
        a = f[dataset][()]
        a[index] = value
        del f[dataset]
        f[dataset] = a
    return edit


CORRUPTIONS = {
    "no_transforms": (lambda f: f.__delitem__("grasps/transforms"), "missing grasps/transforms"),
    "nan_transform": (_set("grasps/transforms", (1, 0, 0), np.nan),
                      "grasps/transforms has non-finite values"),
    "nan_wrist_position": (_set("graspability/wrist_position", (2, 1), np.nan),
                           "wrist_position has non-finite values"),
    "nan_grade": (_set("grasps/qualities/analytic/grade", 0, np.nan), "grade has non-finite"),
    "inf_width": (_set("graspability/width", 3, np.inf), "width has non-finite"),
    "moved_transform": (_set("grasps/transforms", (0, 0, 3), 0.5), "disagree with"),
    "zero_quaternion": (_set("graspability/wrist_quat", 1, 0.0), "non-unit quaternions"),
    "short_column": (lambda f: (f.__delitem__("graspability/width"),
                                f.__setitem__("graspability/width", np.ones(3, np.float32))),
                     "different row counts"),
    "meta_not_object": (lambda f: (f.__delitem__("graspability/meta"),
                                   f.__setitem__("graspability/meta", "[1, 2]")), "not a JSON object"),
    "meta_without_quality": (lambda f: (f.__delitem__("graspability/meta"),
                                        f.__setitem__("graspability/meta", json.dumps(
                                            {"resolution": {}, "method": "x"}))), "quality"),
}


def _replace(dataset, value):
    return lambda f: (f.__delitem__(dataset), f.__setitem__(dataset, value))


def _json_edit(dataset, **changes):
    def edit(f):
        d = json.loads(f[dataset][()])
        for k, v in changes.items():
            keys = k.split("__")
            target = d
            for key in keys[:-1]:
                target = target[key]
            target[keys[-1]] = v
        _replace(dataset, json.dumps(d))(f)
    return edit


# found by the fuzz suite (tests/fuzz): each was a traceback, a leaked warning or a map
# loaded although invalid
CORRUPTIONS.update({
    "column_is_a_group": (lambda f: (f.__delitem__("graspability/part"), f.create_group("graspability/part")),
                          "graspability/part is not a dataset"),
    "column_of_text": (_replace("graspability/width", np.array([b"0.04"] * 4)), "not real numbers"),
    "column_of_complex": (_replace("graspability/width", np.full(4, 0.04 + 1j)), "not real numbers"),
    "negative_radius_object": (_json_edit("object/description", dims__radius=-1.0),
                               "object is not a valid shape: cylinder radius must be > 0 m"),
    "extra_not_a_dict": (_json_edit("graspability/meta", extra=[1, 2, 3]), "extra is list, not dict"),
    "gripper_of_text": (_replace("gripper/configuration", json.dumps({"finger_size": ["a", 1, 1]})),
                        "gripper is not valid: finger_size must be three positive lengths"),
    "grade_above_one": (_set("grasps/qualities/analytic/grade", 1, 3.0), r"grade outside \[0, 1\]"),
    "unhashable_primitive": (_json_edit("object/description", primitive={}), "not a valid shape"),
})


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corrupted_map_is_refused_on_load(map_file, case):
    edit, message = CORRUPTIONS[case]
    _damaged(map_file, edit)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy RuntimeWarning on the way
        with pytest.raises(MapFileError, match=message):
            load_map(map_file)


@pytest.mark.parametrize("command", ["info", "show", "trial"])
@pytest.mark.parametrize("case", ["no_transforms", "nan_transform", "nan_wrist_position"])
def test_info_show_trial_refuse_a_corrupted_map(tmp_path, map_file, capsys, no_work, command, case, recwarn):
    # was: exit 0 (trial: simulated, then a KeyError lost the results; a RuntimeWarning leaked)
    edit, message = CORRUPTIONS[case]
    _damaged(map_file, edit)
    before = map_file.read_bytes()
    extra = {"info": [], "show": ["-o", tmp_path / "x.png"], "trial": ["--top", "2"]}[command]
    line = _fails(capsys, [command, map_file, *extra])
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    assert message in line and str(map_file) in line
    assert map_file.read_bytes() == before and not (tmp_path / "x.png").exists()


def test_schema_version_round_trip(map_file):
    with h5py.File(map_file, "r") as f:
        assert f["graspability/schema_version"][()] == SCHEMA_VERSION == 1
    assert len(load_map(map_file)) == 4
    _damaged(map_file, lambda f: f.__delitem__("graspability/schema_version"))
    assert len(load_map(map_file)) == 4  # earlier files without a version: read as version 1
    _damaged(map_file, lambda f: f.__setitem__("graspability/schema_version", 99))
    with pytest.raises(MapFileError, match="schema version 99.*up to 1"):
        load_map(map_file)
    _damaged(map_file, lambda f: (f.__delitem__("graspability/schema_version"),
                                  f.__setitem__("graspability/schema_version", -3)))
    with pytest.raises(MapFileError, match="not a positive integer"):
        load_map(map_file)


def test_partial_reads_are_validated_too(map_file):
    _damaged(map_file, _set("grasps/transforms", (3, 1, 1), np.nan))
    assert len(load_map(map_file, rows=slice(0, 3))) == 3  # the damaged row is not read
    with pytest.raises(MapFileError, match=r"first at row 3"):
        load_map(map_file, rows=slice(1, 4))


def test_results_are_saved_aside_when_the_map_goes_bad_during_a_simulation(tmp_path, map_file):
    from graspsim.sim import simulate_map

    def clobber(gmap, index):  # the file is replaced by junk while the trials run
        map_file.write_text("not a map any more")

    with pytest.raises(MapFileError, match=r"saved to .*\.npz") as info:
        simulate_map(map_file, top=2, threads=1, on_selected=clobber)
    saved = str(info.value).split("saved to ")[1].split(" instead")[0]
    with np.load(saved) as z:
        assert z["simulated"].tolist() == [False, False, True, True]  # the two best rows
        assert (z["outcome"][2:] >= 0).all() and str(z["__group__"]) == "grasps/qualities/mujoco"
        assert json.loads(str(z["__info__"]))["protocol"]["name"] == "lift_place"


def test_write_sim_results_saves_aside_a_map_that_lost_its_rows(tmp_path, map_file):
    from graspsim.maps import write_sim_results

    shutil.copyfile(save_map(_small_map(3), tmp_path / "other.h5"), map_file)  # replaced meanwhile
    with pytest.raises(MapFileError, match="has 4 rows, the map has 3.*saved to"):
        write_sim_results(map_file, {"outcome": np.arange(4)})
    (saved,) = tmp_path.glob("cyl.mujoco-*.npz")
    with np.load(saved) as z:
        assert z["outcome"].tolist() == [0, 1, 2, 3]


# ------------------------------------------------------------------ C: honest no-ops
@pytest.mark.parametrize("selection", [["--min-grade", "2"], ["--sample", "0"], ["--top", "0"],
                                       ["--top", "3", "--min-grade", "0.95"]])
def test_trial_that_selects_nothing_exits_nonzero(map_file, capsys, no_work, selection):
    line = _fails(capsys, ["trial", map_file, *selection])
    assert "nothing to simulate" in line
    assert read_sim_results(map_file) == {}


def test_trial_huge_sample_requires_all(tmp_path, capsys, no_work):
    from graspsim.cli import trial_cmd as trial

    n = trial.MAX_TRIALS + 1
    T = np.repeat(_small_map(1).T_obj_wrist, n, axis=0)
    big = save_map(hand_made_map(Cylinder(0.02, 0.2), T, np.full(n, 0.04)), tmp_path / "big.h5")
    line = _fails(capsys, ["trial", big, "--sample", "10000000", "--threads", "2"])
    assert f"selects {n:,} trials" in line and "--all" in line and "10,000" in line
    assert "about 63 s on 2 thread(s)" in line  # 10,001 / (80 trials/s x 2 threads)
    assert "--all" in _fails(capsys, ["trial", big, "--threads", "2"])  # no selection: all grasps


def test_trial_with_all_runs_past_the_cap_and_says_how_many(map_file, capsys, monkeypatch):
    from graspsim.cli import trial_cmd as trial

    monkeypatch.setattr(trial, "MAX_TRIALS", 2)
    assert "--all" in _fails(capsys, ["trial", map_file, "--sample", "3", "--threads", "1"])
    assert main(["trial", str(map_file), "--sample", "3", "--all", "--threads", "1"]) == 0
    err = capsys.readouterr().err
    assert "simulating 3 trials" in err and "about 1 s on 1 thread(s)" in err
    assert read_sim_results(map_file)["simulated"].sum() == 3


def test_show_and_campaign_with_empty_selections_exit_nonzero(tmp_path, map_file, capsys):
    assert "nothing to plot" in _fails(capsys, ["show", map_file, "-o", tmp_path / "x.png",
                                                "--min-grade", "2"])
    assert not (tmp_path / "x.png").exists()
    assert "nothing to simulate" in _fails(capsys, ["campaign", "run", map_file, "--out",
                                                    tmp_path / "camp", "--sample", "0"])
    assert "nothing to simulate" in _fails(capsys, ["campaign", "run", map_file, "--out", tmp_path / "camp2",
                                                    "--top", "2", "--min-grade", "2", "--executor", "serial"])
    assert not (tmp_path / "camp2").exists()  # no grade exceeds 1: refused before the folder is made
    line = _fails(capsys, ["campaign", "run", map_file, "--out", tmp_path / "camp3", "--top", "2",
                           "--min-grade", "0.95", "--executor", "serial"], code=1)  # the map's best is 0.9
    assert "no trials" in line


# ------------------------------------------------------------------ D: found by the fuzz suite
def test_map_text_is_stored_without_the_global_heap(map_file):
    # a flipped byte in a variable-length string's global heap hung libhdf5 for good
    # (H5HG__cache_heap_deserialize looping); text is now stored as fixed-length strings
    with h5py.File(map_file) as f:
        for name in ("graspability/format", "graspability/meta", "object/description", "object/primitive",
                     "object/dims", "gripper/type", "gripper/configuration"):
            info = h5py.check_string_dtype(f[name].dtype)
            assert f[name].dtype.kind == "S" and (info is None or info.length is not None), name
    assert len(load_map(map_file)) == 4


@pytest.mark.slow
def test_single_byte_flips_of_a_map_are_refused_or_valid(tmp_path, map_file):
    # flipped bytes in the HDF5 metadata surfaced as RuntimeError / KeyError tracebacks
    data = map_file.read_bytes()
    target = tmp_path / "flipped.h5"
    outcomes = set()
    for i in range(0, len(data), 61):
        b = bytearray(data)
        b[i] ^= 0xFF
        target.write_bytes(bytes(b))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                gmap = load_map(target)
            except MapFileError:
                outcomes.add("refused")
                continue
        outcomes.add("loaded")
        assert map_problems(gmap, allow_empty=True) == []
    assert "refused" in outcomes


def test_map_claiming_billions_of_rows_is_refused_before_reading(map_file, monkeypatch):
    import tracemalloc

    from graspsim.errors import BudgetExceededError

    with h5py.File(map_file, "r+") as f:  # every column claims 10^10 rows; nothing is stored
        for name in [*_ROW_DATASETS, "grasps/transforms"]:
            shape, dtype = f[name].shape, f[name].dtype
            del f[name]
            f.create_dataset(name, shape=(10**10, *shape[1:]), dtype=dtype, chunks=(1024, *shape[1:]))
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", "1GiB")
    tracemalloc.start()
    try:
        with pytest.raises(BudgetExceededError, match=r"reading 10,000,000,000 grasps .* budget of 1 GiB"):
            load_map(map_file)
        assert tracemalloc.get_traced_memory()[1] < 5e6
    finally:
        tracemalloc.stop()


_ROW_DATASETS = ["grasps/qualities/analytic/grade", "grasps/qualities/analytic/fc_angle",
                 "grasps/qualities/analytic/force_closure", "grasps/qualities/analytic/stability",
                 "grasps/qualities/analytic/stability_distance", "graspability/wrist_position",
                 "graspability/wrist_quat", "graspability/grasp_point", "graspability/contacts",
                 "graspability/normals", "graspability/width", "graspability/part"]


def test_a_folder_named_like_a_map_is_a_one_line_error(tmp_path, capsys):
    # h5py's message spanned two lines
    (tmp_path / "dir.h5").mkdir()
    assert "is not a map file" in _fails(capsys, ["info", tmp_path / "dir.h5"])


def test_output_that_is_also_an_input_is_refused(tmp_path, map_file, capsys, no_work):
    cloud = _blob(tmp_path)
    before = cloud.read_bytes()
    assert "also the input cloud" in _fails(capsys, ["adapt", cloud, "-o", cloud, "--db", tmp_path / "db"])
    assert cloud.read_bytes() == before  # was: replaced by the adapted map
    png = tmp_path / "x.png"
    h5 = tmp_path / "x.h5"
    assert "also the map (-o)" in _fails(capsys, ["map", "sphere", "--radius", "0.02", "-o", h5, "--plot", h5])
    assert ".h5 or .hdf5" in _fails(capsys, ["map", "sphere", "--radius", "0.02", "-o", png, "--plot", png])


def test_adapt_validates_its_options_before_reading_the_cloud(tmp_path, capsys, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("read the cloud before checking the options")

    monkeypatch.setattr("graspsim.perception.read_point_cloud", boom)
    for bad, needle in ((["--theta", "2"], "theta"), (["--surface-step", "0"], "surface_step"),
                        (["--table", "auto", "--table-normal", "0", "0", "0"], "normal"),
                        (["--threads", "0"], "threads"), (["--db", _blob(tmp_path)], "not a folder"),
                        (["--table", "high"], "--table takes")):
        assert needle in _fails(capsys, ["adapt", _blob(tmp_path), "-o", tmp_path / "a.h5", *bad])


def test_empty_npy_and_cut_ply_header_are_point_cloud_errors(tmp_path):
    from graspsim.errors import PointCloudError
    from graspsim.perception import read_point_cloud

    (tmp_path / "e.npy").write_bytes(b"")  # was: EOFError
    with pytest.raises(PointCloudError, match="e.npy"):
        read_point_cloud(tmp_path / "e.npy")
    (tmp_path / "c.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex.11\nend_header\n1 2 3\n")  # IndexError
    with pytest.raises(PointCloudError, match="malformed .ply header"):
        read_point_cloud(tmp_path / "c.ply")


def test_paths_with_nul_bytes_long_names_or_link_loops_are_one_line_errors(tmp_path, map_file, capsys, no_work):
    long = tmp_path / ("a" * 300 + ".h5")
    assert "NUL byte" in _fails(capsys, ["map", "sphere", "--radius", "0.02", "-o", str(tmp_path / "a\0b.h5")])
    assert "File name too long" in _fails(capsys, ["map", "sphere", "--radius", "0.02", "-o", long])
    assert "File name too long" in _fails(capsys, ["identify", str(long)[:-3] + ".npy"])
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    assert "broken symbolic link" in _fails(capsys, ["trial", map_file, "--top", "1", "--render", loop])
    assert "no path given" in _fails(capsys, ["show", map_file, "-o", ""])


def test_inputs_with_nul_bytes_or_names_too_long_are_one_line_errors(tmp_path, map_file, capsys, no_work):
    assert "does not exist" in _fails(capsys, ["show", str(tmp_path / "a\0b.h5"), "-o", tmp_path / "x.png"])
    assert "no map database at" in _fails(capsys, ["db", "check", "--db", "a\0b"])
    mesh = tmp_path / ("a" * 300 + ".obj")
    assert "File name too long" in _fails(capsys, ["trial", map_file, "--top", "1", "--mesh", mesh])


def test_campaign_with_impossible_settings_makes_no_folder(tmp_path, map_file, capsys, no_work):
    # --threads -1 failed only after the campaign folder and its spec were written
    for bad in (["--threads", "-1"], ["--max-tasks", "-1"], ["--noise", "--noise-pos", "nan"],
                ["--min-grade", "1"]):  # (no grade exceeds 1: was a folder of empty task records)
        out = tmp_path / "camp"
        _fails(capsys, ["campaign", "run", map_file, "--out", out, "--top", "1", "--executor", "serial", *bad])
        assert not out.exists(), bad


def test_a_scene_that_does_not_compile_is_a_one_line_error(map_file, capsys):
    # MuJoCo's message ("... in fullinertia\nElement name 'object', id 5") spanned two lines
    line = _fails(capsys, ["trial", map_file, "--top", "1", "--threads", "1", "--mass", "1e-265", "--no-write",
                           "--json"])
    assert "does not compile" in line


def test_npy_header_claiming_a_billion_points_is_refused_before_allocating(tmp_path):
    # np.load allocated what the header claimed: 23 GB for a 100-byte file
    import io
    import tracemalloc

    from graspsim.errors import PointCloudError
    from graspsim.perception import read_point_cloud

    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, {"descr": "<f8", "fortran_order": False, "shape": (10**9, 3)})
    (tmp_path / "claim.npy").write_bytes(head.getvalue() + np.zeros(12).tobytes())
    tracemalloc.start()
    try:
        with pytest.raises(PointCloudError, match="header says 1000000000 points"):
            read_point_cloud(tmp_path / "claim.npy")
        assert tracemalloc.get_traced_memory()[1] < 5e6
    finally:
        tracemalloc.stop()
    garbled = (b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': (0,\x10, }  \xe4"
               + b" " * 57 + b"\n")  # a flipped byte found by fuzz_long: tokenize.TokenError from np.load
    (tmp_path / "garbled.npy").write_bytes(garbled)
    with pytest.raises(PointCloudError, match="garbled.npy"):
        read_point_cloud(tmp_path / "garbled.npy")


def test_min_grade_beyond_float32_and_huge_table_normals_leak_no_warning(tmp_path, map_file, capsys):
    # a float32 grade compared with 1e308, the norm of (1e300, 0, 0): RuntimeWarning: overflow
    from graspsim.geometry.table import TablePlane

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "nothing to plot" in _fails(capsys, ["show", map_file, "-o", tmp_path / "x.png", "--min-grade", "1e308"])
        assert "nothing to simulate" in _fails(capsys, ["trial", map_file, "--min-grade", "1e308"])
        assert len(load_map(map_file).filter(min_grade=-1e308)) == 4
        assert TablePlane(normal=(1e300, 0.0, 0.0)).normal == (1.0, 0.0, 0.0)



def test_negative_point_counts_in_ply_and_pcd_headers_are_refused(tmp_path):
    # numpy reads count=-5 as "all": a header's lie went unnoticed (found by fuzz_long)
    from graspsim.errors import PointCloudError
    from graspsim.perception import read_point_cloud

    pts = np.random.default_rng(0).uniform(-0.05, 0.05, (40, 3)).astype("<f4")
    ply = b"ply\nformat binary_little_endian 1.0\nelement vertex -5\nproperty float x\nproperty float y\n" \
          b"property float z\nend_header\n" + pts.tobytes()
    pcd = b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 40\nHEIGHT 1\nPOINTS -5\nDATA binary\n" \
          + pts.tobytes()
    for name, data in (("c.ply", ply), ("c.pcd", pcd)):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(PointCloudError, match="count is -5"):
            read_point_cloud(tmp_path / name)
