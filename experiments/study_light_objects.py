"""Light objects in the simulation: does a grasp's outcome depend on the object's mass?

E10's tuning piles lose most grasps on the domino (3.3 g at the household density) by
``no_contact``: the jaws close, the domino leaves the space between the pads. The cause is
the contact model more than the grasp: MuJoCo's soft contacts are set as accelerations
(``solref``, ``solimp``), so the force a given penetration produces scales with the
effective mass of the contact, here the light object's. Under the gripper's full force
(about 250 N for the Festo at 6 bar) the pads sink far deeper into a light object than
into a heavy one (this study, with the ``soft`` contacts of the results published before
``stiff`` became the default: 4.6 mm into the 3.3 g domino, 1 mm at 98 g), the object
pitches between them and may squirt out under a fingertip. A friction grip of a rigid
object does not depend on its mass like that, so outcomes that do measure the simulator;
the same at a smaller time step (``--timestep``) rules out the integration.

The study puts one mesh of a set alone on the table, resting on a face (``--up``; default:
its shortest extent up, a domino lying flat), gives it each of ``--masses`` (multiples of
the set's mass for it), and executes the same grid of level top-down grasps with
``SceneSim.execute`` (the clutter benchmark's simulation and judge): closing along the
object's longest horizontal axis, centred on its footprint, the fingertips ``--heights``
above the table, moved ``--offsets`` along the closing axis and turned ``--yaws`` about
the vertical. Per mass it reports the grasps that held and the pads' sink: how far the
jaws closed, in the grasps that held, beyond the object's extent along the closing axis
(half the footprint's length less the pads' gap at the end of the close: how far each
pad went into the object).

``--contacts`` picks a named contact model (``graspsim.sim.contact_model``: ``stiff``, the
default, or ``soft``); ``--timestep``, ``--pad-solref`` and ``--pad-solimp`` change it on the
same grid (``SimSettings.timestep``, ``GripperPhysics.pad_solref`` / ``.pad_solimp``).

    python experiments/study_light_objects.py
    python experiments/study_light_objects.py --object lemon --masses 1 3 10
    python experiments/study_light_objects.py --contacts soft [--timestep 0.0005]
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start

from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS

log = logging.getLogger("study_light_objects")


@dataclass(frozen=True)
class Config:
    object: str = opt("domino", "a mesh of the object set, by name")
    object_set: str = opt("household", "the shipped set (or folder) the object comes from")
    up: tuple[float, ...] = opt((), "the object-frame direction that points up (3 numbers; default: its "
                                    "shortest extent's axis)")
    masses: tuple[float, ...] = opt((1.0, 3.0, 10.0, 30.0), "masses as multiples of the set's mass for it")
    heights: tuple[float, ...] = opt((0.0005, 0.001, 0.002, 0.003), "fingertips above the table [m]")
    offsets: tuple[float, ...] = opt((-0.003, -0.0015, 0.0, 0.0015, 0.003),
                                     "the grasp moved along its closing axis [m]")
    yaws: tuple[float, ...] = opt((0.0, 5.0), "the closing axis turned about the vertical [deg]")
    contacts: str = opt(DEFAULT_CONTACTS, "the named contact model (graspsim.sim.contact_model) the next three change",
                        choices=CONTACT_MODELS)
    timestep: float | None = opt(None, "MuJoCo's time step [s] (default: the contact model's; the protocol's "
                                       "phases keep their durations)")
    pad_solref: tuple[float, ...] = opt((), "the pads' MuJoCo solref, 2 numbers (default: the contact model's)")
    pad_solimp: tuple[float, ...] = opt((), "the pads' MuJoCo solimp, 5 numbers (default: the contact model's)")
    QUICK: ClassVar[dict] = {"masses": (1.0, 30.0), "heights": (0.0005,), "offsets": (0.0,), "yaws": (0.0,)}


def _entry(cfg: Config):
    from graspsim.tabletop.mesh_objects import mesh_set

    entries = [e for e in mesh_set(cfg.object_set).entries if e.name == cfg.object]
    if not entries:
        names = sorted(e.name for e in mesh_set(cfg.object_set).entries)
        raise SystemExit(f"no mesh {cfg.object!r} in {cfg.object_set!r}; valid: {names}")
    return entries[0]


def _footprint(sim) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The settled object's surface in the world: (centre (2,) of its footprint on its
    principal horizontal axes, the long axis (2,), extents (2,) along long and short axis)."""
    o = sim.sim_objects[0]
    T = sim.pose(0)
    v = np.asarray(o.surface.vertices, float) @ T[:3, :3].T + T[:3, 3]
    xy = v[:, :2] - v[:, :2].mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov(xy.T))
    u = vecs[:, -1]
    w = np.array([-u[1], u[0]])
    a, b = xy @ u, xy @ w
    centre = v[:, :2].mean(axis=0) + 0.5 * (a.max() + a.min()) * u + 0.5 * (b.max() + b.min()) * w
    return centre, u, np.array([np.ptp(a), np.ptp(b)])


