"""Primitive identification of a segmented object cloud (paper 2.2-2.3).

The paper's loop: the whole cloud starts as one cluster; each cluster is identified
(MLESAC fits of all five models, four features, rule base); an unidentified cluster
goes back to the hierarchical MVBB fit-and-split; a split is only made while it gains
enough volume (theta* < theta_th, eq. 1) and leaves ``min_cluster_points`` on both
sides. When no split is allowed and clusters remain unidentified, identification has
*failed* and the result still lists the identified parts (for a partial map). That is
paper mode (``IdentifyConfig.preset("paper")``); robust mode, the default, runs the same
loop and then decomposes further what it left or explained only roughly
(:mod:`~graspsim.perception.decompose`), with status *partial* when parts are found but
some points are not covered or some parts only approximately.

Preprocessing, once per cloud: statistical outlier removal, PCA normals with outward
orientation and the sensor-noise estimate, over neighbourhoods wider than the noise.

Per cluster, beyond the paper's MLESAC fits: a cylinder is also refined as a cone (a
weak taper is ill-posed for four-point cone samples) and an untapered cone yields a
cylinder; box faces and cylinder and cone ends nobody saw are cut back to their points; a model
larger than its cluster is no hypothesis, and a candidate that reaches beyond its
points while little of its surface has points near it is rejected (see support).
Every random draw comes from the caller's
generator, clusters are visited breadth first, so the same seed gives the same result.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from dataclasses import replace

import numpy as np

from graspsim.perception.classify import Shape
from graspsim.perception.cloud_input import check_cloud
from graspsim.perception.cluster import Cloud, identify_cluster
from graspsim.perception.decompose import keep_going, settled
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.identify_results import Identification, IdentificationStatus, PartResult
from graspsim.perception.mvbb import OrientedBox, min_volume_box
from graspsim.perception.normals import estimate_local_surface, remove_outliers
from graspsim.perception.prepare import check_solid, voxel_downsample
from graspsim.perception.split import best_split, theta_star

__all__ = ["IdentificationStatus", "IdentifyConfig", "PartResult", "Identification", "Cloud",
           "identify", "identify_cluster"]

log = logging.getLogger(__name__)


def _unidentified(part: PartResult, box: OrientedBox) -> PartResult:
    return replace(part, T_world_obj=box.T_world_box.copy())


def _hierarchy(cloud: Cloud, rng: np.random.Generator, cfg: IdentifyConfig):
    """The paper's loop (2.2): (identified leaves, unidentified leaves, splits made);
    leaves are (part, MVBB or None for the unsplit root)."""
    queue: deque[tuple[np.ndarray, OrientedBox | None]] = deque([(np.arange(len(cloud.points)), None)])
    done: list[tuple[PartResult, OrientedBox | None]] = []
    failed: list[tuple[PartResult, OrientedBox]] = []
    n_splits = 0
    while queue:
        idx, box = queue.popleft()
        sub = cloud.points[idx]
        part = cloud.cluster(idx, rng, cfg)
        if part.shape is not Shape.UNIDENTIFIED:
            done.append((part, box))
            continue
        box = box if box is not None else min_volume_box(sub)
        n_leaves = len(done) + len(failed) + len(queue) + 1
        split = None
        if n_leaves < cfg.max_parts and len(idx) >= 2 * cfg.min_cluster_points:
            split = best_split(sub, box, min_points=cfg.min_cluster_points)
        if split is not None:
            others = sum(b.volume for _, b in done + failed if b is not None)
            others += sum(b.volume for _, b in queue if b is not None)
            theta = theta_star(box.volume, (split.boxes[0].volume, split.boxes[1].volume), others)
            log.debug("split of %d points: area ratio %.3f, theta* %.3f (threshold %.3f)",
                      len(idx), split.area_ratio, theta, cfg.theta)
            if theta < cfg.theta:
                n_splits += 1
                queue.append((idx[split.mask], split.boxes[0]))
                queue.append((idx[~split.mask], split.boxes[1]))
                continue
        failed.append((_unidentified(part, box), box))
    return done, failed, n_splits


def _prepare(points: np.ndarray, cfg: IdentifyConfig, limit: int, noise: tuple[float, float] | None = None):
    """(cloud, number of points used, voxel of each input point or None, downsampling):
    at most ``limit`` points. noise: the cloud's (noise, check_noise) [m] if already
    known (else the config's sigma, else estimated)."""
    pts_all = check_cloud(points, min_points=cfg.min_cluster_points)
    down = voxel = None
    if len(pts_all) > limit:
        used, voxel, down = voxel_downsample(pts_all, limit)
        pts_all = pts_all[used]
    keep = remove_outliers(pts_all) if cfg.remove_outliers else np.ones(len(pts_all), bool)
    if keep.sum() < cfg.min_cluster_points:
        keep[:] = True
    kept = np.flatnonzero(keep)
    pts = pts_all[kept]
    check_solid(pts)
    surf = estimate_local_surface(pts, robust=cfg.is_robust and noise is None)
    if noise is None:
        sigma = float(cfg.noise) if cfg.noise is not None else surf.noise
        noise = (sigma, sigma if cfg.noise is not None or not cfg.is_robust else surf.robust_noise)
    reliable = surf.flatness <= np.quantile(surf.flatness, cfg.sample_quantile)
    return Cloud(pts, surf.normals, reliable, kept, *noise), len(pts_all), voxel, down


def identify(points: np.ndarray, *, rng: np.random.Generator,
             config: IdentifyConfig | None = None) -> Identification:
    """Identify the shape primitives of an object cloud (N, 3), world frame [m].

    Paper mode: the paper's loop; robust mode (default): the same loop, then the
    clusters it left unexplained are decomposed further
    (:func:`~graspsim.perception.decompose.keep_going`)."""
    t0 = time.perf_counter()
    cfg = config or IdentifyConfig()
    cloud, n_used, voxel, down = _prepare(points, cfg, cfg.point_limit)
    done, failed, n_splits = _hierarchy(cloud, rng, cfg)
    if cfg.is_robust:
        kept = settled(cloud, done, failed, cfg)
        if kept is not None:  # the paper's answer explains the cloud: it stands
            done = kept
        else:  # decomposition fits many candidates: on a sparser cloud
            if len(cloud.points) > cfg.robust_points:
                # the sensor's noise, as estimated on the denser cloud: thinning keeps
                # real points (the noise is the same) but spreads them, and wider
                # neighbourhoods span both sides of thin walls (a mug: 1.6 -> 5.5 mm)
                cloud, n_used, voxel, down = _prepare(points, cfg, cfg.robust_points,
                                                      (cloud.noise, cloud.check_noise))
                done, failed, n_splits = _hierarchy(cloud, rng, cfg)
            done, failed, n_splits = keep_going(cloud, done, failed, n_splits, rng, cfg)
    if not failed and not any(p.approximate for p, _ in done):
        status = IdentificationStatus.IDENTIFIED
    elif cfg.is_robust and done:
        status = IdentificationStatus.PARTIAL
    else:
        status = IdentificationStatus.FAILED
    parts, left = (tuple(_expand(p, voxel) for p, _ in group) for group in (done, failed))
    return Identification(status, parts, left, n_used if down is None else down.input_points,
                          int(n_used - len(cloud.kept)), cloud.noise, n_splits, time.perf_counter() - t0, down,
                          cfg.mode)


def _expand(part: PartResult, voxel: np.ndarray | None) -> PartResult:
    """The part with the indices of every input point in its voxels (``voxel``: (N,)
    voxel of each input point; None: the cloud was not downsampled)."""
    if voxel is None:
        return part
    member = np.zeros(int(voxel.max()) + 1, bool)
    member[part.indices] = True
    return replace(part, indices=np.flatnonzero(member[voxel]))
