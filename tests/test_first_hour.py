"""First-hour friction (issue 12): help texts, the demo's leftovers, info's plain output,
plots a new user can read."""

from __future__ import annotations

import argparse
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
