"""A gripper from its model file (MJCF, or URDF): what the harness drives and a measured spec.

``measure_model(path)`` reads a two-finger gripper's MuJoCo model (``.xml``) or URDF
(``.urdf``, MuJoCo's importer) and returns the :class:`~graspsim.grippers.spec.GripperSpec` the
planner uses and the :class:`~graspsim.grippers.vendored.Mount` the trial harness
attaches, both measured from the model in MuJoCo, nothing typed in:

* the parts: the root body (the model's single top-level body: the flange), the gripper's
  joints, its actuators, and the two pads: the collision geoms whose names say ``pad``
  (robosuite's ``*_fingerpad_*``), else the pair of moving collision geoms that close
  towards each other (the one pair whose gap shrinks most from open to closed);
* the closing end of every actuator (stepping the model with it at either end of its
  control range) and the opening table: the model at ``ROWS`` openings from closed to
  open, each row the gripper's joint positions, the pad gap and the controls that hold
  it. A prismatic gripper (each pad carried by one slide joint) is posed kinematically
  over its joint ranges; a linkage (any hinge or passive joint) is stepped: the position
  actuators' targets swept from open to closed, each held until the model is at rest;
* the wrist frame: z = the root body's z (the approach), x = the closing axis (pad to
  pad), its origin on the line between the pads, at the root's origin or at the
  rearmost collision geometry when the model reaches behind it (the Franka hand);
* the spec's boxes, enclosing every collision hull at every row of the table (housing:
  the static parts and whatever moving geometry reaches inside the pad planes; jaw:
  the moving parts between the housing and the top of the pads; finger: the pad carrier
  from the top of the flat inner face to the tip), the pad region where the flat face is
  at every opening, the stroke from the table, the grip force from the actuators, the
  closing speed and the masses.

Linkage grippers: the pads move on an arc (the 2F-85's rise and fall by millimetres
over the stroke). The spec keeps graspsim's straight-line model and stays conservative:
its boxes enclose the hulls at every opening and its pad region is where the flat face
lies at every opening, so a contact planned on the spec's pad lands on the real pad
whatever the width. :attr:`Mount.pad_z` holds the pad centre's height at every row
(:func:`pad_arc`) and :attr:`Mount.pad_face` the pad faces' ends; the straight-line
model's error at every row is :func:`straight_line_error`, its largest the spec's
``arc_error``.

What the model does not say is named in a sidecar JSON beside it (``<model>.gripper.json``)
or passed as options: ``name``, ``root_body``, ``pad_geoms`` [two geom names],
``grip_force`` [N per finger], ``opening_from_joints`` (true: the pad gap is the sum of
the two jaw joints, the URDF convention of the Franka hand), ``angle`` (``"radian"`` for
fragments that rely on an includer's compiler, as robosuite's do). Whatever cannot be
determined is a one-line :class:`~graspsim.errors.GripperError` naming the key.

Results are cached on disk by the content hash of the model file, its meshes and the
sidecar (``$GRASPSIM_CACHE_DIR/grippers``, else ``$XDG_CACHE_HOME/graspsim/grippers``, else
``~/.cache/graspsim/grippers``: :mod:`graspsim._cache`).
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim._cache import user_cache
from graspsim._gl import import_mujoco
from graspsim.errors import GripperError
from graspsim.grippers.spec import GripperSpec

__all__ = ["measure_model", "vendored_gripper", "model_report", "pad_arc", "straight_line_error", "sidecar_path",
           "model_digest", "content_digest", "model_content_key", "SIDECAR_KEYS", "MEASURE_VERSION", "ROWS"]

MEASURE_VERSION = 1  # bump when the measurement changes: old cache entries are ignored
ROWS = 17            # rows of the opening table (a linkage: stepped rows)
DENSE = 8            # a linkage's table: each stepped interval split in this many (interpolated poses)
TIP_CLEARANCE = 2e-3  # [m] planned contacts stay this far inside a pad's lower end (where the finger goes on)
PAD_TOL = 2.5e-4     # [m] hull vertices this close to a pad's innermost plane form its flat face
REST_SPEED = 1e-3    # [rad/s, m/s] a stepped linkage is at rest below this joint speed
LINK_CLEARANCE = 1e-3  # [m] see _measure: linkage parts this close to the pad planes count as inside
GRID = 1e-5          # [m] measured lengths are rounded outwards to this
PREFIX = "g/"
SIDECAR_KEYS = ("name", "root_body", "pad_geoms", "grip_force", "opening_from_joints", "angle")
_SUFFIXES = (".xml", ".mjcf", ".urdf")
_DEFAULT_MARGIN = GripperSpec().contact_depth_margin


def is_model_path(key: str) -> bool:
    return str(key).lower().endswith(_SUFFIXES)


def sidecar_path(path: Path) -> Path:
    return path.with_name(path.stem + ".gripper.json")


# ----------------------------------------------------------------------------- loading
def _error(path: Path, what: str) -> GripperError:
    return GripperError(f"gripper model {str(path)!r}: {what}")


def _options(path: Path, options: dict | None) -> dict:
    """The sidecar's keys, overridden by ``options``; unknown keys are an error."""
    out: dict = {}
    side = sidecar_path(path)
    if side.is_file():
        try:
            out = json.loads(side.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise _error(path, f"sidecar {side.name}: {err}") from err
        if not isinstance(out, dict):
            raise _error(path, f"sidecar {side.name} must be a JSON object of {list(SIDECAR_KEYS)}")
    out.update({k: v for k, v in (options or {}).items() if v is not None})
    bad = sorted(set(out) - set(SIDECAR_KEYS))
    if bad:
        raise _error(path, f"unknown options {bad}; valid: {list(SIDECAR_KEYS)}")
    return out


def _load_spec(path: Path, opts: dict):
    """The model's MjSpec with absolute mesh paths (it is attached into another spec)."""
    mujoco = import_mujoco()
    try:
        child = mujoco.MjSpec.from_file(str(path))
    except (ValueError, OSError) as err:
        raise _error(path, f"does not load in MuJoCo: {' '.join(str(err).split())}") from err
    meshdir = path.parent / (child.meshdir or "")
    for mesh in child.meshes:
        if mesh.file and not Path(mesh.file).is_absolute():
            mesh.file = str(meshdir / mesh.file)
    child.meshdir = ""
    if opts.get("angle") is not None:
        if opts["angle"] not in ("radian", "degree"):
            raise _error(path, f"angle must be 'radian' or 'degree', got {opts['angle']!r}")
        child.compiler.degree = opts["angle"] == "degree"
    if path.suffix.lower() == ".urdf" and not child.actuators:
        _add_urdf_drive(path, child, opts)
    taken = {g.name for g in child.geoms}
    for i, g in enumerate(child.geoms):  # the harness names pads (contact settings, sensors)
        if not g.name and f"geom{i}" not in taken:
            g.name = f"geom{i}"
    return child


def _add_urdf_drive(path: Path, child, opts: dict) -> None:
    """A URDF names no actuator: for prismatic fingers (slide joints, coupled by the
    URDF's ``<mimic>``, which MuJoCo imports as an equality) add a fixed tendon over the
    slides and a force actuator on it (control in [-1, 1] x the grip force: the sidecar's
    ``grip_force`` or the joints' URDF effort limit)."""
    mujoco = import_mujoco()

    slides = [j for j in child.joints if j.type == mujoco.mjtJoint.mjJNT_SLIDE]
    if len(slides) != 2 or len(slides) != len([j for j in child.joints if j.type != mujoco.mjtJoint.mjJNT_FREE]):
        raise _error(path, "a URDF names no actuator: graspsim adds one for two prismatic fingers only; "
                           "give an MJCF with its actuator")
    force = opts.get("grip_force")
    if force is None:
        efforts = [j.actfrcrange[1] for j in slides if j.actfrcrange[1] > 0]
        if not efforts:
            raise _error(path, "cannot determine the grip force: the URDF's finger joints have no effort "
                               "limit; give it in the sidecar key 'grip_force' [N per finger]")
        force = min(efforts)
    tendon = child.add_tendon(name="graspsim_opening")
    for j in slides:
        tendon.wrap_joint(j.name, 1.0)
    act = child.add_actuator(name="graspsim_grip", target=tendon.name, trntype=mujoco.mjtTrn.mjTRN_TENDON)
    act.set_to_motor()
    act.gainprm[0] = float(force)
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = [-1.0, 1.0]


def content_digest(path: Path, opts: dict) -> str:
    """sha256 of what the gripper is, wherever its files lie: the model file's bytes, the
    options (the sidecar's keys) and every mesh it names (each by its path relative to
    the model's folder, when it lies under it, and its bytes). A copy of the folder
    elsewhere has the same digest; the files' absolute paths do not enter it."""
    h = hashlib.sha256(b"graspsim-gripper-content-v1")
    h.update(path.read_bytes())
    h.update(json.dumps(opts, sort_keys=True).encode())
    meshes = []
    for mesh in {m.file for m in _load_spec(path, opts).meshes if m.file}:
        try:
            name = Path(mesh).relative_to(path.parent).as_posix()
        except ValueError:  # a mesh outside the model's folder: its name only
            name = Path(mesh).name
        meshes.append((name, mesh))
    for name, mesh in sorted(meshes):
        try:
            data = Path(mesh).read_bytes()
        except OSError as err:
            raise _error(path, f"mesh {mesh} cannot be read: {err}") from err
        h.update(f"{name}:{len(data)}:".encode())
        h.update(data)
    return h.hexdigest()


def model_digest(path: Path, opts: dict) -> str:
    """The measurement's cache key: :func:`content_digest` and the measuring code."""
    h = hashlib.sha256(f"graspsim-gripper-model-v{MEASURE_VERSION}".encode())
    h.update(Path(__file__).read_bytes())  # the measurement's own code: a change re-measures
    h.update(content_digest(path, opts).encode())
    return h.hexdigest()


@functools.lru_cache(maxsize=64)
def _content_key(path: str, stamp: tuple) -> str:
    # per process, keyed by the model file's and sidecar's mtime and size: a mesh edited
    # in place while the process runs keeps its old key until the model file changes
    p = Path(path)
    return content_digest(p, _options(p, None))


def model_content_key(model: str) -> str:
    """``"sha256:<content_digest>"`` of the model file ``model`` (a path) with its sidecar:
    what a spec's ``model`` path stands for in digests and database keys (a copy of the
    file elsewhere gives the same key). GripperError if the file cannot be read."""
    p = Path(model)
    try:
        side = sidecar_path(p)
        files = (p, side) if side.is_file() else (p,)
        stamp = tuple((f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    except (OSError, ValueError) as err:
        raise GripperError(f"cannot read gripper model {model!r}: {err}") from err
    return "sha256:" + _content_key(str(p.resolve()), stamp)


def _harness(child, *, block=None):
    """A measuring model: the gripper attached under a heavy free body (so parent-child
    contacts are filtered as under the trial harness's wrist), gravity off, the
    harness's solver settings; ``block`` = (centre, half sizes) in the root frame adds a
    box fixed to the root to squeeze."""
    mujoco = import_mujoco()

    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    o = spec.option
    o.gravity = [0.0, 0.0, 0.0]
    o.timestep, o.impratio = 0.002, 10.0
    o.cone, o.integrator = mujoco.mjtCone.mjCONE_ELLIPTIC, mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    base = spec.worldbody.add_body(name="base", pos=[0, 0, 1])
    base.add_freejoint(name="base")
    base.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.001], mass=100.0, contype=0, conaffinity=0)
    spec.attach(child, prefix=PREFIX, frame=base.add_frame())
    if block is not None:
        base.add_geom(name="block", type=mujoco.mjtGeom.mjGEOM_BOX, pos=block[0], size=block[1],
                      contype=1, conaffinity=1, friction=[1.0, 0.005, 0.0001], condim=4)
    return spec


# ----------------------------------------------------------------------------- geometry
_HULLS: dict = {}


def _local_hull(model, g: int) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) vertices of geom ``g``'s collision hull in its own frame (a mesh: its convex
    hull, as MuJoCo collides; a primitive: its bounding box) and (E, 2) the hull's edges."""
    key = (id(model), g)
    if key in _HULLS:
        return _HULLS[key]
    mujoco = import_mujoco()
    from scipy.spatial import ConvexHull

    t = int(model.geom_type[g])
    if t == int(mujoco.mjtGeom.mjGEOM_MESH):
        mid = int(model.geom_dataid[g])
        a, n = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        v = model.mesh_vert[a:a + n].astype(float)
    else:
        s = model.geom_size[g]
        G = mujoco.mjtGeom
        half = {int(G.mjGEOM_BOX): s, int(G.mjGEOM_SPHERE): [s[0]] * 3,
                int(G.mjGEOM_CAPSULE): [s[0], s[0], s[0] + s[1]],
                int(G.mjGEOM_CYLINDER): [s[0], s[0], s[1]], int(G.mjGEOM_ELLIPSOID): s}.get(t)
        if half is None:
            raise GripperError(f"collision geom {model.geom(g).name!r} of type {int(t)} is not supported "
                               "(mesh, box, sphere, capsule, cylinder, ellipsoid)")
        v = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T * np.asarray(half)[:3]
    hull = ConvexHull(v)
    keep = hull.vertices
    index = np.full(len(v), -1)
    index[keep] = np.arange(len(keep))
    tri = index[hull.simplices]
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1), axis=0)
    _HULLS[key] = (v[keep], edges)
    return _HULLS[key]


