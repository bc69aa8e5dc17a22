"""Failed clutter grasps of one object judged against its true mesh (issue 34): what went wrong.

Runs E10's protocol (``graspsim.tabletop.clutter.ClutterEpisode``: E10's seeds, scenes,
camera, sensor noise and database, no execution error) on the scenes of a tuning set that
hold ``--object``, executes the best grasp each time, and for every grasp aimed at that
object (``grasp_target``) measures at the executed pose and opening, against the object's
TRUE mesh where the simulator holds it (and against the convex hull, which mesh
preparation simulates when decomposition runs out of time):

* the fingers' samples inside the true mesh (> 1 mm), split into those in space the
  camera did not see (behind the observed surfaces along the rays: ``ViewDepth``) and
  those it saw, the deepest one, and the same depth against the hull;
* the true surface between the pads (the fingers' y and z span, within the opening) and
  its extent along the closing axis, beside the fitted parts' clearance to the fingers;
* where the pads meet it: the contacts' height below the fingertips and their normals'
  angle to the closing axis, and the centre of mass off the closing line;
* the closing axis's angle to the line of sight (``|cos|``);
* the segment's observed points in the same region and their extent along the closing axis.

Per cause, where the object lay between the pads (:func:`off_centre`): how many grasps had the
middle of its true extent more than 8 mm from the gripper's centre, and how many would have had
it, had each grasp been centred on the extent its observed points span there.

Each failure gets a mechanism: a start collision with the finger in the true mesh on the
unseen or the seen side, or in the hull only (the simulation model); no contact with
nothing between the pads or with the object there; a drop with the contacts within 5 mm of
the fingertips, the centre of mass more than 10 mm off the closing line, or neither.

    python experiments/study_true_shape.py --db /work/runs/e10-fsdb --kinds pile packed --seeds 1 --scenes 8
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start

from graspsim.maps.robust import UNSEEN_MARGIN

log = logging.getLogger("study_true_shape")

#: a finger sample this deep inside a mesh [m] counts as inside
INSIDE = 0.001
#: contacts this near the fingertips [m] are "at the tips"; a centre of mass this far off the closing line is "off"
TIP, OFF_COM = 0.005, 0.010
#: an object whose extent between the pads has its middle this far [m] from the gripper's centre is "off centre"
OFF_CENTRE = 0.008


@dataclass(frozen=True)
class Config:
    object: str = opt("duck", "the object whose grasps are judged (a mesh of the set; any: every object's)")
    object_set: str = opt("household-tuning", "objects drawn from this set (never a held-out set)")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    seeds: int = opt(2, "E10's first seeds")
    scenes: int = opt(4, "scenes per seed and kind (those without the object are skipped)")
    seed: int = opt(0, "E10's run seed")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder, read only (default: OUT/fsdb, built fresh)")
    unseen_margin: float | None = opt(None, "the robust score's margin [m] against an object's unseen back "
                                      "(E10's --unseen-margin; alone: the measured UNSEEN_MARGIN)",
                                      const=UNSEEN_MARGIN)
    QUICK: ClassVar[dict] = {"kinds": ("packed",), "seeds": 1, "scenes": 1, "quick_maps": True}

    def __post_init__(self) -> None:
        if self.object_set.endswith("heldout"):
            raise ValueError("diagnose on tuning meshes only, never on a held-out set")


def finger_samples_world(gripper, T: np.ndarray, opening: float, n=(7, 5, 9)) -> dict[str, np.ndarray]:
    """Each finger box's grid of samples (7 x 5 x 9) in the world at wrist pose T and pad gap ``opening``."""
    b = gripper.collision_boxes()
    out = {}
    for name, c, h, s in zip(b.names, b.centers, b.half_extents, b.x_sign):
        if name.startswith("finger"):
            g = np.stack(np.meshgrid(*[np.linspace(-hh, hh, k) for hh, k in zip(h, n)], indexing="ij"),
                         -1).reshape(-1, 3) + c
            g[:, 0] += s * 0.5 * opening
            out[name] = g @ T[:3, :3].T + T[:3, 3]
    return out


