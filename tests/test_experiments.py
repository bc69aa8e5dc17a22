"""Every experiment and benchmark script: its quick mode end to end (each writes the
summary.json its README block is generated from; structure and invariants, not one
machine's floats), and the statistics helper they rely on."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _load(name: str):
    sys.path.insert(0, str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up while the class is built
    spec.loader.exec_module(mod)
    return mod


def test_mixed_anova_matches_one_way_identities():
    common = _load("_stats")
    rng = np.random.default_rng(0)
    y = rng.normal(size=(10, 2)) + [0.0, 0.5]
    g = np.repeat(["larger", "smaller"], 5)
    y[g == "smaller"] += 0.7
    a = common.mixed_anova(y, g)
    d = y[:, 0] - y[:, 1]
    # two levels: the interaction is a one-way ANOVA of the differences, the between
    # effect a one-way ANOVA of the subject means
    assert a["interaction"]["F"] == pytest.approx(stats.f_oneway(d[g == "larger"], d[g == "smaller"]).statistic)
    f_oneway = stats.f_oneway(y.mean(1)[g == "larger"], y.mean(1)[g == "smaller"])
    assert a["between"]["F"] == pytest.approx(f_oneway.statistic)
    assert (a["within"]["df"], a["within"]["df_error"], a["between"]["df_error"]) == (1, 8, 8)
    ph = common.paired_posthoc(rng.normal(size=(10, 3)), ["GQ", "GF", "C"])
    assert len(ph) == 3 and all(p["p"] <= p["p_bonferroni"] <= 1 for p in ph)


def test_cluster_bootstrap_widens_the_interval_only_when_clusters_differ():
    from graspsim import stats as st
    from graspsim.stats import wilson_interval

    rng = np.random.default_rng(0)
    same = st.cluster_bootstrap_interval([45] * 20, [50] * 20, rng)
    assert same == pytest.approx((0.9, 0.9))  # identical maps: resampling them changes nothing
    k, n = [50] * 10 + [40] * 10, [50] * 20  # half the maps perfect, half at 80 %
    lo, hi = st.cluster_bootstrap_interval(k, n, rng)
    wlo, whi = wilson_interval(sum(k), sum(n))
    assert lo < 0.9 < hi and hi - lo > whi - wlo
    assert st.mcnemar(np.array([1, 1, 0, 0], bool), np.array([0, 1, 1, 1], bool))["only_first"] == 1



def test_paired_cluster_difference_keeps_the_pairing():
    from graspsim import stats as st
    rng = np.random.default_rng(0)
    k0, n = np.array([10, 2, 9, 5, 8, 1, 10, 7]), np.full(8, 10)
    # the same outcomes in every scene: no difference in any resample
    assert st.paired_cluster_difference_interval(k0, n, k0, n, rng) == (0.0, 0.0)
    # one more success in every scene: exactly +10 points in every resample, however hard the scenes differ
    assert st.paired_cluster_difference_interval(k0 + 1, n, k0, n, rng) == pytest.approx((0.1, 0.1))
    # the loss of one scene's successes: the interval covers it and reaches 0 (that scene may not be drawn)
    k1 = k0.copy()
    k1[0] = 0
    lo, hi = st.paired_cluster_difference_interval(k1, n, k0, n, rng)
    assert lo < -10 / 80 < hi and hi == pytest.approx(0.0)
    with pytest.raises(ValueError, match="aligned"):
        st.paired_cluster_difference_interval(k0[:3], n, k0, n, rng)

@pytest.mark.slow
def test_e02_quick_writes_table_json_figure(tmp_path):
    out = tmp_path / "e02"
    assert _load("e02_cylinder_scaling").main(["--quick", "--out", str(out)]) == 0
    for f in ("results.json", "table.md", "figure5.png", "config.json"):
        assert (out / f).stat().st_size > 0, f
    r = json.loads((out / "results.json").read_text())
    assert {v["direction"] for v in r["variants"]} == {"larger", "smaller"}
    for v in r["variants"]:
        assert set(v["methods"]) == {"quality", "feasibility", "combined"}
        assert v["methods"]["combined"]["SRN"] > 0 and v["fs"]["wall_s"] > 0
    assert "anova" in r["summary"]["tests"]["SRN"]
    assert "| C | larger |" in (out / "table.md").read_text()


@pytest.mark.slow
def test_e03_quick_writes_table_json_figures_maps(tmp_path):
    out = tmp_path / "e03"
    assert _load("e03_case_study").main(["--quick", "--out", str(out)]) == 0
    for f in ("results.json", "table.md", "figure7.png", "clouds.png", "config.json"):
        assert (out / f).stat().st_size > 0, f
    r = json.loads((out / "results.json").read_text())
    assert [o["object"] for o in r["objects"]] == ["pencil_cup", "glue_bottle", "glue_bottle_capped", "duck_toy",
                                                   "ball_with_tab", "bottle_brush"]
    assert all(run["main"]["wall_s"] > 0 for o in r["objects"] for run in o["runs"])
    for o in r["objects"]:  # "status: match kind + ...", the match as the README prints it
        assert sum(o["outcomes"].values()) == o["seeds"] == 1
        for outcome in o["outcomes"]:
            words = outcome.split(": ", 1)[1].replace(" + ", " ").split()
            assert outcome.split(":")[0] in ("complete", "partial", "failed", "error")
            assert set(words[::2]) <= {"known", "familiar", "build", "no"}, outcome
    assert list((out / "maps").glob("*.h5"))


@pytest.mark.slow
def test_e07_quick_table_filter_removes_start_collisions(tmp_path):
    out = tmp_path / "e07"
    mod = _load("e07_table_filter")
    assert mod.main(["--quick", "--out", str(out)]) == 0
    r = json.loads((out / "summary.json").read_text())
    assert (out / "table.md").stat().st_size > 0
    assert r["pooled"]["table"]["trials"] > 0 and r["pooled"]["table"]["start_collision"] == 0
    assert r["pooled"]["no table"]["start_collision"] > 0
    for label, p in r["pooled"].items():  # the pooled counts are the objects' counts
        es = [o[label] for o in r["objects"] if "trials" in o[label]]
        assert p["trials"] == sum(e["trials"] for e in es) == p["start_collision"] + p["feasible"]
        assert p["success"] == sum(e["success"] for e in es) <= p["feasible"]
    assert r["command"] in mod.readme_section(r) == (out / "README.md").read_text().rstrip("\n") + "\n"


@pytest.mark.slow
def test_e08_quick_pose_baselines(tmp_path):
    out = tmp_path / "e08"
    mod = _load("e08_pose_baselines")
    assert mod.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    pol = s["summary"]["policies"]
    from graspsim.maps.robust import ABLATIONS

    assert set(pol) == {"random", "top_down", "planner", "planner_robust", "planner_robust_open", "planner_clear_3mm",
                        "planner_clear_10mm"} | {f"planner_robust_{a}" for a in ABLATIONS}
    n = s["summary"]["episodes"]
    for p in pol.values():
        assert set(p) >= {"default", "none"} and p["default"]["all"]["episodes"] == n > 0
        assert p["none"]["planner_found"]["episodes"] == s["summary"]["planner_found"]
    # a policy that falls back proposes the one stand-in (the scored top-down grasp, or no grasp)
    r = json.loads((out / "results.json").read_text())
    for ep in r["episodes"]:
        fell = [name for name in ("planner", "planner_robust", "planner_robust_open") if ep[name]["fallback"]]
        for name in fell:
            assert ep[name]["none"] == ep[fell[0]]["none"] and ep[name]["default"] == ep[fell[0]]["default"]
            assert (ep[name]["none"]["outcome"] == "no_grasp") == ep[name]["no_grasp"]
    assert pol["top_down"]["none"]["all"]["success"] > pol["random"]["none"]["all"]["success"]
    # episodes are seeded by the seed rule, keyed by their index
    from graspsim.seeding import derived_seed

    seed = json.loads((out / "config.json").read_text())["seed"]
    assert [ep["seed"] for ep in r["episodes"]] == [derived_seed(seed, "episode", k) for k in range(n)]
    assert s["command"].startswith("python experiments/e08_pose_baselines.py --quick")
    assert s["command"] in mod.readme_section(s)
    # the paired comparison counts the episodes where exactly one of the two succeeded
    for label in ("default", "none"):
        for other, m in s["summary"]["paired"][label].items():
            ok = [(ep["planner_robust"][label]["reward"] > 0, ep[other][label]["reward"] > 0) for ep in r["episodes"]]
            only = (sum(a and not b for a, b in ok), sum(b and not a for a, b in ok))
            assert (m["only_first"], m["only_second"]) == only
            assert 0.0 <= m["p_exact"] <= 1.0
            robust = pol["planner_robust"][label]["all"]["success"]
            assert robust - m["only_first"] + m["only_second"] == pol[other][label]["all"]["success"]
    assert "exact McNemar" in mod.readme_section(s)


def test_e08_noise_labels():
    common = _load("_common")
    assert common.noise_sigmas("none") == (0.0, 0.0) and common.noise_sigmas("default") == (0.003, 2.0)
    assert common.noise_sigmas("5:1") == (0.005, 1.0)
    for bad in ("x", "-1:2", "1:2:3"):
        with pytest.raises(ValueError):
            common.noise_sigmas(bad)


def test_e01_quick_summary_counts(tmp_path):
    out = tmp_path / "e01"
    mod = _load("e01_identification_repetitions")
    assert mod.main(["--trials", "1", "--variants", "2", "--repetitions", "1", "10", "--kinds", "box", "sphere",
                     "--modes", "full", "--workers", "1", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert len(s["summary"]) == 4 and all(c["trials"] == 2 and 0 <= c["successes"] <= 2 for c in s["summary"])
    assert all(c["success_rate"] == c["successes"] / c["trials"] for c in s["summary"])
    text = mod.readme_section(s)
    assert s["command"] in text and "| 10 |" in text and "/2)" in text


def test_e01_quick(tmp_path):
    mod = _load("e01_identification_repetitions")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    cells = {(c["mode"], c["kind"], c["repetitions"]) for c in s["summary"]}
    assert cells == {(m, k, r) for m in ("full", "partial") for k in s["config"]["kinds"] for r in (1, 10)}
    assert all(c["trials"] == 1 and c["successes"] == round(c["success_rate"]) for c in s["summary"])
    rows = json.loads((tmp_path / "results.json").read_text())["trials"]
    assert len(rows) == len(cells) and all(r["n_points"] > 0 for r in rows)
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_e04_quick_pairs_noise_with_exact(tmp_path):
    out = tmp_path / "e04"
    mod = _load("e04_sim_validation")
    assert mod.main(["--quick", "--per-case", "4", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    by = {r["selected_by"]: r for r in s["pooled"]}
    assert set(by) == {"paper", "paper_low", "all", "pad_contact"}
    for r in s["pooled"] + s["per_case"]:
        z = r["noise"]
        assert r["drawn"] == r["feasible"] + r["start_collision"]
        assert z["of_feasible"]["of"] == r["exact"]["of"] == r["feasible"]  # the no-noise denominator
        assert z["of_drawn"]["of"] == r["drawn"]
        # noise-pushed collisions are failed attempts, not dropped from the denominator
        assert z["of_feasible"]["success"] + z["pushed_into_collision"] <= r["feasible"]
        assert z["of_feasible"]["success"] <= z["of_drawn"]["success"]
    assert s["paper_test"]["all_draws"]["drawn"] == 2 * 15
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_bench_fsmap_quick_times_fresh_and_in_process_runs(tmp_path):
    bench = _load("bench_fsmap")
    assert bench.main(["--quick", "--out", str(tmp_path / "b")]) == 0
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["command"] == f"python experiments/bench_fsmap.py --quick --out {tmp_path / 'b'}"
    (row,) = s["rows"]
    assert row["primitive"] == "cylinder" and row["threads"] == 1 and row["grasps"] > 0
    assert row["fresh"]["wall_s"] > row["fresh"]["generation_s"] > 0
    assert row["in_process"]["rebuilt"]["generation_s"] > 0 and row["fresh"]["peak_rss_mb"] > 0
    assert {"import graspsim", "graspsim --help", "graspsim info MAP"} <= set(s["startup"])
    assert len(s["machine"]["load_avg_start"]) == 3 and s["provenance"]["commit"]
    md = bench.readme_section(s)
    assert s["command"] in md and "| cylinder | 1 |" in md


def test_bench_fsmap_reported_summary_renders():
    """The committed numbers the README quotes come with their command and load."""
    bench = _load("bench_fsmap")
    s = json.loads((EXPERIMENTS / "reported" / "bench_fsmap.json").read_text())
    md = bench.readme_section(s)
    assert s["command"].startswith("python experiments/bench_fsmap.py") and s["command"] in md
    assert {r["primitive"] for r in s["rows"]} == {"cylinder", "box", "sphere", "cone", "half_toroid"}
    assert all(r["cold"] and r["cold"]["compile_notice"] for r in s["rows"])
    assert s["db_build"]["serial"]["maps"] == 5 and "FS database" in md


def _summary(out):
    return json.loads((out / "summary.json").read_text())


@pytest.mark.slow
def test_e15_quick_same_scenes_for_both_planners(tmp_path):
    mod = _load("e15_planner_comparison")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    by = {r["planner"]: r for r in s["results"]}
    assert set(by) == {"graspsim", "antipodal"}
    for r in by.values():
        assert [x["seed"] for x in r["per_seed"]] == [x["seed"] for x in by["graspsim"]["per_seed"]]
        assert [x["placed"] for x in r["per_seed"]] == [x["placed"] for x in by["graspsim"]["per_seed"]]
        assert r["gsr"]["seeds"] <= 2
    # two processes, one seed of one planner a task: the same episodes
    assert mod.main(["--quick", "--workers", "2", "--out", str(tmp_path / "w2")]) == 0
    assert [r["pooled"] for r in _summary(tmp_path / "w2")["results"]] == [r["pooled"] for r in s["results"]]
    assert s["config"]["object_set"] == "primitives"
    # graspsim's grasps name the part they were planned from, an external planner's none
    assert by["graspsim"]["pooled"]["per_source"] and not by["antipodal"]["pooled"]["per_source"]
    assert "packed: graspsim GSR" in mod.headline(s) and "antipodal GSR" in mod.headline(s)


@pytest.mark.slow
def test_e14_quick_compares_dataset_labels_with_mujoco(tmp_path):
    mod = _load("e14_cross_simulator")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert s["input"]["format"] == "acronym" and s["input"]["grasps"] == 8
    assert s["input"]["label_source"].startswith("hand-made") and s["input"]["dataset_held"] == 4
    assert set(s["models"]) == set(s["config"]["models"])  # one block per collision model of the mesh
    for model in s["models"].values():
        for name in ("tug", "lift_place"):
            r = model["protocols"][name]
            cells = [v for row in r["confusion"].values() for v in row.values()]
            assert sum(cells) == 8 and r["executable"] == r["agreement"]["n"]
            assert sum(t["grasps"] for t in r["by_type"].values()) == 8
    assert (tmp_path / "imported.graspsim.h5").is_file() and "tug" in (tmp_path / "README.md").read_text()


@pytest.mark.slow
def test_bench_identify_large_quick(tmp_path):
    mod = _load("bench_identify_large")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert [(r["shape"], r["points"]) for r in s["rows"]] == [("sphere", 2000), ("sphere", 25000)]
    for r in s["rows"]:
        assert r["runs"] == 1 and r["status"] == "identified" and r["primitive"] == "sphere"
        assert r["wall_s_median"] > r["identify_s_median"] > 0 and r["peak_rss_mib_max"] > 0
    big = s["rows"][1]  # above IdentifyConfig.max_points: downsampled
    assert 0 < big["downsampling"]["used_points"] < big["points"]
    assert s["headline"]["points"] == 25000 and "of 1 shapes" in s["headline"]["denominator"]
    assert s["agreement"]["sphere 2000 vs 25000"]["same_primitive"]
    assert s["command"] in mod.readme_section(s) == (tmp_path / "README.md").read_text().strip()


@pytest.mark.slow
def test_bench_map_preflight_quick(tmp_path):
    mod = _load("bench_map_preflight")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    (ref,), (est,) = s["refusals"], s["estimates"]
    assert ref["exit"] == 2 and ref["stderr_lines"] == 1 and not ref["output_written"]
    assert est["primitive"] == "sphere" and est["grasps"] > 0 and est["measured_growth_mib"] > 0
    assert s["headline"]["refusals"] == 1 and s["headline"]["all_one_line_exit_2"]
    assert s["headline"]["estimate_over_measured_min"] == est["estimate_mib"] / est["measured_growth_mib"]
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
@pytest.mark.slow
def test_bench_robust_quick(tmp_path):
    mod = _load("bench_robust")
    out = tmp_path / "br"
    assert mod.main(["--quick", "--kinds", "cylinder", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["objects"]) == {"cylinder"} and s["config"]["processes"] == 1 and not s["config"]["cold"]
    assert (out / "fsdb").is_dir()  # a private database, not the user's
    assert s["score_1000"]["per_kind"]["cylinder"]["fresh_process"] is not None
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_e05_threshold_calibration_quick(tmp_path):
    mod = _load("e05_threshold_calibration")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert s["reduced"].startswith("reduced configuration") and set(s["headline"]) == {"default", "friction_limited"}
    for h in s["headline"].values():
        for d in h.values():
            assert d["feasible"] + d["start_collision"] == d["trials"] and d["objects"] == 2
            assert 0 <= d["base_rate"] <= 1 and set(d) >= {"paper", "pad_contact"}
    assert set(s["sensitivity"]) == {"default", "mu_1", "force_30", "noise", "friction_limited"}
    for f in ("summary.md", "trials_main_default.npz", "reliability_default.png", "threshold_vs_mu.png"):
        assert (tmp_path / f).stat().st_size > 0, f
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_e12_fit_grade_model_quick(tmp_path):
    mod = _load("e12_fit_grade_model")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert s["config"]["objects"] == ["box@1", "cylinder@1", "sphere@1"]
    assert 0 < s["feasible"] <= s["trials"] and 0 <= s["success_rate"] <= 1
    assert set(s["cv_auc_by_object"]) == set(s["paper_auc_by_object"]) == set(s["config"]["objects"])
    model = json.loads((tmp_path / "grade_model.json").read_text())
    assert model["provenance"]["script"] == "experiments/e12_fit_grade_model.py"
    assert model["provenance"]["command"] == s["command"] and len(model["coef"]) == len(model["features"])
    # a rerun with the same configuration reuses the simulated trials
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0 and _summary(tmp_path)["trials"] == s["trials"]
    text = mod.readme_section(s)  # the published block: the command, the sizes, and the shipped model kept
    assert s["command"] in text and f"{s['trials']} trials" in text and not s["installed"]
    assert s["shipped_before"]["file"] == "graspsim/data/grade_model.json" and "is kept" in text


@pytest.mark.slow
def test_e12_fits_a_model_files_gripper(tmp_path):
    import shutil

    from graspsim.grades.models import gripper_identity
    from graspsim.grippers import get_gripper, model_folder

    mod = _load("e12_fit_grade_model")
    shutil.copytree(model_folder("rethink_gripper"), tmp_path / "g")
    model = str(tmp_path / "g" / "rethink_gripper.xml")
    out = tmp_path / "e12"
    assert mod.main(["--quick", "--gripper", model, "--objects", "box@0.8", "cylinder@0.8", "--out", str(out)]) == 0
    s = _summary(out)
    assert s["gripper"] == gripper_identity(get_gripper(model)) and s["gripper"]["name"] == "rethink_gripper"
    assert s["trials"] > 0 and s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_bench_sim_quick(tmp_path):
    mod = _load("bench_sim")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert [r["object"] for r in s["rows"]] == ["primitive", "coacd_mesh"]
    for r in s["rows"]:
        assert r["trials"] == 4 and 0 <= r["successes"] <= r["feasible"] <= r["trials"] and r["repeats"] == 1
        assert r["harness_sim_s_per_s"] > 0 and r["harness_over_rollout"] > 0
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_golden_regression_quick_refuses_bands_that_cannot_fail(tmp_path):
    """Four test grasps per set cannot trip a band: the quick run computes the golden
    rates and the bands, then refuses them with one message and writes no golden file."""
    mod = _load("golden_regression")
    golden = tmp_path / "golden.json"
    with pytest.raises(SystemExit) as e:
        mod.main(["--quick", "--golden", str(golden), "--out", str(tmp_path)])
    assert str(e.value.code).startswith("bands that cannot fail:") and "of 4 cannot fail" in str(e.value.code)
    assert not golden.exists()


def test_e01_counts_a_view_with_too_few_points_as_a_failure(monkeypatch):
    from graspsim.errors import PointCloudError

    mod = _load("e01_identification_repetitions")

    def too_few(*a, **k):
        raise PointCloudError("the cloud has 17 points; at least 30 are needed")

    monkeypatch.setattr(mod, "run_trial", too_few)
    cfg = mod.E01Config(trials=1, variants=1, workers=1)
    mode, row = mod._task((cfg, "partial", "box", 0, 10, 0))
    assert mode == "partial" and not row["success"] and row["predicted"] == "too few points" and row["n_points"] > 0


@pytest.mark.slow
def test_e11_quick_gripper_design_sweeps_and_adaptation(tmp_path):
    out = tmp_path / "e11"
    e11 = _load("e11_gripper_design")
    assert e11.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    cfg = s["config"]
    objects = len(cfg["kinds"]) * len(cfg["sizes"])
    for param, sw in s["sweeps"].items():
        assert (out / f"{param}.png").stat().st_size > 0
        assert sw["maps"] == len(sw["rows"]) == len(sw["values"]) * objects
        for r in sw["rows"]:
            assert 0 <= r["hit_voxels"] <= r["voxels"] and 0 <= r["hit_pixels"] <= r["pixels"]
            assert r["accepted"] <= r["grasps"] and r["sim"]["success"] <= r["sim"]["feasible"] <= r["sim"]["drawn"]
            assert r["sim"]["drawn"] == min(cfg["sim_grasps"], r["sim"]["eligible"])
        # one voxel box per sweep: the same hits over more voxels would be a smaller VR
        assert len({r["voxels"] for r in sw["rows"] if r["object"] == sw["rows"][0]["object"]}) == 1
    for r in s["adapted"]:
        assert r["adapted"] <= r["source_accepted"] and r["quality_pose"] + r["feasibility_pose"] >= r["adapted"]
        assert r["SRN"] > 0 and r["adapt_s"] > 0 and r["own_found"] <= r["own_accepted"]
        assert r["adapted_in_own"] <= r["adapted"]
    assert "**finger length**" in e11.readme_section(s)


def test_e13_gripper_validation_quick_counts_add_up_and_reports_impossible_sizes(tmp_path):
    out = tmp_path / "e13"
    mod = _load("e13_gripper_validation")
    # the Franka hand opens 80 mm: the sphere at 1.25x (87.5 mm) is impossible, with its reason
    assert mod.main(["--quick", "--sizes", "1.0", "1.25", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["gripper"]["name"] == "franka_hand" and s["grip_force"] == 70.0
    for r in [s["pooled"], *s["per_primitive"].values(), *s["per_case"]]:
        assert r["drawn"] == r["of"] + r["start_collision"]
        assert r["success"] + sum(r["failures"].values()) == r["of"]
        assert 0 <= r["place_failed_upright_after_settle"] <= r["failures"]["place_failed"]
    assert sum(r["drawn"] for r in s["per_case"]) == s["pooled"]["drawn"] > 0
    assert s["grade"]["name"] == "paper" and s["config"]["settle"] == 2.0
    assert "sphere@1.25" in s["impossible"] and "87.5 mm" in mod.readme_section(s)
    assert s["command"] in mod.readme_section(s)
    with pytest.raises(SystemExit) as exit_:  # a bad gripper: one line, exit 2, before any work
        mod.main(["--quick", "--gripper", "robotiq", "--out", str(tmp_path / "bad")])
    assert exit_.value.code == 2 and not (tmp_path / "bad").exists()


def test_e13_draws_the_grasps_the_grippers_own_calibrated_grade_accepts(tmp_path, capsys):
    from graspsim.grades import get_grade

    mod = _load("e13_gripper_validation")
    out = tmp_path / "pad"
    assert mod.main(["--quick", "--grade", "pad_contact", "--primitives", "box", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    model = get_grade("pad_contact", gripper="franka_hand")
    assert s["grade"] == {"name": "pad_contact", "threshold": model.threshold, "fitted_for": model.gripper}
    (box,) = s["per_case"]
    assert 0 < box["accepted"] and box["drawn"] == min(6, box["accepted_clear_of_table"])
    from graspsim.grades import regrade
    from graspsim.grippers import get_gripper
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map

    fs = generate_fs_map(PAPER_SHAPES["box"], get_gripper("franka_hand"), config=mod.Config(quick=True).map_config)
    assert box["accepted"] == int(np.sum(regrade(fs, model).grade > model.threshold)) != int(np.sum(fs.grade > 0.7))
    assert "calibrated grade `pad_contact` fitted for `franka_hand`" in mod.readme_section(s)
    spec = tmp_path / "mine.json"  # a gripper with no calibrated model: one line, exit 2, before any work
    spec.write_text(json.dumps({"name": "mine"}))
    with pytest.raises(SystemExit) as exit_:
        mod.main(["--quick", "--grade", "pad_contact", "--gripper", str(spec), "--out", str(tmp_path / "bad")])
    assert exit_.value.code == 2 and not (tmp_path / "bad").exists()
    assert "no pad_contact grade model was fitted for gripper 'mine'" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_scene_quick(tmp_path):
    bench = _load("bench_scene")
    # a smaller per-segment budget than E10's, through every path a plan takes (maps prepared, timed, fresh)
    assert bench.main(["--quick", "--budget", "4:50", "--out", str(tmp_path / "b")]) == 0
    s = _summary(tmp_path / "b")
    assert s["config"]["budget"] == "4:50" and "per-segment budget 4:50" in bench.readme_section(s)
    (row,) = s["rows"]
    assert row["objects_seen"] == row["objects"] == 5 and 0 < row["valid_pixels"] <= 1
    assert row["total_s"] >= row["settle_s"] > 0 and row["warm_render_s"] > 0
    assert s["fresh"]["of"] == 1 and s["fresh"]["first"]["wall_s"] > s["fresh"]["first"]["total_s"] > 0
    assert s["command"] in bench.readme_section(s)
    (p,) = s["planning"]["rows"]  # one 5-object pile planned from its first frame
    stages = sum(p[k] for k in ("backproject", "table", "segment", "identify", "plan"))
    assert p["segments"] >= 1 and 0 < stages <= p["total"] + 1e-6
    # the budget held: at most 50 grasps robust-scored per identified part, and as many on the cloud's own
    # features where the parts gave too few (E10's budget scores up to 200)
    assert any(n for n, _ in p["scored"]) and all(n <= 50 * (parts + 1) for n, parts in p["scored"])
    assert p["cpu"] > 0 and s["planning"]["warmup_scenes"] == bench.WARMUP  # timed cold, after other scenes
    text = bench.readme_section(s)
    assert "| pile, 5 objects | 1 |" in text and "as a user meets a new frame" in text
    fresh = s["planning"]["fresh"]  # fresh processes planned the same kind of frame, maps already built
    assert set(fresh) == {"pile", "pile, started"}  # plain, and with the workers started after the imports
    for f in fresh.values():
        assert f["of"] == 1 and f["first"]["wall_s"] > f["first"]["plan_s"] > 0 and f["first"]["grasps"] >= 1
    assert [r["seed"] for r in fresh["pile"]["runs"]] == [r["seed"] for r in fresh["pile, started"]["runs"]]
    assert "In a fresh process (import, draw and render" in text and "start_workers()" in text


@pytest.mark.slow
def test_bench_plan_scene_quick_times_fresh_cli_runs_on_cloud_and_depth_files(tmp_path):
    bench = _load("bench_plan_scene")
    assert bench.main(["--quick", "--out", str(tmp_path / "b")]) == 0
    s = _summary(tmp_path / "b")
    assert [(g["kind"], g["input"]) for g in s["groups"]] == [("packed", "cloud"), ("packed", "depth")]
    for g in s["groups"]:
        assert g["of"] == 1 and [r["seed"] for r in g["runs"]] == [300, 301]
        for r in g["runs"]:  # planned, with grasps written, inside a process that did more
            assert r["exit"] == 0 and r["grasps"] >= 1 and r["wall_s"] > r["plan_s"] > 0
            assert (tmp_path / "b" / f"packed{r['seed']}_{g['input']}.json").exists()
    assert (tmp_path / "b" / "inputs" / "packed300.pcd.json").exists()  # the camera record beside the cloud
    text = bench.readme_section(s)
    assert s["command"] in text and "| packed, 5 objects | depth |" in text


@pytest.mark.slow
def test_scene_fingerprint_is_the_same_twice_and_names_what_differs(tmp_path, capsys, monkeypatch):
    fp = _load("scene_fingerprint")
    first = ["--scenes", "1", "--kinds", "packed", "--coarse-db", "--out", str(tmp_path / "a")]
    assert fp.main(first) == 0  # fills the database with the maps the frame needs
    db = str(tmp_path / "a" / "fsdb")
    base = ["--scenes", "1", "--kinds", "packed", "--coarse-db", "--db", db]
    assert fp.main([*base, "--out", str(tmp_path / "b")]) == 0
    a = _summary(tmp_path / "b")
    (frame,) = a["frames"]
    assert frame["n_segments"] == len(frame["segments"]) >= 3 and frame["n_grasps"] > 0
    assert a["database"]["start"] == a["database"]["end"]  # nothing built: a rerun can compare
    assert fp.main([*base, "--out", str(tmp_path / "c"), "--compare", str(tmp_path / "b" / "summary.json")]) == 0
    assert _summary(tmp_path / "c")["differences"] == []
    a["frames"][0]["segments"][1] = "0" * 64  # as if one segment's plan had changed
    (tmp_path / "changed.json").write_text(json.dumps(a))
    capsys.readouterr()
    assert fp.main([*base, "--out", str(tmp_path / "d"), "--compare", str(tmp_path / "changed.json")]) == 1
    assert "packed 100: segments" in capsys.readouterr().out
    from dataclasses import replace

    from graspsim.tabletop import clutter

    settings = clutter.scene_settings  # a planning change: fewer grasps kept per segment
    monkeypatch.setattr(clutter, "scene_settings", lambda kind: replace(settings(kind), keep=2))
    assert fp.main([*base, "--out", str(tmp_path / "e"), "--compare", str(tmp_path / "b" / "summary.json")]) == 1
    assert "packed 100: grasps" in capsys.readouterr().out


@pytest.mark.slow
def test_e10_quick_clutter_removal_counts_add_up(tmp_path):
    mod = _load("e10_clutter_removal")
    out = tmp_path / "e10"
    assert mod.main(["--quick", "--out", str(out)]) == 0
    s = _summary(out)
    assert s["complete"] and len(s["conditions"]) == len(mod.conditions(mod.Config(**mod.Config.QUICK)))
    for r in s["conditions"]:
        eps = r["episodes"]
        assert r["scenes"] == len(eps) == 1
        assert r["attempts"] == sum(e["attempts"] for e in eps) == r["successes"] + sum(r["failure_causes"].values())
        assert r["removed"] == sum(e["removed"] for e in eps) == r["successes"] + r["other_objects"] <= r["placed"]
        assert r["placed"] == 2 and r["complete"] and r["target"] == 1
        assert r["segmentation"]["objects_seen"] >= r["segmentation"]["one_cluster"]
        p = r["planning_s"]
        assert p["first_frame"]["count"] == 1 and p["first_frame"]["count"] + p["later_frames"]["count"] == p["count"]
    assert s["conditions"][1]["ablation"] == "ground_truth"
    assert s["database"]["start"]["maps"] == s["database"]["end"]["maps"]  # nothing stored during the run
    assert s["command"] in mod.readme_section(s) == (out / "README.md").read_text().rstrip("\n") + "\n"


def test_e10_run_database_builds_missing_maps_in_memory_only(tmp_path):
    """The run's database never grows: a part no stored map serves gets its map built in
    memory, the same map a stored build gives, and the index and folder stay as they were."""
    from graspsim.maps.database import MapDatabase
    from graspsim.primitives import Box

    mod = _load("e10_clutter_removal")
    cfg = mod.map_config(True)
    MapDatabase(tmp_path / "db", config=cfg).build([Box(0.06, 0.06, 0.06)])
    files = sorted(p.name for p in (tmp_path / "db").rglob("*"))
    run = mod.RunDatabase(tmp_path / "db", config=cfg)
    m = run.get(Box(0.03, 0.04, 0.05))
    assert sorted(p.name for p in (tmp_path / "db").rglob("*")) == files and len(run.entries()) == 1
    assert run.built == {run.key(Box(0.03, 0.04, 0.05))} and run.get(Box(0.03, 0.04, 0.05)) is m
    ref = MapDatabase(tmp_path / "ref", config=cfg).get(Box(0.03, 0.04, 0.05))
    assert len(m) == len(ref) and np.array_equal(m.grade, ref.grade) and np.array_equal(m.T_obj_wrist, ref.T_obj_wrist)


def test_e10_run_database_plans_on_the_scene_workers_and_records_maps_built_in_memory(tmp_path, monkeypatch):
    """E10's read-only database has a scene's segments planned on the workers (its copies
    plan alike: issue 34's planning time as a user's loop meets it), with the grasps the
    plain database gives; a segment whose part no stored map serves is planned in this
    process, whose ``built`` records the map built in memory."""
    from graspsim.maps.database import MapDatabase
    from graspsim.planning import scene_segments
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SceneConfig
    from graspsim.primitives import Box, Cylinder, Sphere
    from graspsim.primitives.clouds import table_scene_cloud

    mod = _load("e10_clutter_removal")
    cfg = mod.map_config(True)
    plain = MapDatabase(tmp_path / "db", config=cfg)
    plain.build([Box(0.06, 0.06, 0.06), Sphere(0.035)])
    run = mod.RunDatabase(tmp_path / "db", config=cfg)
    assert scene_segments.copies_plan_alike(run)
    asked = []  # per batch: the workers it was planned on (1: in this process)
    real = scene_segments.stream_segments

    def spy(fn, groups, workers=1):
        asked.extend(workers if parallel else 1 for _, _, parallel in groups)
        return real(fn, groups, workers)

    monkeypatch.setattr(scene_segments, "stream_segments", spy)
    shapes = [Box(0.05, 0.06, 0.07), Sphere(0.03)]
    pts = table_scene_cloud(shapes, np.array([[-0.05, 0.0], [0.05, 0.0]]), np.random.default_rng(3), noise=0.0005)[0]
    record = lambda sp: ([(s.status, s.primitives) for s in sp.segments],  # noqa: E731
                         [(g.T_world_wrist.tobytes(), g.score) for g in sp.grasps])
    there = plan_scene(pts, db=run, rng=np.random.default_rng(1), config=SceneConfig(workers=2))
    here = plan_scene(pts, db=plain, rng=np.random.default_rng(1), config=SceneConfig(workers=1))
    assert asked == [2, 1] and record(there) == record(here) and not run.built
    pts = table_scene_cloud([Box(0.05, 0.06, 0.07), Cylinder(0.025, 0.1)], np.array([[-0.05, 0.0], [0.05, 0.0]]),
                            np.random.default_rng(3), noise=0.0005)[0]
    sp = plan_scene(pts, db=run, rng=np.random.default_rng(1), config=SceneConfig(workers=2))
    assert "cylinder" in {p for s in sp.segments for p in s.primitives}  # no stored cylinder map: one is built
    assert asked[-1] == 1 and run.built  # in this process, in memory, recorded
    # sent to a worker without the maps built in memory (a map each, with every segment sent)
    import pickle

    copy = pickle.loads(pickle.dumps(run))
    assert run._memory and not copy._memory and not copy.built and copy.root == run.root
    assert len(pickle.dumps(run)) < 100_000


def test_e10_others_cut_only_the_conditions_outside_the_goals():
    mod = _load("e10_clutter_removal")
    cfg = mod.Config(scenes=50, others=20, seeds=1, object_sets=("primitives",))
    got = {(c["kind"], c["objects"], c["noise"], c["ablation"]): mod.target(cfg, c) for c in mod.conditions(cfg)}
    assert got[("pile", 5, "none", None)] == got[("packed", 5, "default", None)] == 50
    assert got[("pile", 10, "none", None)] == got[("pile", 5, "none", "ground_truth")] == 20
    assert mod.target(mod.Config(scenes=50, seeds=1), {"objects": 10, "ablation": None}) == 50
    assert mod.target(mod.Config(scenes=20, seeds=5), {"objects": 5, "ablation": None}) == 100  # 5 seeds x 20
    conds = mod.conditions(cfg)
    r = mod.rounds(mod.Config(scenes=4, others=2, block=2, seeds=1, object_sets=("primitives",)), conds)
    goal = {i for i, c in enumerate(conds) if c["objects"] == 5 and c["ablation"] is None}
    assert [sorted({i for i, _ in x}) == sorted(goal) for x in r] == [True, True, False]  # the goals first
    assert sorted(p for x in r for p in x) == sorted([(i, j) for i in goal for j in range(4)]
                                                     + [(i, j) for i in range(len(conds)) if i not in goal
                                                        for j in range(2)])
    assert sum(len(x) for x in mod.rounds(mod.Config(scenes=3, block=2, seeds=1), conds)) == 3 * len(conds)


def test_e10_ablations_turn_off_one_thing_each():
    """Each E10 ablation changes its one setting of the clutter protocol and no other."""
    mod = _load("e10_clutter_removal")
    full = mod._clutter_config({"kind": "pile", "noise": "none", "ablation": None})
    assert full.feel and not full.ground_truth and full.scene.neighbours
    changed = {}
    for a in mod.ABLATIONS:
        c = mod._clutter_config({"kind": "pile", "noise": "none", "ablation": a})
        changed[a] = sorted(k for k in ("feel", "ground_truth") if getattr(c, k) != getattr(full, k)) + \
            (["neighbours"] if c.scene.neighbours != full.scene.neighbours else [])
    assert changed == {"no_neighbours": ["neighbours"], "ground_truth": ["ground_truth"], "no_feel": ["feel"]}


def test_e10_reports_per_seed_and_mean_std_over_seeds():
    """Seeds are the field's unit: GSR and DR per seed, mean +- sample std over them, each
    object set apart, every seed's scenes from its own derived seed."""
    from graspsim.tabletop.clutter import Attempt, ClutterResult

    mod = _load("e10_clutter_removal")
    cfg = mod.Config(seeds=3, scenes=2, object_sets=("household-tuning", "household-heldout"))
    assert len({mod.seed_of(cfg, k) for k in range(3)}) == 3
    assert {c["object_set"] for c in mod.conditions(cfg)} == {"household-tuning", "household-heldout"}

    def ep(ok: int, n: int, removed: int) -> ClutterResult:
        a = [Attempt(j if j < 3 else None, {}, j < ok, "success" if j < ok else "slipped", 1.0 - 0.1 * j, 0.1, {},
                     1, 1, 1, between=7 + j, source="features" if j == 3 else "box") for j in range(n)]
        return ClutterResult(5, tuple(a), removed, "cleared", 5, 5, 1.0, ("a", "b", "c", "d", "e"))

    pairs = [(0, ep(4, 4, 4)), (0, ep(4, 4, 4)), (1, ep(2, 4, 2)), (1, ep(2, 4, 2))]
    row = mod._row({"object_set": "x", "kind": "pile", "objects": 5, "noise": "none", "ablation": None}, pairs)
    e = row["episodes"][2]  # each grasp's score and seen points, in order, beside its cause
    assert e["causes"] == ["success"] * 2 + ["slipped"] * 2 and e["scores"] == [1.0, 0.9, 0.8, 0.7]
    assert e["between"] == [7, 8, 9, 10]
    assert e["sources"] == ["box", "box", "box", "features"]
    assert e["targets"] == ["a", "b", "c", None]  # the object each was aimed at, by name
    assert row["per_source"] == {"box": {"grasps": 12, "lifted": 10, "failed": {"slipped": 2}},
                                 "features": {"grasps": 4, "lifted": 2, "failed": {"slipped": 2}}}
    assert [s["gsr"] for s in row["per_seed"]] == [1.0, 0.5] and [s["dr"] for s in row["per_seed"]] == [0.8, 0.4]
    assert row["gsr_over_seeds"]["mean"] == pytest.approx(0.75)
    assert row["gsr_over_seeds"]["std"] == pytest.approx(np.std([1.0, 0.5], ddof=1))
    import sys

    text = "\n".join(sys.modules["_e10_report"].literature_lines([row]))
    assert "75.0 ± 35.4 (2)" in text and "GIGA" in text and "EdgeGraspNet" in text
    rep = sys.modules["_e10_report"]
    table = rep.source_lines([row, {**row, "ablation": "no_feel"}])  # the full method's conditions only
    assert table[-2:] == ["| x | pile | box | 12 | 10 (83.3 %) | slipped 2 |",
                          "| x | pile | features | 4 | 2 (50.0 %) | slipped 2 |"]
    assert rep.source_lines([{k: v for k, v in row.items() if k != "per_source"}]) == []  # runs before it


