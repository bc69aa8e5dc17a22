"""Experiment E14: a grasp dataset's own labels against MuJoCo (cross-simulator agreement).

Input: an ACRONYM ``.h5`` (or GraspGen ``.json``) grasp file whose object mesh lies where
the file says (ACRONYM's layout: ``grasps/`` and ``meshes/`` side by side), or ``--mesh``.
The published run uses ACRONYM's example grasp file
``data/examples/grasps/Mug_10f6e09036350e92b3f21f1137c3c347_0.0002682457830986903.h5``
with ``data/examples/meshes/Mug/10f6e09036350e92b3f21f1137c3c347.obj`` from
https://github.com/NVlabs/acronym (2000 Franka "panda" grasps labelled in FleX). Neither is
committed here: the grasps are CC BY-NC 4.0 and the mug is a ShapeNetSem mesh, which may
not be redistributed; clone that repository and pass ``--grasps``.

Every grasp is read through :func:`graspsim.maps.imported.import_beside` into the output
folder (the dataset file is only read): ACRONYM's Franka frame turned into graspsim's
wrist frame (``graspsim.maps.formats``), the dataset's object mass, friction and pre-grasp
opening kept (ACRONYM: 13 g, mu 1.0, fingers fully open). The grasps simulated are a
seeded sample spread over the object's surface (``graspsim trial --sample``; the same
for every model and protocol; ``--sample 0``: all), each without execution error with
the vendored Franka hand (70 N per finger) through ``simulate_map`` -- what ``graspsim
trial FILE --protocol P`` runs -- in two protocols:

* ``tug``, the ACRONYM-style one: no table, no gravity; the hand closes, then pulls of
  1 g x mass in six directions (graspsim's ``Tug``); held = the object never moved more
  than 1 cm in the hand (ACRONYM's FleX test closes and then shakes the gripper; 98.7 %
  of the example file's FleX-held grasps moved less than 1 cm while shaken);
* ``lift_place``, graspsim's own: the object resting on a table, lifted, held, placed.

and against each of ``--models``, the object's collision models:

* ``default``: what ``graspsim trial`` simulates (:func:`graspsim.sim.prepare_mesh`'s
  defaults: CoACD's parts within 15 CPU seconds, else the convex hull -- which the
  example's mug gets: its cavity filled);
* ``coacd``: CoACD's parts without a time limit (at most 16: walls thickened by mm);
* ``surface``: the mesh's own surface, a thin prism per face
  (:func:`graspsim.sim.surface_model`; several times slower per trial).

Denominators: every sampled grasp is a trial; a grasp whose start pose is in
collision (with the object or, in lift_place, the table) is *not executable* in MuJoCo
and has its own column. Reported per model and protocol: the confusion table (dataset label x
MuJoCo held / not held / not executable), agreement and Cohen's kappa on the executable
grasps, and the goal figure: of the grasps that held in the dataset and are executable
in MuJoCo, the share that hold in MuJoCo (95 % Wilson interval), overall, by grasp
type (approach direction in the mesh frame: from +z, from the side, from -z), by whether a
finger starts inside the object's convex hull (in a concavity: the mug's cavity) and by
how far the object moved while the jaws closed.

    git clone https://github.com/NVlabs/acronym ~/acronym
    python experiments/e14_cross_simulator.py --publish --sample 1000 \
        --grasps ~/acronym/data/examples/grasps/Mug_10f6e09036350e92b3f21f1137c3c347_0.0002682457830986903.h5
    python experiments/e14_cross_simulator.py --quick     # a generated ACRONYM-layout file

Cost: the published run (1000 grasps, three models, two protocols) took 17 min on 2 loaded
cores (806 CPU seconds), nearly all of it the surface model's trials.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, md_table, opt, rate_ci, start, write_text

from graspsim.maps import load_map, read_sim_results
from graspsim.maps.imported import SOURCE_GROUP, import_beside
from graspsim.sim import CoacdParams, TrialOutcome, make_protocol, prepare_mesh, simulate_map, surface_model
from graspsim.stats import wilson_interval

log = logging.getLogger("e14")
MODELS = ("default", "coacd", "surface")
TYPES = {"from +z": (-np.inf, -0.5), "side": (-0.5, 0.5), "from -z": (0.5, np.inf)}  # approach . z ranges


@dataclass(frozen=True)
class Config:
    grasps: str = opt("", "ACRONYM .h5 / GraspGen .json grasp file (empty with --quick: a generated one)")
    mesh: str = opt("", "the object's mesh (default: the file's object/file, found beside it)")
    protocols: tuple[str, ...] = opt(("tug", "lift_place"), "protocols", choices=("tug", "lift_place"))
    models: tuple[str, ...] = opt(MODELS, "the object's collision models (see the doc)",
                                  choices=MODELS)
    sample: int = opt(300, "grasps simulated, a seeded sample spread over the surface (0: all)")
    seed: int = opt(0, "run seed (draws the sample; no execution error)")
    threads: int = opt(2, "simulation threads")
    quick: bool = opt(False, "generated input", cli=False)
    QUICK: ClassVar[dict] = {"quick": True, "sample": 0}

    def __post_init__(self) -> None:
        if self.grasps and not Path(self.grasps).expanduser().is_file():
            raise ValueError(f"--grasps {self.grasps}: no such file")
        if self.sample < 0:
            raise ValueError(f"--sample must be >= 0 (0: all), got {self.sample}")


def quick_input(folder: Path) -> Path:
    """A grasp file in ACRONYM's layout, as the dataset's are (``acronym_tools.load_grasps``
    reads it): eight Franka grasps from above across the 5 cm faces of a 5 x 6 x 8 cm box,
    turned 0-49 deg about the vertical, every other one labelled held (a smoke test of the
    pipeline; the file says so in its ``graspsim`` attribute)."""
    import json

    import h5py
    import trimesh

    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(folder / "meshes" / "box.obj")
    T = np.tile(np.eye(4), (8, 1, 1))
    for k in range(8):  # base link A: z down, fingers (x_A) turned 7k deg; the pads 1.2 cm below the top
        t = np.radians(7.0 * k)
        x, z = np.array([np.cos(t), np.sin(t), 0.0]), np.array([0.0, 0.0, -1.0])
        T[k, :3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
        T[k, :3, 3] = [0.0, 0.0, 0.04 - 0.012 + 0.1034]
    out = folder / "Box_quick.h5"
    with h5py.File(out, "w") as f:
        f["grasps/transforms"] = T
        f["grasps/qualities/flex/object_in_gripper"] = np.arange(8) % 2
        f["object/file"], f["object/scale"] = np.bytes_(b"meshes/box.obj"), 1.0
        f["object/mass"], f["object/friction"] = 0.1, 1.0
        f["gripper/type"], f["gripper/configuration"] = np.bytes_(b"panda"), np.array([0.04])
        f.attrs["graspsim"] = json.dumps({"label_source": "hand-made labels (E14 --quick smoke test)"})
    return out


#: bins [m] of how far the object moved while the jaws closed (MuJoCo's ``close_lin``)
CLOSING_BINS = ((0.0, 0.01), (0.01, 0.03), (0.03, np.inf))


def compare(dataset: np.ndarray, held: np.ndarray, outcome: np.ndarray, approach_z: np.ndarray,
            close_lin: np.ndarray, in_hull: np.ndarray | None = None,
            dataset_close_lin: np.ndarray | None = None) -> dict:
    """The confusion table and agreement of dataset labels (1 held) with MuJoCo's; the
    goal figure by grasp type, by whether a finger starts in a concavity (``in_hull``)
    and by the object's motion while the jaws closed, in MuJoCo and in the dataset's
    own simulator (``dataset_close_lin``, ACRONYM's ``object_motion_during_closing_linear``)."""
    execu = outcome != TrialOutcome.START_COLLISION
    ds = dataset == 1
    mj = held == 1
    table = {f"dataset {'held' if d else 'not held'}": {
        "mujoco held": int(np.sum((ds == d) & execu & mj)), "mujoco not held": int(np.sum((ds == d) & execu & ~mj)),
        "not executable": int(np.sum((ds == d) & ~execu))} for d in (True, False)}
    n = int(execu.sum())
    agree = int(np.sum(execu & (ds == mj)))
    p_o = agree / n if n else float("nan")
    p_e = ((ds[execu].mean() * mj[execu].mean() + (1 - ds[execu].mean()) * (1 - mj[execu].mean()))
           if n else float("nan"))
    kappa = (p_o - p_e) / (1 - p_e) if n and p_e < 1 else float("nan")
    goal = _rate(int(np.sum(ds & execu & mj)), int(np.sum(ds & execu)))
    by_type = {}
    for name, (lo, hi) in TYPES.items():
        m = (approach_z >= lo) & (approach_z <= hi) if name != "side" else (approach_z > lo) & (approach_z < hi)
        by_type[name] = {"grasps": int(m.sum()), "dataset_held": int(np.sum(m & ds)),
                         "executable": int(np.sum(m & execu)),
                         "held_of_dataset_held_executable": _rate(int(np.sum(m & ds & execu & mj)),
                                                                  int(np.sum(m & ds & execu))),
                         "agreement": _rate(int(np.sum(m & execu & (ds == mj))), int(np.sum(m & execu)))}
    moved, moved_ds = {}, {}
    for lo, hi in CLOSING_BINS:
        name = f"{lo * 100:g}-{hi * 100:g} cm" if np.isfinite(hi) else f">= {lo * 100:g} cm"
        m = ds & execu & (close_lin >= lo) & (close_lin < hi)
        moved[name] = _rate(int(np.sum(m & mj)), int(m.sum()))
        if dataset_close_lin is not None:
            m = ds & execu & (dataset_close_lin >= lo) & (dataset_close_lin < hi)
            moved_ds[name] = _rate(int(np.sum(m & mj)), int(m.sum()))
    concavity = {}
    if in_hull is not None:
        for name, m in (("a finger in a concavity", in_hull), ("both fingers outside the hull", ~in_hull)):
            concavity[name] = {"grasps": int(m.sum()), "dataset_held": int(np.sum(m & ds)),
                               "executable": int(np.sum(m & execu)),
                               "held_of_dataset_held_executable": _rate(int(np.sum(m & ds & execu & mj)),
                                                                        int(np.sum(m & ds & execu))),
                               "agreement": _rate(int(np.sum(m & execu & (ds == mj))), int(np.sum(m & execu)))}
    fails = {o.label: int(np.sum(ds & execu & (outcome == o))) for o in TrialOutcome
             if o not in (TrialOutcome.SUCCESS, TrialOutcome.START_COLLISION)}
    return {"grasps": len(ds), "executable": n, "confusion": table, "agreement": _rate(agree, n),
            "kappa": kappa, "goal": goal, "by_type": by_type, "by_concavity": concavity, "by_closing_motion": moved,
            "by_dataset_closing_motion": moved_ds, "dataset_held_outcomes": fails}


def _rate(k: int, n: int) -> dict:
    lo, hi = wilson_interval(k, n)
    return {"k": k, "n": n, "rate": k / n if n else None, "ci": [float(lo), float(hi)]}


def collision_model(model: str, file: str, scale: float):
    """The object's collision model ``model`` (see the doc) of the mesh file at ``scale``."""
    if model == "surface":
        return surface_model(file, scale=scale)
    return prepare_mesh(file, scale=scale, params=CoacdParams(time_limit=math.inf) if model == "coacd"
                        else CoacdParams())


def dataset_motion(src: Path, n: int, phase: str) -> np.ndarray | None:
    """(N,) how far [m] the object moved in the hand in the dataset's own simulator while
    the jaws closed (``phase`` "closing") or while it shook the hand ("shaking"): ACRONYM's
    ``grasps/qualities/flex/object_motion_during_<phase>_linear``; None where the file has
    no such column."""
    if src.suffix.lower() not in (".h5", ".hdf5"):
        return None
    import h5py

    with h5py.File(src, "r") as f:
        key = f"grasps/qualities/flex/object_motion_during_{phase}_linear"
        v = f[key][()] if key in f else None
    return np.asarray(v, float) if v is not None and len(v) == n else None


def finger_in_hull(gmap, mesh) -> np.ndarray:
    """(N,) whether a finger box's centre, at the pre-grasp opening, lies inside the convex
    hull of ``mesh`` (trimesh) at the start: a grasp reaching into a concavity."""
    spec = gmap.meta.gripper_spec
    b = spec.collision_boxes()
    fingers = [b.names.index(n) for n in ("finger_neg", "finger_pos")]
    opening = spec.pregrasp_opening(gmap.width)
    T = gmap.T_obj_wrist
    hull = mesh.convex_hull
    inside = np.zeros(len(gmap), bool)
    for k in fingers:
        c = np.repeat(b.centers[k][None], len(gmap), axis=0)
        c[:, 0] += b.x_sign[k] * 0.5 * opening
        inside |= hull.contains(np.einsum("nij,nj->ni", T[:, :3, :3], c) + T[:, :3, 3])
    return inside


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=NAMED, quiet=("graspsim.sim.batch",))
    if not (cfg.quick or cfg.grasps):
        print("e14_cross_simulator.py: --grasps FILE is required (ACRONYM's example: see the script's doc), "
              "or --quick", file=sys.stderr)
        return 2
    src = quick_input(out) if cfg.quick and not cfg.grasps else Path(cfg.grasps).expanduser()
    kw = {"mesh": cfg.mesh} if cfg.mesh else {}
    imported = import_beside(src, out / "imported.graspsim.h5", **kw)
    gmap = load_map(imported)
    labels = read_sim_results(imported, SOURCE_GROUP)
    dataset_all = np.asarray(labels["object_in_gripper"]).astype(int)
    ds_close = dataset_motion(src, len(gmap), "closing")
    ds_shake = dataset_motion(src, len(gmap), "shaking")
    obj = gmap.meta.object
    per_model = {}
    for model in cfg.models:
        prepared = collision_model(model, obj["file"], float(obj.get("scale", 1.0)))
        per = {}
        for name in cfg.protocols:
            log.info("%s, %s model (%s, %d parts): %s grasps", name, model, prepared.method, len(prepared.parts),
                     cfg.sample or len(gmap))
            trials = simulate_map(imported, protocol=make_protocol(name), sample=cfg.sample or None, seed=cfg.seed,
                                  threads=cfg.threads, mesh=prepared, write=False)
            res, index = trials.results, trials.index
            chosen = gmap.select(index)
            in_hull = finger_in_hull(chosen, prepared.surface)
            per[name] = compare(dataset_all[index], res.object_in_gripper, res.outcome,
                                chosen.approach[:, 2].astype(float),
                                np.nan_to_num(res.metrics["close_lin"], nan=np.inf), in_hull,
                                None if ds_close is None else ds_close[index])
            np.savez_compressed(out / f"trials_{model}_{name}.npz", index=index, outcome=res.outcome,
                                held=res.object_in_gripper, dataset=dataset_all[index], in_hull=in_hull,
                                **{k: v for k, v in res.metrics.items()})
            per[name]["trials_per_second"] = res.trials_per_second
        inside = sum(trimesh.convex.convex_hull(q).volume for q in prepared.parts)  # overlaps counted twice
        per_model[model] = {"model": {**{k: prepared.describe()[k] for k in ("method", "parts", "volume_cm3")},
                                      "parts_volume_cm3": round(1e6 * inside, 2)}, "protocols": per}
    rec = gmap.meta.extra["import"]
    data = {"config": cfg, "input": {"file": src.name, "format": rec["format"], "grasps": len(gmap),
                                     "label_source": rec["label_source"], "dataset_held": int(np.sum(dataset_all == 1)),
                                     "object": {k: gmap.meta.object.get(k) for k in ("scale", "mass")},
                                     "friction": gmap.meta.quality["friction"],
                                     "opening": float(gmap.meta.gripper_spec.pregrasp_opening(gmap.width[:1])[0]),
                                     "T_grasp_wrist": rec["T_grasp_wrist"]},
            "gripper": gmap.meta.gripper["name"], "sample": cfg.sample or len(gmap), "models": per_model}
    if ds_shake is not None:  # what "held" meant in the dataset's simulator: the motion while shaken
        held_ds = dataset_all == 1
        data["input"]["dataset_held_shaken_under_1cm"] = _rate(int(np.sum(held_ds & (ds_shake < 0.01))),
                                                               int(held_ds.sum()))
        data["input"]["dataset_not_held_shaken_under_1cm"] = _rate(int(np.sum(~held_ds & (ds_shake < 0.01))),
                                                                   int((~held_ds).sum()))
    md = run.write(out, data, readme_section)
    write_text(out / "summary.md", md)
    print(md)
    return 0


