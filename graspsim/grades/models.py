"""Grade models: the paper's grade and a calibrated flat-pad contact grade, selectable.

* :class:`PaperGrade` -- the paper's grade (``QualityModel``: force closure + stability,
  accepted > 0.7). It is the default everywhere, for reproducing the paper.
* :class:`LogisticGrade` -- P(success) of a logistic model on the features of
  :mod:`graspsim.grades.grade_features`, fitted to simulated lift-and-place trials and shipped
  as JSON with its provenance (``graspsim/data/grade_model.json``, name
  ``"pad_contact"``); its threshold is the one that reached the target precision on
  objects held out from the fit.

:func:`regrade` gives a map the grade of a model; the map records it in
``meta.quality``: ``name``, ``threshold``, ``d_ref``, the model (``grade_model``) and
the quality it replaced (``base_quality``).

A calibrated grade is a gripper's: its pad features and the outcomes it was fitted to
are that gripper's. Each model names the gripper it was fitted for (``gripper``, with
the spec's digest); ``"pad_contact"`` resolves to the model shipped for a map's gripper
(:func:`model_path`: ``grade_model.json`` for the Festo HGPL-25-60-A,
``grade_model.<gripper>.json`` for the others), and grading a map of another gripper
with a model is a :class:`~graspsim.errors.GripperError`.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np
from scipy.special import expit

from graspsim.errors import GripperError, InvalidParameterError
from graspsim.grades.grade_features import FEATURES, FeatureConfig, map_features
from graspsim.grades.paper import QualityModel

__all__ = ["PaperGrade", "LogisticGrade", "get_grade", "regrade", "GRADE_NAMES",
           "model_path", "gripper_identity", "check_gripper"]

GRADE_NAMES = ("paper", "pad_contact")
log = logging.getLogger(__name__)
#: The gripper of the first shipped model (``grade_model.json``, fitted before models
#: named their gripper: E12 at a577077 fitted it on Festo trials).
FESTO = "festo_hgpl_25_60_a"


def model_path(gripper: str = FESTO) -> Path:
    """Where the calibrated model shipped for ``gripper`` (a name) lives:
    ``graspsim/data/grade_model.json`` (the Festo's) or ``grade_model.<name>.json``."""
    if not isinstance(gripper, str) or not gripper or "/" in gripper or "\\" in gripper:
        raise GripperError(f"a grade model's gripper is a gripper name, got {gripper!r}")
    name = "grade_model.json" if gripper == FESTO else f"grade_model.{gripper}.json"
    return Path(str(resources.files("graspsim") / "data" / name))


def gripper_identity(spec) -> dict:
    """``{"name", "digest"}`` of a gripper (a ``GripperSpec`` or its dict): what a
    fitted model records as the gripper it was fitted for."""
    from graspsim.grippers import gripper_key

    d = gripper_key(spec, missing_ok=True)  # a model file by its content (a copy: the same gripper)
    digest = hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:10]
    return {"name": str(d.get("name")), "digest": digest}


def check_gripper(model, gripper: dict) -> None:
    """Refuse (GripperError) to grade grasps of ``gripper`` (a map's ``meta.gripper``)
    with a model fitted for another gripper (a model that names none, an old file, is
    the Festo's); the same name with another spec digest is logged as a warning. The
    paper's grade (no ``gripper`` field) sees only the contacts: any gripper."""
    if not hasattr(model, "gripper"):
        return
    fitted = model.gripper or {"name": FESTO}
    name = str(gripper.get("name"))
    if fitted.get("name") != name:
        raise GripperError(
            f"grade model {model.name!r} was fitted for gripper {fitted.get('name')!r}; the map is of "
            f"{name!r} (fit one for it: python experiments/e12_fit_grade_model.py --gripper {name})")
    digest = gripper_identity(gripper)["digest"]
    if fitted.get("digest") not in (None, digest):
        log.warning("grade model %r was fitted for another spec of gripper %r (digest %s, the map's %s)",
                    model.name, name, fitted["digest"], digest)


