"""First-hour friction (issue 12): help texts, the demo's leftovers, info's plain output,
plots a new user can read."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import build_parser, main
from graspsim.maps import save_map
from graspsim.primitives import Cylinder

REPO = Path(__file__).resolve().parents[1]


def _subparsers(parser: argparse.ArgumentParser, prefix: str = ""):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield f"{prefix}{name}", sub
                yield from _subparsers(sub, f"{prefix}{name} ")


def test_every_command_has_a_plain_description_in_its_help():
    subs = dict(_subparsers(build_parser()))
    assert {"show", "info", "db build", "db list", "db lookup", "identify"} <= set(subs)
    for name, p in subs.items():
        assert p.description and len(p.description) > 40, f"`graspsim {name} --help` has no description"
        assert "``" not in p.format_help(), f"`graspsim {name} --help` shows reST markup"


def test_db_list_offers_only_the_options_it_uses(capsys):
    with pytest.raises(SystemExit):
        main(["db", "list", "--help"])
    text = capsys.readouterr().out
    assert "--db" in text and "--json" in text
    assert "--surface-step" not in text and "--mu" not in text


def test_demo_output_folder_is_ignored_by_git():
    lines = (REPO / ".gitignore").read_text().splitlines()
    assert "graspsim-demo/" in lines


def _map(tmp_path):
    ang = np.linspace(0.0, np.pi / 2, 5)
    T = np.stack([grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for a in ang])
    m = hand_made_map(Cylinder(0.02, 0.20), T, np.full(5, 0.04), grades=np.linspace(0.5, 0.9, 5),
                      mass=0.1)
    m = m.with_meta(quality={**m.meta.quality, "name": "paper", "fc_weight": 0.5},
                    resolution={"surface_step": 0.005, "rotation_step": np.radians(11.0),
                                "depth_step": 0.01, "closing_cone": np.radians(22.0)})
    return save_map(m, tmp_path / "cyl.h5")


def test_info_plain_output_is_readable_and_shows_the_settings(tmp_path, capsys):
    assert main(["info", str(_map(tmp_path))]) == 0
    out = capsys.readouterr().out
    assert "{'" not in out and "': " not in out  # no Python dict repr
    assert "cylinder(radius=2 cm, height=20 cm), mass 100 g" in out
    for setting in ("friction mu 0.5", "surface step 5 mm", "rotation step 11 deg",
                    "closing cone 22 deg", "festo_hgpl_25_60_a"):
        assert setting in out


def test_plot_z_label_clears_the_colour_bar(tmp_path):
    from graspsim.maps import load_map
    from graspsim.plots import map_figure

    gmap = load_map(_map(tmp_path))
    for maps in ([gmap], [gmap, gmap]):
        fig = map_figure(maps)
        try:
            fig.canvas.draw()
            r = fig.canvas.get_renderer()
            bar = fig.axes[-1].get_tightbbox(r)  # the colour bar with its ticks and label
            whole = fig.bbox
            for ax in fig.axes[:-1]:
                z = ax.zaxis.label.get_window_extent(r)
                assert not z.overlaps(bar), "the z label overlaps the colour bar"
                assert whole.x0 <= z.x0 and z.x1 <= whole.x1  # and stays on the figure
        finally:
            import matplotlib.pyplot as plt

            plt.close(fig)


# ---------------------------------------------------------------- issue 35: the first hour again
FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


def _bottle_map(tmp_path):
    """A hand-made map on the glue bottle (a compound of two cylinders) whose few grasps
    all lie on its wide lower part."""
    from graspsim.primitives.case_study import glue_bottle

    ang = np.linspace(0.0, np.pi, 8)
    z = float(glue_bottle().aabb[0, 2]) + 0.02
    T = np.stack([grasp_pose([0, 0, z], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0]) for a in ang])
    m = hand_made_map(glue_bottle(), T, np.full(8, 0.052), grades=np.linspace(0.6, 0.95, 8), mass=0.08)
    return save_map(m, tmp_path / "bottle.h5")


def test_info_of_a_compound_map_names_its_parts_not_a_repr(tmp_path, capsys):
    assert main(["info", str(_bottle_map(tmp_path))]) == 0
    out = capsys.readouterr().out
    row = next(ln for ln in out.splitlines() if ln.startswith("object"))
    assert "array(" not in out and "Compound(" not in out and "poses=" not in out
    assert "compound of 2 parts: cylinder(radius=" in row and "+ cylinder(" in row and "cm overall" in row
    assert max(len(ln) for ln in out.splitlines()) < 200  # no row padded to an 888-character repr


def _labels_overlap(ax, renderer) -> bool:
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        boxes = [t.get_window_extent(renderer) for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
        if any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:]):
            return True
    return False


def test_map_plot_holds_the_whole_object_says_what_is_drawn_and_keeps_tick_labels_apart(tmp_path):
    import matplotlib.pyplot as plt

    from graspsim.maps import load_map
    from graspsim.plots import map_figure

    gmap = load_map(_bottle_map(tmp_path))
    lo, hi = gmap.meta.shape.aabb
    fig = map_figure([gmap], min_grade=0.7, max_points=3)
    try:
        fig.canvas.draw()
        ax = fig.axes[0]
        for k, lim in enumerate((ax.get_xlim(), ax.get_ylim(), ax.get_zlim())):
            assert lim[0] <= lo[k] and hi[k] <= lim[1], "the axes cut the object off"
        shown = int(gmap.above(0.7).sum())
        assert f"a uniform sample of 3 of the {shown:,} grasps with grade > 0.7 drawn" in ax.get_title()
        assert any("each dot:" in t.get_text() and "grade" in t.get_text() for t in fig.texts)
        assert not _labels_overlap(ax, fig.canvas.get_renderer())
    finally:
        plt.close(fig)
    fig = map_figure([gmap])
    try:
        assert f"all {len(gmap)} grasps drawn" in fig.axes[0].get_title()
    finally:
        plt.close(fig)


@pytest.fixture(scope="module")
def cylinder_map(tmp_path_factory):
    """A coarse FS map of the paper's 2 x 20 cm cylinder (its grasps from below meet the
    table), from a database of it in the folder beside it ("db")."""
    import shutil

    folder = tmp_path_factory.mktemp("cyl")
    assert main(["db", "build", "--primitives", "cylinder", "--db", str(folder / "db"), *FAST_FLAGS, "--json"]) == 0
    return Path(shutil.copyfile(next((folder / "db").glob("cylinder/*.h5")), folder / "cyl.h5"))


def test_trial_headline_gives_counts_attempts_and_table_blocked_poses_apart(cylinder_map, tmp_path, capsys):
    import shutil

    m = shutil.copyfile(cylinder_map, tmp_path / "m.h5")
    capsys.readouterr()
    argv = ["trial", str(m), "--sample", "10", "--min-grade", "0.7", "--threads", "1", "--no-write"]
    assert main(argv + ["--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    blocked = s["start_collisions"]
    assert blocked["table"] > 0, "the cylinder's grasps from below should meet the table"
    assert blocked["table"] + blocked["object"] == s["counts"]["start_collision"] == s["trials"] - s["feasible"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    ok, n, feasible = s["success"], s["trials"], s["feasible"]
    assert f"success rate: {ok} of {feasible} feasible poses = {100 * ok / feasible:.1f} %" in out
    assert f"{n} attempts, {n - feasible} excluded as infeasible" in out
    assert f"{blocked['table']} blocked by the table" in out
    assert f"of all {n} attempts {ok} succeeded" in out
    rows = [ln for ln in out.splitlines()
            if ln.rstrip().endswith(" %") and not ln.startswith(("success rate", "outcome"))]
    assert len(rows) == 8 and all(re.search(r"\d\d?\d?\.\d %$", ln.rstrip()) for ln in rows), rows


def test_trial_again_keeps_earlier_results_or_needs_replace(cylinder_map, tmp_path, capsys):
    import shutil

    from graspsim.maps.io import read_sim_results

    m = shutil.copyfile(cylinder_map, tmp_path / "m.h5")
    run = ["trial", str(m), "--sample", "4", "--min-grade", "0.7", "--threads", "1", "--json"]
    assert main(run) == 0
    first = read_sim_results(m)["simulated"].copy()
    assert main(run[:-1] + ["--seed", "7", "--json"]) == 0  # other grasps, the same settings: kept beside
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    both = read_sim_results(m)["simulated"]
    assert s["kept_stored"] == int(first.sum()) and np.all(both[first]) and both.sum() > first.sum()
    before = m.read_bytes()
    assert main(run) == 2  # the same grasps again would replace results: refused before simulating
    err = capsys.readouterr().err
    assert "--replace" in err and "already holds the results of" in err and m.read_bytes() == before
    assert main(run[:-1] + ["--noise", "--json"]) == 2  # other settings: the same
    assert main(run + ["--replace"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["replaced_stored"] == int(both.sum())
    with pytest.raises(SystemExit):
        main(["trial", "--help"])
    assert "--replace" in capsys.readouterr().out


def test_db_commands_take_db_and_root_still_works_with_a_note(tmp_path, capsys):
    db = tmp_path / "db"
    assert main(["db", "build", "--primitives", "sphere", "--db", str(db), *FAST_FLAGS, "--json"]) == 0
    capsys.readouterr()
    assert main(["db", "list", "--root", str(db), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out.strip().splitlines()[-1])["maps"] and "--root is deprecated" in err and "--db" in err
    assert main(["db", "check", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert out.strip().endswith("1 map listed, 1 valid; no problems") and "0 problems" not in out


def test_adapt_prints_dimensions_as_identify_does(cylinder_map, tmp_path, capsys):
    from graspsim.primitives import synthetic_cloud
    from graspsim.transforms import make_transform

    cloud = synthetic_cloud(Cylinder(0.02, 0.2), np.random.default_rng(1), resolution=0.006, noise=0.0003,
                            T_world_obj=make_transform(np.eye(3), [0.3, 0.0, 0.1])).points
    np.save(tmp_path / "c.npy", cloud)
    db = cylinder_map.parent / "db"
    args = [str(tmp_path / "c.npy"), "--db", str(db), "--seed", "0"]
    assert main(["identify", *args]) == 0
    ident = capsys.readouterr().out
    assert main(["adapt", *args, "-o", str(tmp_path / "a.h5"), *FAST_FLAGS]) == 0
    adapt = capsys.readouterr().out
    dims = re.search(r"radius=[\d.]+ cm, height=[\d.]+ cm", ident)
    assert dims and dims.group(0) in adapt, (ident, adapt)
    assert "{'radius'" not in adapt


def test_a_typo_in_a_subcommand_option_shows_that_subcommand_usage(capsys):
    for argv, usage, typo in ((["map", "sphere", "--radisu", "0.02", "-o", "x.h5"], "usage: graspsim map ", "--radisu"),
                              (["db", "build", "--primtives", "box"], "usage: graspsim db build ", "--primtives"),
                              (["info", "x.h5", "--jsn"], "usage: graspsim info ", "--jsn")):
        with pytest.raises(SystemExit) as e:
            main(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2 and err.startswith(usage), err[:200]
        assert "error: unrecognized arguments: " + typo in err


def test_map_output_needs_a_map_file_extension(tmp_path, capsys):
    from graspsim.errors import MapFileError
    from graspsim.maps import load_map

    out = tmp_path / "cyl.txt"
    assert main(["map", "sphere", "--radius", "0.02", "-o", str(out), *FAST_FLAGS]) == 2
    err = capsys.readouterr().err
    assert ".h5 or .hdf5" in err and "cyl.txt" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []
    from graspsim.maps import save_map

    with pytest.raises(MapFileError, match=r"\.h5"):
        save_map(load_map(_map(tmp_path)), tmp_path / "m.png")
    assert not (tmp_path / "m.png").exists()


def test_glossary_terms_are_defined_in_the_readme_and_the_help_of_commands_printing_them(capsys):
    from graspsim.cli._common import GLOSSARY

    readme = (REPO / "README.md").read_text()
    top = readme[:readme.index("## A quick tour")]
    for term in GLOSSARY:
        assert f"**{term}**" in top, f"the README's set-up does not define {term!r}"
    uses = {"info": ("grade", "SR / VR"), "map": ("FS map", "SR / VR"), "trial": ("feasible", "robust score"),
            "adapt": ("known / familiar / build", "robust score"), "identify": ("known / familiar / build",),
            "demo": ("FS map", "known / familiar / build", "robust score"), "design": ("SR / VR",)}
    for command, terms in uses.items():
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        for term in terms:
            assert f"{term}: " + " ".join(GLOSSARY[term].split())[:40] in text, (command, term)
    assert 'python -m pytest -m "not slow"' in top and "graspsim demo" in top
    from graspsim.maps.match import KNOWN_TOL  # the tolerance of known, as the rule has it

    within = f"within {100 * KNOWN_TOL:g} %"
    assert within in GLOSSARY["known / familiar / build"] and within in " ".join(top.split())


def test_a_map_built_on_demand_reports_its_progress(tmp_path):
    """The planner's build case (the demo's sixth map) goes through BUILD_PROGRESS, which
    the command line turns into a progress bar on a terminal."""
    import contextlib
    import math

    from graspsim.maps.database import BUILD_PROGRESS, MapDatabase
    from graspsim.maps.generate import MapConfig
    from graspsim.primitives import Sphere

    seen = []

    @contextlib.contextmanager
    def hook(shape):
        seen.append(str(shape))
        yield lambda frac: seen.append(frac)

    db = MapDatabase(tmp_path / "db", config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
    token = BUILD_PROGRESS.set(hook)
    try:
        db.get(Sphere(0.03))
    finally:
        BUILD_PROGRESS.reset(token)
    assert seen[0] == str(Sphere(0.03)) and len(seen) > 2 and seen[-1] == 1.0


def test_trial_render_estimate_counts_the_rendering(capsys):
    import argparse

    from graspsim.cli._common import progress
    from graspsim.cli.trial_cmd import RENDER_SECONDS_PER_TRIAL, _selection_check

    args = argparse.Namespace(threads=2, min_grade=None, sample=10, top=None, all=False, json=False,
                              render="out", render_count=3)
    ten_grasps = type("Map", (), {"__len__": lambda self: 10})()  # all the check reads of a map
    with progress(None, "x", enabled=False) as bar:
        _selection_check(args, bar)(ten_grasps, np.arange(10))
    err = capsys.readouterr().err
    assert f"rendering up to 3 of them: at least {3 * RENDER_SECONDS_PER_TRIAL:.0f} s" in err, err