def _hull(model, data, g: int, R_root: np.ndarray, p_root: np.ndarray) -> np.ndarray:
    """(V, 3) vertices of geom ``g``'s collision hull in the root frame (see _local_hull)."""
    v = _local_hull(model, g)[0]
    w = data.geom_xpos[g] + v @ data.geom_xmat[g].reshape(3, 3).T
    return (w - p_root) @ R_root


def _top_inside(v: np.ndarray, edges: np.ndarray, u: np.ndarray, c: float) -> float:
    """The highest z of the convex hull of ``v`` (V, 3; ``edges`` (E, 2)) where ``u`` (V,,
    linear in the points) < c: the vertices there and where the hull's edges cross u = c."""
    z = [v[u < c, 2].max()]
    i, j = edges[:, 0], edges[:, 1]
    cross = (u[i] - c) * (u[j] - c) < 0
    if np.any(cross):
        t = (c - u[i[cross]]) / (u[j[cross]] - u[i[cross]])
        z.append((v[i[cross], 2] + t * (v[j[cross], 2] - v[i[cross], 2])).max())
    return float(max(z))


def _clip_z(v: np.ndarray, edges: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Points spanning the convex hull of ``v`` (V, 3; ``edges`` (E, 2)) cut to lo <= z <= hi:
    its vertices inside and where its edges cross the two planes (empty if none)."""
    z = v[:, 2]
    out = [v[(z >= lo) & (z <= hi)]]
    i, j = edges[:, 0], edges[:, 1]
    for plane in (lo, hi):
        if not np.isfinite(plane):
            continue
        cross = (z[i] - plane) * (z[j] - plane) < 0
        t = (plane - z[i[cross]]) / (z[j[cross]] - z[i[cross]])
        out.append(v[i[cross]] + t[:, None] * (v[j[cross]] - v[i[cross]]))
    return np.concatenate(out)


def _grid(v: float, rnd=np.ceil) -> float:
    return round(float(rnd(float(v) / GRID - 1e-6 * np.sign(v))) * GRID, 8)


def _r(v: float) -> float:
    return round(float(v), 8)


# ----------------------------------------------------------------------------- the model
@dataclass
class _Parts:
    model: object
    root: int
    joints: list[int]
    acts: list[int]
    geoms: list[int]          # collision geoms of the gripper
    static: set[int]          # geoms welded to the root
    pads: list[int]           # two pad geoms


def _identify(path: Path, child, opts: dict) -> _Parts:
    mujoco = import_mujoco()

    try:
        model = _harness(child).compile()
    except ValueError as err:
        raise _error(path, f"does not compile: {' '.join(str(err).split())}") from err
    base = model.body("base").id
    tops = [b for b in range(model.nbody) if model.body_parentid[b] == base]
    if opts.get("root_body"):
        try:
            root = model.body(PREFIX + opts["root_body"]).id
        except KeyError:
            raise _error(path, f"root_body {opts['root_body']!r} is not a body of the model") from None
    elif len(tops) == 1:
        root = tops[0]
    else:
        names = [model.body(b).name[len(PREFIX):] for b in tops]
        raise _error(path, f"{len(tops)} top-level bodies {names}; name the gripper's in the sidecar key 'root_body'")

    def under(b: int) -> bool:
        while b > 0:
            if b == root:
                return True
            b = model.body_parentid[b]
        return False

    joints = [j for j in range(model.njnt) if under(model.jnt_bodyid[j])
              and int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))]
    if not joints:
        raise _error(path, "no fingers found: the model has no slide or hinge joint under its root body "
                           f"{model.body(root).name[len(PREFIX):]!r} (name the gripper's body in 'root_body')")
    if model.nu == 0:
        raise _error(path, "no actuator: the harness closes the fingers with the model's own actuator(s); "
                           "add one to the model (MJCF <actuator>)")
    geoms = [g for g in range(model.ngeom) if under(model.geom_bodyid[g])
             and (model.geom_contype[g] or model.geom_conaffinity[g])]
    wroot = model.body_weldid[root]
    static = {g for g in geoms if model.body_weldid[model.geom_bodyid[g]] == wroot}
    moving = [g for g in geoms if g not in static]
    if len({int(model.geom_bodyid[g]) for g in moving}) < 2:
        raise _error(path, "no fingers found: fewer than two bodies with collision geometry move with the "
                           "joints; name the two pad geoms in the sidecar key 'pad_geoms'")
    if opts.get("pad_geoms") is not None:
        names = opts["pad_geoms"]
        if not (isinstance(names, list) and len(names) == 2):
            raise _error(path, f"pad_geoms must be two geom names, got {names!r}")
        try:
            pads = [model.geom(PREFIX + n).id for n in names]
        except KeyError:
            raise _error(path, f"pad_geoms {names} are not both geoms of the model") from None
    else:
        pads = [g for g in moving if "pad" in model.geom(g).name[len(PREFIX):].lower()]
        if len(pads) != 2 or model.geom_bodyid[pads[0]] == model.geom_bodyid[pads[1]]:
            pads = []  # found geometrically once the closing direction is known
    return _Parts(model, root, joints, list(range(model.nu)), geoms, static, pads)


def _frame(data, root: int) -> tuple[np.ndarray, np.ndarray]:
    return data.xmat[root].reshape(3, 3).copy(), data.xpos[root].copy()


def _settle(model, data, ctrl_to: np.ndarray, *, ramp: float = 0.2, hold: float = 0.4) -> None:
    """Ramp the controls to ``ctrl_to`` over ``ramp`` s and hold them ``hold`` s."""
    mujoco = import_mujoco()

    c0 = data.ctrl.copy()
    n1, n2 = int(round(ramp / model.opt.timestep)), int(round(hold / model.opt.timestep))
    for k in range(n1):
        data.ctrl[:] = c0 + (ctrl_to - c0) * (k + 1) / n1
        mujoco.mj_step(model, data)
    data.ctrl[:] = ctrl_to
    mujoco.mj_step(model, data, nstep=n2)


def _is_position(model, a: int) -> bool:
    mujoco = import_mujoco()

    return (model.actuator_biastype[a] == int(mujoco.mjtBias.mjBIAS_AFFINE)
            and model.actuator_biasprm[a, 1] < 0)


def _centres(model, data, geoms) -> np.ndarray:
    return np.array([data.geom_xpos[g] for g in geoms])


def _spread(model, data, geoms) -> float:
    c = _centres(model, data, geoms)
    return float(np.max(np.linalg.norm(c[:, None] - c[None], axis=-1)))


def _ends(path: Path, parts: _Parts) -> tuple[np.ndarray, np.ndarray]:
    """(ctrl_open, ctrl_close) (nu,): for each actuator the end of its control range that
    opens / closes the fingers, found by stepping the model with it at either end."""
    mujoco = import_mujoco()

    m = parts.model
    if not np.all(m.actuator_ctrllimited.astype(bool)):
        bad = [m.actuator(a).name[len(PREFIX):] for a in parts.acts if not m.actuator_ctrllimited[a]]
        raise _error(path, f"actuators {bad} have no ctrlrange: the harness needs both ends (open, closed)")
    lo, hi = m.actuator_ctrlrange[:, 0].copy(), m.actuator_ctrlrange[:, 1].copy()
    rest = np.where([_is_position(m, a) for a in range(m.nu)], 0.5 * (lo + hi), 0.0)
    moving = [g for g in parts.geoms if g not in parts.static]
    geoms = parts.pads or moving
    close = np.empty(m.nu)
    d = mujoco.MjData(m)
    for a in range(m.nu):
        spread = []
        for end in (lo[a], hi[a]):
            mujoco.mj_resetData(m, d)
            c = rest.copy()
            c[a] = end
            d.ctrl[:] = rest
            _settle(m, d, c, ramp=0.1, hold=0.3)
            spread.append(_spread(m, d, geoms))
        if abs(spread[0] - spread[1]) < 1e-4:
            raise _error(path, f"actuator {m.actuator(a).name[len(PREFIX):] or a!r} does not move the fingers "
                               "(their spread changes < 0.1 mm between its control limits)")
        close[a] = lo[a] if spread[0] < spread[1] else hi[a]
    return np.where(close == lo, hi, lo), close


def _find_pads(path: Path, parts: _Parts, q_open: np.ndarray, q_closed: np.ndarray) -> list[int]:
    """The two moving collision geoms on different bodies whose gap shrinks most from
    open to closed (the inner faces that close towards each other)."""
    mujoco = import_mujoco()

    m = parts.model
    d = mujoco.MjData(m)
    moving = [g for g in parts.geoms if g not in parts.static]
    gaps = []
    for q in (q_open, q_closed):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        row = {}
        for i, a in enumerate(moving):
            for b in moving[i + 1:]:
                if m.geom_bodyid[a] != m.geom_bodyid[b]:
                    row[a, b] = mujoco.mj_geomDistance(m, d, a, b, 1.0, None)
        gaps.append(row)
    best = max(gaps[0], key=lambda k: gaps[0][k] - gaps[1][k], default=None)
    if best is None or gaps[0][best] - gaps[1][best] < 1e-3:
        raise _error(path, "no fingers found: no two moving collision geoms close towards each other; "
                           "name the two pad geoms in the sidecar key 'pad_geoms'")
    return list(best)


@dataclass
class _Table:
    qpos: np.ndarray        # (K, nq) of the measuring model
    ctrl: np.ndarray        # (K, nu) controls holding each row
    prismatic: bool
    contacts: np.ndarray | None = None  # (K,) the gripper's contacts with itself at rest (linkage)


def _jaw_joint(m, parts: _Parts, pad: int) -> int:
    """The first gripper joint on the chain from the root to the pad's body."""
    chain, b = [], int(m.geom_bodyid[pad])
    while b != parts.root and b > 0:
        chain.append(b)
        b = m.body_parentid[b]
    for b in reversed(chain):
        js = [j for j in parts.joints if m.jnt_bodyid[j] == b]
        if js:
            return js[0]
    raise GripperError(f"pad geom {m.geom(pad).name[len(PREFIX):]!r} does not move with any joint")


def _table(path: Path, parts: _Parts, ctrl_open, ctrl_close) -> _Table:
    mujoco = import_mujoco()

    m = parts.model
    d = mujoco.MjData(m)
    t = np.linspace(0.0, 1.0, ROWS)
    jaws = [_jaw_joint(m, parts, p) for p in parts.pads]
    chains = []
    for p in parts.pads:
        b, n = int(m.geom_bodyid[p]), []
        while b != parts.root:
            n += [j for j in parts.joints if m.jnt_bodyid[j] == b]
            b = m.body_parentid[b]
        chains.append(n)
    prismatic = (len(parts.joints) == 2 and all(len(c) == 1 for c in chains)
                 and all(m.jnt_type[j] == int(mujoco.mjtJoint.mjJNT_SLIDE) for j in jaws))
    if prismatic:
        # each pad on one slide: pose the joints over their ranges (closing end from stepping)
        mujoco.mj_resetData(m, d)
        d.ctrl[:] = ctrl_open
        _settle(m, d, ctrl_close, ramp=0.1, hold=0.4)
        qa = [m.jnt_qposadr[j] for j in jaws]
        closed = [m.jnt_range[j][int(np.argmin(np.abs(m.jnt_range[j] - d.qpos[a])))] for j, a in zip(jaws, qa)]
        opened = [m.jnt_range[j][1] if c == m.jnt_range[j][0] else m.jnt_range[j][0] for j, c in zip(jaws, closed)]
        for a in range(m.nu):  # a position servo opens its joint only as far as its control range reaches
            if _is_position(m, a) and m.actuator_trntype[a] == int(mujoco.mjtTrn.mjTRN_JOINT) \
                    and int(m.actuator_trnid[a, 0]) in jaws:
                i = jaws.index(int(m.actuator_trnid[a, 0]))
                reach = ctrl_open[a] / m.actuator_gear[a, 0]
                if abs(reach - closed[i]) < abs(opened[i] - closed[i]):
                    opened[i] = reach
        stroke = min(abs(o - c) for o, c in zip(opened, closed))  # equal strokes keep the centre
        q = np.repeat(m.qpos0[None], ROWS, axis=0)
        for a, c, o in zip(qa, closed, opened):
            q[:, a] = c + np.sign(o - c) * stroke * t
        ctrl = np.repeat(ctrl_close[None], ROWS, axis=0)
        for a in range(m.nu):
            if _is_position(m, a) and m.actuator_trntype[a] == int(mujoco.mjtTrn.mjTRN_JOINT):
                j = int(m.actuator_trnid[a, 0])
                ctrl[:, a] = np.clip(q[:, m.jnt_qposadr[j]] * m.actuator_gear[a, 0], *m.actuator_ctrlrange[a])
            elif not _is_position(m, a):
                ctrl[:, a] = 0.0
        return _Table(q[::-1].copy(), ctrl[::-1].copy(), True)
    if not all(_is_position(m, a) for a in range(m.nu)):
        raise _error(path, "a linkage gripper driven by a force actuator: graspsim steps linkages with "
                           "position actuators only")
    mujoco.mj_resetData(m, d)
    d.ctrl[:] = ctrl_open
    _settle(m, d, ctrl_open, ramp=0.1, hold=0.5)
    q, c, n = [], [], []
    dofs = [m.jnt_dofadr[j] for j in parts.joints]
    for tk in t:
        ck = ctrl_open + tk * (ctrl_close - ctrl_open)
        _settle(m, d, ck, ramp=0.1, hold=0.2)
        for _ in range(30):  # to rest: a linkage's passive joints may follow slowly (soft couplings)
            if np.abs(d.qvel[dofs]).max() < REST_SPEED:
                break
            mujoco.mj_step(m, d, nstep=50)
        if not np.all(np.isfinite(d.qpos)):
            raise _error(path, "the model diverges when its actuators are stepped (check its joint damping)")
        q.append(d.qpos.copy())
        c.append(ck)
        n.append(d.ncon)
    q0, c0, n0 = np.array(q), np.array(c), np.array(n)
    # the harness interpolates the joints between rows: the spec is measured at those poses too
    f = np.linspace(0.0, 1.0, DENSE + 1)[:-1, None]
    q = np.concatenate([(q0[:-1, None] + f * (q0[1:] - q0[:-1])[:, None]).reshape(-1, q0.shape[1]), q0[-1:]])
    c = np.concatenate([(c0[:-1, None] + f * (c0[1:] - c0[:-1])[:, None]).reshape(-1, c0.shape[1]), c0[-1:]])
    n = np.concatenate([np.repeat(np.maximum(n0[:-1], n0[1:]), DENSE), n0[-1:]])
    return _Table(q, c, False, n)


def _measure(path: Path, opts: dict) -> tuple[dict, dict]:
    """(spec fields, mount fields) of the model at ``path``."""
    mujoco = import_mujoco()
    from scipy.spatial import ConvexHull

    _HULLS.clear()  # keyed by the model's id: valid within one measurement
    child = _load_spec(path, opts)
    parts = _identify(path, child, opts)
    m = parts.model
    d = mujoco.MjData(m)
    ctrl_open, ctrl_close = _ends(path, parts)
    named = bool(parts.pads)
    if not parts.pads:
        qs = []
        for c in (ctrl_open, ctrl_close):
            mujoco.mj_resetData(m, d)
            d.ctrl[:] = ctrl_open
            _settle(m, d, c, ramp=0.1, hold=0.4)
            qs.append(d.qpos.copy())
        parts.pads = _find_pads(path, parts, *qs)
    table = _table(path, parts, ctrl_open, ctrl_close)

    # rows: hull vertices in the root frame
    rows = []
    for q in table.qpos:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        R, p = _frame(d, parts.root)
        rows.append({g: _hull(m, d, g, R, p) for g in parts.geoms})
    pa, pb = parts.pads
    open_row, shut_row = rows[0], rows[-1]  # the table runs from open to closed
    move = [open_row[g].mean(axis=0) - shut_row[g].mean(axis=0) for g in (pa, pb)]
    axis = move[1] - move[0]
    axis[2] = 0.0  # the closing axis: how the pads part, normal to the approach (the root's z)
    if np.linalg.norm(axis) < 1e-4:
        raise _error(path, "the pads do not open across the root body's z axis (the approach); "
                           "name the flange body in 'root_body'")
    axis /= np.linalg.norm(axis)
    axis = np.where(np.abs(axis) < 1e-6, 0.0, axis)
    axis /= np.linalg.norm(axis)
    if axis[np.argmax(np.abs(axis))] < 0:
        axis = -axis
    if (move[1] - move[0]) @ axis < 0:
        pa, pb = pb, pa
    R_w = np.stack([axis, np.cross([0.0, 0.0, 1.0], axis), [0.0, 0.0, 1.0]])  # rows: wrist axes in root
    side = {}
    for g in parts.geoms:
        if g in parts.static:
            continue
        side[g] = 1 if (open_row[g].mean(axis=0) @ axis) > (0.5 * (open_row[pa].mean(axis=0)
                                                                    + open_row[pb].mean(axis=0)) @ axis) else -1
    side[pa], side[pb] = -1, 1
    mid = 0.5 * (open_row[pa].mean(axis=0) + open_row[pb].mean(axis=0)) @ R_w.T
    cx, cy = (_r(round(v / GRID) * GRID) for v in mid[:2])
    W = [{g: v @ R_w.T - [cx, cy, 0.0] for g, v in row.items()} for row in rows]  # wrist-frame x, y; root z
    if opts.get("opening_from_joints"):
        jq = [m.jnt_qposadr[_jaw_joint(m, parts, pd)] for pd in (pa, pb)]
        gaps = table.qpos[:, jq].sum(axis=1)
    else:
        carrier = [[g for g in parts.geoms if m.geom_bodyid[g] == m.geom_bodyid[pd]] for pd in (pa, pb)]

        def inner(w, s):  # the innermost point of the pad's body from the pad's top to the tip
            pd = (pa, pb)[s]
            v = np.concatenate([w[g] for g in carrier[s]])
            v = v[v[:, 2] >= w[pd][:, 2].min() - 1e-9]
            return v[:, 0].min() if s else v[:, 0].max()

        gaps = np.array([inner(w, 1) - inner(w, 0) for w in W])
    order = np.argsort(gaps, kind="stable")
    keep = [order[0]]
    for k in order[1:]:
        if gaps[k] > gaps[keep[-1]] + 1e-6:
            keep.append(k)
    if len(keep) < 2:
        raise _error(path, "the pad gap does not change with the actuators")
    keep = np.array([k for k in keep if gaps[k] >= -1e-9])  # pads pressed into each other: not an opening
    if table.contacts is not None:  # a linkage closing on its own parts (pads on knuckles) is past its range
        free = table.contacts <= table.contacts[0]
        keep = keep[np.array([free[:k + 1].all() for k in keep], bool)] if len(keep) else keep
    if len(keep) < 2:
        raise _error(path, "the pads never stand apart")
    gaps, W = gaps[keep], [W[k] for k in keep]
    qtab, ctab = table.qpos[keep], table.ctrl[keep]
    lo = max(0.0, float(gaps[0]))
    if gaps[-1] <= lo + 1e-3:
        raise _error(path, f"the pads open to {gaps[-1] * 1000:.1f} mm only")

    def u_of(w, g, k):  # outward distance from the pad plane of g's side at row k
        return side[g] * w[g][:, 0] - 0.5 * gaps[k]

    static_v = np.concatenate([W[0][g] for g in parts.static]) if parts.static else np.zeros((0, 3))
    lo = float(gaps[0])
    tops, bots, inward, tip, zmin = [], [], [], -np.inf, 0.0
    for k, w in enumerate(W):
        for g, v in w.items():
            zmin = min(zmin, v[:, 2].min())
            if g in parts.static:
                continue
            tip = max(tip, v[:, 2].max())
            u = u_of(w, g, k)
            # the pads' bodies define the pad planes (to the meshes' precision); the other
            # moving parts must keep LINK_CLEARANCE outside them (they swing between the
            # table's rows), or the housing box takes them in
            tol = PAD_TOL if m.geom_bodyid[g] in (m.geom_bodyid[pa], m.geom_bodyid[pb]) else -LINK_CLEARANCE
            if np.any(u < -tol):  # (a linkage part also rises between the rows: by less than its clearance)
                inward.append(_top_inside(v, _local_hull(m, g)[1], u, -tol) + (0.0 if tol > 0 else LINK_CLEARANCE))
        for pd in (pa, pb):  # a named pad geom is all pad; a finger found geometrically: its flat face
            u = u_of(w, pd, k)
            face = w[pd] if named else w[pd][u <= u.min() + PAD_TOL]
            tops.append(face[:, 2].min())
            bots.append(face[:, 2].max())
    palm = max(static_v[:, 2].max() if len(static_v) else zmin, max(inward, default=-np.inf))
    # the housing box covers what reaches inside the pad planes (a linkage's inner knuckles
    # between the fingers); the pad region starts below it
    pad_top, pad_bot = max(max(tops), palm), min(bots)
    if pad_top >= pad_bot - 1e-3:
        raise _error(path, "the pads share no height over the opening range below the parts that reach "
                           "inside the pad planes (pad arc too steep, or the pads are not the innermost faces; "
                           "name them in the sidecar key 'pad_geoms')")
    z0g, palmg, topg, tipg = _grid(zmin, np.floor), _grid(palm), _grid(pad_top), _grid(tip)
    hx = hy = jx = jy = fx = fy = 0.0
    if len(static_v):
        hx, hy = np.abs(static_v[:, 0]).max(), np.abs(static_v[:, 1]).max()
    for k, w in enumerate(W):
        for g, v in w.items():
            if g in parts.static:
                continue
            for lo_z, hi_z, box in ((-np.inf, palmg, "h"), (palmg, topg, "j"), (topg, np.inf, "f")):
                c = _clip_z(v, _local_hull(m, g)[1], lo_z, hi_z)
                if not len(c):
                    continue
                if box == "h":
                    hx, hy = max(hx, np.abs(c[:, 0]).max()), max(hy, np.abs(c[:, 1]).max())
                else:
                    u = side[g] * c[:, 0] - 0.5 * gaps[k]
                    if box == "j":
                        jx, jy = max(jx, u.max()), max(jy, 2 * np.abs(c[:, 1]).max())
                    else:
                        fx, fy = max(fx, u.max()), max(fy, 2 * np.abs(c[:, 1]).max())
    fx, fy = _grid(fx), _grid(fy)
    jx, jy = max(_grid(jx), fx), max(_grid(jy), fy)
    hx = max(_grid(hx), _grid(0.5 * gaps[-1] + jx))
    hy = max(_grid(hy), _grid(0.5 * max(jy, fy)))
    tip_margin = None
    if tip - pad_bot > 5e-4:  # the finger reaches past the pad (or the pad rises on an arc): no contact there
        tip_margin = _grid(tip - pad_bot + TIP_CLEARANCE)
    # masses: the static bodies; one side's moving bodies split by volume (finger zone / all)
    bodies = {int(m.geom_bodyid[g]) for g in parts.geoms}
    wroot = m.body_weldid[parts.root]
    sub = [b for b in range(m.nbody) if _under(m, b, parts.root)]
    housing_mass = float(sum(m.body_mass[b] for b in sub if m.body_weldid[b] == wroot))
    pos_bodies = {int(m.geom_bodyid[g]) for g in side if side[g] == 1} & bodies
    side_mass = float(sum(m.body_mass[b] for b in sub if m.body_weldid[b] != wroot
                          and any(_under(m, b, pb2) or _under(m, pb2, b) for pb2 in pos_bodies)
                          and b in pos_bodies)) or float(m.body_mass[m.geom_bodyid[pb]])
    vol_all = vol_f = 0.0
    for g, v in W[0].items():
        if side.get(g) == 1:
            vol_all += ConvexHull(v).volume
            c = _clip_z(v, _local_hull(m, g)[1], pad_top, np.inf)
            if len(c) >= 4:
                try:
                    vol_f += ConvexHull(c).volume
                except Exception:  # noqa: BLE001 (a flat slice has no volume)
                    pass
    share = round(vol_f / vol_all, 4) if vol_all > 0 else 0.5
    R_rel = np.empty(9)
    mujoco.mju_quat2Mat(R_rel, m.body_quat[parts.root])
    R_rel = R_rel.reshape(3, 3)

    def to_base(p_w):  # a wrist-frame point (z: root) -> the measuring base's frame; and the rotation
        p_root = R_w.T @ (np.asarray(p_w) + [cx, cy, 0.0])
        return m.body_pos[parts.root] + R_rel @ p_root, R_rel @ R_w.T

    force, speed = _force_and_speed(path, parts, opts, table, ctrl_open, ctrl_close, gaps, pa, pb,
                                    W, qtab, to_base)
    name = opts.get("name") or _name(path, child)
    spec = dict(
        name=name, housing_size=[2 * hx, 2 * hy, _r(palmg - z0g)], jaw_size=[jx, jy, _r(max(topg - palmg, GRID))],
        finger_size=[fx, fy, _r(tipg - topg)], pad_length=_r(tipg - topg), tip_margin=tip_margin,
        stroke_per_jaw=_r((gaps[-1] - lo) / 2), closed_gap=_r(lo), rated_force=force, closing_speed=speed,
        housing_mass=housing_mass, jaw_mass=_r((1 - share) * side_mass), finger_mass=_r(share * side_mass))
    if spec["finger_size"][2] <= 0:
        raise _error(path, "the pads have no length below the jaws")
    # each row's flat pad faces (K, 2 pads, (upper end, lower end)) in the wrist frame
    pad_face = np.array(list(zip(tops, bots))).reshape(len(W), 2, 2) - z0g
    if not table.prismatic:  # a linkage: the straight-line model's largest error (see straight_line_error)
        try:  # the spec's nominal TCP: the middle of the contacts it plans
            planned = GripperSpec(**{k: tuple(v) if isinstance(v, list) else v for k, v in spec.items()}).nominal_tcp[2]
        except GripperError as e:
            raise _error(path, f"the measured spec is not valid: {e}") from e
        err = float(np.abs(pad_face.mean(axis=2) - planned).max())
        if err > GRID:
            spec["arc_error"] = _grid(err)
    # the harness's table: joint values of the gripper (by name), controls, pad heights
    jnames = [m.joint(j).name[len(PREFIX):] for j in parts.joints]
    jcols = [m.jnt_qposadr[j] for j in parts.joints]
    jaw_neg, jaw_pos = (_jaw_joint(m, parts, pd) for pd in (pa, pb))
    pad_z = [[float(0.5 * (w[pd][:, 2].min() + w[pd][:, 2].max()) - z0g) for pd in (pa, pb)] for w in W]
    pad_x = [[float(w[pd][:, 0].mean()) for pd in (pa, pb)] for w in W]
    mount = dict(
        root_body=m.body(parts.root).name[len(PREFIX):], joints=jnames,
        jaw_joints=[m.joint(jaw_neg).name[len(PREFIX):], m.joint(jaw_pos).name[len(PREFIX):]],
        pad_geoms=[m.geom(pa).name[len(PREFIX):], m.geom(pb).name[len(PREFIX):]],
        actuators=[m.actuator(a).name[len(PREFIX):] for a in range(m.nu)],
        pos=[-cx, -cy, -z0g], quat=_quat(R_w),
        openings=[float(max(g, 0.0)) for g in gaps], qpos=qtab[:, jcols].tolist(),
        ctrl_open=ctrl_open.tolist(), ctrl_close=ctrl_close.tolist(), ctrl_hold=ctab.tolist(),
        hold=bool(any(_is_position(m, a) for a in range(m.nu))), pad_z=pad_z, pad_x=pad_x,
        model_force=force, prismatic=table.prismatic, pad_top=float(pad_top - z0g), pad_bottom=float(pad_bot - z0g),
        pad_face=pad_face.tolist())
    return spec, mount


def _under(m, b: int, root: int) -> bool:
    while b > 0:
        if b == root:
            return True
        b = m.body_parentid[b]
    return False


def _quat(R_w: np.ndarray) -> list[float]:
    """(w, x, y, z) of the root frame in the wrist frame (R_W_root = R_w)."""
    mujoco = import_mujoco()

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R_w).ravel())
    if q[0] < 0:
        q = -q
    return [float(round(v, 12)) for v in q]


