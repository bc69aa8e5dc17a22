"""Benchmark: a user's mesh made ready for simulation, and `graspsim trial --mesh` on it
(issue 33, "meshes as users have them").

Goals: any mesh of up to 500 k faces ready for simulation in <= 20 s the first time and
<= 1 s from the cache; `graspsim trial MAP --top 10 --mesh MESH` <= 60 s in all.

For every mesh (generated hard cases, plus every mesh file under ``--folder`` when
given), each step in a fresh Python process, as a user runs it:

* ``first``: :func:`graspsim.prepare_mesh` with an empty cache folder: the call's own
  time (the goal's number; reading the file included), and apart from it the import of
  ``graspsim.sim`` (mujoco, trimesh, scipy: the same for every mesh) and the process's wall time;
  the call's CPU time (its worker process's included) says how much of a slow call was
  the machine's load;
* ``cached``: the same call again in a new process (a cache hit), timed the same way;
* ``trial`` (the generated cases, every ``--trial-every``-th file of the folder and
  those named by ``--trial-names``, the Lego brick by default):
  ``graspsim trial MAP --top 10 --mesh MESH --json --no-write`` with another empty cache,
  wall time of the whole command. MAP holds 10 horizontal grasps through the mesh's
  centre (a hand-made map, the mesh in its frame): the trial's outcomes measure the time
  of the mesh path, not grasp quality.

Generated cases: an open cylinder (a tube without caps, 256 sections), the issue's
327,680-face cylinder (81,920 sections), a 500,000-face torus (non-convex, closed: it is
decimated, then decomposed within the time limit). Quick mode: a 64-section tube, its trial, no folder.

    python experiments/bench_mesh_prep.py --folder ../shared/objects
    python experiments/bench_mesh_prep.py --quick --out results/bench_mesh_prep-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # hand_made
from _common import machine_load, opt, run_cli_fresh, run_fresh, start

log = logging.getLogger("bench_mesh_prep")
GOAL_FIRST_S, GOAL_CACHED_S, GOAL_TRIAL_S = 20.0, 1.0, 60.0

_PREPARE = """
import json, resource, sys, time
def cpu():
    return time.process_time() + sum(resource.getrusage(resource.RUSAGE_CHILDREN)[:2])
t0 = time.perf_counter()
from graspsim.sim import prepare_mesh
t1, c1 = time.perf_counter(), cpu()
p = prepare_mesh(sys.argv[1])
print(json.dumps({**p.describe(), "import_s": t1 - t0, "call_s": time.perf_counter() - t1, "call_cpu_s": cpu() - c1}))
"""


@dataclass(frozen=True)
class Config:
    folder: str = opt("", "a folder of mesh files (searched recursively: .stl .obj .ply); none by default")
    trial_every: int = opt(4, "trial every N-th mesh of --folder (1: all)")
    trial_names: tuple[str, ...] = opt(("lego",), "meshes of --folder always trialled (file stems)")
    tube_sections: int = opt(256, "sections of the open cylinder")
    big_sections: int = opt(81_920, "sections of the big cylinder (4 x sections faces)")
    torus_faces: int = opt(500_000, "faces of the torus")
    trials: bool = opt(True, "time `graspsim trial --top 10 --mesh` too")
    QUICK: ClassVar[dict] = {"tube_sections": 64, "big_sections": 0, "torus_faces": 0}


def generated(cfg: Config, folder: Path) -> list[tuple[str, Path]]:
    """The hard cases written as STL files into ``folder``: (name, path)."""
    import trimesh

    out = []
    tube = trimesh.creation.cylinder(0.03, 0.1, sections=cfg.tube_sections)
    tube = trimesh.Trimesh(tube.vertices, tube.faces[np.abs(tube.face_normals[:, 2]) < 0.5])
    out.append((f"open_cylinder_{len(tube.faces)}f", tube))
    if cfg.big_sections:
        big = trimesh.creation.cylinder(0.03, 0.1, sections=cfg.big_sections)
        out.append((f"cylinder_{len(big.faces)}f", big))
    if cfg.torus_faces:
        n = max(8, int(round(np.sqrt(cfg.torus_faces / 2))))
        torus = trimesh.creation.torus(0.035, 0.012, major_sections=n, minor_sections=n)
        out.append((f"torus_{len(torus.faces)}f", torus))
    paths = []
    for name, mesh in out:
        mesh.export(folder / f"{name}.stl")
        paths.append((name, folder / f"{name}.stl"))
    return paths


def hand_made_map(mesh_path: Path, out: Path) -> Path:
    """10 horizontal grasps through the mesh's bounding-box centre (mesh frame)."""
    from hand_made import grasp_pose, hand_made_map  # the tests' hand-made grasps, as bench_sim uses them

    from graspsim.maps import save_map
    from graspsim.primitives import Cylinder
    from graspsim.sim.meshes import load_mesh

    mesh = load_mesh(mesh_path)
    c = mesh.bounds.mean(axis=0)
    yaw = np.linspace(0.0, np.pi, 10, endpoint=False)
    T = np.stack([grasp_pose(c, [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0]) for a in yaw])
    m = hand_made_map(Cylinder(0.02, 0.1), T, np.full(10, 0.05), grades=np.full(10, 0.8))
    return save_map(m, out)


