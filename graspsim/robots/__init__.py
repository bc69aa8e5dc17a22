"""Robot arms carrying graspsim grippers: which grasps an arm reaches, and grasps
executed by the arm in MuJoCo (reach-to-grasp).

* :mod:`~graspsim.robots.arm`: the arm's model (the vendored Franka Emika Panda,
  ``mjcf/panda``) on a base beside the table, the gripper on its flange (its model file,
  or the box model generated from its spec),
  position servos on its joints;
* :mod:`~graspsim.robots.reach`: inverse kinematics with mink, joint limits and
  collisions (MuJoCo's collision detection) of a grasp, its pre-grasp and its approach;
* :mod:`~graspsim.robots.capability`: the arm's capability map (wrist position x
  approach direction), the fast first cut for thousands of poses, cached by content;
* :mod:`~graspsim.robots.execute`: the arm's trial scene, the plan of a grasp (move,
  approach, lift, place, retreat) and its execution by the servos;
* :mod:`~graspsim.robots.maptrials`: a map's grasps executed by the arm
  (``graspsim trial --robot panda``);
* :mod:`~graspsim.robots.mapreach`: which of a map's grasps the arm reaches, stored as
  the map's ``reachable`` column (``graspsim reach``, ``graspsim adapt --robot``).

May use: the base modules, geometry, primitives, grippers, grades, maps, plots and sim
(never perception, planning, tabletop or anything above). With sim and tabletop, a
package that imports mujoco directly (after :mod:`graspsim._gl` chose the backend).
"""

from __future__ import annotations

from graspsim._gl import default_gl

default_gl()  # before any submodule imports mujoco

from graspsim.robots.arm import ARMS, PANDA, ROBOTS, ArmServos, ArmSpec, base_transform, build_robot_model, get_arm  # noqa: E402,E501
from graspsim.robots.capability import CapabilityConfig, CapabilityMap, capability_map  # noqa: E402
from graspsim.robots.execute import ArmLiftPlace, ArmScene, build_arm_scene, plan_grasp, plan_grasps, run_arm_trials  # noqa: E402,E501
from graspsim.robots.mapreach import mark_reach, mark_reach_file, reach_column  # noqa: E402
from graspsim.robots.maptrials import simulate_map_arm  # noqa: E402
from graspsim.robots.reach import ArmKinematics, Reach, check_reach  # noqa: E402

__all__ = ["ARMS", "PANDA", "ROBOTS", "ArmServos", "ArmSpec", "base_transform", "build_robot_model", "get_arm",
           "CapabilityConfig", "CapabilityMap", "capability_map", "ArmLiftPlace", "ArmScene", "build_arm_scene",
           "plan_grasp", "plan_grasps", "run_arm_trials",
           "mark_reach", "mark_reach_file", "reach_column", "ArmKinematics", "Reach", "check_reach", "simulate_map_arm"]