MODEL_TEXT = {"default": "the default preparation (`graspsim trial`'s)", "coacd": "CoACD without a time limit",
              "surface": "the mesh's own surface (a 1.5 mm prism per face)"}


def _rates(rows: dict) -> list:
    return [[t, v["grasps"], v["dataset_held"], v["executable"],
             rate_ci(v["held_of_dataset_held_executable"]["k"], v["held_of_dataset_held_executable"]["n"],
                     v["held_of_dataset_held_executable"]["ci"]),
             rate_ci(v["agreement"]["k"], v["agreement"]["n"], v["agreement"]["ci"])] for t, v in rows.items()]


def readme_section(s: dict) -> str:
    """The README's E14 paragraph and tables (see ``experiments/report.py``)."""
    i = s["input"]
    L = [f"`{s['command']}` ({i['file']}: {i['grasps']} grasps, {i['dataset_held']} labelled held by "
         f"{i['label_source']}; {s['sample']} of them simulated, a seeded sample spread over the object's surface; "
         f"the gripper `{s['gripper']}`, opened to {1000 * i['opening']:.0f} mm as in the "
         f"dataset; object mass {1000 * (i['object']['mass'] or float('nan')):.1f} g, friction {i['friction']:g} "
         "from the file; no execution error. Not executable: the start pose collides in MuJoCo)."]
    if "dataset_held_shaken_under_1cm" in i:
        a, b = i["dataset_held_shaken_under_1cm"], i["dataset_not_held_shaken_under_1cm"]
        L[-1] += (f" In the dataset's own simulator, {rate_ci(a['k'], a['n'], a['ci'])} of the grasps it labelled "
                  f"held moved the object less than 1 cm while shaken, and {rate_ci(b['k'], b['n'], b['ci'])} of "
                  "those it labelled not held: the tug's 1 cm slip tolerance is the dataset's notion of held.")
    L += [""]
    goals = "; ".join(
        f"{MODEL_TEXT.get(model, model)} ({r['model']['method']}): " + ", ".join(
            f"{name} {rate_ci(g['k'], g['n'], g['ci'])}" for name, g in
            ((name, r_p["goal"]) for name, r_p in r["protocols"].items()))
        for model, r in s["models"].items())
    L += ["The goal figure (of the grasps that held in the dataset and are executable in MuJoCo, the share that "
          f"hold in MuJoCo; goal >= 80 %) by collision model: {goals}. Why it depends on the model for "
          "ACRONYM's example mug (the hull fills its cavity, CoACD's parts thicken its walls), how FleX's "
          "protocol and graspsim's compare and the gap that is left: docs/datasets.md.", ""]
    head = ["", "grasps", "dataset held", "executable", "held in MuJoCo of dataset-held executable",
            "agreement (executable)"]
    for model, r_model in s["models"].items():
        m = r_model["model"]
        L += [f"#### Collision model: {MODEL_TEXT.get(model, model)} -- {m['method']}, {m['parts']} convex "
              f"part(s) enclosing {m['parts_volume_cm3']:.0f} cm³ (the mesh: {m['volume_cm3']:.0f} cm³)", ""]
        for name, r in r_model["protocols"].items():
            g = r["goal"]
            L += [f"**{name}**: of the grasps that held in the dataset and are executable in MuJoCo, "
                  f"{rate_ci(g['k'], g['n'], g['ci'])} hold in MuJoCo; agreement on the executable grasps "
                  f"{rate_ci(r['agreement']['k'], r['agreement']['n'], r['agreement']['ci'])}, Cohen's kappa "
                  f"{'n/a' if r['kappa'] is None else format(r['kappa'], '.2f')}; the dataset-held grasps MuJoCo "
                  "lost: " + (", ".join(f"{k} {v}" for k, v in r["dataset_held_outcomes"].items() if v) or "none")
                  + ".", ""]
            rows = [[k, v["mujoco held"], v["mujoco not held"], v["not executable"]] for k, v in r["confusion"].items()]
            L += [md_table(["", "MuJoCo held", "MuJoCo not held", "not executable"], rows), ""]
            rows = _rates(r["by_type"]) + _rates(r.get("by_concavity", {}))
            L += [md_table(["approach (mesh frame) / where the fingers start", *head[1:]], rows), ""]
            mj, dsm = r.get("by_closing_motion", {}), r.get("by_dataset_closing_motion") or {}
            rows = [[k, rate_ci(v["k"], v["n"], v["ci"])] + ([rate_ci(dsm[k]["k"], dsm[k]["n"], dsm[k]["ci"])]
                                                              if dsm else []) for k, v in mj.items()]
            if rows:
                L += [md_table(["object moved while the jaws closed", "in MuJoCo: held in MuJoCo of dataset-held "
                                "executable"] + (["in the dataset's simulator: the same"] if dsm else []), rows), ""]
    return "\n".join(L)


if __name__ == "__main__":
    raise SystemExit(main())
