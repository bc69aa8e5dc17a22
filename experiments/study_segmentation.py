"""Segmentation study: the clustering radius and the number of cameras against E10's first
frames (issue 17: >= 95 % of objects one cluster in packed scenes with >= 1 cm gaps).

E10 measures segmentation on the first frame of each scene. This script renders exactly
those frames -- scene ``i`` is ``make_scene(n, kind, derived_seed(seed, "scene", i))``,
its depth noise and table fit draw from ``rng_for(seed, "clutter", i)`` as the episode's
do -- from E10's one camera, and from ``rig(k)`` for each other ``--cameras`` value (the
views fused into one cloud, each drawing its depth noise in turn from the same stream).
Each cloud is perceived with E10's settings for its kind (``scene_settings(kind)``:
table, points above it on a 3 mm grid, clustered as E10 clusters them, "default": by the
spacing rule, and for packed scenes, whose objects stand >= 1 cm apart, those clusters
closer than ``GAP_LINK`` x 1 cm joined), and the same points are clustered by the spacing
rule alone (``cluster_radius``: 2.5 x the median nearest-neighbour spacing within 3-7 mm,
"spacing"; packed scenes only, as for piles it is the default) and at each
``--radii-mm`` value (one radius, nothing joined). Per condition: objects seen (>= 40
points), one cluster (``one_cluster_objects``),
and of the others those *merged* (their largest segment is mixed: < 90 % theirs) and
*split* (the rest: spread over segments, or not segmented), and the objects not one
cluster by name. And per kind and size the closest observed points of two different
objects in one view (the gap a radius must stay under) with the objects' footprint gap.
No planning, no grasps.

    python experiments/study_segmentation.py
    python experiments/study_segmentation.py --quick --out results/study_segmentation-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import derived_seed, load_sentence, opt, rng_for, run_study

log = logging.getLogger("study_segmentation")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(50, "scenes per kind and size (E10's first frames)")
    sizes: tuple[int, ...] = opt((5, 10), "objects per scene")
    kinds: tuple[str, ...] = opt(("packed", "pile"), "scene kinds", choices=("pile", "packed"))
    radii_mm: tuple[float, ...] = opt((5.0, 6.0, 7.0, 8.0, 9.0), "clustering radii [mm] compared with the default")
    cameras: tuple[int, ...] = opt((1, 2), "cameras whose views are fused (1: E10's frame)")
    seed: int = opt(0, "E10's seed")
    object_set: str = opt("mixed", "objects drawn from this set (a named set or a folder of meshes)")
    crease_angles: tuple[float, ...] = opt((30.0, 40.0, 50.0), "crease angles [deg] compared (one camera): links "
                                           "across sharper concave creases cut (euclidean_clusters)")
    QUICK: ClassVar[dict] = {"scenes": 2, "sizes": (5,), "kinds": ("packed",), "radii_mm": (7.0,), "cameras": (1,),
                             "crease_angles": (40.0,)}

    def __post_init__(self) -> None:
        if self.scenes < 1 or min(self.radii_mm, default=1) <= 0 or min(self.sizes) < 1:
            raise ValueError("--scenes >= 1, --sizes >= 1 and radii > 0 are needed")
        if not self.cameras or not all(1 <= k <= 3 for k in self.cameras):
            raise ValueError("--cameras takes 1 to 3 cameras per rig")


def first_frame(n: int, kind: str, i: int, seed: int, cameras: int = 1, object_set: str = "mixed"):
    """(perception, per-point object ids, footprint gaps, object names, viewpoint) of E10's
    first frame of scene i (``cameras`` > 1: that many views around the table, fused; no
    viewpoint)."""
    from graspsim.geometry.camera import fuse, rig
    from graspsim.planning.scene import perceive_scene
    from graspsim.tabletop.clutter import ClutterConfig, scene_settings
    from graspsim.tabletop.table_scene import footprint_gaps, make_scene

    cfg = ClutterConfig()
    scene = make_scene(n, kind, derived_seed(seed, "scene", i), object_set=object_set)
    depth_rng, plan_rng, _ = rng_for(seed, "clutter", i).spawn(3)  # as ClutterEpisode draws them
    sim = scene.sim()
    frames = [sim.render(cam, noise=cfg.depth_noise, rng=depth_rng) for cam in rig(cameras)]
    sim.close()
    points, labels = fuse(frames)
    eye = rig(cameras)[0].T_world_camera[:3, 3] if cameras == 1 else None  # as ClutterEpisode plans
    per = perceive_scene(points, plan_rng, scene_settings(kind), viewpoint=eye)
    return per, labels[per.indices], footprint_gaps(scene), [o.name for o in scene.objects], eye


def merged_objects(truth: np.ndarray, found: np.ndarray, min_seen: int = 40) -> int:
    """Objects seen whose largest segment is mixed (< 90 % theirs): merged with another."""
    merged = 0
    for k in np.unique(truth[truth >= 0]):
        segs = found[(truth == k) & (found >= 0)]
        if np.sum(truth == k) >= min_seen and len(segs):
            merged += np.mean(truth[found == np.bincount(segs).argmax()] == k) < 0.9
    return int(merged)


def missed_names(truth: np.ndarray, found: np.ndarray, names: list[str]) -> list[str]:
    """Names of the objects seen that are not one cluster (``one_cluster_objects``' rule,
    object by object: the others' points count as not this object's)."""
    from graspsim.tabletop.clutter import one_cluster_objects

    out = []
    for k in np.unique(truth[truth >= 0]):
        seen, one = one_cluster_objects(np.where(truth == k, 0, -1), found)
        out += [names[k]] * (seen - one)
    return out


def closest_pairs(per, truth: np.ndarray, gaps: np.ndarray) -> list[tuple[float, float]]:
    """(closest observed distance, footprint gap) [m] of every pair of objects seen."""
    from scipy.spatial import cKDTree

    ids = [k for k in np.unique(truth[truth >= 0]) if np.sum(truth == k) >= 40]
    trees = {k: cKDTree(per.points[truth == k]) for k in ids}
    return [(float(trees[b].query(per.points[truth == a])[0].min()), float(gaps[a, b]))
            for j, a in enumerate(ids) for b in ids[j + 1:]]


def run(cfg: Config) -> dict:
    table, closest = [], []
    for kind in cfg.kinds:
        for n in cfg.sizes:
            for k in cfg.cameras:
                rows, pairs = _condition(cfg, kind, n, k)
                table += rows
                if k == 1:
                    pairs.sort()
                    closest.append({"kind": kind, "objects": n, "pairs": len(pairs),
                                    "closest_mm": [round(d * 1000, 1) for d, _ in pairs[:5]],
                                    "footprint_gap_mm": [round(g * 1000, 1) for _, g in pairs[:5]]})
    return {"table": table, "closest": closest,
            "denominators": "objects with >= 40 points (after the 3 mm grid) in the first frame of each scene; "
                            "pairs: every two such objects of a scene"}


def _condition(cfg: Config, kind: str, n: int, cameras: int) -> tuple[list[dict], list]:
    """The table rows of one kind, size and camera count, and the closest pairs seen."""
    from graspsim.perception.segment import cluster_radius, euclidean_clusters, gap_link
    from graspsim.tabletop.clutter import one_cluster_objects, scene_settings

    scene_cfg = scene_settings(kind)
    touching = scene_cfg.min_gap is None and cameras == 1  # where E10 cuts creases (piles, one camera)
    creases = ["no crease", *(f"crease {a:g}" for a in cfg.crease_angles)] if touching else []
    conds = ["default", *creases, *(["spacing"] if scene_cfg.min_gap is not None else []),
             *(f"{r:g} mm" for r in cfg.radii_mm)]
    counts = {c: np.zeros(4, int) for c in conds}  # seen, one, split, merged
    missed = {c: Counter() for c in conds}  # objects not one cluster, by name
    pairs = []
    for i in range(cfg.scenes):
        per, truth, gaps, names, eye = first_frame(n, kind, i, cfg.seed, cameras, cfg.object_set)
        pairs += closest_pairs(per, truth, gaps) if cameras == 1 else []
        for c in conds:
            if c == "default":  # E10's segments
                found = per.segment
            elif c == "no crease" or c.startswith("crease"):  # E10's rule without / with another crease angle
                found = euclidean_clusters(per.points, radius=per.radius, min_points=scene_cfg.min_points,
                                           link=gap_link(scene_cfg.min_gap), viewpoint=eye,
                                           crease_angle=None if c == "no crease" else float(c.split()[1]))
            else:
                r = cluster_radius(per.points, max_radius=scene_cfg.max_radius) if c == "spacing" else (
                    float(c.split()[0]) / 1000)
                found = euclidean_clusters(per.points, radius=r, min_points=scene_cfg.min_points)
            seen, one = one_cluster_objects(truth, found)
            merged = merged_objects(truth, found)
            counts[c] += (seen, one, seen - one - merged, merged)
            missed[c].update(missed_names(truth, found, names))
    rows = []
    for c in conds:
        seen, one, split, merged = (int(x) for x in counts[c])
        rows.append({"kind": kind, "objects": n, "cameras": cameras, "radius": c, "seen": seen, "one_cluster": one,
                     "share": one / seen if seen else None, "split": split, "merged": merged,
                     "not_one_cluster": dict(missed[c].most_common())})
        log.info("%s%d %d camera(s) %-8s one cluster %d/%d, split %d, merged %d", kind, n, cameras, c, one, seen,
                 split, merged)
    return rows, pairs


def readme_section(s: dict) -> str:
    """One table: objects one cluster / split / merged per scene kind, size and radius."""
    L = [f"`{s['command']}`: the first frame of each of E10's scenes ({s['config']['scenes']} per kind and size, "
         "D435-like cameras, sensor noise on; 1 camera is E10's view, 2 are two views fused), clustered at each "
         "radius; *default* is E10's segmentation: the *spacing* rule (2.5 x the median nearest-neighbour spacing, "
         "3-7 mm; 5.7 mm on these 3 mm grids), and for packed scenes, whose objects stand >= 1 cm apart, its "
         "clusters closer than 0.8 x that gap (8 mm) joined" + (
             "; in piles (objects may touch), from one camera, the points along concave creases sharper than "
             "SceneConfig.crease_angle taken out first (*no crease*: without that; *crease A*: at A deg). Objects "
             f"from the \"{s['config'].get('object_set', 'mixed')}\" set" if "crease_angles" in s["config"] else "")
         + ". Objects with >= 40 points; *split*: its largest "
         "segment is >= 90 % its own but holds < 90 % of it (or none), *merged*: that segment is mixed.", "",
         "| scene | cameras | radius | one cluster | split | merged |", "|---|---|---|---|---|---|"]
    for t in s["table"]:
        share = "-" if t["share"] is None else f"{100 * t['share']:.1f} %"
        L.append(f"| {t['kind']} {t['objects']} | {t['cameras']} | {t['radius']} | {share} "
                 f"({t['one_cluster']}/{t['seen']}) | "
                 f"{t['split']} | {t['merged']} |")
    missed = [f"{t['kind']} {t['objects']}: " + ", ".join(f"{k} {v}" for k, v in t["not_one_cluster"].items())
              for t in s["table"] if t["cameras"] == 1 and t["radius"] == "default" and t.get("not_one_cluster")]
    L += ["", f"Objects not one cluster, one camera, the default rule: {'; '.join(missed) or 'none'}."]
    L += ["", "Closest observed points of two different objects in one view (their footprint gap) [mm], the "
          "smallest five pairs:", ""]
    L += [f"- {c['kind']} {c['objects']} ({c['pairs']} pairs): " +
          ", ".join(f"{d:g} ({g:g})" for d, g in zip(c["closest_mm"], c["footprint_gap_mm"])) for c in s["closest"]]
    L += ["", load_sentence(s)]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    return run_study(Config, __file__, run, readme_section, argv, __doc__)


if __name__ == "__main__":
    raise SystemExit(main())