def test_e10_seeds_are_graspsim_scenes_and_old_summaries_say_their_set_and_seed():
    """One seed rule (clutter_stats.benchmark_seeds, as ``graspsim scene --seeds``), and the
    published summary written before object sets and seeds renders as the "mixed" set and
    one seed, never a placeholder, in the README headline and the results block."""
    from graspsim.tabletop.clutter_stats import benchmark_seeds

    mod = _load("e10_clutter_removal")
    for seeds in (1, 3):
        cfg = mod.Config(seeds=seeds, seed=7, object_sets=("primitives",))
        assert [mod.seed_of(cfg, k) for k in range(seeds)] == benchmark_seeds(7, seeds)
    assert mod.seed_of(mod.Config(seeds=1, seed=7, object_sets=("primitives",)), 0) == 7
    s = json.loads((EXPERIMENTS / "reported" / "e10_clutter_removal.json").read_text())
    assert s["config"]["object_sets"] and all("per_seed" in r for r in s["conditions"])
    seeds, scenes = s["config"]["seeds"], s["config"]["scenes"]
    head = mod.headline(s)
    n = len({(r["object_set"], r["kind"], r["objects"]) for r in s["conditions"] if not r["ablation"]})
    assert head.count(f"({seeds} x {scenes})") == n and all(o in head for o in s["config"]["object_sets"])
    assert head.startswith("Clutter removal without / with execution error") and "not run" not in head
    # a summary written before object sets and seeds (its config names one object_set, its conditions
    # no set and no per-seed rows): the "mixed" set and one seed
    old = {**s, "config": {**{k: v for k, v in s["config"].items() if k not in ("seeds", "object_sets")},
                           "object_set": "mixed"},
           "conditions": [{k: v for k, v in r.items()
                           if k not in ("object_set", "per_seed", "gsr_over_seeds", "dr_over_seeds", "per_object")}
                          for r in s["conditions"]]}
    head = mod.headline(old)
    n = len({(r["kind"], r["objects"]) for r in s["conditions"] if not r["ablation"]})  # one set then
    assert head.count("mixed ") == n and head.count(f"(1 x {s['conditions'][0]['scenes']})") == n
    block = mod.readme_section(old)
    assert "| - |" not in block and "n/a (" not in block