def mechanism(r: dict) -> str:
    """The failure's mechanism from a row's measures (see the module's docstring)."""
    cause = r["cause"]
    if cause.startswith("start_collision"):
        f = r["fingers"].values()
        if any(v["in_true_seen"] for v in f):
            return "finger in the true mesh, seen side"
        if any(v["in_true"] for v in f):
            return "finger in the true mesh, unseen side"
        if any(v["in_hull"] for v in f):
            return "finger in the hull only (simulation model)"
        return "neighbour or table"
    if cause == "no_contact":
        return "nothing between the pads" if not r["true_between"] else "object between the pads, pushed out"
    if cause == "dropped":
        if r.get("contact_below_tip_mm") is not None and max(r["contact_below_tip_mm"]) <= 1000 * TIP:
            return "contacts at the fingertips"
        if r.get("com_off_line_mm") is not None and r["com_off_line_mm"] > 1000 * OFF_COM:
            return "centre of mass off the closing line"
        return "dropped, other"
    return cause


def _in_closing_region(P: np.ndarray, gripper, opening: float) -> np.ndarray:
    """Which wrist-frame points ``P`` (N, 3) lie between the fingers: across the finger width, from the
    jaws to the fingertips, within the pad gap ``opening`` (+ 2 mm)."""
    return ((np.abs(P[:, 1]) <= 0.5 * gripper.finger_size[1]) & (P[:, 2] >= gripper.jaw_base_z)
            & (P[:, 2] <= gripper.fingertip_z) & (np.abs(P[:, 0]) <= 0.5 * opening + 0.002))


def off_centre(rows: list[dict]) -> dict:
    """Where the object lies between the pads, by outcome: per cause, the grasps whose rows hold the
    true extent along the closing axis, how many had its middle more than :data:`OFF_CENTRE` from the
    gripper's centre (the first pad to touch pushes the object that far before the other arrives), the
    median distance, and the same if each grasp had been centred on the extent the segment's observed
    points span there (``seen_extent_mm``; grasps with both)."""
    out: dict[str, dict] = {}
    for r in rows:
        if "true_extent_mm" not in r:
            continue
        t = 0.5 * sum(r["true_extent_mm"])
        g = out.setdefault(r["cause"], {"grasps": 0, "off": [], "off_if_centred_on_seen": []})
        g["grasps"] += 1
        g["off"].append(abs(t))
        if "seen_extent_mm" in r:
            g["off_if_centred_on_seen"].append(abs(t - 0.5 * sum(r["seen_extent_mm"])))
    lim = 1000 * OFF_CENTRE
    return {c: {"grasps": g["grasps"], "off_centre": sum(x > lim for x in g["off"]),
                "median_off_mm": float(np.median(g["off"])),
                "with_seen": len(g["off_if_centred_on_seen"]),
                "off_centre_if_centred_on_seen": sum(x > lim for x in g["off_if_centred_on_seen"]),
                "median_off_if_centred_on_seen_mm": float(np.median(g["off_if_centred_on_seen"]))
                if g["off_if_centred_on_seen"] else None}
            for c, g in sorted(out.items(), key=lambda t: -t[1]["grasps"])}


