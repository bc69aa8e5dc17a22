"""Trial scenes assembled with ``mujoco.MjSpec``: table, object, gripper.

Frames: the world has z up and the table top at z = 0 (a plane: everything below it is
inside the table, so a pose under the table penetrates it). The object rests on the
table in a stable pose ``T_world_obj`` (its object frame's +z up when that is stable,
docs/design.md §3), its centre of mass above the world origin. Map poses become world poses
as ``T_world_wrist = T_world_obj @ T_obj_wrist``.

Contact and solver settings are pinned in :class:`SimSettings` with documented defaults:
elliptic friction cone with impratio 100 (the pyramidal cone with impratio 1 drops
spheres; at impratio 10 MuJoCo's soft friction let a light object held at the full
grip force creep in the hand at loads well inside the friction cone -- a contact
normal 15-25 deg off the closing axis turns a 250 N grip into a 60-110 N tangential
load -- until it slipped out: 17 of the 20 clutter "drops" replayed by
``experiments/study_drops.py`` held at impratio 100, while those whose contact normals
lay outside the cone still dropped; the Coulomb limit itself is unchanged),
implicitfast integration at 1 ms (4 ms steps gave ~16 % false failures; 2 ms steps, with
the pads' softer contacts, squeezed objects of a few grams out of the grasp: the contact
models below), and condim 4 (torsional friction) on pads and object.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field, replace

import mujoco
import numpy as np

from graspsim.checks import NON_NEGATIVE, POSITIVE, check_fields
from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS, check_contacts
from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.sim.authored_model import authored_names, model_drive
from graspsim.sim.harness import build_gripper_spec
from graspsim.sim.model import IMPRATIO, NAMES, TIMESTEP, GripDrive, GripperNames, GripperPhysics, box_drive
from graspsim.sim.objects import SimObject

__all__ = ["SimSettings", "CONTACT_MODELS", "contact_model", "contact_settings", "Scene", "build_scene",
           "observed_pose", "resting_pose", "add_gripper", "gripper_drive", "gripper_geoms"]

log = logging.getLogger(__name__)

_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}
_INTEGRATORS = {"implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                "euler": mujoco.mjtIntegrator.mjINT_EULER,
                "rk4": mujoco.mjtIntegrator.mjINT_RK4}
OBJECT = "object"
TABLE = "table"


@dataclass(frozen=True)
class SimSettings:
    """Contact, drive and solver settings of a trial scene.

    friction: sliding friction pad-object (default: the planner's mu = 0.5, so the
        simulation tests the grade's own assumption). table_friction: object-table.
    torsional_friction, rolling_friction [m]: MuJoCo's contact-patch coefficients.
    grip_force: per jaw [N]; None = the gripper spec's (250 N for the HGPL-25 at 6 bar).
    density [kg/m^3]: object mass when none is given (water: a conservative default).
    timestep [s], impratio, cone, integrator, condim, diagexact, iterations,
    ls_iterations, tolerance: MuJoCo options (see the module docstring; impratio 10
        was the default before the clutter drops were diagnosed, and the ``soft`` contact
        model before the light objects were: ``contact_model("soft", SimSettings(impratio=10))``
        reproduces the earliest trials, ``contact_model("soft")`` those in between).
    start_penetration [m]: deeper overlaps of gripper and object/table at t = 0 make the
        trial START_COLLISION (the pose is infeasible, not a failed grasp).
    physics: the gripper's model parameters (:class:`GripperPhysics`).
    """

    friction: float = 0.5
    table_friction: float = 0.5
    torsional_friction: float = 0.005
    rolling_friction: float = 0.0001
    grip_force: float | None = None
    density: float = 1000.0
    timestep: float = TIMESTEP
    impratio: float = IMPRATIO
    cone: str = "elliptic"
    integrator: str = "implicitfast"
    condim: int = 4
    diagexact: bool = True
    iterations: int = 100
    ls_iterations: int = 50
    tolerance: float = 1e-8
    start_penetration: float = 0.001
    physics: GripperPhysics = field(default_factory=GripperPhysics)

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE.saying("a number > 0"), "friction", "table_friction", "density", "timestep",
                     "impratio", "tolerance")
        check_fields(self, NON_NEGATIVE, "torsional_friction", "rolling_friction", "start_penetration")
        if self.grip_force is not None and not (math.isfinite(self.grip_force) and self.grip_force > 0):
            raise InvalidParameterError(f"grip_force must be > 0 N or None, got {self.grip_force!r}")
        if self.cone not in _CONES:
            raise InvalidParameterError(f"cone {self.cone!r} unknown; valid: {sorted(_CONES)}")
        if self.integrator not in _INTEGRATORS:
            raise InvalidParameterError(
                f"integrator {self.integrator!r} unknown; valid: {sorted(_INTEGRATORS)}")
        if self.condim not in (3, 4, 6):
            raise InvalidParameterError(f"condim must be 3, 4 or 6, got {self.condim!r}")
        if self.timestep > 0.01:
            raise InvalidParameterError(f"timestep {self.timestep} s is too coarse for contact; use <= 0.01 s")
        if self.iterations < 1 or self.ls_iterations < 1:
            raise InvalidParameterError("iterations and ls_iterations must be >= 1")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["physics"] = self.physics.to_dict()
        return d


#: The named contact models (:data:`graspsim.contacts.CONTACT_MODELS`, the default first). ``stiff`` (the default,
#: ``SimSettings()``): 1 ms steps, the pads' ``solref`` 2 ms and impedance ramp 2 mm.
#: ``soft``: 2 ms steps, the pads' ``solref`` 4 ms and ramp 5 mm -- every simulated result
#: published before ``stiff`` became the default (docs/results.md says which), kept to
#: reproduce them.
#: MuJoCo's contacts are accelerations, so the soft pads sink millimetres into an object of a
#: few grams at the full grip force and squeeze it out of a grasp a heavier one holds
#: (``experiments/study_light_objects.py``); the stiff pads hold a level grasp of a 3.3 g
#: domino as of a 100 g one, at twice the steps per simulated second.
_SOFT_PADS = dict(pad_solref=(0.004, 1.0), pad_solimp=(0.95, 0.99, 0.005, 0.5, 2.0))


def contact_model(name: str, base: SimSettings | None = None) -> SimSettings:
    """``base`` (default ``SimSettings()``) with the contact model ``name`` of
    :data:`CONTACT_MODELS`: its timestep and its pads' ``solref``/``solimp`` (the rest of
    ``base`` kept); any other name is an :class:`InvalidParameterError` naming them."""
    base = base or SimSettings()
    if check_contacts(name) == DEFAULT_CONTACTS:
        stock = GripperPhysics()
        return replace(base, timestep=TIMESTEP,
                       physics=replace(base.physics, pad_solref=stock.pad_solref, pad_solimp=stock.pad_solimp))
    return replace(base, timestep=0.002, physics=replace(base.physics, **_SOFT_PADS))  # "soft"


def contact_settings(name: str) -> SimSettings | None:
    """The settings of the contact model ``name`` for a configuration's ``sim`` field, or
    None for :data:`~graspsim.contacts.DEFAULT_CONTACTS` (the caller's own default
    settings then stand); an unknown name is an :class:`InvalidParameterError` naming the
    valid ones."""
    return None if check_contacts(name) == DEFAULT_CONTACTS else contact_model(name)


@dataclass(frozen=True, eq=False)
class Scene:
    """A compiled trial scene and the addresses the trial code needs.

    T_world_obj: (4, 4) resting pose of the object. grip_force: per jaw [N].
    qadr_* / dadr_*: qpos / qvel addresses; pad_sensors: sensordata addresses of the
    two pad-object contact sensors (found, force xyz in the world frame). drive: how the
    gripper's joints are posed at an opening and its actuators commanded.
    """

    model: mujoco.MjModel
    gripper: GripperSpec
    obj: SimObject
    settings: SimSettings
    T_world_obj: np.ndarray
    table: bool
    gravity: bool
    grip_force: float
    qadr_wrist: int
    qadr_jaws: np.ndarray
    qadr_obj: int
    dadr_obj: int
    obj_body: int
    pad_sensors: np.ndarray
    gripper_geoms: np.ndarray
    contact_geoms: np.ndarray
    drive: GripDrive

    @property
    def nstate(self) -> int:
        return mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_FULLPHYSICS)

    def info(self) -> dict:
        """JSON-able description for trial records."""
        return {"object": self.obj.description, "mass": self.obj.mass,
                "gripper": self.gripper.to_dict(), "grip_force": self.grip_force,
                "settings": self.settings.to_dict(), "table": self.table,
                "gravity": self.gravity, "T_world_obj": self.T_world_obj.tolist(),
                "mujoco_version": mujoco.__version__}


def _inside(poly: np.ndarray, point: np.ndarray, margin: float = 1e-4) -> bool:
    """Is the 2D ``point`` inside the convex hull of ``poly`` (K, 2) by ``margin``?"""
    from scipy.spatial import ConvexHull, QhullError

    if len(poly) < 3:
        return False
    try:
        hull = ConvexHull(poly)
    except QhullError:
        return False
    return bool(np.all(hull.equations[:, :2] @ point + hull.equations[:, 2] < -margin))


def _stable_rotation(v: np.ndarray, com: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) resting the object on the hull face closest to its centre of mass
    among the faces it can stand on (COM over the face)."""
    from scipy.spatial import ConvexHull
    from scipy.spatial.transform import Rotation

    hull = ConvexHull(v)
    best, best_h = None, np.inf
    for eq in np.unique(np.round(hull.equations, 7), axis=0):
        n, d = eq[:3] / np.linalg.norm(eq[:3]), eq[3]
        h = -(n @ com + d)  # COM height above this face
        on = v[np.abs(v @ n + d) < 1e-6]
        e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        if h < best_h and _inside(on @ np.stack([e1, e2], 1), com @ np.stack([e1, e2], 1)):
            best, best_h = n, h
    if best is None:
        raise SimulationError("the object has no stable resting pose on a table")
    R, _ = Rotation.align_vectors([[0.0, 0.0, -1.0]], [best])
    return R.as_matrix()


