"""Fitted grade models are a gripper's: provenance, refusal for another gripper, and what
the robust score, the gripper adaptation and ``graspsim calibrate`` do with them."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import GripperError
from graspsim.grades import LogisticGrade, get_grade, regrade
from graspsim.grades.models import FESTO, check_gripper, gripper_identity, model_path
from graspsim.grippers import get_gripper
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box

COARSE = MapConfig(surface_step=0.012, rotation_step=math.radians(30.0), closing_cone=math.radians(30.0))
OTHER = replace(HGPL_25_60_A, name="my_gripper")  # a user's gripper: no model fitted for it


@pytest.fixture(scope="module")
def festo_map():
    return generate_fs_map(Box(0.04, 0.05, 0.08), HGPL_25_60_A, config=COARSE, threads=1)


@pytest.fixture(scope="module")
def other_map():
    return generate_fs_map(Box(0.04, 0.05, 0.08), OTHER, config=COARSE, threads=1)


def test_shipped_model_names_the_gripper_it_was_fitted_for():
    m = get_grade("pad_contact")
    assert m.gripper == gripper_identity(HGPL_25_60_A)
    assert LogisticGrade.from_dict(m.to_dict()).gripper == m.gripper
    assert model_path(FESTO).name == "grade_model.json"
    assert model_path("franka_hand").name == "grade_model.franka_hand.json"
    with pytest.raises(GripperError):
        model_path("../evil")


def test_a_model_refuses_maps_of_another_gripper(festo_map, other_map):
    festo = get_grade("pad_contact")
    with pytest.raises(GripperError, match="fitted for gripper 'festo_hgpl_25_60_a'; the map is of 'my_gripper'"):
        festo.grade_rows(other_map, np.arange(5))
    with pytest.raises(GripperError):
        regrade(other_map, festo)
    mine = LogisticGrade.from_dict({**festo.to_dict(), "gripper": gripper_identity(OTHER)})
    assert np.all(np.isfinite(mine.grade_rows(other_map, np.arange(5))))
    with pytest.raises(GripperError, match="fitted for gripper 'my_gripper'"):
        mine.grade_rows(festo_map, np.arange(5))
    legacy = LogisticGrade.from_dict({k: v for k, v in festo.to_dict().items() if k != "gripper"})
    assert legacy.gripper is None
    check_gripper(legacy, festo_map.meta.gripper)  # a model naming none is the Festo's
    with pytest.raises(GripperError):
        check_gripper(legacy, other_map.meta.gripper)


def test_pad_contact_resolves_per_gripper():
    with pytest.raises(GripperError, match="no pad_contact grade model was fitted for gripper 'my_gripper'"):
        get_grade("pad_contact", gripper="my_gripper")
    assert get_grade("pad_contact", gripper=FESTO).gripper["name"] == FESTO
    if model_path("franka_hand").exists():
        franka = get_grade("pad_contact", gripper="franka_hand")
        assert franka.gripper == gripper_identity(get_gripper("franka_hand"))
        assert franka.provenance["gripper"]["name"] == "franka_hand"


def test_robust_score_uses_the_maps_gripper_model_or_the_grade(festo_map, other_map):
    from graspsim.maps.robust import RobustConfig, score_map

    cfg = RobustConfig(top=20, samples=4)
    festo = score_map(festo_map, None, cfg)
    rows = np.flatnonzero(festo.robust_feasible > 0)[:5]
    expect = get_grade("pad_contact").grade_rows(festo_map, rows)
    np.testing.assert_allclose(festo.robust[rows], festo.robust_feasible[rows] * expect, rtol=1e-6)
    assert festo.meta.extra["robust"]["success_model"] == "pad_contact fitted for 'festo_hgpl_25_60_a'"
    other = score_map(other_map, None, cfg)  # no model for this gripper: its grade stands in
    rows = np.flatnonzero(other.robust_feasible > 0)[:5]
    np.testing.assert_allclose(other.robust[rows], other.robust_feasible[rows] * other_map.grade[rows], rtol=1e-6)
    assert "no pad_contact model fitted for gripper 'my_gripper'" in other.meta.extra["robust"]["success_model"]


def test_adapted_map_is_not_graded_by_the_source_grippers_model(festo_map):
    from graspsim.maps.regrip import adapt_to_gripper

    pad = regrade(festo_map, get_grade("pad_contact"))
    out = adapt_to_gripper(pad, OTHER)
    assert out.meta.quality["name"] == "paper"  # no model for OTHER: the paper's grade
    assert np.all((out.grade >= 0) & (out.grade <= 1))


def test_calibrate_refuses_a_model_of_another_gripper_before_simulating(other_map, tmp_path, capsys):
    from graspsim.cli import main
    from graspsim.maps import save_map

    path = tmp_path / "m.h5"
    save_map(other_map, path)
    model = tmp_path / "festo_model.json"
    get_grade("pad_contact").save(model)
    assert main(["calibrate", str(path), "--grade", str(model), "--per-bin", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fitted for gripper 'festo_hgpl_25_60_a'" in err[0]
    assert json.loads(model.read_text())["gripper"]["name"] == FESTO


def test_the_papers_grade_grades_any_gripper(other_map):
    from graspsim.grades import PaperGrade

    check_gripper(PaperGrade(), other_map.meta.gripper)
    np.testing.assert_allclose(PaperGrade().grade_rows(other_map, np.arange(5)), other_map.grade[:5], atol=1e-6)


def test_the_franka_hand_ships_its_own_model_and_the_robust_score_uses_it():
    from graspsim.maps.robust import RobustConfig, score_map

    franka = get_gripper("franka_hand")
    model = get_grade("pad_contact", gripper="franka_hand")
    assert model.gripper == gripper_identity(franka) and model.provenance["gripper"]["name"] == "franka_hand"
    assert model.provenance["trials"] > 1000 and model.provenance["cv_auc"]["object"] > 0.8
    fs = generate_fs_map(Box(0.04, 0.05, 0.06), franka, config=COARSE, threads=1)
    scored = score_map(fs, None, RobustConfig(top=20, samples=4))
    rows = np.flatnonzero(scored.robust_feasible > 0)[:5]
    assert len(rows)
    np.testing.assert_allclose(scored.robust[rows], scored.robust_feasible[rows] * model.grade_rows(fs, rows),
                               rtol=1e-6)
    assert scored.meta.extra["robust"]["success_model"] == "pad_contact fitted for 'franka_hand'"
    pad = regrade(fs, model)
    assert pad.meta.quality["grade_model"]["gripper"]["name"] == "franka_hand"
    with pytest.raises(GripperError):
        get_grade("pad_contact").grade_rows(fs, rows)  # the Festo's model: refused


@pytest.mark.parametrize("name", ["festo_hgpl_25_60_a", "franka_hand", "robotiq_2f85", "rethink_gripper"])
def test_every_registered_gripper_ships_a_grade_fitted_for_its_current_spec(name):
    # E12 per gripper (docs/results.md): a spec changed since its fit must be refitted
    m = get_grade("pad_contact", gripper=name)
    assert m.gripper == gripper_identity(get_gripper(name)) and 0 < m.threshold < 1
    assert m.provenance["script"] == "experiments/e12_fit_grade_model.py" and m.provenance["trials"] > 1000