@pytest.mark.slow
def test_study_fit_points_quick_counts_agreement_against_every_point(tmp_path):
    study = _load("study_fit_points")
    assert study.main(["--quick", "--out", str(tmp_path / "s")]) == 0
    s = _summary(tmp_path / "s")
    rows = {t["condition"]: t for t in s["table"]}
    assert set(rows) == {"all", "all, reseeded", "fit_points=600"}
    n = rows["all"]["n"]
    assert n >= 3 and rows["all"]["kinds"] == rows["all"]["dims"] == rows["all"]["rates"] == n  # itself
    bounded = rows["fit_points=600"]
    assert bounded["rates"] <= bounded["dims"] <= bounded["kinds"] <= n
    # a cloud the bound leaves alone is identified exactly as on every point
    assert bounded["kinds"] >= n - bounded["thinned"]
    assert len(s["clouds"]) == n and s["command"] in study.readme_section(s)


def test_study_segmentation_quick_counts_every_object_once(tmp_path):
    study = _load("study_segmentation")
    # 2 mm: under the 3 mm grid's spacing, so objects break into pieces (counted as split)
    assert study.main(["--quick", "--radii-mm", "2", "7", "--out", str(tmp_path / "s")]) == 0
    s = _summary(tmp_path / "s")
    rows = {t["radius"]: t for t in s["table"]}
    # packed scenes: E10's radius from their 1 cm gap ("default") and the spacing rule without it
    assert set(rows) == {"default", "spacing", "2 mm", "7 mm"} and {t["cameras"] for t in s["table"]} == {1}
    for t in rows.values():  # every object seen is one cluster, split or merged
        assert t["seen"] >= 8 and t["one_cluster"] + t["split"] + t["merged"] == t["seen"]
        assert t["merged"] == 0  # packed objects stand >= 1 cm apart
        assert sum(t["not_one_cluster"].values()) == t["seen"] - t["one_cluster"]
    assert rows["2 mm"]["split"] > 0 and rows["2 mm"]["one_cluster"] < rows["7 mm"]["one_cluster"]
    assert rows["default"]["one_cluster"] >= rows["spacing"]["one_cluster"]  # a wider radius, nothing merged
    (c,) = s["closest"]
    assert c["pairs"] >= 8 and min(c["closest_mm"]) > 8.0  # the 1 cm gaps stay wider than E10's 8 mm radius
    assert s["command"] in study.readme_section(s)