def _name(path: Path, child) -> str:
    import re

    n = child.modelname if child.modelname and child.modelname not in ("MuJoCo Model", "base") else path.stem
    return re.sub(r"[^A-Za-z0-9_.-]", "_", n)


def _force_and_speed(path, parts, opts, table, ctrl_open, ctrl_close, gaps, pa, pb, W, qtab, to_base):
    """The grip force per finger [N] and the closing speed per jaw [m/s] (see the module doc)."""
    mujoco = import_mujoco()

    m = parts.model
    force = opts.get("grip_force")
    if force is not None:
        try:
            force = float(force)
        except (TypeError, ValueError):
            raise _error(path, f"grip_force must be a number of newtons, got {force!r}") from None
        if not (np.isfinite(force) and force > 0):
            raise _error(path, f"grip_force must be > 0 N, got {force!r}")
    speed = None
    if force is None:
        per = []
        for a in range(m.nu):
            limit = m.actuator_forcerange[a, 1] if m.actuator_forcelimited[a] else np.inf
            trn = m.actuator_trntype[a]
            slide = False
            if trn == int(mujoco.mjtTrn.mjTRN_JOINT):
                slide = m.jnt_type[m.actuator_trnid[a, 0]] == int(mujoco.mjtJoint.mjJNT_SLIDE)
            elif trn == int(mujoco.mjtTrn.mjTRN_TENDON):
                tid = m.actuator_trnid[a, 0]
                adr, num = m.tendon_adr[tid], m.tendon_num[tid]
                slide = all(m.wrap_type[i] == int(mujoco.mjtWrap.mjWRAP_JOINT)
                            and m.jnt_type[m.wrap_objid[i]] == int(mujoco.mjtJoint.mjJNT_SLIDE)
                            for i in range(adr, adr + num))
            if not slide:
                per = None
                break
            if _is_position(m, a):
                if not np.isfinite(limit):
                    per = None
                    break
                per.append(float(limit))
            else:
                per.append(float(min(abs(m.actuator_gainprm[a, 0] * ctrl_close[a]), limit)))
        if per:
            force = min(per)
    if force is None:
        force = _squeeze(path, opts, parts, ctrl_close, qtab, gaps, W, pa, pb, to_base)
    # closing speed: a force actuator on damped slides moves at force / damping; else stepped
    dampers = [m.dof_damping[m.jnt_dofadr[_jaw_joint(m, parts, pd)]] for pd in (pa, pb)]
    if table.prismatic and not any(_is_position(m, a) for a in range(m.nu)) and min(dampers) > 0:
        speed = force / max(dampers)
    else:
        d = mujoco.MjData(m)
        d.qpos[:] = qtab[-1]  # the widest row
        d.ctrl[:] = ctrl_open
        mujoco.mj_forward(m, d)
        d.ctrl[:] = ctrl_close
        jq = m.jnt_qposadr[_jaw_joint(m, parts, pb)]
        qa = qtab[:, jq]  # the +x jaw joint: monotonic over the table
        up = qa[-1] > qa[0]
        span = gaps[-1] - gaps[0]
        t, dt = 0.0, m.opt.timestep
        while t < 2.0:
            mujoco.mj_step(m, d)
            t += dt
            w = np.interp(d.qpos[jq], qa if up else qa[::-1], gaps if up else gaps[::-1])
            if w <= gaps[-1] - 0.8 * span:
                break
        speed = 0.8 * span / 2 / max(t, dt)
    return float(round(force, 6)), float(round(speed, 6))