def _rows(gmap, rows):
    return np.arange(len(gmap)) if rows is None else np.asarray(rows)


@dataclass(frozen=True)
class PaperGrade:
    """The paper's grade, w q_fc + (1 - w) q_st, of the map's contacts (docs/design.md §5)."""

    quality: QualityModel = QualityModel()

    @property
    def name(self) -> str:
        return self.quality.name

    @property
    def threshold(self) -> float:
        return self.quality.threshold

    def grade_rows(self, gmap, rows=None) -> np.ndarray:
        """Grades (n,) of the map's rows (all, or indices/mask ``rows``)."""
        r = _rows(gmap, rows)
        c, n = gmap.contacts[r].astype(float), gmap.normals[r].astype(float)
        com = np.asarray(gmap.meta.object.get("com", np.zeros(3)), float)
        d_ref = gmap.meta.quality.get("d_ref")
        if d_ref is None:
            from graspsim.primitives import shape_from_dict

            d_ref = self.quality.reference_distance(shape_from_dict(gmap.meta.object).circumradius)
        return self.quality.evaluate(c[:, 0], c[:, 1], n[:, 0], n[:, 1], com, float(d_ref)).grade

    def apply(self, gmap):
        return regrade(gmap, self)

    def to_dict(self) -> dict:
        return {"kind": "paper", **self.quality.to_dict()}


@dataclass(frozen=True)
class LogisticGrade:
    """grade = expit(intercept + sum_k coef_k (x_k - mean_k) / scale_k) over the named
    features; an estimate of P(success) under the protocol it was fitted to.
    threshold: accepted above it. gripper: ``{"name", "digest"}`` of the gripper it was
    fitted for (:func:`gripper_identity`; None: a file from before models named it,
    the Festo's); maps of another gripper are refused. provenance: how it was fitted
    (script, seed, data, MuJoCo version, cross-validated scores)."""

    name: str
    features: tuple[str, ...]
    mean: tuple[float, ...]
    scale: tuple[float, ...]
    coef: tuple[float, ...]
    intercept: float
    threshold: float = 0.5
    feature_config: FeatureConfig = FeatureConfig()
    gripper: dict | None = field(default=None, compare=False, hash=False)
    provenance: dict = field(default_factory=dict, compare=False, hash=False)

    def __post_init__(self) -> None:
        for k in ("features", "mean", "scale", "coef"):
            object.__setattr__(self, k, tuple(getattr(self, k)))
        k = len(self.features)
        if not (len(self.mean) == len(self.scale) == len(self.coef) == k) or k == 0:
            raise InvalidParameterError(
                f"a logistic grade needs one mean, scale and coef per feature; got {k} features, "
                f"{len(self.mean)} means, {len(self.scale)} scales, {len(self.coef)} coefs")
        unknown = sorted(set(self.features) - set(FEATURES))
        if unknown:
            raise InvalidParameterError(f"unknown grade features {unknown}; valid: {list(FEATURES)}")
        if not all(s > 0 for s in self.scale):
            raise InvalidParameterError(f"feature scales must be > 0, got {self.scale}")
        if not 0.0 <= self.threshold <= 1.0:
            raise InvalidParameterError(f"threshold must be in [0, 1], got {self.threshold!r}")

    def score(self, feats: dict) -> np.ndarray:
        """Grades (n,) from a feature dict {name: (n,)} (extra keys ignored)."""
        z = np.full(len(feats[self.features[0]]), float(self.intercept))
        for k, m, s, c in zip(self.features, self.mean, self.scale, self.coef):
            z += c * (np.asarray(feats[k], float) - m) / s
        return expit(z)

    def grade_rows(self, gmap, rows=None) -> np.ndarray:
        check_gripper(self, gmap.meta.gripper)
        return self.score(map_features(gmap, self.features, rows, self.feature_config))

    def apply(self, gmap):
        return regrade(gmap, self)

    def to_dict(self) -> dict:
        return {"kind": "logistic", "name": self.name, "features": list(self.features),
                "mean": list(self.mean), "scale": list(self.scale), "coef": list(self.coef),
                "intercept": float(self.intercept), "threshold": float(self.threshold),
                "feature_config": self.feature_config.to_dict(),
                **({"gripper": dict(self.gripper)} if self.gripper is not None else {}),
                "provenance": self.provenance}

    @classmethod
    def from_dict(cls, d: dict) -> LogisticGrade:
        try:
            if d.get("kind", "logistic") != "logistic":
                raise InvalidParameterError(f"not a logistic grade model: kind {d.get('kind')!r}")
            return cls(name=d["name"], features=d["features"], mean=d["mean"], scale=d["scale"],
                       coef=d["coef"], intercept=float(d["intercept"]),
                       threshold=float(d.get("threshold", 0.5)),
                       feature_config=FeatureConfig(**d.get("feature_config", {})),
                       gripper=_gripper_field(d.get("gripper")), provenance=d.get("provenance", {}))
        except (KeyError, TypeError, AttributeError) as err:
            raise InvalidParameterError(f"bad logistic grade model: {err}") from err

    def save(self, path: str | os.PathLike) -> Path:
        from graspsim._atomic import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=1, sort_keys=False) + "\n",
                          InvalidParameterError)
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> LogisticGrade:
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise InvalidParameterError(f"cannot read grade model {path}: {err}") from err
        return cls.from_dict(d)