@pytest.mark.slow
def test_study_true_shape_quick(tmp_path):
    """The duck's grasps in one packed scene judged against its true mesh: every grasp aimed at
    it is a row, every failed one has a mechanism, the section names its command."""
    out = tmp_path / "sts"
    study = _load("study_true_shape")
    assert study.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["grasps"] == len(s["rows"]) >= 1 and 0 <= s["lifted"] <= s["grasps"]
    assert sum(s["mechanisms"].values()) == s["grasps"] - s["lifted"]
    assert all(-1.0 <= r["closing_sight_cos"] <= 1.0 and r["parts"] for r in s["rows"])
    assert s["command"] in study.readme_section(s)
    with_extent = [r for r in s["rows"] if "true_extent_mm" in r]
    assert sum(g["grasps"] for g in s["off_centre"].values()) == len(with_extent)
    for r in with_extent:  # the object's extent lies between the pads (+ 2 mm)
        lo, hi = r["true_extent_mm"]
        assert -r["opening_mm"] / 2 - 2.5 <= lo <= hi <= r["opening_mm"] / 2 + 2.5
    for r in s["rows"]:  # the scene planner's grasps close on >= 5 of their segment's points (SEEN_BETWEEN)
        assert r["seen_between"] >= 5
        lo, hi = r["seen_extent_mm"]
        assert -r["opening_mm"] / 2 - 2.5 <= lo <= hi <= r["opening_mm"] / 2 + 2.5