def _squeeze(path, opts, parts, ctrl_close, qtab, gaps, W, pa, pb, to_base) -> float:
    """The smallest pad force [N] when the model closes on a block fixed between its pads
    at 1/4, 1/2 and 3/4 of the opening range (no force range to read: a position servo
    on a linkage pushes with what its gain and the linkage give)."""
    mujoco = import_mujoco()

    forces = []
    for frac in (0.25, 0.5, 0.75):
        k = int(np.argmin(np.abs(gaps - (gaps[0] + frac * (gaps[-1] - gaps[0])))))
        w = W[k]
        z_lo = max(w[pa][:, 2].min(), w[pb][:, 2].min())
        z_hi = min(w[pa][:, 2].max(), w[pb][:, 2].max())
        half_y = 0.25 * min(np.ptp(w[pa][:, 1]), np.ptp(w[pb][:, 1]))
        centre = 0.5 * (w[pa].mean(axis=0) + w[pb].mean(axis=0))
        centre[2] = 0.5 * (z_lo + z_hi)
        pos, R = to_base(centre)
        half = np.abs(R @ np.array([0.4 * gaps[k], max(half_y, 0.002), max(0.25 * (z_hi - z_lo), 0.002)]))
        m = _harness(_load_spec(path, opts), block=(pos.tolist(), half.tolist())).compile()
        d = mujoco.MjData(m)
        d.qpos[:] = qtab[k]
        d.ctrl[:] = ctrl_close
        mujoco.mj_step(m, d, nstep=int(round(1.0 / m.opt.timestep)))
        block = m.geom("block").id
        pads = [m.geom(parts.model.geom(g).name).id for g in (pa, pb)]
        f, out = np.zeros(2), np.zeros(6)
        for i in range(d.ncon):
            con = d.contact[i]
            for s, pd in enumerate(pads):
                if {int(con.geom[0]), int(con.geom[1])} == {pd, block}:
                    mujoco.mj_contactForce(m, d, i, out)
                    f[s] += out[0]
        if f.min() <= 0:
            raise _error(path, "cannot determine the grip force: the pads do not squeeze a block between "
                               "them; give it in the sidecar key 'grip_force' [N per finger]")
        forces.append(float(f.min()))
    return min(forces)


