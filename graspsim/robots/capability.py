"""A capability map of an arm: which wrist positions and approach directions it reaches.

In the spirit of Zacharias et al.'s capability maps: the wrist's workspace in the arm's
base frame is cut into cubes of ``voxel`` [m], and the approach directions (the wrist's
z axis) into ``directions`` cells around the sphere (the nearest of a Fibonacci set). The
map is built by sampling ``samples`` joint configurations uniformly inside the joint
limits (a seeded draw), placing each sample's wrist by forward kinematics (the model's
own chain, vectorised: body offsets and hinge rotations read from the compiled MuJoCo
model), dropping samples with a link frame below the table top (z < 0 in the base frame:
the base stands on the table), and marking each sample's cell. A cell's reachability
then spreads to the neighbouring cubes (the same direction cell), so the map errs on the
side of reachable: it is the fast first cut, and exact IK (:mod:`graspsim.robots.reach`)
judges what it lets through. Each marked cell keeps one sample's joints: a seed for
that IK. The roll about the approach axis is not in the map (the Panda's last joint
turns the hand nearly all the way round).

The map is cached on disk keyed by the content that defines it: the arm's model file,
the gripper's flange-to-wrist transform and the map's settings
(``$GRASPSIM_CACHE_DIR/reach``, else ``$XDG_CACHE_HOME/graspsim/reach``, else
``~/.cache/graspsim/reach``: :mod:`graspsim._cache`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np

from graspsim._cache import user_cache
from graspsim.checks import POSITIVE, check_fields, integer
from graspsim.errors import GraspsimError, InvalidParameterError
from graspsim.robots.arm import ARM_PREFIX, ArmSpec
from graspsim.transforms import invert_transform, quat_to_matrix

__all__ = ["CapabilityConfig", "CapabilityMap", "ChainFK", "capability_map", "fibonacci_sphere", "default_cache_dir"]

_VERSION = 2
log = logging.getLogger(__name__)


def default_cache_dir() -> Path:
    """Where capability maps are kept: ``user_cache("reach")`` (:mod:`graspsim._cache`)."""
    return user_cache("reach")


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


class ChainFK:
    """Vectorised forward kinematics of the arm's serial chain of hinges, read from a
    compiled model: base (the arm's first link) -> every link -> the wrist site."""

    def __init__(self, model: mujoco.MjModel, arm: ArmSpec, wrist_site: str = "wrist") -> None:
        base = model.body(ARM_PREFIX + arm.links[0]).id
        site = model.site(wrist_site).id
        chain = []
        b = model.site_bodyid[site]
        while b != base:
            chain.append(b)
            b = model.body_parentid[b]
        chain.reverse()
        self.steps = []
        for b in chain:
            T = np.eye(4)
            T[:3, :3] = quat_to_matrix(model.body_quat[b])
            T[:3, 3] = model.body_pos[b]
            jn = model.body_jntnum[b]
            if jn > 1:
                raise InvalidParameterError(f"body {model.body(b).name!r} has {jn} joints: not a serial hinge chain")
            axis = None
            if jn == 1:
                j = model.body_jntadr[b]
                if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or np.linalg.norm(model.jnt_pos[j]) > 1e-12:
                    raise InvalidParameterError("the arm's joints must be hinges at their bodies' origins")
                axis = model.jnt_axis[j].copy()
            self.steps.append((T, axis))
        self.T_site = np.eye(4)
        self.T_site[:3, :3] = quat_to_matrix(model.site_quat[site])
        self.T_site[:3, 3] = model.site_pos[site]
        self.njoint = sum(a is not None for _, a in self.steps)

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q (N, 7) -> (T_base_wrist (N, 4, 4), lowest link-frame height (N,) in the base frame)."""
        q = np.asarray(q, float)
        n = len(q)
        T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        low = np.full(n, np.inf)
        k = 0
        for F, axis in self.steps:
            T = T @ F
            if axis is not None:
                c, s = np.cos(q[:, k]), np.sin(q[:, k])
                K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
                R = (np.eye(3)[None] + s[:, None, None] * K[None] + (1 - c)[:, None, None] * (K @ K)[None])
                J = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
                J[:, :3, :3] = R
                T = T @ J
                k += 1
            low = np.minimum(low, T[:, 2, 3])
        T = T @ self.T_site
        return T, np.minimum(low, T[:, 2, 3])


@dataclass(frozen=True)
class CapabilityConfig:
    """voxel [m]: cube side; directions: approach cells on the sphere; samples: joint
    configurations drawn; extent [m]: half side of the mapped cube around the base (z
    from -extent / 2); dilate: cubes a marked cell spreads to (each way); seed: the draw."""

    voxel: float = 0.05
    directions: int = 64
    samples: int = 500_000
    extent: float = 1.0
    dilate: int = 1
    seed: int = 0

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE.saying("> 0 m"), "voxel", owner="CapabilityConfig")
        check_fields(self, integer(1), "directions", "samples", owner="CapabilityConfig")
        check_fields(self, integer(0), "dilate", owner="CapabilityConfig")
        if not (isinstance(self.extent, (int, float)) and math.isfinite(self.extent) and self.extent > self.voxel):
            raise InvalidParameterError(f"CapabilityConfig.extent must be > voxel ({self.voxel} m), "
                                        f"got {self.extent!r}")


@dataclass(frozen=True, eq=False)
class CapabilityMap:
    """The map: ``cells`` (X, Y, Z, D) int32, the sample index seeding each cell (-1:
    none; after dilation a cell may borrow a neighbour's seed), ``q`` (M, 7) the kept
    samples' joints, ``T_world_base``, the settings and the content key."""

    cells: np.ndarray
    q: np.ndarray
    config: CapabilityConfig
    T_world_base: np.ndarray
    key: str

    def lookup(self, T_world_wrist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reachable (N,) bool, seed joints (N, 7), NaN where unreachable) of wrist poses (N, 4, 4)."""
        T = np.asarray(T_world_wrist, float).reshape(-1, 4, 4)
        B = invert_transform(self.T_world_base)
        p = np.einsum("ij,nj->ni", B[:3, :3], T[:, :3, 3]) + B[:3, 3]
        z = np.einsum("ij,nj->ni", B[:3, :3], T[:, :3, 2])
        c = self.config
        lo = np.array([-c.extent, -c.extent, -c.extent / 2])
        idx = np.floor((p - lo) / c.voxel).astype(np.int64)
        shape = np.array(self.cells.shape[:3])
        inside = np.all((idx >= 0) & (idx < shape), axis=1)
        d = np.argmax(z @ fibonacci_sphere(c.directions).T, axis=1)
        seed = np.full(len(T), -1, np.int64)
        i = idx[inside]
        seed[inside] = self.cells[i[:, 0], i[:, 1], i[:, 2], d[inside]]
        q = np.full((len(T), self.q.shape[1]), np.nan)
        q[seed >= 0] = self.q[seed[seed >= 0]]
        return seed >= 0, q

    def fraction(self) -> float:
        """The share of cells marked reachable."""
        return float(np.mean(self.cells >= 0))


def _key(arm: ArmSpec, fk: ChainFK, config: CapabilityConfig) -> str:
    h = hashlib.sha256()
    h.update(Path(arm.path).read_bytes())
    chain = [(np.round(F, 9).tolist(), None if a is None else np.round(a, 9).tolist()) for F, a in fk.steps]
    h.update(json.dumps({"v": _VERSION, "chain": chain, "site": np.round(fk.T_site, 9).tolist(),
                         "config": asdict(config)}, sort_keys=True).encode())
    return h.hexdigest()[:24]


def _build(model: mujoco.MjModel, arm: ArmSpec, fk: ChainFK, config: CapabilityConfig,
           on_progress=None) -> tuple[np.ndarray, np.ndarray]:
    jid = [model.joint(ARM_PREFIX + j).id for j in arm.joints]
    lo_q, hi_q = model.jnt_range[jid].T
    c = config
    rng = np.random.default_rng(c.seed)
    n_side = int(math.ceil(2 * c.extent / c.voxel))
    n_z = int(math.ceil(1.5 * c.extent / c.voxel))
    cells = np.full((n_side, n_side, n_z, c.directions), -1, np.int32)
    dirs = fibonacci_sphere(c.directions)
    lo = np.array([-c.extent, -c.extent, -c.extent / 2])
    kept = []
    chunk = 100_000
    for a in range(0, c.samples, chunk):
        q = rng.uniform(lo_q, hi_q, size=(min(chunk, c.samples - a), len(jid)))
        T, low = fk(q)
        ok = low >= 0.0
        q, T = q[ok], T[ok]
        idx = np.floor((T[:, :3, 3] - lo) / c.voxel).astype(np.int64)
        inside = np.all((idx >= 0) & (idx < cells.shape[:3]), axis=1)
        q, T, idx = q[inside], T[inside], idx[inside]
        d = np.argmax(T[:, :3, 2] @ dirs.T, axis=1)
        base = sum(len(k) for k in kept)
        cells[idx[:, 0], idx[:, 1], idx[:, 2], d] = base + np.arange(len(q), dtype=np.int32)
        kept.append(q)
        if on_progress is not None:
            on_progress(min(a + chunk, c.samples))
    q = np.concatenate(kept) if kept else np.zeros((0, len(jid)))
    flat = np.flatnonzero(cells >= 0)  # sparse: the marked cells and their seeds' joints only
    return cells.shape, flat, q[cells.ravel()[flat]].astype(np.float32)


#: The cached maps read in this process, by file (path, size, modification time) and
#: dilation: a clutter run makes a scene (and asks for the map) per episode, and reading
#: one (decompressing, dilating) takes 0.2-0.3 s, most of a scene's first reachability check.
_READ: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
_READ_MAX = 4


def _read(path: Path, dilate: int) -> tuple[np.ndarray, np.ndarray]:
    """(cells, q) of the cached map at ``path`` dilated by ``dilate``, read once per process
    while the file is unchanged (the arrays are shared: read-only)."""
    st = path.stat()
    memo = (str(path.resolve()), st.st_size, st.st_mtime_ns, int(dilate))
    if memo not in _READ:
        with np.load(path) as z:
            shape, flat, q = tuple(z["shape"]), z["flat"], z["q"]
        cells, q = _dense(shape, flat, dilate), q.astype(float)
        cells.setflags(write=False)
        q.setflags(write=False)
        while len(_READ) >= _READ_MAX:
            _READ.pop(next(iter(_READ)))
        _READ[memo] = (cells, q)
    return _READ[memo]


def _dense(shape, flat: np.ndarray, dilate: int) -> np.ndarray:
    """The cells (X, Y, Z, D) int32 of the stored sparse form, spread by ``dilate`` cubes."""
    from scipy.ndimage import maximum_filter

    cells = np.full(int(np.prod(shape)), -1, np.int32)
    cells[flat] = np.arange(len(flat), dtype=np.int32)
    cells = cells.reshape(tuple(int(s) for s in shape))
    if dilate:
        size = (2 * dilate + 1,) * 3 + (1,)
        cells = np.maximum(cells, maximum_filter(cells, size=size, mode="constant", cval=-1))
    return cells


def capability_map(model: mujoco.MjModel, arm: ArmSpec, T_world_base: np.ndarray,
                   config: CapabilityConfig = CapabilityConfig(), *, cache_dir=None, on_progress=None) -> CapabilityMap:
    """The capability map of ``arm`` (with its gripper, as compiled in ``model``) placed at
    ``T_world_base``: read from the cache when its content key is there, else built and
    cached (module doc). ``cache_dir=False``: no cache."""
    from graspsim._atomic import atomic_path

    fk = ChainFK(model, arm)
    key = _key(arm, fk, config)
    path = None
    if cache_dir is not False:
        path = Path(cache_dir or default_cache_dir()) / f"{arm.name}-{key}.npz"
        if path.is_file():
            try:
                cells, q = _read(path, config.dilate)
                return CapabilityMap(cells=cells, q=q, config=config, T_world_base=np.asarray(T_world_base, float),
                                     key=key)
            except (OSError, ValueError, KeyError):
                pass  # unreadable: built again and replaced
    log.warning("building the %s's capability map (first run only; cached in %s) ...", arm.name,
                "memory" if path is None else path.parent)
    t0 = time.perf_counter()
    shape, flat, q = _build(model, arm, fk, config, on_progress)
    log.warning("capability map built in %.1f s", time.perf_counter() - t0)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(path) as tmp:
                with open(tmp, "wb") as f:
                    np.savez_compressed(f, shape=np.array(shape), flat=flat, q=q)
        except (OSError, GraspsimError):
            pass  # a read-only cache: the map still serves this run
    return CapabilityMap(cells=_dense(shape, flat, config.dilate), q=q.astype(float), config=config,
                         T_world_base=np.asarray(T_world_base, float), key=key)