def measure(name: str, path: Path, trial: bool, work: Path) -> dict:
    row = {"mesh": name, "file": str(path)}
    safe = name.replace("/", "_")
    cache = work / f"cache-{safe}"
    for step in ("first", "cached"):
        r = run_fresh([sys.executable, "-c", _PREPARE, str(path)], {"GRASPSIM_CACHE_DIR": str(cache)})
        if r["exit"] != 0:
            row[step] = {"exit": r["exit"], "error": r["stderr"].strip().splitlines()[-1:]}
            log.warning("%s: %s failed: %s", name, step, row[step]["error"])
            return row
        d = json.loads(r["stdout"].strip().splitlines()[-1])
        row[step] = {"wall_s": r["wall_s"], "import_s": d["import_s"], "call_s": d["call_s"],
                     "call_cpu_s": d["call_cpu_s"],
                     "load_before": r["load_before"]}
        row.update({k: d[k] for k in ("faces", "watertight", "method", "parts", "mass_from", "warning")})
    if trial:
        gmap = hand_made_map(path, work / f"{safe}.h5")
        r = run_cli_fresh(["trial", str(gmap), "--top", "10", "--mesh", str(path), "--json", "--no-write"],
                          {"GRASPSIM_CACHE_DIR": str(work / f"trial-cache-{safe}")})
        s = json.loads(r["stdout"].strip().splitlines()[-1]) if r["exit"] == 0 else {}
        row["trial"] = {"exit": r["exit"], "wall_s": r["wall_s"], "trials": s.get("trials"),
                        "counts": s.get("counts"), "load_before": r["load_before"]}
    log.info("%s: %s", name, {k: row.get(k) for k in ("method", "parts", "first", "cached", "trial")})
    return row


def run(cfg: Config) -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="bench_mesh_prep-") as tmp:
        work = Path(tmp)
        cases = [(n, p, cfg.trials) for n, p in generated(cfg, work)]
        if cfg.folder:
            files = sorted(p for p in Path(cfg.folder).rglob("*") if p.suffix.lower() in (".stl", ".obj", ".ply"))
            cases += [(f"{p.parent.name}/{p.stem}", p,
                       cfg.trials and (i % max(1, cfg.trial_every) == 0 or p.stem in cfg.trial_names))
                      for i, p in enumerate(files)]
        rows = [measure(name, path, trial, work) for name, path, trial in cases]
    return rows


def goals(rows: list[dict]) -> dict:
    """How many meshes met each goal, of how many measured."""
    def count(step, key, goal):
        done = [r[step][key] for r in rows if step in r and key in r[step]]
        return {"met": sum(x <= goal for x in done), "of": len(done), "worst_s": max(done, default=None),
                "goal_s": goal}
    return {"first": count("first", "call_s", GOAL_FIRST_S), "cached": count("cached", "call_s", GOAL_CACHED_S),
            "trial": count("trial", "wall_s", GOAL_TRIAL_S),
            "fallback": sum(r.get("method") == "hull" for r in rows), "meshes": len(rows)}


def table(rows: list[dict]) -> str:
    f = lambda r, s, k: f"{r[s][k]:.2f}" if s in r and k in r[s] else "–"  # noqa: E731
    out = ["| mesh | faces | closed | model | parts | mass from | first [s] | first CPU [s] | cached [s] | "
           "cached CPU [s] | import [s] | trial 10 [s] |", "|---|---:|---|---|---:|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r['mesh']} | {r.get('faces', '–')} | {'yes' if r.get('watertight') else 'no'} | "
                   f"{r.get('method', 'error')} | {r.get('parts', '–')} | {r.get('mass_from', '–')} | "
                   f"{f(r, 'first', 'call_s')} | {f(r, 'first', 'call_cpu_s')} | {f(r, 'cached', 'call_s')} | "
                   f"{f(r, 'cached', 'call_cpu_s')} | {f(r, 'cached', 'import_s')} | "
                   f"{f(r, 'trial', 'wall_s')} |")
    return "\n".join(out)


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    rows = run(cfg)
    text = record.write(out, {"config": cfg, "rows": rows, "goals": goals(rows)}, readme_section)
    (out / "table.md").write_text(table(rows) + "\n")
    print(text)
    return 0


def readme_section(s: dict) -> str:
    g, (load0, _) = s["goals"], machine_load(s)
    line = lambda k, what: (f"{what}: {g[k]['met']}/{g[k]['of']} within {g[k]['goal_s']:g} s (worst "  # noqa: E731
                            f"{g[k]['worst_s']:.1f} s)" if g[k]["of"] else f"{what}: not measured")
    return "\n".join([
        f"`{s['command']}` (each step a fresh process; {s['machine']['cpus']} cores, load average "
        f"{load0[0]:g} at the start; 'first' is `prepare_mesh`'s own time with an empty cache, 'cached' on a "
        "cache hit, 'import' that of `import graspsim.sim` before it, 'trial' `graspsim trial MAP --top 10 "
        "--mesh MESH` in all, "
        f"with an empty cache). {g['fallback']} of {g['meshes']} meshes fell back to hulls (model 'hull').", "",
        "- " + line("first", "ready for simulation, first time"),
        "- " + line("cached", "from the cache"),
        "- " + line("trial", "trial of 10 grasps"), "", table(s["rows"])]) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