# ----------------------------------------------------------------------------- public
def measure_model(path: str | Path, options: dict | None = None, *, model: str | None = None):
    """(GripperSpec, Mount) of the gripper model at ``path`` (see the module doc).
    options: the sidecar's keys (they override it); model: the spec's ``model`` (a
    vendored folder name; default: the file's resolved path)."""
    p = Path(path)
    try:
        if not p.is_file():
            raise OSError("not a regular file")
        p = p.resolve()
    except (OSError, ValueError) as err:
        raise GripperError(f"cannot read gripper model {str(path)!r}: {err}") from err
    opts = _options(p, options)
    digest = model_digest(p, opts)
    return _measured(str(p), digest, json.dumps(opts, sort_keys=True), model)


def vendored_gripper(name: str):
    """(GripperSpec, Mount) of the vendored model ``name`` (``mjcf/<name>/<name>.xml``),
    measured from its file like any model file."""
    from graspsim.grippers.vendored import model_folder

    return measure_model(model_folder(name) / f"{name}.xml", {"name": name}, model=name)


@functools.lru_cache(maxsize=16)
def _measured(path: str, digest: str, opts_json: str, model: str | None):
    from graspsim._atomic import atomic_write_text
    from graspsim.errors import MapFileError
    from graspsim.grippers.vendored import Mount

    p, opts = Path(path), json.loads(opts_json)
    cache = user_cache("grippers") / f"{digest[:40]}.json"
    data = None
    try:
        data = json.loads(cache.read_text())
    except (OSError, ValueError):
        data = None
    if not (isinstance(data, dict) and data.get("version") == MEASURE_VERSION):
        spec_f, mount_f = _measure(p, opts)
        data = {"version": MEASURE_VERSION, "spec": spec_f, "mount": mount_f}
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(cache, json.dumps(data), error=MapFileError)
        except (OSError, MapFileError):
            pass  # an unwritable cache only costs the next process the measurement
    spec_f, mf = dict(data["spec"]), data["mount"]
    spec_f = {k: tuple(v) if isinstance(v, list) else v for k, v in spec_f.items()}
    try:
        spec = GripperSpec(**spec_f, model=model or str(p))
    except GripperError as err:
        raise _error(p, f"the measured spec is not valid: {err}") from err
    mount = Mount(
        name=spec.name, path=p, root_body=mf["root_body"], jaw_joints=tuple(mf["jaw_joints"]),
        pad_geoms=tuple(mf["pad_geoms"]), actuators=tuple(mf["actuators"]), pos=tuple(mf["pos"]),
        quat=tuple(mf["quat"]), joints=tuple(mf["joints"]), openings=np.array(mf["openings"]),
        qpos=np.array(mf["qpos"]), ctrl_open=np.array(mf["ctrl_open"]), ctrl_close=np.array(mf["ctrl_close"]),
        ctrl_hold=np.array(mf["ctrl_hold"]), hold=bool(mf["hold"]), model_force=float(mf["model_force"]),
        pad_z=np.array(mf["pad_z"]), prismatic=bool(mf["prismatic"]), options=tuple(sorted(opts.items())),
        pad_face=np.array(mf["pad_face"]))
    return spec, mount