def test_study_true_shape_off_centre_counts_by_cause():
    """off_centre: per cause, the grasps whose object's true middle is more than 8 mm from the
    gripper's centre, and what centring on the observed extent would have left."""
    study = _load("study_true_shape")
    rows = [{"cause": "success", "true_extent_mm": [-20.0, 20.0], "seen_extent_mm": [-20.0, 10.0]},
            {"cause": "success", "true_extent_mm": [-10.0, 30.0]},  # middle 10 mm off; nothing seen there
            {"cause": "no_contact", "true_extent_mm": [0.0, 30.0], "seen_extent_mm": [1.0, 29.0]},
            {"cause": "no_contact", "true_extent_mm": [-30.0, -10.0], "seen_extent_mm": [-40.0, 40.0]},
            {"cause": "dropped"}]  # no true surface between the pads: not counted
    o = study.off_centre(rows)
    assert list(o) == ["success", "no_contact"]
    assert o["success"] == {"grasps": 2, "off_centre": 1, "median_off_mm": 5.0, "with_seen": 1,
                            "off_centre_if_centred_on_seen": 0, "median_off_if_centred_on_seen_mm": 5.0}
    # centred on what was seen: 15 -> 0 mm off, and -20 -> -20 mm (the seen points spanned both sides)
    assert o["no_contact"]["off_centre"] == 2 and o["no_contact"]["median_off_mm"] == 17.5
    assert o["no_contact"]["off_centre_if_centred_on_seen"] == 1
    assert o["no_contact"]["median_off_if_centred_on_seen_mm"] == 10.0