def measure(ep, look, grasp, k: int, mesh, hull, gripper) -> dict:
    """The measures of ``grasp`` (aimed at object ``k``) before it is executed."""
    import trimesh
    from scipy.spatial import cKDTree

    from graspsim.maps.occlusion import ViewDepth

    T = np.asarray(grasp.T_world_wrist, float)
    spec = ep.scene.objects[k].spec
    T_w_file = ep.sim.pose(k) @ spec.T_obj_file
    inv = np.linalg.inv(T_w_file)
    eye = ep.camera.T_world_camera[:3, 3]
    view = ViewDepth(look.view.world(), eye)
    mem = look.plan.memory[grasp.segment]
    parts = list(mem.ident.parts) if mem.ident else []
    r = {"opening_mm": 1000 * grasp.opening, "score": grasp.score, "parts": [str(p.primitive()) for p in parts],
         "fingers": {}}
    for name, P in finger_samples_world(gripper, T, grasp.opening).items():
        L = P @ inv[:3, :3].T + inv[:3, 3]
        d_true, d_hull = (trimesh.proximity.signed_distance(m, L) for m in (mesh, hull))  # > 0 inside
        occ = view.occluded(P)
        gap = np.full(len(P), np.inf)
        for p in parts:
            Ti = np.linalg.inv(p.T_world_obj)
            gap = np.minimum(gap, p.primitive().sdf(P @ Ti[:3, :3].T + Ti[:3, 3]))
        inside = d_true > INSIDE
        U = P[occ]
        to_target = to_scene = np.inf
        if len(U):  # how near the unseen finger samples come to the target (its points, its parts) and to the scene
            to_target = float(min(cKDTree(mem.points).query(U)[0].min(), np.abs(gap[occ]).min()))
            to_scene = float(cKDTree(look.view.world()).query(U)[0].min())
        r["fingers"][name] = {"in_true": int(inside.sum()), "in_true_unseen": int((inside & occ).sum()),
                              "in_true_seen": int((inside & ~occ).sum()), "in_hull": int((d_hull > INSIDE).sum()),
                              "depth_true_mm": 1000 * float(d_true.max()), "depth_hull_mm": 1000 * float(d_hull.max()),
                              "parts_clearance_mm": 1000 * float(gap.min()), "unseen_share": float(occ.mean()),
                              "unseen_to_target_mm": 1000 * to_target, "unseen_to_scene_mm": 1000 * to_scene}
    # the true surface between the pads, in the wrist frame
    S, fi = trimesh.sample.sample_surface_even(mesh, 20000, seed=0)
    W = np.linalg.inv(T) @ T_w_file
    Sw, Nw = S @ W[:3, :3].T + W[:3, 3], mesh.face_normals[fi] @ W[:3, :3].T
    between = _in_closing_region(Sw, gripper, grasp.opening)
    r["true_between"] = int(between.sum())
    # the segment's observed points in the same region: what the planner saw of that extent
    Pw = np.asarray(mem.points, float) @ np.linalg.inv(T)[:3, :3].T + np.linalg.inv(T)[:3, 3]
    seen = _in_closing_region(Pw, gripper, grasp.opening)
    r["seen_between"] = int(seen.sum())
    if seen.any():
        r["seen_extent_mm"] = [1000 * float(Pw[seen, 0].min()), 1000 * float(Pw[seen, 0].max())]
    if between.any():
        x = np.where(between, Sw[:, 0], np.nan)
        lo, hi = int(np.nanargmin(x)), int(np.nanargmax(x))
        r["true_extent_mm"] = [1000 * float(Sw[lo, 0]), 1000 * float(Sw[hi, 0])]
        r["contact_below_tip_mm"] = [1000 * float(gripper.fingertip_z - Sw[j, 2]) for j in (lo, hi)]
        r["contact_normal_deg"] = [float(np.degrees(np.arccos(np.clip(s * Nw[j, 0], -1, 1))))
                                   for j, s in ((lo, -1.0), (hi, 1.0))]
        com = (W @ np.r_[np.linalg.inv(spec.T_obj_file)[:3, 3], 1.0])[:3]
        r["com_off_line_mm"] = 1000 * float(abs(com[1]))
    at = T @ np.r_[gripper.nominal_tcp, 1.0]
    sight = (at[:3] - eye) / np.linalg.norm(at[:3] - eye)
    r["closing_sight_cos"] = float(abs(T[:3, 0] @ sight))
    return r


def episodes(cfg: Config, kind: str, db) -> list[dict]:
    import e10_clutter_removal as e10
    import trimesh

    from graspsim.tabletop.clutter import benchmark_episode, grasp_target
    from graspsim.tabletop.scene_objects import ASSETS

    e10cfg = e10.Config(seed=cfg.seed, seeds=max(cfg.seeds, e10.Config().seeds), scenes=cfg.scenes)
    clutter = e10._clutter_config({"kind": kind, "noise": "none", "ablation": None}, cfg.unseen_margin)
    rows = []
    for s in range(cfg.seeds):
        sd = e10.seed_of(e10cfg, s)
        for i in range(cfg.scenes):
            ep = benchmark_episode(5, kind, sd, i, db=db, config=clutter, object_set=cfg.object_set)
            scene = ep.scene
            mine = [j for j, o in enumerate(scene.objects) if cfg.object in (o.name, "any")]
            if not mine:
                ep.close()
                continue
            meshes = {}
            for j in mine:
                spec = scene.objects[j].spec
                path = Path(spec.file) if Path(spec.file).is_absolute() else ASSETS / spec.file
                mesh = trimesh.load(path, force="mesh")
                mesh.apply_scale(spec.scale)
                meshes[j] = (mesh, mesh.convex_hull)
            try:
                for look, g, _, _ in e10.looks(ep):
                    k = grasp_target(look, g, db.gripper)
                    r = measure(ep, look, g, k, *meshes[k], db.gripper) if k in meshes else None
                    a = ep.execute(look, g)
                    if r is not None:
                        r.update(kind=kind, seed=s, scene=i, cause=a.cause, object=scene.objects[k].name)
                        r["mechanism"] = "success" if a.success else mechanism(r)
                        rows.append(r)
                        log.info("%s seed %d scene %d: %s (%s)", kind, s, i, a.cause, r["mechanism"])
            finally:
                ep.close()
    return rows