def pad_arc(mount, openings) -> np.ndarray:
    """(N, 2) height [m] of the (neg, pos) pad centres above the wrist origin at pad gaps
    ``openings`` (N,): the model's arc, interpolated from its opening table."""
    w = np.atleast_1d(np.asarray(openings, float))
    return np.stack([np.interp(w, mount.openings, mount.pad_z[:, s]) for s in range(2)], -1)


def straight_line_error(spec: GripperSpec, mount) -> dict:
    """The straight-line model's error at every row of the opening table: the planner puts
    each pad at x = +-opening/2 with its planned contacts between fixed heights (centred
    on the nominal TCP); the model's pad faces move on an arc (a linkage). Lists over the
    rows [m], heights along the approach (z, towards the tip), each pad (neg, pos):

    * ``openings`` (K,): the pad gaps;
    * ``centre_offset`` (K, 2): the pad face's centre minus the nominal TCP's height (the
      straight-line model's pad centre); ``spec.arc_error`` is its largest magnitude;
    * ``margin_upper`` / ``margin_lower`` (K, 2): how far the planned contact region lies
      inside the face at its upper (flange-side) / lower (tip-side) end (>= 0: a contact
      planned anywhere on the spec's pad lands on the real pad at that opening);
    * ``unused`` (K, 2): the face's length outside the planned region (what following the
      arc would recover)."""
    if mount.pad_face is None:
        raise GripperError(f"gripper model of {spec.name!r}: no pad faces measured (an old cache entry)")
    face = np.asarray(mount.pad_face, float)
    lo, hi = float(spec.tcp_offset(spec.depth_hi)), float(spec.tcp_offset(spec.depth_lo))  # upper, lower end
    centre = face.mean(axis=2) - float(spec.nominal_tcp[2])
    return {"openings": np.asarray(mount.openings, float).tolist(), "centre_offset": centre.tolist(),
            "margin_upper": (lo - face[:, :, 0]).tolist(), "margin_lower": (face[:, :, 1] - hi).tolist(),
            "unused": ((face[:, :, 1] - face[:, :, 0]) - (hi - lo)).tolist(),
            "planned": [lo, hi]}


def model_report(spec: GripperSpec, mount) -> dict:
    """What was measured, for the docs and the CLI: the opening range, the force, the
    pads' rise over the stroke (``arc_rise``: the largest change of a pad centre's height)
    and the straight-line model's error (``arc_error``, :func:`straight_line_error`; 0 for
    pads that move on a line)."""
    z = mount.pad_z
    return {"name": spec.name, "model": str(mount.path), "opening": [spec.min_opening, spec.max_opening],
            "grip_force": spec.grip_force, "closing_speed": spec.closing_speed,
            "pads": list(mount.pad_geoms), "jaw_joints": list(mount.jaw_joints),
            "actuators": list(mount.actuators), "linkage": not mount.prismatic,
            "arc_rise": float(np.ptp(z, axis=0).max()), "arc_error": spec.arc_error or 0.0,
            "straight_line_error": straight_line_error(spec, mount)}
