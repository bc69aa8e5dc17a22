"""Fitting a :class:`LogisticGrade` to trial outcomes, cross-validated by object.

The features are standardised, the logistic model is fitted by IRLS with a small ridge
penalty, and every score reported is *out of fold*: each object's trials are predicted
by a model fitted without that object (leave-one-object-out) -- and, stricter, without
any object of the same primitive kind. The shipped threshold is the one whose out-of-
fold precision reaches the target, so it was chosen on objects the model had not seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graspsim import stats
from graspsim.errors import InvalidParameterError
from graspsim.grades.grade_features import FeatureConfig
from graspsim.grades.models import LogisticGrade

__all__ = ["GradeFit", "fit_grade", "out_of_fold"]


@dataclass(frozen=True, eq=False)
class GradeFit:
    """The fitted model and its out-of-fold predictions (N,) per grouping
    ({"object": ..., "kind": ...}) with their pooled and per-group AUCs."""

    model: LogisticGrade
    oof: dict
    auc: dict
    auc_by_group: dict
    threshold_oof: float


def _design(X: np.ndarray, mean: np.ndarray, scale: np.ndarray) -> np.ndarray:
    return (X - mean) / scale


def out_of_fold(X: np.ndarray, y: np.ndarray, groups: np.ndarray, *, l2: float) -> np.ndarray:
    """Out-of-fold P(success) (N,): each group predicted by a fit without it."""
    p = np.full(len(y), np.nan)
    for g in np.unique(groups):
        te = groups == g
        if np.all(te):
            raise InvalidParameterError("cross-validation needs at least two groups")
        mean, scale = X[~te].mean(axis=0), X[~te].std(axis=0) + 1e-12
        b = stats.fit_logistic(_design(X[~te], mean, scale), y[~te], l2=l2)
        p[te] = stats.logistic_predict(b, _design(X[te], mean, scale))
    return p


def fit_grade(features: dict, success, objects, kinds=None, *, weights=None,
              names: tuple[str, ...] | None = None, l2: float = 1e-3, target: float = 0.97,
              name: str = "pad_contact", config: FeatureConfig = FeatureConfig(),
              provenance: dict | None = None, min_count: int = 20) -> GradeFit:
    """Fit P(success) on ``features`` ({name: (N,)}) of N trials.

    objects (N,): the object of each trial (held out together); kinds (N,): its
    primitive kind (for the stricter leave-one-kind-out check); weights (N,): population
    weights, used for the threshold's precision (not for the fit).
    """
    names = tuple(names or features)
    X = np.column_stack([np.asarray(features[k], float) for k in names])
    y = np.asarray(success, bool).astype(float)
    objects = np.asarray(objects)
    w = np.ones(len(y)) if weights is None else np.asarray(weights, float)
    if len(X) != len(y) or len(objects) != len(y):
        raise InvalidParameterError("features, success and objects need one entry per trial")
    oof = {"object": out_of_fold(X, y, objects, l2=l2)}
    if kinds is not None:
        oof["kind"] = out_of_fold(X, y, np.asarray(kinds), l2=l2)
    yb = y > 0
    auc = {k: stats.roc_auc(p, yb) for k, p in oof.items()}
    auc.update({f"{k}_population": stats.roc_auc(p, yb, w) for k, p in oof.items()})
    by_group = {str(g): stats.roc_auc(oof["object"][objects == g], yb[objects == g])
                for g in np.unique(objects)}
    t_oof = stats.threshold_for_precision(oof["object"], yb, target, w, min_count=min_count)
    mean, scale = X.mean(axis=0), X.std(axis=0) + 1e-12
    b = stats.fit_logistic(_design(X, mean, scale), y, l2=l2)
    thr = float(t_oof) if np.isfinite(t_oof) else 0.5
    model = LogisticGrade(name=name, features=names, mean=tuple(mean.tolist()),
                          scale=tuple(scale.tolist()), coef=tuple(b[1:].tolist()),
                          intercept=float(b[0]), threshold=min(max(thr, 0.0), 1.0),
                          feature_config=config, provenance=provenance or {})
    return GradeFit(model, oof, auc, by_group, float(t_oof))
