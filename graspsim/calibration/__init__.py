"""Grade-vs-success calibration: trials, statistics, reports, figures.

Pure statistics live in :mod:`graspsim.stats`; the trials (which need
mujoco) in :mod:`graspsim.calibration.trials`, imported on first use; simulation
conditions and their presets in :mod:`graspsim.calibration.conditions`; the success-rate
regression in :mod:`graspsim.calibration.regression`.

May use: the base modules, geometry, primitives, grippers, grades, maps, plots, perception,
planning and sim (never tabletop, the viewer, the envs, the apps or the CLI).
"""

from __future__ import annotations

from graspsim.calibration.report import CalibrationReport, ScoreReport, calibrate, score_report
from graspsim.calibration.sampling import stratified_rows
from graspsim.calibration.trial_table import TrialTable
from graspsim.stats import (
    Reliability,
    bootstrap,
    fit_logistic,
    logistic_predict,
    precision_recall,
    reliability,
    roc_auc,
    roc_curve,
    threshold_for_precision,
    wilson_interval,
    youden_threshold,
)

_CAMPAIGN = ("CalibrationCase", "SimCondition", "FRICTION_LIMITED", "CONDITIONS", "CaseSample",
             "draw_samples", "simulate_samples", "case_seed")

__all__ = [
    "CalibrationReport", "ScoreReport", "calibrate", "score_report",
    "stratified_rows",
    "Reliability", "bootstrap", "fit_logistic", "logistic_predict", "precision_recall",
    "reliability", "roc_auc", "roc_curve", "threshold_for_precision", "wilson_interval",
    "youden_threshold", "TrialTable", *_CAMPAIGN,
]


def __getattr__(name: str):
    if name in _CAMPAIGN:  # keeps mujoco out of plain imports
        from graspsim.calibration import trials

        return getattr(trials, name)
    raise AttributeError(f"module 'graspsim.calibration' has no attribute {name!r}")
