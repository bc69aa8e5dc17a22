"""Settings of the grasp environments: one frozen, validated dataclass.

``gymnasium.make("graspsim/GraspSelect-v0", **kwargs)`` passes its keyword arguments
here; an unknown name or a bad value raises :class:`InvalidParameterError` saying what
is valid. No mujoco here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from enum import Enum

import numpy as np

from graspsim.checks import NON_NEGATIVE, POSITIVE, Rule, check_fields, integer
from graspsim.envs.object_sets import resolve_object_set
from graspsim.errors import InvalidParameterError
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import DEFAULT_OPENINGS, POSITION_SIGMA, ROTATION_SIGMA

__all__ = ["EnvConfig", "Perception", "RewardMode", "View", "make_config"]

_FRACTION = Rule(lambda v: isinstance(v, (int, float)) and 0 <= v < 1, "a fraction in [0, 1)")
_SHARE = Rule(lambda v: isinstance(v, (int, float)) and 0 <= v <= 1, "a fraction in [0, 1]")


class RewardMode(str, Enum):
    BINARY = "binary"  # 1 for SUCCESS, else 0
    SHAPED = "shaped"  # 1 for SUCCESS, else partial credit from lift and slip (<= 0.5)


class Perception(str, Enum):
    CLOUD = "cloud"  # the paper's run-time stage: identify the object's primitives in the cloud
    MODEL = "model"  # the true primitives and pose are given (no identification error)


class View(str, Enum):
    FULL = "full"  # all around (merged views), minus what the table hides
    SINGLE = "single"  # one camera above the table at a random azimuth


@dataclass(frozen=True)
class EnvConfig:
    """Environment settings. Lengths [m], angles [rad].

    objects: object set name(s) (see :mod:`graspsim.envs.object_sets`): ``"primitives"``,
        ``"compounds"``, ``"all"``, a kind (``"cylinder"``, ``"bottle"``, ...) or a tuple.
    n_candidates: K, the number of candidate grasps offered (GraspSelect).
    cloud_size: N, points in the observed cloud (sampled from the sensor cloud, with
        repeats when it has fewer; the planner sees the whole sensor cloud).
    cloud_resolution, cloud_noise, cloud_outliers: the synthetic sensor (point spacing,
        Gaussian sigma, outlier fraction); view: ``"full"`` or ``"single"``;
        camera_distance: single-view camera distance from the object.
    table_cut: the table is segmented out by dropping points below this height.
    position_noise, rotation_noise: execution error of the robot per trial, Gaussian at
        the TCP (0 and 0: exact execution); the planner's robust score assumes the same
        error (:meth:`robust_sigmas`; with none, its default 3 mm / 2 deg).
    protocol: ``"lift_place"`` (default) or ``"tug"``, or a Protocol instance.
    reward: ``"binary"`` or ``"shaped"``.
    lying: probability that a cylinder lies on its side.
    placement: the object's centre of mass lands uniformly in [-placement, placement]^2
        on the table, at a uniform random yaw.
    table_margin: a candidate is valid only when its gripper (at the pre-grasp opening)
        stays this far above the table in the estimated object pose.
    pool_size: grasps used per stored FS map (see ``PooledDatabase``).
    db_root: map database folder (None: ``$GRASPSIM_DB`` or ``~/.cache/graspsim/db``);
        map_config: its generation settings (None: the paper's); the five reference maps
        are built there on first use.
    identify_repetitions: MLESAC repetitions of the identification (paper: 10).
    perception: ``"cloud"`` (default): the planner identifies the object in the sensor
        cloud, as the paper's run-time stage; ``"model"``: it is given the true
        primitives and pose (:func:`graspsim.planning.planner.plan_shape`) -- no identification
        error, and a reset costs little more than the map's retrieval (GraspSelect).
    max_redraws: objects drawn per reset before giving up when none offers a valid
        candidate (GraspSelect).
    threads: native threads for :meth:`GraspSelectEnv.evaluate_candidates`.
    openings: extra pad gaps per side [m] the planner's robust ranking may open the
        jaws beyond the map's pre-grasp opening (``RobustConfig.openings``); each
        candidate is executed at the one its robust score chose (GraspSelect; the
        ``extra_opening`` candidate column). ``(0.0,)``: the map's opening, as the
        paper.
    gripper: the gripper: a registered name (``"festo_hgpl_25_60_a"``, ``"franka_hand"``),
        a spec .json or a :class:`~graspsim.grippers.spec.GripperSpec`; its own FS maps (the
        database keys maps by the gripper) and its own simulated model. The objects' widths
        are drawn within what it spans (:func:`graspsim.envs.object_sets.size_limits`: its
        stroke; the Festo takes the sets' full ranges).
    """

    objects: str | tuple[str, ...] = "primitives"
    n_candidates: int = 16
    cloud_size: int = 512
    cloud_resolution: float = 0.005
    cloud_noise: float = 0.001
    cloud_outliers: float = 0.0
    view: View = View.FULL
    camera_distance: float = 0.6
    table_cut: float = 0.003
    position_noise: float = POSITION_SIGMA
    rotation_noise: float = ROTATION_SIGMA
    protocol: object = "lift_place"
    reward: RewardMode = RewardMode.BINARY
    lying: float = 0.5
    placement: float = 0.1
    table_margin: float = 0.002
    pool_size: int = 300
    db_root: str | None = None
    map_config: MapConfig | None = None
    identify_repetitions: int = 10
    perception: Perception = Perception.CLOUD
    max_redraws: int = 20
    threads: int = 1
    openings: tuple[float, ...] = DEFAULT_OPENINGS
    gripper: object = "festo_hgpl_25_60_a"

    def robust_sigmas(self) -> dict:
        """The planner's robust pose error (``RobustConfig`` fields): the execution error
        stated here where there is one, so the grasps ranked first are those that survive
        it; with none (both 0) the robust score's own default (3 mm / 2 deg)."""
        if self.position_noise > 0 or self.rotation_noise > 0:
            return {"position_sigma": float(self.position_noise), "rotation_sigma": float(self.rotation_noise)}
        return {}

    def __post_init__(self) -> None:
        objects = self.objects if isinstance(self.objects, str) else tuple(self.objects)
        object.__setattr__(self, "objects", objects)
        resolve_object_set(objects)  # raises on unknown names
        check_fields(self, integer(1), "n_candidates", "cloud_size", "pool_size", "identify_repetitions",
                     "max_redraws", "threads")
        check_fields(self, POSITIVE, "cloud_resolution", "camera_distance")
        check_fields(self, NON_NEGATIVE, "cloud_noise", "table_cut", "position_noise", "rotation_noise", "placement",
                     "table_margin")
        check_fields(self, _FRACTION, "cloud_outliers")
        check_fields(self, _SHARE, "lying")
        for name, kind in (("view", View), ("perception", Perception), ("reward", RewardMode)):
            try:
                object.__setattr__(self, name, kind(getattr(self, name)))
            except ValueError:
                raise InvalidParameterError(
                    f"{name} must be one of {[v.value for v in kind]}, got {getattr(self, name)!r}") from None
        try:
            openings = tuple(float(v) for v in np.atleast_1d(np.asarray(self.openings, float)))
        except (TypeError, ValueError):
            openings = ()
        if not openings or any(not (math.isfinite(v) and 0 <= v <= 0.05) for v in openings):
            raise InvalidParameterError(
                f"openings must be extra gaps per side in [0, 0.05] m (0.0: the map's opening), got {self.openings!r}")
        object.__setattr__(self, "openings", openings)
        check_database_fields(self)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["view"], d["reward"] = self.view.value, self.reward.value
        p = self.protocol
        d["protocol"] = p if isinstance(p, str) else p.to_dict()
        d["map_config"] = None if self.map_config is None else self.map_config.to_dict()
        d["openings"] = list(self.openings)
        d["gripper"] = self.gripper if isinstance(self.gripper, str) else self.gripper.to_dict()
        return d


def check_database_fields(cfg) -> None:
    """The map database fields every env's settings share: ``map_config`` (a MapConfig
    or None), ``db_root`` (made a str), ``gripper`` (a name, spec .json or spec)."""
    if cfg.map_config is not None and not isinstance(cfg.map_config, MapConfig):
        raise InvalidParameterError(f"map_config must be a MapConfig or None, got {cfg.map_config!r}")
    if cfg.db_root is not None:
        object.__setattr__(cfg, "db_root", str(cfg.db_root))
    from graspsim.grippers import get_gripper

    get_gripper(cfg.gripper)  # raises GripperError (an InvalidParameterError) on a bad one


def make_config(config=None, kind: type = EnvConfig, /, **kwargs):
    """``config`` (or the defaults) of the settings dataclass ``kind`` (EnvConfig, or
    another env's) with ``kwargs`` overriding fields; unknown names raise
    :class:`InvalidParameterError` listing the valid ones."""
    valid = {f.name for f in fields(kind)}
    unknown = sorted(set(kwargs) - valid)
    if unknown:
        raise InvalidParameterError(f"unknown environment option(s) {unknown}; valid: {sorted(valid)}")
    if config is None:
        return kind(**kwargs)
    if not isinstance(config, kind):
        raise InvalidParameterError(f"config must be a {kind.__name__}, got {type(config).__name__}")
    d = {f.name: getattr(config, f.name) for f in fields(kind)}
    d.update(kwargs)
    return kind(**d)
