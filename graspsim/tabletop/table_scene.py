"""Table-top scenes of several objects: drawn, settled by physics, saved and reloaded.

``make_scene(n, "pile", seed)`` drops ``n`` objects (from :mod:`graspsim.tabletop.scene_objects`)
at random orientations over a ``area`` x ``area`` square of the table, the lowest free
height each, into a bin of that size, lets them settle, takes the bin away (as VGN does)
and lets them settle again; ``"packed"`` stands them upright at random yaw side by
side in rows, at least ``gap`` apart (axis-aligned footprints), and settles them. A scene
that does not come to rest inside the table's region is drawn again from the same stream
(``attempts`` records how many it took). The :class:`TableScene` records every object's
description and settled pose (position and w, x, y, z quaternion, as MuJoCo holds them),
so ``SceneSim(scene)`` rebuilds the same MuJoCo scene, here or from :func:`load_scene`.

    scene = make_scene(5, "pile", seed=3)
    sim = scene.sim()                      # a SceneSim: render, execute, remove
    save_scene(scene, "pile3.json"); load_scene("pile3.json")
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

import numpy as np

from graspsim._atomic import atomic_write_text
from graspsim.errors import InvalidParameterError, OutputPathError, SimulationError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.seeding import rng_for
from graspsim.sim.trial_scene import SimSettings, resting_pose
from graspsim.tabletop.scene_objects import ObjectSpec, check_object_set, draw_object
from graspsim.tabletop.scene_sim import SceneOutcome, SceneSim
from graspsim.transforms import make_transform, matrix_to_quat, quat_to_matrix, random_rotation

__all__ = ["PlacedObject", "TableScene", "make_scene", "save_scene", "load_scene", "footprint_gaps", "object_view",
           "SceneSim", "SceneOutcome", "KINDS", "PACKED_GAP", "known_gap"]

KINDS = ("pile", "packed")
#: The least footprint gap [m] between the objects of a packed scene (``make_scene``'s
#: default ``gap``: packed scenes hold their objects at least 1 cm apart).
PACKED_GAP = 0.01
FORMAT = "graspsim.table_scene/1"
MAX_OBJECTS = 30


@dataclass(frozen=True, eq=False)
class PlacedObject:
    """An object of a scene and its settled pose: pos (3,) [m], quat (4,) w, x, y, z."""

    spec: ObjectSpec
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def T_world_obj(self) -> np.ndarray:
        return make_transform(quat_to_matrix(np.asarray(self.quat)), np.asarray(self.pos))

    @property
    def T_world_file(self) -> np.ndarray:
        """(4, 4) the pose of a mesh's file frame (= T_world_obj for shapes)."""
        return self.T_world_obj @ self.spec.T_obj_file

    def to_dict(self) -> dict:
        d = {"object": self.spec.to_dict(), "pos": list(self.pos), "quat": list(self.quat)}
        if self.spec.source == "mesh":  # the pose in the mesh file's own frame, for the user (not read back)
            T = self.T_world_file
            d["file_pose"] = {"pos": T[:3, 3].tolist(), "quat": matrix_to_quat(T[:3, :3]).tolist()}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> PlacedObject:
        pos, quat = tuple(float(x) for x in d["pos"]), tuple(float(x) for x in d["quat"])
        if len(pos) != 3 or len(quat) != 4 or not all(map(math.isfinite, pos + quat)):
            raise InvalidParameterError(f"bad object pose {d['pos']!r} {d['quat']!r}")
        return cls(ObjectSpec.from_dict(d["object"]), pos, quat)


@dataclass(frozen=True, eq=False)
class TableScene:
    """A settled scene. seed, kind ("pile" | "packed"), object_set: how it was drawn;
    objects: in id order; attempts: draws it took to settle inside the table's region."""

    seed: int
    kind: str
    object_set: str
    objects: tuple[PlacedObject, ...]
    attempts: int = 1

    def sim(self, **kw) -> SceneSim:
        """A fresh :class:`SceneSim` of this scene (keyword arguments: SceneSim's)."""
        return SceneSim([(o.spec, o.T_world_obj) for o in self.objects], **kw)

    def to_dict(self) -> dict:
        return {"format": FORMAT, "seed": self.seed, "kind": self.kind, "object_set": self.object_set,
                "attempts": self.attempts, "objects": [o.to_dict() for o in self.objects]}

    @classmethod
    def from_dict(cls, d: dict) -> TableScene:
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InvalidParameterError(f"not a table scene (format {FORMAT!r} expected)")
        try:
            objs = tuple(PlacedObject.from_dict(o) for o in d["objects"])
            return cls(int(d["seed"]), str(d["kind"]), str(d["object_set"]), objs, int(d.get("attempts", 1)))
        except (KeyError, TypeError, ValueError) as err:
            raise InvalidParameterError(f"bad table scene: {err!r}") from err


