"""The experiment harness (experiments/_common.py): config -> CLI flags, the one
summary writer, the standing-object cloud."""

import importlib.util
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _load(name: str):
    sys.path.insert(0, str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


h = _load("_common")


@dataclass(frozen=True)
class Cfg:
    seed: int = h.opt(0, "run seed")
    per_case: int = h.opt(500, "grasps per case")
    sigma: float = h.opt(0.5)
    kinds: tuple[str, ...] = h.opt(("box", "sphere"), choices=("box", "sphere", "cone"))
    table: bool = h.opt(True, "with the table")
    label: str | None = h.opt(None)
    hidden: int = h.opt(3, cli=False)
    QUICK: ClassVar[dict] = {"per_case": 8, "kinds": ("box",)}

    def __post_init__(self):
        if self.per_case < 1:
            raise ValueError(f"per_case must be >= 1, got {self.per_case}")


def test_config_flags_come_from_the_dataclass():
    cfg, opts = h.parse_config(Cfg, "experiments/e99_x.py", [])
    assert cfg == Cfg() and opts.out == "results/e99_x" and not opts.publish and not opts.quick
    cfg, opts = h.parse_config(Cfg, "e99_x.py", ["--per-case", "7", "--kinds", "cone", "box", "--no-table",
                                                 "--sigma", "2", "--label", "a", "--out", "o", "--publish"])
    assert cfg == Cfg(per_case=7, kinds=("cone", "box"), table=False, sigma=2.0, label="a")
    assert (opts.out, opts.publish) == ("o", True)
    # --quick takes QUICK's values; flags given still win
    assert h.parse_config(Cfg, "x.py", ["--quick"])[0] == Cfg(per_case=8, kinds=("box",))
    assert h.parse_config(Cfg, "x.py", ["--quick", "--per-case", "2"])[0] == Cfg(per_case=2, kinds=("box",))


@pytest.mark.parametrize("argv, message", [(["--per-case", "0"], "per_case must be >= 1, got 0"),
                                           (["--kinds", "torus"], "invalid choice: 'torus'"),
                                           (["--hidden", "4"], "unrecognized arguments: --hidden 4")])
def test_bad_flags_exit_2_with_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        h.parse_config(Cfg, "x.py", argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and "Traceback" not in "".join(err)


def test_run_record_writes_summary_readme_config_and_publishes(tmp_path, monkeypatch):
    monkeypatch.setattr(h, "EXPERIMENTS", tmp_path / "experiments")
    run = h.RunRecord("experiments/e99_x.py", ["--quick", "--out", "a b"])
    text = run.write(tmp_path / "out", {"config": Cfg(), "headline": {"k": 3, "n": 4, "rate": np.float64(0.75),
                                                                        "nan": float("nan")}},
                     lambda s: f"`{s['command']}`: {s['headline']['k']}/{s['headline']['n']}", publish=True)
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["command"] == "python experiments/e99_x.py --quick --out 'a b'" and s["experiment"] == "e99_x"
    assert s["headline"] == {"k": 3, "n": 4, "rate": 0.75, "nan": None}
    assert set(s["machine"]) >= {"cpus", "load_avg_start", "load_avg_end", "wall_s", "cpu_s", "date", "reference_s"}
    assert 0 < s["machine"]["reference_s"] < 60
    assert {"numpy", "git_commit"} <= set(s["versions"]) and "commit" in s["provenance"]
    assert text == "`python experiments/e99_x.py --quick --out 'a b'`: 3/4"
    assert (tmp_path / "out" / "README.md").read_text() == text + "\n"
    assert json.loads((tmp_path / "out" / "config.json").read_text())["kinds"] == ["box", "sphere"]
    assert json.loads((tmp_path / "experiments" / "reported" / "e99_x.json").read_text()) == s


def test_start_is_mains_preamble(tmp_path, monkeypatch):
    import logging

    monkeypatch.setattr(h, "EXPERIMENTS", tmp_path / "experiments")
    monkeypatch.setattr(logging.getLogger("graspsim.x"), "level", logging.NOTSET)
    out = tmp_path / "o" / "p"
    cfg, got, run = h.start(Cfg, "experiments/e99_x.py", ["--quick", "--out", str(out), "--publish"], "doc",
                            quiet=("graspsim.x",))
    assert cfg == Cfg(per_case=8, kinds=("box",)) and got == out and out.is_dir()
    assert logging.getLogger("graspsim.x").level == logging.WARNING
    assert run.command.startswith("python experiments/e99_x.py --quick")
    run.write(out, {"config": cfg})  # --publish given: write publishes unless told otherwise
    assert (tmp_path / "experiments" / "reported" / "e99_x.json").is_file()
    _, _, quiet_run = h.start(Cfg, "experiments/e98_y.py", ["--out", str(out)])
    quiet_run.write(out, {"config": cfg})
    assert not (tmp_path / "experiments" / "reported" / "e98_y.json").exists()


def test_publishing_a_variant_writes_its_own_reported_json(tmp_path, monkeypatch):
    """--out results/STEM.VARIANT --publish -> experiments/reported/STEM.VARIANT.json; the
    script's own STEM.json stays as it was."""
    monkeypatch.setattr(h, "EXPERIMENTS", tmp_path / "experiments")
    reported = tmp_path / "experiments" / "reported"
    reported.mkdir(parents=True)
    (reported / "e99_x.json").write_text('{"kept": true}\n')
    out = tmp_path / "results" / "e99_x.noise"
    _, _, run = h.start(Cfg, "experiments/e99_x.py", ["--quick", "--out", str(out), "--publish"], "doc")
    run.write(out, {"config": Cfg()})
    assert json.loads((reported / "e99_x.noise.json").read_text())["experiment"] == "e99_x"
    assert json.loads((reported / "e99_x.json").read_text()) == {"kept": True}
    assert run.report_key(tmp_path / "e99_xy") == run.report_key(tmp_path / "e99_x.") == "e99_x"


def test_host_reference_is_said_only_where_a_run_recorded_it():
    """The host's reference time (_timing.host_reference, recorded as the run ends) joins the
    load sentence; a summary from before it was recorded reads as it did."""
    old = {"machine": {"load_avg_start": [1.0], "load_avg_end": [2.0], "cpus": 2}}
    new = {"machine": {**old["machine"], "reference_s": 0.0571}}
    assert h.load_sentence(old) == "Load average 1.0 at the start, 2.0 at the end, 2 cores."
    assert h.load_sentence(new).startswith("Load average 1.0 at the start, 2.0 at the end, 2 cores, "
                                           "host reference 57 ms")
    assert h.reference_clause(old) == ""


def test_machine_load_reads_old_and_new_summaries():
    assert h.machine_load({"machine": {"load_before": [1.0], "load_after": [2.0]}}) == ([1.0], [2.0])
    assert h.machine_load({"machine": {"load_avg_start": [3.0], "load_avg_end": [4.0]}}) == ([3.0], [4.0])


def test_standing_cloud_stands_on_the_table_at_a_drawn_yaw():
    from graspsim.primitives import Box

    box = Box(0.04, 0.06, 0.1)
    pts, T = h.standing_cloud(box, h.rng_for(0, "box"), resolution=0.004, noise=0.0, outliers=0.0)
    assert pts.min(axis=0)[2] == pytest.approx(0.0, abs=1e-9) and pts.max(axis=0)[2] == pytest.approx(0.1)
    assert np.allclose(T[:3, 3], [0.55, -0.05, 0.05]) and np.allclose(T[2, :3], [0, 0, 1])
    again, T2 = h.standing_cloud(box, h.rng_for(0, "box"), resolution=0.004, noise=0.0, outliers=0.0)
    assert np.array_equal(pts, again) and np.array_equal(T, T2)
    _, T3 = h.standing_cloud(box, h.rng_for(1, "box"), resolution=0.004, noise=0.0, outliers=0.0)
    assert not np.allclose(T[:3, :3], T3[:3, :3])
    one_view, _ = h.standing_cloud(box, h.rng_for(0, "box"), resolution=0.004, noise=0.0, outliers=0.0,
                                   camera=(0.6, 45.0))
    assert 0 < len(one_view) < len(pts)


def test_mean_sd_and_rates_text():
    assert h.mean_sd_text(12.345, 1.5, 1) == "12.3 (1.5)" and h.mean_sd_text(3.0, float("nan")) == "3 (-)"
    assert h.mean_sd_text(float("nan"), 1.0) == "n/a"
    assert h.rate_ci(3, 4, (0.3, 0.95)) == "75.0 % (3/4) [30.0, 95.0]" and h.rate_ci(0, 0) == "n/a (0/0)"
    assert h.pct(None) == "n/a" and h.pct(None, missing="-") == "-"


def test_experiment_database_is_private_and_fresh_unless_given(tmp_path):
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.primitives import Box

    cfg = h.map_config(quick=True)
    db = h.experiment_database(None, tmp_path, cfg)
    assert db.root == tmp_path / "fsdb" and len(h.database_record(db)["maps"]) == len(PAPER_SHAPES)
    db.add(Box(0.02, 0.03, 0.04))  # a part's map built during a run
    assert len(h.database_record(db)["maps"]) == len(PAPER_SHAPES) + 1
    again = h.experiment_database(None, tmp_path, cfg)  # a rerun starts from the paper's shapes only
    other = h.experiment_database(None, tmp_path / "b", cfg)
    assert h.database_record(again)["maps"] == h.database_record(other)["maps"]
    assert len(h.database_record(again)["maps"]) == len(PAPER_SHAPES)
    again.add(Box(0.02, 0.03, 0.04))
    given = h.experiment_database(str(tmp_path / "fsdb"), tmp_path / "elsewhere", cfg)  # --db: used as it is
    assert len(h.database_record(given)["maps"]) == len(PAPER_SHAPES) + 1 and not (tmp_path / "elsewhere").exists()


# scripts not yet on the one entry (other branches own them); the list only shrinks
NOT_YET_ON_START = {"bench_scene", "e10_clutter_removal", "viewer_screenshot"}


def test_every_experiment_script_starts_with_the_harness_entry():
    import ast

    late = []
    for path in sorted(EXPERIMENTS.glob("*.py")):
        if path.name.startswith("_") or path.stem in NOT_YET_ON_START or path.stem == "report":
            continue
        tree = ast.parse(path.read_text())
        main = next((f for f in tree.body if isinstance(f, ast.FunctionDef) and f.name == "main"), None)
        if main is None:
            continue
        calls = {getattr(n.func, "id", getattr(n.func, "attr", None)) for n in ast.walk(main)
                 if isinstance(n, ast.Call)}
        # start(...) or run_study(...), the whole main of a study, which begins with start
        if not calls & {"start", "run_study"} or calls & {"parse_config", "RunRecord", "ArgumentParser", "basicConfig"}:
            late.append(path.stem)
    assert not late, f"scripts whose main does not begin with start(Config, __file__, argv, __doc__): {late}"