def run(cfg: Config, db) -> dict:
    rows = [r for kind in cfg.kinds for r in episodes(cfg, kind, db)]
    mech: dict[str, int] = {}
    for r in rows:
        if r["cause"] != "success":
            mech[r["mechanism"]] = mech.get(r["mechanism"], 0) + 1
    return {"grasps": len(rows), "lifted": sum(r["cause"] == "success" for r in rows), "mechanisms": mech,
            "off_centre": off_centre(rows), "rows": rows,
            "denominators": f"grasps aimed at the {cfg.object} in the scenes run"
            + (" (any: every object's grasps)" if cfg.object == "any" else "")}


def _extent(e) -> str:
    return "-" if e is None else f"{e[0]:.0f} to {e[1]:.0f}"


def readme_section(s: dict) -> str:
    c = s["config"]
    aimed = "grasps lifted the object they were aimed at" if c["object"] == "any" else \
        f"grasps aimed at the {c['object']} lifted it"
    L = [f"`{s['command']}`: {s['lifted']}/{s['grasps']} {aimed} "
         f"({', '.join(c['kinds'])}, {c['seeds']} seeds x {c['scenes']} scenes of {c['object_set']}).", "",
         "| failure mechanism | grasps |", "|---|---|"]
    L += [f"| {m} | {n} |" for m, n in sorted(s["mechanisms"].items(), key=lambda t: -t[1])]
    if s.get("off_centre"):
        lim = f"{1000 * OFF_CENTRE:g} mm"
        L += ["", f"Where the object lay between the pads (its true extent along the closing axis; off centre: its "
                  f"middle more than {lim} from the gripper's centre), and had each grasp been centred on the "
                  "extent its segment's observed points span there:", "",
              "| cause | grasps | off centre | median offset [mm] | with seen points | off centre if centred on them "
              "| median offset then [mm] |", "|---|---|---|---|---|---|---|"]
        for cause, g in s["off_centre"].items():
            then = g["median_off_if_centred_on_seen_mm"]
            L.append(f"| {cause} | {g['grasps']} | {g['off_centre']} | {g['median_off_mm']:.1f} | {g['with_seen']} | "
                     f"{g['off_centre_if_centred_on_seen']} | {'-' if then is None else f'{then:.1f}'} |")
    L += ["", "The failed grasps:", "",
          "| kind | seed | scene | object | parts | cause | mechanism | closing . sight | "
          "true in fingers (unseen/seen) [mm deep] | hull [mm deep] | parts clearance [mm] | true / seen extent "
          "between the pads [mm] |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in (r for r in s["rows"] if r["cause"] != "success"):
        f = r["fingers"].values()
        L.append(f"| {r['kind']} | {r['seed']} | {r['scene']} | {r.get('object', c['object'])} | "
                 f"{'; '.join(r['parts'])} | {r['cause']} | "
                 f"{r['mechanism']} | {r['closing_sight_cos']:.2f} | "
                 f"{'/'.join(str(v['in_true_unseen']) + ':' + str(v['in_true_seen']) for v in f)} "
                 f"[{max(v['depth_true_mm'] for v in f):.1f}] | {max(v['depth_hull_mm'] for v in f):.1f} | "
                 f"{min(v['parts_clearance_mm'] for v in f):.1f} | {_extent(r.get('true_extent_mm'))} / "
                 f"{_extent(r.get('seen_extent_mm'))} |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    from e10_clutter_removal import read_only_database

    cfg, out, record = start(Config, __file__, argv, __doc__)
    db = read_only_database(cfg, out)
    print(record.write(out, {"config": cfg, **run(cfg, db)}, readme_section))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