def test_study_light_objects_quick_grasps_each_mass_alike(tmp_path):
    """One domino at two masses, the same level grasp at each: a row per mass, both held with
    their pads' sink measured, the heavy one's smaller than the light one's, and the light one's
    shallow under the default (stiff) contacts -- the soft ones sank 4.6 mm into it; the section
    naming its command."""
    study = _load("study_light_objects")
    out = tmp_path / "slo"
    assert study.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    light, heavy = s["rows"]
    assert heavy["mass_kg"] == pytest.approx(30 * light["mass_kg"]) and light["grasps"] == heavy["grasps"] == 1
    assert s["up"] == [0.0, 1.0, 0.0] and light["extent_mm"] == pytest.approx([50.8, 25.4], abs=0.5)  # lying flat
    assert heavy["held"] == 1 and 0.0 < heavy["sink_mm_median"] < 5.0
    # MuJoCo's contacts are accelerations: the pads go deeper into the lighter one, whose mass the sim holds
    assert light["held"] == 1 and light["sink_mm_median"] > 2 * heavy["sink_mm_median"]
    assert light["sink_mm_median"] < 3.0  # the stiff pads (1.5 mm); the soft ones' 4.6 mm fails here
    assert s["command"] in study.readme_section(s)


@pytest.mark.slow
def test_study_clutter_failures_quick(tmp_path):
    out = tmp_path / "scf"
    assert _load("study_clutter_failures").main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["grasps"] == len(s["rows"]) == sum(s["causes"].values()) >= 1
    assert s["lifted_target"] <= s["removed"] <= s["placed"] == 2
    for r in s["rows"]:
        assert r["segment"] in ("planned", "reused") and 0.0 <= r["score"] <= 1.0
        assert all(0.0 <= v <= 1.0 for v in r["outside_3_6_10mm"]) and r["parts"]
        assert bool(r["overlaps_mm"]) <= r["cause"].startswith("start_collision")
        assert r["lowest_planned_mm"] == r["lowest_executed_mm"]  # no execution error: the planned pose


@pytest.mark.slow
def test_study_scene_budget_quick_pairs_the_budgets(tmp_path):
    study = _load("study_scene_budget")
    out = tmp_path / "ssb"
    assert study.main(["--quick", "--out", str(out)]) == 0
    s = _summary(out)
    rows = {r["budget"]: r for r in s["rows"]}
    assert set(rows) == {"32:200", "4:50"} and len(s["episodes"]) == 2
    for r in rows.values():
        assert r["scenes"] == 1 and r["successes"] <= r["attempts"] and r["removed"] <= r["placed"] == 2
        # one plan_scene call at least per executed grasp, the first frame's among them
        e = next(e for e in s["episodes"] if e["budget"] == r["budget"])
        assert len(e["plan_cpu_s"]) == len(e["scored"]) >= e["attempts"] >= 1 and all(c > 0 for c in e["plan_cpu_s"])
        assert r["first_frame_cpu_s"]["count"] == r["first_frame_scored"]["count"] == 1
        assert 0 <= r["scenes_building_maps"] <= r["scenes"]
    assert rows["32:200"]["differs_from_reference"] == 0  # the reference is itself
    # the smaller budget stops each segment sooner: fewer grasps scored in the same first frame
    assert 0 < rows["4:50"]["first_frame_scored"]["median"] < rows["32:200"]["first_frame_scored"]["median"]
    assert s["command"] in study.readme_section(s)


def test_study_scene_budget_leaves_a_skipped_scene_out_of_every_budget():
    study = _load("study_scene_budget")
    cfg = study.Config(budgets=("32:200", "8:100"), kinds=("pile",), scenes=3)

    def ep(budget, scene, ok, skipped=None):
        if skipped:
            return {"kind": "pile", "budget": budget, "scene": scene, "skipped": skipped}
        return {"kind": "pile", "budget": budget, "scene": scene, "skipped": None, "placed": 2, "removed": ok,
                "attempts": 2, "successes": ok, "stop": "cleared", "causes": ["success"] * ok + ["dropped"] * (2 - ok),
                "scores": [0.9, 0.8], "plan_cpu_s": [0.5, 0.2], "scored": [100, 40], "planning_s": [0.3, 0.1],
                "built_in_memory": []}

    # scene 1 failed under 8:100 only: it leaves both rows, and the pairing
    eps = [ep("32:200", 0, 2), ep("32:200", 1, 2), ep("32:200", 2, 1),
           ep("8:100", 0, 1), ep("8:100", 1, 0, skipped="did not settle"), ep("8:100", 2, 1)]
    rows = {r["budget"]: r for r in study.summarize(cfg, eps)}
    for r in rows.values():
        assert r["scenes"] == 2 and r["skipped_scenes"] == [1] and r["attempts"] == 4
    assert (rows["32:200"]["successes"], rows["8:100"]["successes"]) == (3, 2)
    assert rows["8:100"]["differs_from_reference"] == 1 and rows["32:200"]["differs_from_reference"] == 0
    assert [a["scene"] for a, _ in study._paired(eps, "pile", "8:100", "32:200")] == [0, 2]


def test_scene_budgets_parse_or_are_refused():
    from graspsim.planning.scene_config import budget_fields

    assert budget_fields("") == {} and budget_fields("8:100") == {"enough": 8, "per_segment": 100}
    for bad in ("32", "a:b", "0:10", "8:-1", "8:100:1"):
        with pytest.raises(ValueError, match="budget"):
            budget_fields(bad)
    study = _load("study_scene_budget")
    with pytest.raises(ValueError, match="distinct"):
        study.Config(budgets=("8:100", "8:100"))
    with pytest.raises(ValueError, match="budget"):
        study.Config(budgets=("32:200", ""))


@pytest.mark.slow
def test_bench_mesh_prep_quick_times_first_cached_and_trial_in_fresh_processes(tmp_path):
    bench = _load("bench_mesh_prep")
    assert bench.main(["--quick", "--out", str(tmp_path / "b")]) == 0
    s = _summary(tmp_path / "b")
    (row,) = s["rows"]
    assert row["mesh"] == "open_cylinder_128f" and not row["watertight"] and row["mass_from"] == "parts"
    assert row["first"]["wall_s"] > row["first"]["call_s"] > 0 and row["cached"]["import_s"] > 0
    assert row["trial"]["exit"] == 0 and row["trial"]["trials"] == 10
    assert s["goals"]["first"]["of"] == s["goals"]["cached"]["of"] == s["goals"]["trial"]["of"] == 1
    md = bench.readme_section(s)
    assert s["command"] in md and "| open_cylinder_128f | 128 | no |" in md


def test_bench_mesh_prep_reported_summary_renders():
    """The committed numbers the README quotes come with their command, load and goals."""
    bench = _load("bench_mesh_prep")
    s = json.loads((EXPERIMENTS / "reported" / "bench_mesh_prep.json").read_text())
    md = bench.readme_section(s)
    assert s["command"].startswith("python experiments/bench_mesh_prep.py") and s["command"] in md
    names = {r["mesh"] for r in s["rows"]}
    assert {"open_cylinder_512f", "cylinder_327680f", "torus_500000f", "pybullet/lego"} <= names
    assert s["goals"]["meshes"] == len(s["rows"]) and "from the cache" in md


@pytest.mark.slow
def test_bench_reach_quick(tmp_path):
    mod = _load("bench_reach")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    (row,) = s["rows"]
    assert row["kind"] == "box" and row["best"] == 10 and sum(row["verdicts"].values()) == 10
    assert row["lookup_poses"] >= 20_000 and row["poses_per_s"] > 0
    assert (tmp_path / "reach-cache").is_dir()  # the capability map cached under --out, not the user's cache
    assert s["command"] in mod.readme_section(s)


@pytest.mark.slow
def test_e16_quick_pairs_arm_and_floating_on_the_same_grasps(tmp_path):
    mod = _load("e16_arm_execution")
    assert mod.main(["--quick", "--out", str(tmp_path)]) == 0
    s = _summary(tmp_path)
    assert s["episodes"] == 2 and s["top1_arm"]["n"] == s["top1_floating"]["n"] == 2
    assert s["executed_unreachable"] == 0  # never executes what the check refused
    for e in s["rows"][0]["episodes"]:
        assert len(e["arm"]) == len(e["reach"]) == 3
    d = s["clutter"]["database"]  # read only during the run: both conditions plan against the same stored maps
    assert d["maps"] and len(list((tmp_path / "fsdb").rglob("*.h5"))) == len(d["maps"])
    assert s["command"] in mod.readme_section(s)


def test_e16_clutter_plans_both_conditions_against_one_read_only_database(tmp_path, monkeypatch):
    """The floating gripper and the arm clear their scenes against the same database,
    never stored into during the run (a database grown by whichever ran first would
    plan the second differently)."""
    from graspsim.grippers import get_gripper
    from graspsim.tabletop import clutter

    mod = _load("e16_arm_execution")
    common = _load("_common")
    seen = []

    class Stop(Exception):
        pass

    def fake(*args, db, **kwargs):
        seen.append(db)
        if len(seen) == 2:
            raise Stop
        return []

    monkeypatch.setattr(clutter, "run_benchmark", fake)
    cfg = mod.Config(**mod.Config.QUICK)
    with pytest.raises(Stop):
        mod.run_clutter_part(cfg, get_gripper(cfg.gripper), tmp_path)
    assert seen[0] is seen[1] and isinstance(seen[0], common.RunDatabase)
    assert seen[0].root == tmp_path / "fsdb"