def _gripper_field(g) -> dict | None:
    if g is None:
        return None
    if not isinstance(g, dict) or not isinstance(g.get("name"), str):
        raise InvalidParameterError(f"a grade model's gripper is {{'name': ..., 'digest': ...}}, got {g!r}")
    return {"name": g["name"], **({"digest": str(g["digest"])} if "digest" in g else {})}


def get_grade(spec: str | os.PathLike | None = "paper", quality: QualityModel | None = None, *,
              gripper: str | None = None):
    """A grade model: ``"paper"`` (the default; ``quality`` overrides its parameters),
    ``"pad_contact"`` (the calibrated model shipped for ``gripper``, a name; default
    the Festo's; a GripperError when none was fitted for it) or a path to a model JSON."""
    if spec is None or spec == "paper":
        return PaperGrade(quality or QualityModel())
    if spec == "pad_contact":
        path = model_path(gripper or FESTO)
        if not path.exists():
            raise GripperError(f"no pad_contact grade model was fitted for gripper {gripper!r} (fit one: "
                               f"python experiments/e12_fit_grade_model.py --gripper {gripper} --install)")
        return LogisticGrade.load(path)
    p = Path(spec)
    if p.suffix == ".json" and p.exists():
        return LogisticGrade.load(p)
    raise InvalidParameterError(f"unknown grade {str(spec)!r}; valid: {list(GRADE_NAMES)} or a model .json")


def regrade(gmap, model, rows=None):
    """The map (or its ``rows``) with ``grade`` computed by ``model``; the other
    quality columns (fc_angle, q_fc, q_st, ...) stay the paper's. ``meta.quality``
    records the model (see the module docstring)."""
    sub = gmap if rows is None else gmap.select(rows)
    grade = np.asarray(model.grade_rows(sub), np.float32)
    old = dict(gmap.meta.quality)
    base = old.get("base_quality", {k: v for k, v in old.items() if k != "d_ref"})
    if isinstance(model, PaperGrade):
        quality = {**model.quality.to_dict(), "d_ref": old.get("d_ref")}
    else:
        spec = model.to_dict()
        spec.pop("provenance", None)  # the model file keeps it; the map keeps the parameters
        quality = {"name": model.name, "threshold": float(model.threshold), "d_ref": old.get("d_ref"),
                   "grade_model": spec, "base_quality": base}
    return replace(sub, grade=grade).with_meta(quality=quality)
