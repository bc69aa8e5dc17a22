"""Calibration statistics, sampling, trial tables and reports (no simulation here)."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from graspsim.calibration import (
    TrialTable,
    calibrate,
    fit_logistic,
    precision_recall,
    reliability,
    roc_auc,
    stratified_rows,
    threshold_for_precision,
    wilson_interval,
    youden_threshold,
)
from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.stats import bootstrap


def _synthetic(rng, n=4000):
    s = rng.random(n)
    y = rng.random(n) < 0.4 + 0.6 * s  # P(success | s) rises linearly
    return s, y


def test_wilson_interval_known_values():
    lo, hi = wilson_interval(15, 15)  # the paper's 15 / 15
    assert float(lo) == pytest.approx(0.7961, abs=1e-4) and float(hi) == 1.0
    lo, hi = wilson_interval([0, 50], [0, 100])
    assert np.isnan(lo[0]) and lo[1] == pytest.approx(0.4038, abs=1e-4)


def test_auc_matches_mann_whitney_and_weights_replicate(rng):
    s, y = _synthetic(rng, 500)
    s = np.round(s, 2)  # ties count one half
    u = mannwhitneyu(s[y], s[~y]).statistic
    assert roc_auc(s, y) == pytest.approx(u / (y.sum() * (~y).sum()), rel=1e-12)
    w = rng.integers(1, 4, len(s))
    assert roc_auc(s, y, w) == pytest.approx(roc_auc(np.repeat(s, w), np.repeat(y, w)), rel=1e-12)
    assert math.isnan(roc_auc(s, np.ones(len(s), bool)))


def test_logistic_fit_recovers_coefficients(rng):
    x = rng.normal(size=(20000, 2))
    p = 1 / (1 + np.exp(-(0.5 + 1.5 * x[:, 0] - 2.0 * x[:, 1])))
    b = fit_logistic(x, rng.random(len(p)) < p)
    np.testing.assert_allclose(b, [0.5, 1.5, -2.0], atol=0.1)
    # ridge shrinks slopes, not the intercept
    assert np.all(np.abs(fit_logistic(x, rng.random(len(p)) < p, l2=1.0)[1:]) < 1.0)


def test_thresholds(rng):
    s, y = _synthetic(rng, 20000)
    # precision of s > t is 0.4 + 0.6 (1 + t) / 2 = 0.97 at t = 0.9
    t = threshold_for_precision(s, y, 0.97)
    assert 0.88 < t < 0.97
    p, r, a = precision_recall(s, y, t)
    assert p >= 0.97 and a == pytest.approx(1 - t, abs=0.02)
    top_fails = np.arange(100) < 99  # the best-scored trial fails: 100 % is never reached
    assert math.isnan(threshold_for_precision(np.arange(100.0), top_fails, 1.0))
    assert threshold_for_precision(s, np.ones(len(s), bool), 0.97) == -math.inf
    sep = np.r_[np.zeros(50), np.ones(50)]
    assert youden_threshold(np.r_[rng.random(50) * 0.4, 0.6 + rng.random(50) * 0.4], sep > 0) < 0.6


def test_reliability_and_bootstrap(rng):
    s, y = _synthetic(rng)
    rel = reliability(s, y)
    assert rel.n.sum() == len(s)
    assert np.all(rel.lo <= rel.rate) and np.all(rel.rate <= rel.hi)
    np.testing.assert_allclose(rel.rate, 0.4 + 0.6 * rel.mean_score, atol=0.08)
    lo, hi = bootstrap(lambda i: roc_auc(s[i], y[i]), len(s), rng=rng, n_boot=100)
    assert lo < roc_auc(s, y) < hi


def test_stratified_rows_weights_estimate_the_population(rng):
    score = rng.random(10000) ** 2
    eligible = rng.random(10000) < 0.7
    rows, w = stratified_rows(score, eligible, 30, rng)
    assert np.all(eligible[rows]) and len(np.unique(rows)) == len(rows)
    assert w.sum() == pytest.approx(eligible.sum())
    # a population mean estimated from the stratified sample
    assert np.sum(w * score[rows]) / w.sum() == pytest.approx(score[eligible].mean(), abs=0.02)
    with pytest.raises(InvalidParameterError):
        stratified_rows(score, eligible, 0, rng)


def test_table_clearance_top_down_and_from_below():
    down = np.eye(4)
    down[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach -z, wrist above
    down[2, 3] = G.fingertip_z + 0.01  # fingertips 1 cm above the table
    up = np.eye(4)
    up[2, 3] = 0.05  # approach +z: the arm and housing are under the table
    z = G.lowest_point(np.stack([down, up]), G.pregrasp_opening(np.array([0.03, 0.03])))
    assert z[0] == pytest.approx(0.01, abs=1e-9) and z[1] == pytest.approx(0.05 - G.arm_length)


def _table(rng, n=600):
    s, y = _synthetic(rng, n)
    out = np.where(y, 0, 3).astype(np.int8)
    out[:20] = 1  # START_COLLISION: reported apart
    return TrialTable({"case": np.repeat(["a/fs", "b/fs"], n // 2), "group": np.repeat(["a", "b"], n // 2),
                       "outcome": out, "success": out == 0, "grade": s, "weight": np.ones(n),
                       "q_fc": s ** 2}, {"note": "synthetic"})


def test_trial_table_round_trip(tmp_path, rng):
    t = _table(rng)
    t.save(tmp_path / "t.npz")
    back = TrialTable.load(tmp_path / "t.npz")
    assert back.meta == {"note": "synthetic"} and sorted(back.columns) == sorted(t.columns)
    np.testing.assert_array_equal(back["grade"], t["grade"])
    both = TrialTable.concat([t, t.select(np.arange(10)).with_columns(extra=np.ones(10))])
    assert len(both) == len(t) + 10 and np.isnan(both["extra"][0])
    with pytest.raises(InvalidParameterError, match="no column"):
        t["nope"]


def test_calibrate_report(rng):
    rep = calibrate(_table(rng), {"paper": "grade", "fc": "q_fc"}, n_boot=50, components=("q_fc", "-grade"))
    assert rep.summary["feasible"] == len(_table(rng)) - 20
    assert rep.summary["counts"]["start_collision"] == 20
    r = rep.scores["paper"]
    assert 0.6 < r.auc < 0.8 and r.auc_ci[0] <= r.auc <= r.auc_ci[1]
    assert set(r.at) == {"at_0.7", "target", "youden"}
    assert rep.components["-grade"]["auc"] == pytest.approx(1 - r.auc)
    d = rep.to_dict()
    assert d["scores"]["fc"]["name"] == "fc"
    assert "| paper |" in rep.markdown()


def test_base_rate_counts_start_collision_as_a_failed_attempt(rng):
    """The base rate (success of every drawn grasp) per feasible trial and per attempt,
    and the precision at 0.7 per attempt: START_COLLISION is a failure there."""
    t = _table(rng)
    t = t.with_columns(weight=np.where(np.arange(len(t)) % 2, 1.0, 3.0))
    w, y, feas = t["weight"], t["outcome"] == 0, t["outcome"] != 1
    rep = calibrate(t, {"paper": "grade"}, n_boot=20)
    s = rep.summary
    assert s["start_collision"] == 20 and s["base_attempts"] == len(t) and s["base_feasible"] == len(t) - 20
    assert s["base_rate"] == pytest.approx(np.sum(w * y) / np.sum(w[feas]))
    assert s["base_rate_attempts"] == pytest.approx(np.sum(w * y) / np.sum(w))
    assert s["base_rate"] == pytest.approx(s["success_rate_population"])
    op = rep.scores["paper"].at["at_0.7"]
    acc = t["grade"] > 0.7
    assert op["precision_attempts"] == pytest.approx(np.sum(w * (acc & y)) / np.sum(w * acc))
    assert op["trials_accepted_attempts"] == acc.sum() >= op["trials_accepted"]
    assert op["precision_attempts"] < op["precision"]  # some START_COLLISION among the accepted
    assert "base rate" in rep.markdown() and "precision (attempts)" in rep.markdown()


def test_conditions_presets_and_masses():
    from graspsim.calibration.conditions import CONDITIONS, SimCondition, condition, conditioned_object
    from graspsim.primitives import Box
    from graspsim.sim import object_from_shape

    fl = condition("friction_limited")
    assert (fl.grip_force, fl.mass, fl.friction) == (8.0, 0.5, 0.5) and set(CONDITIONS) == {"default",
                                                                                         "friction_limited"}
    assert condition("friction_limited", mass=0.25).mass == 0.25 and CONDITIONS["friction_limited"].mass == 0.5
    with pytest.raises(InvalidParameterError, match="friction_limited"):
        condition("heavy")
    for bad in ({"mass": 0.0}, {"mass": math.nan}, {"mass": "1"}, {"grip_force": -1.0}, {"mass_scale": 0},
                {"noise": (0.003, 0.03)}):
        with pytest.raises(InvalidParameterError):
            SimCondition(**bad)
    obj = object_from_shape(Box(0.05, 0.05, 0.05), mass=0.1)
    assert conditioned_object(obj, SimCondition()) is obj
    heavy = conditioned_object(obj, replace(fl, mass_scale=2.0))
    assert heavy.mass == pytest.approx(1.0)  # 0.5 kg, then x 2
    np.testing.assert_allclose(heavy.inertia, obj.inertia * 10.0)
    assert conditioned_object(obj, SimCondition(mass_scale=3.0)).mass == pytest.approx(0.3)


@pytest.fixture(scope="module")
def box_case():
    from graspsim.calibration import CalibrationCase
    from graspsim.calibration.regression import REGRESSION_MAPS
    from graspsim.maps.generate import generate_fs_map
    from graspsim.primitives import Box

    return CalibrationCase("box/fs", generate_fs_map(Box(0.05, 0.05, 0.07), config=REGRESSION_MAPS, threads=2),
                           group="box")


def test_a_condition_names_its_contact_model_and_its_trials_simulate_with_it(box_case, monkeypatch):
    """SimCondition.contacts: recorded when not the default, an unknown name refused in one line
    naming the valid ones, and the trials' scene built with that model's settings."""
    import graspsim.sim as sim
    from graspsim.calibration import SimCondition, draw_samples, simulate_samples

    assert "contacts" not in SimCondition().to_dict()
    assert SimCondition(contacts="soft").to_dict()["contacts"] == "soft"
    with pytest.raises(InvalidParameterError, match="valid: stiff, soft"):
        SimCondition(contacts="default")
    built = []

    def stop(obj, gripper, settings, **kw):
        built.append(settings)
        raise RuntimeError("enough")

    monkeypatch.setattr(sim, "build_scene", stop)
    (smp,) = draw_samples([box_case], 1, seed=5)
    for contacts in ("soft", "stiff"):
        with pytest.raises(RuntimeError, match="enough"):
            simulate_samples([smp], SimCondition(contacts=contacts), seed=5, threads=1)
    assert built == [sim.contact_model("soft", sim.SimSettings()), sim.SimSettings()]


def test_campaign_draws_clear_poses_and_is_deterministic(box_case):
    from graspsim.calibration import SimCondition, draw_samples, simulate_samples
    from graspsim.calibration.trials import table_features

    (smp,) = draw_samples([box_case], 2, seed=5)
    assert 0 < len(smp.rows) <= 20 and smp.weights.sum() == pytest.approx(smp.eligible)
    t1 = simulate_samples([smp], SimCondition(), seed=5, threads=2)
    t2 = simulate_samples([smp], SimCondition(), seed=5, threads=1)
    np.testing.assert_array_equal(t1["outcome"], t2["outcome"])
    assert np.all(t1.feasible)  # drawn among poses that clear the table
    assert t1.meta["mujoco_version"] and t1.meta["cases"][0]["eligible"] == smp.eligible
    np.testing.assert_allclose(table_features(t1)["pad_residual_angle"], t1["f_pad_residual_angle"])


def test_cli_calibrate_json(tmp_path, box_case, capsys):
    import json

    from graspsim.cli import main
    from graspsim.maps import save_map

    save_map(box_case.gmap, tmp_path / "box.h5")
    rc = main(["calibrate", str(tmp_path / "box.h5"), "--per-bin", "2", "--boot", "20", "--threads", "2",
               "-o", str(tmp_path / "cal"), "--json"])
    assert rc == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(s["grades"]) == {"paper", "pad_contact"} and s["trials"] > 0
    assert (tmp_path / "cal" / "report.md").exists() and (tmp_path / "cal" / "reliability.png").exists()
    assert main(["calibrate", str(tmp_path / "box.h5"), "--per-bin", "0"]) == 2


def test_e05_readme_section_from_the_reported_summary():
    """The committed E05 summary renders its README block: the command, both conditions
    with and without the closing directions beyond 22 deg, base rates beside precisions."""
    import importlib.util
    import json
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "experiments"))
    spec = importlib.util.spec_from_file_location("e05_tc", root / "experiments" / "e05_threshold_calibration.py")
    e05 = importlib.util.module_from_spec(spec)
    sys.modules["e05_tc"] = e05  # dataclasses look their module up while the class is built
    spec.loader.exec_module(e05)
    summary = json.loads((root / "experiments" / "reported" / "e05_threshold_calibration.json").read_text())
    md = e05.readme_section(summary)
    assert summary["command"].startswith("python experiments/e05_threshold_calibration.py") and summary["command"] in md
    assert summary["versions"]["git_commit"] and summary["versions"]["git_dirty"] is False
    for cond in ("default", "friction_limited"):
        h = summary["headline"][cond]["all_closing_directions"]
        assert f"| {cond} | all | {h['feasible']} ({h['start_collision']}) | {100 * h['base_rate']:.1f} %" in md
        assert f"| {cond} | ≤ 22° |" in md
    assert "44°" in md and "22°" in md and "per attempt" in md



def test_the_recorded_commit_is_dirty_for_changed_code_not_for_published_summaries(tmp_path):
    """git_state (library_versions' commit record): a changed summary under
    experiments/reported/ -- what --publish writes, run after run in one worktree -- leaves the
    code clean; a changed file under experiments/ or graspsim/ makes it dirty."""
    import shutil
    import subprocess

    from graspsim.calibration.outputs import git_state

    if shutil.which("git") is None:
        pytest.skip("no git")
    git = ["git", "-c", "user.email=t@example.org", "-c", "user.name=t", "-c", "commit.gpgsign=false"]
    for f in ("graspsim/a.py", "experiments/e.py", "experiments/reported/e.json"):
        (tmp_path / f).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / f).write_text("1\n")
    subprocess.run([*git, "init", "-q"], cwd=tmp_path, check=True)
    subprocess.run([*git, "add", "-A"], cwd=tmp_path, check=True)
    subprocess.run([*git, "commit", "-qm", "x"], cwd=tmp_path, check=True)
    s = git_state(tmp_path)
    assert len(s["git_commit"]) == 40 and s["git_dirty"] is False
    (tmp_path / "experiments/reported/e.json").write_text("2\n")
    assert git_state(tmp_path)["git_dirty"] is False
    for f in ("experiments/e.py", "graspsim/a.py"):
        (tmp_path / f).write_text("2\n")
        assert git_state(tmp_path)["git_dirty"] is True
        subprocess.run([*git, "checkout", "-q", "--", f], cwd=tmp_path, check=True)