def test_e10_unseen_margin_reaches_the_planner(tmp_path, monkeypatch, capsys):
    """E10 --unseen-margin [M] (alone: the measured UNSEEN_MARGIN) reaches every scene's
    planner through the scene commands' path (with_unseen_margin) and its config record;
    without it the scene planner's default; a bad margin is a one-line error."""
    from graspsim.maps.robust import UNSEEN_MARGIN
    from graspsim.planning.scene_config import SceneConfig

    mod = _load("e10_clutter_removal")
    common = sys.modules["_common"]
    seen = []
    monkeypatch.setattr(mod, "run_benchmark", lambda *a, config, **k: seen.append(config) or [])
    default = SceneConfig().planner.robust.unseen_margin
    for argv, want in (([], default), (["--unseen-margin"], UNSEEN_MARGIN), (["--unseen-margin", "0.01"], 0.01)):
        cfg, _ = common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--scenes", "1",
                                                                "--seeds", "1", *argv])
        assert cfg.unseen_margin == (None if not argv else want)
        for c in mod.conditions(cfg)[:2]:
            mod._block((c, cfg, str(tmp_path / "db"), 0, 1))
            assert seen[-1].planning.planner.robust.unseen_margin == want, (argv, c)
    assert UNSEEN_MARGIN > 0
    with pytest.raises(SystemExit):
        common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--unseen-margin", "0.5"])
    assert "unseen margin" in capsys.readouterr().err


def test_e10_seen_between_reaches_the_planner(tmp_path, monkeypatch, capsys):
    """E10 --seen-between N reaches every scene's planner through the scene commands' path
    (with_seen_between); without it the scene planner's default; a bad count is refused."""
    from graspsim.planning.scene_config import SceneConfig

    mod = _load("e10_clutter_removal")
    common = sys.modules["_common"]
    seen = []
    monkeypatch.setattr(mod, "run_benchmark", lambda *a, config, **k: seen.append(config) or [])
    for argv, want in (([], SceneConfig().planner.seen_between), (["--seen-between", "0"], 0),
                       (["--seen-between", "9"], 9)):
        cfg, _ = common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--scenes", "1",
                                                                "--seeds", "1", *argv])
        for c in mod.conditions(cfg)[:2]:
            mod._block((c, cfg, str(tmp_path / "db"), 0, 1))
            assert seen[-1].planning.planner.seen_between == want, (argv, c)
    with pytest.raises(SystemExit):
        common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--seen-between", "-2"])
    assert "whole number >= 0" in capsys.readouterr().err


def test_e10_feature_grasps_reach_the_planner(tmp_path, monkeypatch, capsys):
    """E10 --feature-grasps reaches every scene's settings through the scene commands' path
    (with_feature_grasps): by default (fallback) feature grasps on packed tables, and in piles
    only as a frame's last resort (not in the segments' settings); apart, always and never as
    said; a bad value is refused."""
    mod = _load("e10_clutter_removal")
    common = sys.modules["_common"]
    seen = []
    monkeypatch.setattr(mod, "run_benchmark", lambda *a, config, **k: seen.append(config) or [])
    for argv, want in (([], {"pile": False, "packed": True}), (["--feature-grasps", "apart"], {"pile": False,
                       "packed": True}), (["--feature-grasps", "always"], {"pile": True,
                       "packed": True}), (["--feature-grasps", "never"], {"pile": False, "packed": False})):
        cfg, _ = common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--scenes", "1",
                                                                "--seeds", "1", "--kinds", "pile", "packed", *argv])
        conds = mod.conditions(cfg)
        assert {c["kind"] for c in conds} == {"pile", "packed"}
        for c in conds:
            mod._block((c, cfg, str(tmp_path / "db"), 0, 1))
            assert (seen[-1].planning.segment_features is not None) == want[c["kind"]], (argv, c)
            assert seen[-1].planning.feature_grasps == (argv[1] if argv else "fallback")
    with pytest.raises(SystemExit):
        common.parse_config(mod.Config, mod.__file__, ["--object-sets", "primitives", "--feature-grasps", "x"])
    assert "--feature-grasps" in capsys.readouterr().err


def test_scene_fingerprint_names_a_bad_object_set_or_size(tmp_path, capsys):
    fp = _load("scene_fingerprint")
    for argv, what in ((["--object-set", "no-such-set"], "unknown object set"), (["--objects", "11"], "--objects")):
        with pytest.raises(SystemExit) as e:
            fp.main([*argv, "--out", str(tmp_path / "x")])
        assert e.value.code == 2 and what in capsys.readouterr().err
    assert not (tmp_path / "x" / "summary.json").exists()


@pytest.mark.slow
def test_bench_first_frame_quick_plans_each_frame_cold_then_another_warm(tmp_path):
    bench = _load("bench_first_frame")
    assert bench.main(["--quick", "--out", str(tmp_path / "b")]) == 0
    s = _summary(tmp_path / "b")
    (g,) = s["groups"]
    assert (g["kind"], g["objects"]) == ("pile", 5)
    assert [(r["seed"], r["warm_seed"]) for r in g["runs"]] == [(500, 501), (501, 500)]  # each cold, the next warm
    for r in g["runs"]:
        for w in ("cold", "warm"):
            assert r[w]["timing"]["total"] > 0 and r[w]["segments"] >= 1 and r[w]["grasps"] >= 1
        assert r["wall_s"] > r["cold"]["timing"]["total"] + r["warm"]["timing"]["total"]
    assert g["cold"]["total"]["n"] == g["warm"]["total"]["n"] == 2
    assert "| pile, 5 objects (2) |" in bench.readme_section(s)


@pytest.mark.slow
def test_study_start_collisions_finds_the_gripper_part_in_an_object(tmp_path):
    """The gripper posed with its pads' centre at an object's centre, jaws open less than the
    object is wide: study_start_collisions.contacts names a pad (finger) in that object, a
    few mm deep; lifted 30 cm clear, nothing. The quick run replays an episode."""
    study = _load("study_start_collisions")
    from graspsim.tabletop.table_scene import make_scene

    scene = make_scene(1, "packed", 3, object_set="primitives")
    sim = scene.sim()
    try:
        g = sim.gripper
        c = sim.data.xipos[sim.body[0]].copy()
        R = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # from above, closing along x
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, c - R @ np.asarray(g.nominal_tcp, float)
        hits = study.contacts(sim, T, 0.005)
        assert hits and hits[0]["what"] == 0 and hits[0]["depth"] > 0.001
        assert any(h["part"].startswith("finger") and h["what"] == 0 for h in hits)
        T[2, 3] += 0.3
        assert not [h for h in study.contacts(sim, T, 0.005) if h["depth"] > 0]
    finally:
        sim.close()
    out = tmp_path / "ssc"
    assert study.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["rows"] and all(r["case"] == "0:0" for r in s["rows"])
    for r in s["rows"]:
        assert ("hits" in r) == r["cause"].startswith("start_collision")


@pytest.mark.slow
def test_study_drops_quick_replays_the_grasps_it_executed(tmp_path):
    out = tmp_path / "sd"
    assert _load("study_drops").main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    replayed = [r for r in s["rows"] if "replay" in r]
    assert replayed and all(r["cause"] in ("success", "dropped", "slipped", "no_contact") for r in replayed)
    for r in replayed:
        rep = r["replay"]
        assert rep["mass_kg"] > 0 and set(rep["variants"]) == {"impratio100"}
        if r["cause"] == "success":  # the step-by-step replay is the executed grasp: held through the hold
            assert rep["lost"] is None and rep["variants"]["impratio100"]["held"]
            pads = rep["close"]["pads"]
            assert set(pads) == {"neg", "pos"} and all(0.0 <= p["normal_vs_axis_deg"] <= 90.0 for p in pads.values())


def test_provenance_calls_a_tree_dirty_for_code_not_for_published_summaries(tmp_path, monkeypatch):
    """A run's ``--publish`` writes experiments/reported/: that alone must not mark the next
    run's commit ``-dirty``; a changed tracked file anywhere else must."""
    import shutil
    import subprocess

    if shutil.which("git") is None:
        pytest.skip("git not installed")
    common = _load("_common")
    repo = tmp_path / "repo"
    (repo / "experiments" / "reported").mkdir(parents=True)
    (repo / "experiments" / "reported" / "e.json").write_text("{}")
    (repo / "code.py").write_text("x = 1\n")

    def git(*a):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *a], cwd=repo, check=True,
                       capture_output=True)

    git("init", "-q")
    git("add", "-A")
    git("commit", "-q", "-m", "init")
    monkeypatch.setattr(common, "EXPERIMENTS", repo / "experiments")
    assert not common.provenance()["commit"].endswith("-dirty")
    (repo / "experiments" / "reported" / "e.json").write_text('{"new": 1}')
    (repo / "scratch.txt").write_text("untracked")
    assert not common.provenance()["commit"].endswith("-dirty")
    (repo / "code.py").write_text("x = 2\n")
    assert common.provenance()["commit"].endswith("-dirty")


def test_study_identification_stability_counts_each_variant_once(tmp_path):
    """The study adapts a cloud and its jittered variants through adapt_cloud: one record per
    variant, with its attempts, and the pooled rows add up."""
    study = _load("study_identification_stability")
    assert study.main(["--objects-dir", "assets/objects", "--objects", "pybullet/lego.stl", "--views", "full",
                       "--jitters", "2", "--db", str(tmp_path / "db"), "--out", str(tmp_path / "s")]) == 0
    s = _summary(tmp_path / "s")
    (row,) = s["rows"]
    assert len(row["variants"]) == 3 and row["usable"] == sum(v["accepted"] > 0 for v in row["variants"])
    assert all(v["attempts"] is None or v["attempts"] >= 1 for v in row["variants"])
    pool = s["pooled"]["development/full"]
    assert pool["variants"] == 3 and pool["usable"] == row["usable"] and pool["clouds"] == 1
    assert s["command"] in study.readme_section(s)