def _align_to_z(up: np.ndarray) -> np.ndarray:
    """A rotation taking the unit vector ``up`` to +z (the shortest one)."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    c = float(up[2])
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    from scipy.spatial.transform import Rotation

    axis = np.cross(up, [0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)
    return Rotation.from_rotvec(axis * math.acos(c)).as_matrix()


def resting_pose(obj: SimObject, *, support_tol: float = 0.002,
                 up: np.ndarray | None = None) -> np.ndarray:
    """T_world_obj (4, 4): the object on the table (z = 0), centre of mass over the origin.

    ``up`` (3,), object frame: the direction that should point up (default +z: the
    object frame of docs/design.md §3 stands upright). It is kept when the centre of mass lies
    over the support polygon (points within ``support_tol`` of the lowest); otherwise
    the object rests on the hull face nearest its centre of mass that it can stand on.
    """
    v0 = np.asarray(obj.surface.vertices, float)
    T = np.eye(4)
    T[:3, :3] = _align_to_z(np.array([0.0, 0.0, 1.0]) if up is None else up)
    v = v0 @ T[:3, :3].T
    com = T[:3, :3] @ obj.com
    low = v[v[:, 2] < v[:, 2].min() + support_tol][:, :2]
    if not _inside(low, com[:2]):
        T[:3, :3] = _stable_rotation(v0, obj.com)
        log.info("object is not stable upright; resting it on another face")
    vw = v0 @ T[:3, :3].T
    cw = T[:3, :3] @ obj.com
    T[:3, 3] = np.array([-cw[0], -cw[1], -vw[:, 2].min()])
    return T


def observed_pose(obj: SimObject, T_cloud_obj: np.ndarray, normal=(0.0, 0.0, 1.0)) -> np.ndarray:
    """T_world_obj (4, 4): the object standing on the table as it was seen -- its pose
    in the cloud's frame ``T_cloud_obj`` turned so that the table's ``normal`` (cloud
    frame) points up, its lowest point on the table (z = 0) and its centre of mass over
    the origin (a shift along the table, which changes nothing physical).

    No stability rule moves it: a map adapted from a cloud holds grasps for the object
    as it stood (above the table it stood on), so any other resting face would put them
    elsewhere -- into the object or the table. A mesh in the cloud's frame (the real
    object) thus stands where the cloud was, on the plane under its lowest point."""
    from graspsim.transforms import make_transform

    T = np.asarray(T_cloud_obj, float)
    R = _align_to_z(np.asarray(normal, float)) @ T[:3, :3]
    v = np.asarray(obj.surface.vertices, float) @ R.T
    c = R @ obj.com
    return make_transform(R, np.array([-c[0], -c[1], -v[:, 2].min()]))


def _add_object(spec: mujoco.MjSpec, obj: SimObject, T_world_obj: np.ndarray,
                s: SimSettings, *, name: str = OBJECT,
                rgba: tuple[float, float, float, float] = (0.85, 0.55, 0.2, 1.0)) -> None:
    """Add ``obj`` as a free body ``name`` (geoms ``<name>_<i>``) at ``T_world_obj``."""
    from graspsim.transforms import matrix_to_quat

    body = spec.worldbody.add_body(name=name, pos=T_world_obj[:3, 3],
                                   quat=matrix_to_quat(T_world_obj[:3, :3]))
    body.add_freejoint(name=name)
    body.explicitinertial = True
    body.mass = obj.mass
    body.ipos = obj.com
    I = obj.inertia
    body.fullinertia = [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
    friction = [s.table_friction if obj.friction is None else obj.friction, s.torsional_friction,
                s.rolling_friction]
    kinds = {"box": mujoco.mjtGeom.mjGEOM_BOX, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
             "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "mesh": mujoco.mjtGeom.mjGEOM_MESH}
    for i, g in enumerate(obj.geoms):
        kw = dict(name=f"{name}_{i}", type=kinds[g.kind], pos=g.pos, quat=g.quat,
                  friction=friction, condim=s.condim, rgba=list(rgba), priority=int(obj.friction is not None))
        if g.kind == "mesh":
            mesh = spec.add_mesh(name=f"{name}_{i}", uservert=np.asarray(g.vertices, float).ravel())
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX
            kw["meshname"] = mesh.name
        else:
            kw["size"] = g.size
        body.add_geom(**kw)


def _set_options(spec: mujoco.MjSpec, s: SimSettings, *, gravity: bool = True) -> None:
    """The solver options of :class:`SimSettings`, an offscreen buffer and a light."""
    o = spec.option
    o.timestep, o.impratio, o.tolerance = s.timestep, s.impratio, s.tolerance
    o.iterations, o.ls_iterations = s.iterations, s.ls_iterations
    o.cone, o.integrator = _CONES[s.cone], _INTEGRATORS[s.integrator]
    if s.diagexact:
        o.enableflags |= mujoco.mjtEnableBit.mjENBL_DIAGEXACT
    if not gravity:
        o.gravity = [0.0, 0.0, 0.0]
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 1280, 960
    spec.worldbody.add_light(pos=[0.3, -0.3, 1.2], dir=[-0.25, 0.25, -1.0])


def _add_table(spec: mujoco.MjSpec, s: SimSettings, *, rolling: float | None = None,
               size: float = 0.4) -> None:
    """The table: a plane at z = 0 (infinite for collisions; ``size`` [m] half side drawn).
    ``rolling`` [m]: a rolling resistance (contact dimension 6 on the table; None: the
    settings' friction and condim)."""
    roll = s.rolling_friction if rolling is None else rolling
    spec.worldbody.add_geom(name=TABLE, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[size, size, 0.01],
                            friction=[s.table_friction, s.torsional_friction, roll],
                            condim=s.condim if rolling is None else 6, rgba=[0.6, 0.6, 0.62, 1.0])


def build_scene(obj: SimObject, gripper: GripperSpec = HGPL_25_60_A,
                settings: SimSettings = SimSettings(), *, table: bool = True,
                gravity: bool = True, up: np.ndarray | None = None,
                T_world_obj: np.ndarray | None = None) -> Scene:
    """Compile the trial scene for ``obj`` (build once, run many trials); ``up``: the
    object-frame direction to stand upright (see :func:`resting_pose`); ``T_world_obj``:
    the object's pose on the table when it is known (e.g. :func:`observed_pose`: as a
    cloud saw it), instead of a resting pose (ignored without a table)."""
    s = settings
    force = float(gripper.grip_force if s.grip_force is None else s.grip_force)
    if not table:
        T_world_obj = np.eye(4)
    elif T_world_obj is None:
        T_world_obj = resting_pose(obj, up=up)
    else:
        T_world_obj = np.asarray(T_world_obj, float)
    top = float((obj.surface.vertices @ T_world_obj[:3, :3].T)[:, 2].max() + T_world_obj[2, 3])
    home = (0.0, 0.0, top + gripper.fingertip_z + 0.1)  # qpos0: hanging clear above the object
    spec, names = add_gripper(gripper, s, force, home)
    spec.modelname = f"trial_{gripper.name}"
    _set_options(spec, s, gravity=gravity)
    if table:
        _add_table(spec, s)
    _add_object(spec, obj, T_world_obj, s)
    add_pad_sensors(spec, gripper, names, OBJECT, "")
    try:
        model = spec.compile()
    except ValueError as err:
        raise SimulationError(f"the trial scene does not compile: {' '.join(str(err).split())}") from err
    jid = lambda n: model.joint(n).id  # noqa: E731
    drive = gripper_drive(model, gripper)
    gids = gripper_geoms(model)
    others = [i for i in range(model.ngeom) if model.geom_bodyid[i] == model.body(OBJECT).id]
    if table:
        others.append(model.geom(TABLE).id)
    return Scene(
        model=model, gripper=gripper, obj=obj, settings=s, T_world_obj=T_world_obj,
        table=table, gravity=gravity, grip_force=force,
        qadr_wrist=int(model.jnt_qposadr[jid(NAMES.wrist)]),
        qadr_jaws=drive.qadr_jaws,
        qadr_obj=int(model.jnt_qposadr[jid(OBJECT)]), dadr_obj=int(model.jnt_dofadr[jid(OBJECT)]),
        obj_body=int(model.body(OBJECT).id),
        pad_sensors=np.array([model.sensor_adr[model.sensor(f"pad_{k}").id] for k in ("neg", "pos")]),
        gripper_geoms=np.array(gids), contact_geoms=np.array(others), drive=drive,
    )


def add_gripper(gripper: GripperSpec, s: SimSettings, force: float,
                home: tuple[float, float, float]) -> tuple[mujoco.MjSpec, GripperNames]:
    """A new spec holding the gripper on the harness's wrist: the box model generated from
    the spec, or the gripper's model file as authored (``gripper.model``)."""
    fric = (s.friction, s.torsional_friction, s.rolling_friction)
    spec = build_gripper_spec(gripper, s.physics, grip_force=force, friction=fric, condim=s.condim, home_pos=home)
    return spec, authored_names(gripper)


def add_pad_sensors(spec: mujoco.MjSpec, gripper: GripperSpec, names: GripperNames, body: str, suffix: str) -> None:
    """Contact sensors ``pad_neg<suffix>``, ``pad_pos<suffix>``: each pad's contacts with
    ``body`` (found, net force). A model file's pad counts with its finger body (every
    geom the finger carries: a tilting linkage finger may touch with its tip first)."""
    for side in ("neg", "pos"):
        pad = getattr(names, f"finger_{side}")
        if gripper.model is None:
            kind, obj = mujoco.mjtObj.mjOBJ_GEOM, pad
        else:
            kind, obj = mujoco.mjtObj.mjOBJ_BODY, spec.geom(pad).parent.name
        sens = spec.add_sensor(name=f"pad_{side}{suffix}", type=mujoco.mjtSensor.mjSENS_CONTACT,
                               objtype=kind, objname=obj, reftype=mujoco.mjtObj.mjOBJ_BODY, refname=body)
        sens.intprm[:3] = [3, 3, 1]  # data: found | force; reduce: net force; one slot


def gripper_drive(model: mujoco.MjModel, gripper: GripperSpec) -> GripDrive:
    """How the harness poses and commands ``gripper`` in the compiled ``model``."""
    return box_drive(model, gripper) if gripper.model is None else model_drive(model, gripper)


def gripper_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the gripper's colliding geoms: every one on the wrist body's subtree."""
    wrist = model.body(NAMES.wrist).id
    return np.array([i for i in range(model.ngeom) if model.body_rootid[model.geom_bodyid[i]] == wrist
                     and (model.geom_contype[i] or model.geom_conaffinity[i])], int)
