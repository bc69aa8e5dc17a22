"""Identification trials of paper experiment 3.2 / figure 4 (E01's, not part of the library).

Seven size variants per primitive (the paper's reference shapes and six others across
the gripper's range), synthetic clouds at 0.5 cm resolution with sensor noise and
outliers in random poses, either complete or seen from one camera. A trial succeeds
when identification ends ``identified`` with exactly one part of the true primitive
kind (the paper's measure); the dimension error, wall time and CPU time of the
identification are recorded too (CPU time is the fairer figure on a shared machine).

Trials are independent tasks, each seeded from one ``SeedSequence`` by its position in
the grid, so results do not depend on how many worker processes run them.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import time
from dataclasses import dataclass

import numpy as np

from graspsim.perception.identify import IdentificationStatus, IdentifyConfig, identify
from graspsim.primitives import make_primitive, synthetic_cloud
from graspsim.transforms import make_transform, normalize, random_rotation

__all__ = ["SIZE_VARIANTS", "CloudSpec", "TrialResult", "run_trial", "trial_cloud", "dims_error"]

#: Seven size variants per primitive [m]; the first is the paper's reference shape.
SIZE_VARIANTS: dict[str, tuple[dict[str, float], ...]] = {
    "box": tuple(dict(x=a, y=b, z=c) for a, b, c in [
        (0.06, 0.06, 0.06), (0.04, 0.04, 0.04), (0.08, 0.08, 0.08), (0.03, 0.05, 0.10),
        (0.04, 0.06, 0.12), (0.02, 0.08, 0.10), (0.05, 0.05, 0.15)]),
    "cylinder": tuple(dict(radius=r, height=h) for r, h in [
        (0.02, 0.20), (0.015, 0.10), (0.03, 0.08), (0.04, 0.06), (0.025, 0.15),
        (0.01, 0.12), (0.035, 0.12)]),
    "sphere": tuple(dict(radius=r) for r in [0.035, 0.02, 0.025, 0.03, 0.04, 0.05, 0.06]),
    "cone": tuple(dict(bottom_radius=a, top_radius=b, height=h) for a, b, h in [
        (0.04, 0.02, 0.10), (0.03, 0.0, 0.08), (0.05, 0.02, 0.08), (0.03, 0.015, 0.12),
        (0.04, 0.01, 0.06), (0.025, 0.01, 0.10), (0.06, 0.03, 0.07)]),
    "half_toroid": tuple(dict(major_radius=R, minor_radius=r) for R, r in [
        (0.04, 0.01), (0.03, 0.008), (0.05, 0.012), (0.06, 0.015), (0.035, 0.012),
        (0.05, 0.008), (0.045, 0.015)]),
}


@dataclass(frozen=True)
class CloudSpec:
    """How trial clouds are made: resolution, noise sigma [m] (along the viewing ray
    for partial clouds), outlier fraction, single view or complete, camera distance [m]."""

    resolution: float = 0.005
    noise: float = 0.001
    outliers: float = 0.01
    partial: bool = False
    camera_distance: float = 0.6


@dataclass(frozen=True)
class TrialResult:
    kind: str
    variant: int
    repetitions: int
    trial: int
    success: bool
    predicted: str
    n_parts: int
    dims_err: float
    seconds: float
    cpu_seconds: float
    n_points: int


def dims_error(kind: str, true: dict[str, float], found: dict[str, float]) -> float:
    """Largest per-dimension difference [m] (box edges compared sorted)."""
    if kind == "box":
        return float(np.max(np.abs(np.sort(list(true.values())) - np.sort(list(found.values())))))
    return float(max(abs(true[k] - found[k]) for k in true))


def trial_cloud(kind: str, variant: int, seed: np.random.SeedSequence, spec: CloudSpec = CloudSpec()):
    """The trial's synthetic cloud and the generator its identification draws from."""
    cloud_rng, id_rng = (np.random.default_rng(s) for s in seed.spawn(2))
    shape = make_primitive(kind, **SIZE_VARIANTS[kind][variant])
    T = make_transform(random_rotation(cloud_rng), cloud_rng.uniform(-0.3, 0.3, 3))
    camera = None
    if spec.partial:
        camera = normalize(cloud_rng.normal(size=3)) * spec.camera_distance
    cloud = synthetic_cloud(shape, cloud_rng, resolution=spec.resolution, noise=spec.noise,
                            outliers=spec.outliers, camera=camera, T_world_obj=T)
    return cloud, id_rng


def run_trial(kind: str, variant: int, repetitions: int, trial: int, seed: np.random.SeedSequence,
              spec: CloudSpec = CloudSpec(), config: IdentifyConfig | None = None) -> TrialResult:
    """One identification trial; ``seed`` fixes both the cloud and the identification."""
    cloud, id_rng = trial_cloud(kind, variant, seed, spec)
    dims = SIZE_VARIANTS[kind][variant]
    cfg = IdentifyConfig.preset("paper", repetitions=repetitions) if config is None else config
    t0, c0 = time.perf_counter(), time.process_time()
    res = identify(cloud.points, rng=id_rng, config=cfg)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    ok = res.status is IdentificationStatus.IDENTIFIED and len(res.parts) == 1
    pred = res.parts[0].shape.value if len(res.parts) == 1 else (
        "failed" if res.status is IdentificationStatus.FAILED else f"{len(res.parts)} parts")
    err = dims_error(kind, dims, res.parts[0].dims) if ok and pred == kind else float("nan")
    return TrialResult(kind, variant, repetitions, trial, bool(ok and pred == kind), pred,
                       len(res.parts), err, seconds, cpu, len(cloud.points))
