"""The README's viewer screenshot, made as a user makes it.

The README's two-cylinder "bottle" (a 3 x 8 cm body under a 1 x 12 cm neck) standing
on a table: its adapted map from a private FS database (``results/viewer_screenshot/fsdb``,
built fresh from the paper's five shapes unless ``--db`` names one), 40 grasps with
grade > 0.7 drawn uniformly and lifted in MuJoCo (``graspsim trial``, recorded), then
``graspsim view --screenshot`` of 500 of the grasps with grade > 0.7 coloured by grade,
the parts coloured by part, the table, and the full gripper of a successful grasp.

    python experiments/viewer_screenshot.py [--out docs/viewer.png] [--db FOLDER]
    python experiments/viewer_screenshot.py --scene [--out docs/viewer_scene.png]

``--scene``: the scene mode instead. A packed table of four objects (``make_scene(4,
"packed", 2)``, saved as a user's ``graspsim scene --save-scenes`` would) and
``graspsim view --scene --screenshot``: the depth cloud, the points above the table
coloured by segment, the fitted table, each object's three best grasps and the chosen
one, planned against the same private database.

Needs the viewer extra and Chromium. The picture depends on the simulated outcomes
(seeded) and on Chromium's software renderer; it is an illustration, not a measurement.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import default_out, experiment_database, map_config


def _bottle_map(path: Path, db) -> Path:
    import graspsim as gs
    from graspsim.geometry.table import TablePlane
    from graspsim.maps.io import save_map
    from graspsim.planning.planner import PlannerConfig, plan_shape
    from graspsim.transforms import make_transform

    bottle = gs.Compound.from_parts([gs.Cylinder(0.03, 0.08), gs.Cylinder(0.01, 0.12)],
                                    [np.eye(4), make_transform(np.eye(3), [0, 0, 0.1])])
    result = plan_shape(bottle, T_world_obj=np.eye(4), db=db, config=PlannerConfig(table=TablePlane()))
    return save_map(result.map, path)


def _graspsim(*args: str) -> str:
    r = subprocess.run([sys.executable, "-m", "graspsim", *args], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"graspsim {' '.join(args)} failed: {r.stderr[-2000:]}")
    return r.stdout


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None, help="the picture (default docs/viewer.png; --scene: "
                    "docs/viewer_scene.png)")
    ap.add_argument("--scene", action="store_true", help="a table-top scene in the viewer's scene mode")
    ap.add_argument("--db", default=None,
                    help=f"FS database folder (default: {default_out(__file__)}/fsdb, built fresh)")
    a = ap.parse_args(argv)
    from graspsim.maps.io import read_sim_results

    a.out = a.out or ("docs/viewer_scene.png" if a.scene else "docs/viewer.png")
    db = experiment_database(a.db, default_out(__file__), map_config())
    if a.scene:
        return _scene_picture(a.out, db)
    with tempfile.TemporaryDirectory() as d:
        m = _bottle_map(Path(d) / "bottle.h5", db)
        _graspsim("trial", str(m), "--sample", "40", "--min-grade", "0.7", "--seed", "0",
                  "--record", str(Path(d) / "trials.npz"))
        first = int(np.flatnonzero(read_sim_results(m)["outcome"] == 0)[0])  # a successful grasp
        _graspsim("view", str(m), "--min-grade", "0.7", "--max-drawn", "500", "--pick", str(first),
                  "--screenshot", a.out)
    print(f"wrote {a.out}")
    return 0


def _palette(path: str, colours: int = 64) -> None:
    """Store the picture with a 64-colour palette (the grey depth cloud's speckle costs
    0.5 MB as true colour, 0.17 MB so; the segment colours stay distinct)."""
    from PIL import Image

    Image.open(path).convert("RGB").quantize(colours).save(path, optimize=True)


def _scene_picture(out: str, db) -> int:
    from graspsim.tabletop.table_scene import make_scene, save_scene

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "scene000.json"
        save_scene(make_scene(4, "packed", 2, gripper=db.gripper), path)
        _graspsim("view", "--scene", str(path), "--db", str(db.root), "--top", "3", "--screenshot", out)
    _palette(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
