"""Valid inputs the fuzz cases start from, built once per process in a temporary folder:
a small FS map database (one cylinder at a coarse resolution), one of its map files,
a hand-made map with a few grasps, and clouds that identify as the stored cylinder
(known) and as a larger one (familiar: its map is scaled).
"""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The coarse generation settings of the fuzz database (the CLI flags and their MapConfig).
FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


@dataclass(frozen=True)
class Assets:
    folder: Path
    db: Path  # a database holding the FS map of a 2 x 20 cm cylinder (FAST_FLAGS)
    real_map: Path  # a copy of that map (~60 k grasps)
    hand_map: Path  # a hand-made map of 6 grasps on the same cylinder
    known_cloud: Path  # (N, 3) .npy cloud of the stored cylinder, posed
    familiar_cloud: Path  # (N, 3) .npy cloud of a 2.5 x 15 cm cylinder
    scene_cloud: Path  # (N, 3) .npy table-top scene: the stored cylinder standing on a table, seen from above
    mesh: Path  # the stored cylinder as a mesh (.obj), in its object frame

    def fresh(self) -> Path:
        """A new empty folder for one case (removed with the assets)."""
        return Path(tempfile.mkdtemp(dir=self.folder, prefix="case-"))


def _hand_map():
    from hand_made import grasp_pose, hand_made_map

    from graspsim.primitives import Cylinder

    ang = np.linspace(0.0, np.pi, 6)
    T = np.stack([grasp_pose([0, 0, 0.02 * k], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for k, a in enumerate(ang)])
    return hand_made_map(Cylinder(0.02, 0.20), T, np.full(6, 0.04), grades=np.linspace(0.5, 0.95, 6))


def _scene(seed: int) -> np.ndarray:
    """The stored cylinder standing on a 50 cm table, as a camera at (0.5, 0, 0.6) sees it."""
    from graspsim.primitives import Cylinder, synthetic_cloud
    from graspsim.transforms import make_transform

    rng = np.random.default_rng(seed)
    obj = synthetic_cloud(Cylinder(0.02, 0.20), rng, resolution=0.006, noise=0.0003, camera=np.array([0.5, 0, 0.6]),
                          T_world_obj=make_transform(np.eye(3), [0.0, 0.0, 0.1])).points
    grid = np.mgrid[-0.25:0.25:0.008, -0.25:0.25:0.008].reshape(2, -1).T
    return np.concatenate([obj, np.column_stack([grid, rng.normal(0.0, 5e-4, len(grid))])])


def _cloud(shape, seed: int) -> np.ndarray:
    from graspsim.primitives import synthetic_cloud
    from graspsim.transforms import make_transform, random_rotation

    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), [0.3, -0.1, 0.2])
    return synthetic_cloud(shape, rng, resolution=0.006, noise=0.0003, T_world_obj=T).points


@functools.lru_cache(maxsize=1)
def assets() -> Assets:
    from graspsim.cli import main
    from graspsim.maps.io import save_map
    from graspsim.primitives import Cylinder

    folder = Path(tempfile.mkdtemp(prefix="graspsim-fuzz-"))
    atexit.register(shutil.rmtree, folder, True)
    db = folder / "db"
    assert main(["db", "build", "--primitives", "cylinder", "--db", str(db), *FAST_FLAGS, "--json"]) == 0
    real = folder / "real.h5"
    shutil.copyfile(next(db.glob("cylinder/*.h5")), real)
    hand = save_map(_hand_map(), folder / "hand.h5")
    known, familiar = folder / "known.npy", folder / "familiar.npy"
    np.save(known, _cloud(Cylinder(0.02, 0.20), 1))
    np.save(familiar, _cloud(Cylinder(0.025, 0.15), 2))
    scene, mesh = folder / "scene.npy", folder / "cyl.obj"
    np.save(scene, _scene(3))
    Cylinder(0.02, 0.20).mesh(sections=24).export(mesh)
    return Assets(folder, db, real, hand, known, familiar, scene, mesh)