def test_seen_between_study_counts_each_grasp_in_one_band_and_refuses_held_out_sets(capsys):
    """study_seen_between: every grasp lands in exactly one band of its point count, its
    outcome in exactly one column; a held-out set is refused before any work."""
    mod = _load("study_seen_between")
    common = sys.modules["_common"]
    grasps = [{"between": n, "cause": c, "success": c == "success"}
              for n, c in ((0, "success"), (0, "no_contact"), (3, "start_collision_target"), (4, "dropped"),
                           (5, "success"), (9, "no_contact"), (10, "success"), (29, "no_contact"), (30, "success"),
                           (49, "slipped"), (50, "success"), (10_000, "start_collision_table"))]
    rows = mod.bands(grasps)
    assert [r["grasps"] for r in rows] == [2, 2, 2, 2, 2, 2]
    for r in rows:
        assert r["lifted"] + r["no_contact"] + r["start_collision"] + r["other_failures"] == r["grasps"]
    assert [r["lifted"] for r in rows] == [1, 0, 1, 1, 1, 1] and rows[1]["other_failures"] == 1
    assert rows[-1]["start_collision"] == 1
    # the sparse split: 5 to SPARSE_BETWEEN - 1 points against the rest, per kind and pooled; under 5: neither
    eps = [{"kind": "pile", "skipped": None, "grasps": grasps[:8]}, {"kind": "packed", "skipped": None,
                                                                    "grasps": grasps[8:]}]
    split = {r["kind"]: r for r in mod.sparse_split(eps)}
    assert split["pile"]["sparse"] == {"grasps": 4, "lifted": 2} and split["pile"]["other"]["grasps"] == 0
    assert split["packed"]["other"] == {"grasps": 4, "lifted": 2}
    assert split["both"]["sparse"]["grasps"] + split["both"]["other"]["grasps"] == 8 and mod.sparse_split([]) == []
    with pytest.raises(SystemExit):
        common.parse_config(mod.Config, mod.__file__, ["--object-sets", "household-heldout"])
    assert "held-out" in capsys.readouterr().err


def test_e10_score_bands_counts_each_grasp_in_its_band_source_and_object(tmp_path, capsys):
    """e10_score_bands: every grasp of the chosen execution error in one score band (edges
    belong to the band above), lifted and start collisions counted; by source and by
    object only where the run records them; bad edges and no runs are one line."""
    mod = _load("e10_score_bands")

    def cond(noise, eps, extra=True):
        return {"object_set": "s", "kind": "pile", "objects": 5, "noise": noise, "ablation": None,
                "episodes": [{"causes": c, "scores": sc, **({"sources": src, "targets": t} if extra else {})}
                             for c, sc, src, t in eps]}

    ok, sc, nc = "success", "start_collision_target", "no_contact"
    run = {"conditions": [
        cond("none", [([ok, sc], [0.9, 0.3], ["box", "features"], ["a", "b"]),
                      ([nc, ok, ok], [0.5, 0.85, 0.2], ["cylinder", "box", "box"], ["a", "a", "b"])]),
        cond("default", [([sc], [0.1], ["box"], ["a"])]),
        {**cond("none", [([ok], [0.99], None, None)], extra=False), "object_set": "t"}]}
    s = mod.score_bands([run])
    assert s["bands"] == ["< 0.5", "0.5 to 0.85", ">= 0.85"]
    assert s["sets"]["s"] == {"< 0.5": {"grasps": 2, "lifted": 1, "start_collision": 1},
                              "0.5 to 0.85": {"grasps": 1, "lifted": 0, "start_collision": 0},
                              ">= 0.85": {"grasps": 2, "lifted": 2, "start_collision": 0}}
    assert s["sets"]["t"][">= 0.85"]["grasps"] == 1  # no sources or targets recorded: counted all the same
    (label,) = s["by_source"]
    assert s["by_source"][label]["box"]["< 0.5"] == {"grasps": 1, "lifted": 1, "start_collision": 0}
    assert s["by_source"][label]["other"]["0.5 to 0.85"]["grasps"] == 1  # the cylinder
    assert s["below_top_by_object"][label] == {"b": {"grasps": 2, "below": 2, "below_failed": 1},
                                               "a": {"grasps": 3, "below": 1, "below_failed": 1}}
    assert mod.score_bands([run], "default")["sets"]["s"]["< 0.5"]["start_collision"] == 1
    f = tmp_path / "run.json"
    f.write_text(json.dumps(run))
    assert mod.main(["--runs", str(f), "--out", str(tmp_path / "out")]) == 0
    assert "| s | 1/2, 1 start coll. | 0/1, 0 start coll. | 2/2, 0 start coll. |" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="ascend"):
        mod.main(["--runs", str(f), "--edges", "0.9", "0.5", "--out", str(tmp_path / "out")])
    with pytest.raises(SystemExit, match="--runs"):
        mod.main(["--out", str(tmp_path / "out")])


def test_e10_paired_counts_same_better_and_worse_episodes(tmp_path, capsys):
    """e10_paired pairs two runs' episodes by condition, seed and scene: same (causes and
    removed equal), more or fewer removed, as many by other attempts, the changed ones among
    the episodes the earlier run ended with no grasp; a condition in one run only is named
    and skipped; a missing file is one line."""
    mod = _load("e10_paired")

    def cond(kind, eps):
        return {"object_set": "s", "kind": kind, "objects": 5, "noise": "none", "ablation": None,
                "episodes": [{"seed": 1, "scene": i, "causes": c, "removed": r, "placed": 5,
                              "successes": c.count("success"), "attempts": len(c),
                              "stop": "cleared" if r == 5 else "no_grasp" if c[-1] == "success" else "failures"}
                             for i, (c, r) in enumerate(eps)]}

    ok, fail = "success", "no_contact"
    base = {"conditions": [cond("pile", [([ok] * 5, 5), ([ok, fail, fail], 1), ([ok] * 5, 5), ([fail, ok], 1)]),
                           cond("packed", [([ok], 1)])]}
    new = {"conditions": [cond("pile", [([ok] * 5, 5), ([ok] * 5, 5), ([ok, fail, fail], 1), ([ok, fail], 1)])]}
    rows, only = mod.compare(base, new)
    (r,) = rows
    assert (r["paired"], r["same"], r["more_removed"], r["fewer_removed"], r["otherwise"]) == (4, 1, 1, 1, 1)
    assert r["base_removed"] == r["new_removed"] == 12 and r["new_attempts"] == 15
    assert (r["base_no_grasp"], r["changed_no_grasp"]) == (1, 1)  # [fail, ok] ended with no grasp, then changed
    assert only == ["s packed of 5, no execution error"]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(base))
    b.write_text(json.dumps(new))
    assert mod.main(["--base", str(a), "--new", str(b), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr()
    assert "1 of 4 paired episodes the same" in out.out and "only in one run" in out.err
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["rows"][0]["same"] == 1
    with pytest.raises(SystemExit, match="not a file"):
        mod.main(["--base", str(tmp_path / "missing.json"), "--new", str(b), "--out", str(tmp_path / "out")])


@pytest.mark.slow
def test_study_timestep_simulates_each_grasp_at_every_step_then_executes_it_as_run(tmp_path, monkeypatch):
    """study_timestep: every executed grasp is simulated, uncommitted, at the run's step and
    at each finer one, then executed by the episode at the run's step (the model's step
    restored); the simulation at the run's step gives the episode's outcome."""
    from graspsim.tabletop.scene_sim import SceneSim

    seen = []
    real = SceneSim.execute

    def spy(self, *a, commit=True, **k):
        seen.append((round(float(self.model.opt.timestep), 7), commit))
        return real(self, *a, commit=commit, **k)

    monkeypatch.setattr(SceneSim, "execute", spy)
    out = tmp_path / "st"
    assert _load("study_timestep").main(["--quick", "--steps", "0.0005", "0.00025", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    rows = s["rows"]
    assert rows and seen == [(0.001, False), (0.0005, False), (0.00025, False), (0.001, True)] * len(rows)
    for r in rows:
        assert set(r["again"]) == {repr(0.001), repr(0.0005), repr(0.00025)} and r["again"][repr(0.001)] == r["cause"]
    (c,) = s["conditions"]
    assert c["grasps"] == len(rows) and c["as_run_differs"] == 0
    for key, v in c["steps"].items():
        assert v["lifted"] == sum(r["again"][key] == "success" for r in rows)
        assert len(v["changed"]) == sum(r["again"][key] != r["cause"] for r in rows)


def test_bench_scene_replay_gives_every_frame_the_margin_asked_for():
    """``--unseen-margin`` reaches the planner of every frame replayed, by E10's path
    (``with_unseen_margin``), and without it each frame keeps the settings it was captured with."""
    import types
    from unittest import mock

    from graspsim.planning.scene_config import SceneConfig, with_unseen_margin

    bench = _load("bench_scene_replay")
    seen = []

    def plan(points, *, db, config, **kw):
        seen.append((config.workers, config.planner.robust.unseen_margin))
        return types.SimpleNamespace(grasps=[], segments=[], timing={})

    captured = with_unseen_margin(SceneConfig(), 0.01)
    frames = [(np.zeros((3, 3)), {"config": captured, "rng": np.random.default_rng(0), "previous": None})] * 2
    with mock.patch("graspsim.planning.scene.plan_scene", plan):
        bench.replay(frames, None, 1, unseen_margin=0.03)
        assert seen == [(1, 0.03)] * 4  # an untimed and a timed plan of each frame, in this process
        seen.clear()
        bench.replay(frames, None, 1)
    assert seen == [(1, 0.01)] * 4


@pytest.mark.slow
def test_bench_scene_replay_quick(tmp_path):
    """A capture of E10's frames replays as the episode planned them (every frame, every
    timed round), and a replay of the saved capture plans them alike again."""
    bench = _load("bench_scene_replay")
    out = tmp_path / "bsr"
    assert bench.main(["--quick", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["frames"] >= 1 and len(s["digests"]) == s["frames"]
    assert s["episode_unlike_replay"] == 0 and s["replays_unlike_first"] == 0
    assert s["cpu_per_frame"] > 0 and all(len(r) == s["frames"] for r in s["cpu_s"])
    shares = [v["share"] for v in s["segments"].values()]
    assert shares and abs(sum(shares) - 1.0) < 1e-9
    assert s["command"] in bench.readme_section(s)
    again = tmp_path / "bsr2"
    assert bench.main(["--quick", "--frames", str(out / "frames.pkl"), "--out", str(again)]) == 0
    s2 = json.loads((again / "summary.json").read_text())
    assert s2["digests"] == s["digests"] and s2["episode_unlike_replay"] is None
