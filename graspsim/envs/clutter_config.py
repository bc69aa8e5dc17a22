"""Settings of ``graspsim/ClutterClear-v0``: one frozen, validated dataclass.

``gymnasium.make("graspsim/ClutterClear-v0", **kwargs)`` passes its keyword arguments
here; an unknown name or a bad value raises :class:`InvalidParameterError` saying what
is valid. Importing it loads no mujoco (validating the object set does).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from graspsim.checks import BOOLEAN, check_fields, integer, or_none
from graspsim.contacts import DEFAULT_CONTACTS, check_contacts
from graspsim.errors import InvalidParameterError
from graspsim.maps.map_config import MapConfig

__all__ = ["ClutterEnvConfig", "make_clutter_config"]

_KINDS = ("pile", "packed")  # graspsim.tabletop.table_scene.KINDS (not imported: it loads mujoco)
_MAX_OBJECTS = 30  # graspsim.tabletop.table_scene.MAX_OBJECTS


@dataclass(frozen=True)
class ClutterEnvConfig:
    """Environment settings.

    n_objects, kind (``"pile"`` | ``"packed"``), object_set: the scenes drawn at reset
        (:func:`graspsim.tabletop.table_scene.make_scene`; a set of :mod:`graspsim.tabletop.scene_objects`:
        ``"household"``, the clutter benchmark's (``graspsim scene``'s default), ``"mixed"``, ... or a
        folder of the user's mesh files, as ``graspsim scene --objects-dir``). The first reset
        prepares the simulation body of every mesh the set draws, as ``graspsim scene`` does (convex
        parts, up to 15 s of CPU a mesh the first time, then cached on disk: well under a second).
    n_candidates: K, candidate grasps offered per step (the scene's ranking, best first).
    cloud_size: N, points of the observed depth cloud (a fixed-size sample of the frame's
        back-projected points, with repeats when it has fewer).
    depth_image: also observe the (H, W) depth image [m] (0: no depth).
    depth_noise: the sensor's noise model (False: a perfect sensor).
    execution_error: the arm misses each pose (3 mm / 2 deg sigma, ``ExecutionNoise()``).
    neighbours: grasps are checked against the whole scene (False: the ablation).
    max_attempts: grasps per episode before truncation (None: 2 x objects + 2);
    max_failures: consecutive failed grasps that end (terminate) an episode.
    max_redraws: scenes drawn per reset before giving up when none offers a grasp.
    db_root, map_config, gripper: the map database (None: ``$GRASPSIM_DB`` or
        ``~/.cache/graspsim/db``; the paper's generation settings; the Festo); maps of
        new sizes are built there on first use.
    robot, robot_base: ``"panda"``: the Franka Emika Panda arm standing at ``robot_base``
        (x [m], y [m], yaw [rad] on the table top) executes the chosen grasps
        (:class:`graspsim.tabletop.clutter.ClutterRobot`, as ``graspsim scene --robot panda``):
        its gripper must be simulated from its model file (e.g. ``gripper="franka_hand"``);
        a chosen grasp it cannot reach or approach is a failed step (cause ``unreachable``
        / ``approach_collision``, never executed); ``"none"``: the floating gripper.
    progress: progress bars on stderr, when it is a terminal, for work that takes longer than 2 s:
        the first reset's mesh preparation, and FS maps of new sizes that a reset or step builds
        (False: quiet; bars a caller set itself through ``graspsim.maps.database.BUILD_PROGRESS``
        are left as they are).
    contacts: the simulation's contact model (:func:`graspsim.sim.contact_model`: ``"stiff"``,
        the default, or ``"soft"``, the earlier one; as ``graspsim scene --contacts``).
    """

    n_objects: int = 3
    kind: str = "pile"
    object_set: str = "household"  # graspsim.tabletop.mesh_objects.BENCHMARK_SET, as graspsim scene
    n_candidates: int = 16
    cloud_size: int = 2048
    depth_image: bool = False
    depth_noise: bool = True
    execution_error: bool = False
    neighbours: bool = True
    max_attempts: int | None = None
    max_failures: int = 2
    max_redraws: int = 4
    db_root: str | None = None
    map_config: MapConfig | None = None
    gripper: object = "festo_hgpl_25_60_a"
    robot: str = "none"
    robot_base: tuple = (-0.5, 0.0, 0.0)
    contacts: str = DEFAULT_CONTACTS
    progress: bool = True

    def __post_init__(self) -> None:
        check_fields(self, integer(1), "n_objects", "n_candidates", "cloud_size", "max_failures", "max_redraws")
        if self.n_objects > _MAX_OBJECTS:
            raise InvalidParameterError(f"n_objects must be at most {_MAX_OBJECTS}, got {self.n_objects}")
        check_fields(self, or_none(integer(1)), "max_attempts")
        if self.kind not in _KINDS:
            raise InvalidParameterError(f"kind {self.kind!r} unknown; valid: {list(_KINDS)}")
        from graspsim.tabletop.scene_objects import check_object_set

        try:
            check_object_set(self.object_set)
        except InvalidParameterError as err:
            raise InvalidParameterError(f"object_set: {err}") from None
        check_fields(self, BOOLEAN, "depth_image", "depth_noise", "execution_error", "neighbours", "progress")
        check_contacts(self.contacts)  # an unknown name: one line naming the valid ones
        from graspsim.envs.env_config import check_database_fields

        check_database_fields(self)
        if self.robot != "none":
            from graspsim.grippers import get_gripper
            from graspsim.robots.arm import ROBOTS, base_transform

            if self.robot not in ROBOTS:
                raise InvalidParameterError(f"robot {self.robot!r} unknown; valid: {list(ROBOTS)}")
            base_transform(self.robot_base)
            get_gripper(self.gripper)  # a bad name or spec: one line, before any work

    def to_dict(self) -> dict:
        d = asdict(self)
        d["map_config"] = None if self.map_config is None else self.map_config.to_dict()
        d["gripper"] = self.gripper if isinstance(self.gripper, str) else self.gripper.to_dict()
        d["robot_base"] = list(self.robot_base)
        return d


def make_clutter_config(config: ClutterEnvConfig | None = None, **kwargs) -> ClutterEnvConfig:
    """``config`` (or the defaults) with ``kwargs`` overriding fields (see
    :func:`graspsim.envs.env_config.make_config`)."""
    from graspsim.envs.env_config import make_config

    return make_config(config, ClutterEnvConfig, **kwargs)