def _grasp(gripper, centre: np.ndarray, axis: np.ndarray, yaw: float, height: float, offset: float,
           opening: float) -> np.ndarray:
    """A level top-down wrist pose closing along ``axis`` turned by ``yaw`` [rad], the
    fingertips ``height`` above the table, moved ``offset`` along the closing axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    x = np.array([c * axis[0] - s * axis[1], s * axis[0] + c * axis[1], 0.0])
    z = np.array([0.0, 0.0, -1.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = [centre[0], centre[1], 0.0]
    T[:3, 3] += offset * x
    T[2, 3] = 1.0
    low = float(gripper.lowest_along(T[2, :3][None], T[2, 3:4], np.array([opening]))[0])
    T[2, 3] += height - low
    return T


def _closed_gap(sim, T: np.ndarray, opening: float) -> float:
    """The pads' gap [m] at the end of the close of a grasp at ``T`` (replayed, nothing kept)."""
    from graspsim.sim.batch import simulate

    p, m = sim.protocol, sim.model
    ph = p.steps(m.opt.timestep)
    c1 = ph["close"][1]
    control = p.controls(sim, T[None], np.array([opening]))[:, :c1 + 1]
    states, _ = simulate(sim, p, sim._start_state(T, opening)[None], np.ascontiguousarray(control))
    return float(np.sum(states[0, c1, 1 + sim.drive.qadr]))  # each jaw's value is its pad's distance from the centre


def settings(cfg: Config):
    """The scene's simulation settings with the study's time step and pad contact parameters."""
    from graspsim.sim.trial_scene import contact_model

    base = contact_model(cfg.contacts)
    physics = replace(base.physics, **({"pad_solref": cfg.pad_solref} if cfg.pad_solref else {}),
                      **({"pad_solimp": cfg.pad_solimp} if cfg.pad_solimp else {}))
    return replace(base, physics=physics, **({"timestep": cfg.timestep} if cfg.timestep is not None else {}))


def run(cfg: Config) -> dict:
    from graspsim.sim.trial_scene import resting_pose
    from graspsim.tabletop.scene_objects import mesh_spec
    from graspsim.tabletop.scene_sim import SceneSim

    spec = mesh_spec(_entry(cfg))
    obj = spec.sim_object()
    base = obj.mass
    ext = np.ptp(np.asarray(obj.surface.vertices, float), axis=0)
    up = np.asarray(cfg.up, float) if cfg.up else np.eye(3)[int(np.argmin(ext))]
    sim_settings = settings(cfg)
    rows = []
    for k in cfg.masses:
        mass = float(k * base)
        sim = SceneSim([(replace(spec, mass=mass), resting_pose(obj, up=up))], settings=sim_settings)
        try:
            sim.settle()
            centre, axis, extent = _footprint(sim)
            opening = float(min(sim.gripper.max_opening, extent[0] + 0.03))
            held, sinks = 0, []
            for yaw in cfg.yaws:
                for h in cfg.heights:
                    for off in cfg.offsets:
                        T = _grasp(sim.gripper, centre, axis, np.radians(yaw), h, off, opening)
                        out = sim.execute(T, opening, target=0, commit=False)
                        if out.success:
                            held += 1
                            # held, the object has turned square to the pads: its length lies between them
                            sinks.append(0.5 * (extent[0] - _closed_gap(sim, T, opening)))
            n = len(cfg.yaws) * len(cfg.heights) * len(cfg.offsets)
            rows.append({"mass_kg": mass, "times_set_mass": k, "grasps": n, "held": held,
                         "sink_mm_median": None if not sinks else round(1000 * float(np.median(sinks)), 2),
                         "extent_mm": [round(1000 * float(e), 1) for e in extent]})
            log.info("%.1f g: %d of %d held", 1000 * mass, held, n)
        finally:
            sim.close()
    return {"object": cfg.object, "up": up.tolist(), "timestep": sim_settings.timestep,
            "physics": sim_settings.physics.to_dict(), "rows": rows,
            "denominators": "grasps: every yaw x height x offset of the grid, per mass; held: the clutter "
                            "benchmark's success (lifted and held); sink: median over the grasps that held"}


def readme_section(s: dict) -> str:
    ph = s["physics"]
    dt = (f"time step {1000 * s['timestep']:g} ms, the pads' solref {ph['pad_solref']}, solimp "
          f"{ph['pad_solimp']}")
    L = [f"`{s['command']}`: {s['object']} alone on the table ({s['rows'][0]['extent_mm'][0]} x "
         f"{s['rows'][0]['extent_mm'][1]} mm footprint, up = object axis {s['up']}), the same grid of level "
         f"top-down grasps at every mass (SceneSim.execute, the clutter benchmark's simulation; {dt}); "
         "sink: how far "
         "each pad went into the object by the end of the close, median over the grasps that held.", "",
         "| mass | x the set's | held | pads' sink [mm] |", "|---|---|---|---|"]
    for r in s["rows"]:
        sink = "–" if r["sink_mm_median"] is None else f"{r['sink_mm_median']:.2f}"
        L.append(f"| {1000 * r['mass_kg']:.1f} g | {r['times_set_mass']:g} | {r['held']}/{r['grasps']} | {sink} |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    record.write(out, {"config": cfg, **run(cfg)}, readme_section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