def save_scene(scene: TableScene, path: str | os.PathLike) -> None:
    """Write ``scene`` as JSON (atomically)."""
    atomic_write_text(path, json.dumps(scene.to_dict(), indent=1) + "\n", OutputPathError)


def load_scene(path: str | os.PathLike) -> TableScene:
    """Read a scene written by :func:`save_scene`."""
    from graspsim._files import read_small_text

    text = read_small_text(path, "table scene", InvalidParameterError)
    try:
        d = json.loads(text)
    except ValueError as err:
        raise InvalidParameterError(f"cannot read table scene {path}: {err}") from err
    return TableScene.from_dict(d)


def _radius(spec: ObjectSpec) -> float:
    return float(np.linalg.norm(np.asarray(spec.sim_object().surface.vertices), axis=1).max())


def _pile_poses(specs: list[ObjectSpec], rng: np.random.Generator, area: float) -> list[np.ndarray]:
    """Random orientations over the area (bounding spheres inside it), each at the lowest
    height where its bounding sphere clears the table and the objects placed before it."""
    out, centres, radii = [], [], []
    for spec in specs:
        r = _radius(spec)
        R = random_rotation(rng)
        half = max(0.0, 0.5 * area - r - 0.005)  # inside the bin's walls
        xy = rng.uniform(-half, half, 2)
        z = r + 0.005
        while any(np.linalg.norm(np.array([*xy, z]) - c) < r + rc + 0.005 for c, rc in zip(centres, radii)):
            z += 0.005
        out.append(make_transform(R, [*xy, z]))
        centres.append(np.array([*xy, z]))
        radii.append(r)
    return out


def _footprint(spec: ObjectSpec, T: np.ndarray) -> np.ndarray:
    """(2, 2) xy min and max of the object's surface at pose T."""
    v = np.asarray(spec.sim_object().surface.vertices) @ T[:3, :3].T + T[:3, 3]
    return np.stack([v[:, :2].min(0), v[:, :2].max(0)])


def _packed_poses(specs: list[ObjectSpec], rng: np.random.Generator, gap: float) -> list[np.ndarray]:
    """Upright at random yaw, in rows of ceil(sqrt(n)), footprints ``gap``-``1.6 gap`` apart."""
    cols = math.ceil(math.sqrt(len(specs)))
    poses = []
    for spec in specs:
        a = rng.uniform(-math.pi, math.pi)
        Rz = make_transform(np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]),
                            np.zeros(3))
        poses.append(Rz @ resting_pose(spec.sim_object()))
    y = 0.0
    for row in range(0, len(specs), cols):
        x, depth = 0.0, 0.0
        for i in range(row, min(row + cols, len(specs))):
            fp = _footprint(specs[i], poses[i])
            poses[i][:2, 3] += [x - fp[0, 0], y - fp[0, 1]]
            x += fp[1, 0] - fp[0, 0] + gap * rng.uniform(1.0, 1.6)
            depth = max(depth, fp[1, 1] - fp[0, 1])
        y += depth + gap * rng.uniform(1.0, 1.6)
    fps = np.array([_footprint(s, T) for s, T in zip(specs, poses)])
    centre = 0.5 * (fps[:, 0].min(0) + fps[:, 1].max(0))
    for T in poses:
        T[:2, 3] -= centre
    return poses


def footprint_gaps(scene: TableScene) -> np.ndarray:
    """(n, n) gap [m] between the axis-aligned xy footprints of every pair of objects (the
    larger of the x and y separations; negative: they overlap; inf on the diagonal)."""
    fps = np.array([_footprint(o.spec, o.T_world_obj) for o in scene.objects])
    lo, hi = fps[:, 0], fps[:, 1]
    sep = np.maximum(lo[None] - hi[:, None], lo[:, None] - hi[None])  # (n, n, 2)
    g = sep.max(-1)
    np.fill_diagonal(g, np.inf)
    return g


def _settled(sim: SceneSim, kind: str, gap: float, specs) -> list[PlacedObject] | None:
    """The objects' settled poses, or None when the draw is unusable (off the table
    region, still moving, or a packed gap closed)."""
    sim.settle(max_time=4.0 if kind == "pile" else 1.0)
    if len(sim.bin_geoms):
        sim.open_bin()
        sim.settle(max_time=3.0)
    if len(sim.speeds()) and (sim.speeds()[:, 0].max() > 0.02):
        return None
    if sim.outside():
        return None
    placed = []
    for k, spec in enumerate(specs):
        q = sim.data.qpos[sim.qadr[k]:sim.qadr[k] + 7]
        if q[2] < 0:
            return None
        placed.append(PlacedObject(spec, tuple(float(x) for x in q[:3]), tuple(float(x) for x in q[3:])))
    if kind == "packed":
        g = footprint_gaps(TableScene(0, kind, "", tuple(placed)))
        if len(placed) > 1 and g.min() < gap:
            return None
    return placed


def known_gap(kind: str) -> float | None:
    """The least gap [m] known to part any two objects of a scene of ``kind`` made with
    the default ``gap`` (what whoever placed them knows; segmentation may rely on it,
    ``SceneConfig.min_gap``): :data:`PACKED_GAP` for packed scenes, None for piles (their
    objects touch)."""
    if kind not in KINDS:
        raise InvalidParameterError(f"scene kind {kind!r} unknown; valid: {list(KINDS)}")
    return PACKED_GAP if kind == "packed" else None


def make_scene(n_objects: int, kind: str = "pile", seed: int = 0, *, object_set: str = "mixed",
               gripper: GripperSpec = HGPL_25_60_A, settings: SimSettings = SimSettings(),
               area: float = 0.3, gap: float = PACKED_GAP, max_attempts: int = 8) -> TableScene:
    """A settled scene of ``n_objects`` drawn from ``object_set`` (see the module
    docstring); area [m]: side of the drop square; gap [m]: least footprint gap of packed
    scenes. Deterministic: the stream is ``rng_for(seed, "table_scene", kind, n_objects)``."""
    if isinstance(n_objects, bool) or not isinstance(n_objects, int) or not 1 <= n_objects <= MAX_OBJECTS:
        raise InvalidParameterError(f"n_objects must be a whole number in [1, {MAX_OBJECTS}], got {n_objects!r}")
    if kind not in KINDS:
        raise InvalidParameterError(f"scene kind {kind!r} unknown; valid: {list(KINDS)}")
    check_object_set(object_set)
    if not (0.1 <= area <= 0.6) or not (0 <= gap <= 0.1):
        raise InvalidParameterError(f"area must be in [0.1, 0.6] m and gap in [0, 0.1] m, got {area!r}, {gap!r}")
    rng = rng_for(seed, "table_scene", kind, n_objects)
    for attempt in range(1, max_attempts + 1):
        specs = [draw_object(rng, object_set, gripper) for _ in range(n_objects)]
        poses = _pile_poses(specs, rng, area) if kind == "pile" else _packed_poses(specs, rng, gap)
        sim = SceneSim(list(zip(specs, poses)), gripper=gripper, settings=settings,
                       bin=0.5 * area if kind == "pile" else None)
        placed = _settled(sim, kind, gap, specs)
        if placed is not None:
            return TableScene(int(seed), kind, object_set, tuple(placed), attempt)
    raise SimulationError(f"no {kind} scene of {n_objects} objects settled on the table in {max_attempts} draws "
                          f"(seed {seed})")


def object_view(obj, camera, *, T_world_obj: np.ndarray | None = None, noise=None,
                rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What ``camera`` sees of one object (an ObjectSpec or SimObject) on the table:
    (points (N, 3), world frame [m], T_world_obj (4, 4)). The object rests upright at the
    origin (``resting_pose``) unless ``T_world_obj`` is given; noise: a ``DepthNoise``
    drawn from ``rng``. The one camera model for single views and table scenes."""
    from graspsim.geometry.camera import backproject

    body = obj.sim_object() if isinstance(obj, ObjectSpec) else obj
    T = resting_pose(body) if T_world_obj is None else np.asarray(T_world_obj, float)
    sim = SceneSim([(obj, T)])
    try:
        view = backproject(sim.render(camera, noise=noise, rng=rng))
    finally:
        sim.close()
    return view.world()[view.labels == 0], sim.pose(0)
