"""Run-time planning: a point cloud (or a known shape) to ranked, adapted grasps.

* :mod:`~graspsim.planning.planner`: one object's cloud -> identification -> stored,
  scaled or combined maps -> grasps ranked by the robust score (``plan``, ``plan_shape``,
  ``plan_stream``, ``PlannerConfig``); its results in :mod:`~graspsim.planning.plan_results`
  and its stage timings in :mod:`~graspsim.planning.stages`;
* a table-top scene of several objects: :mod:`~graspsim.planning.scene` (``plan_scene``,
  ``perceive_scene``), its settings in :mod:`~graspsim.planning.scene_config`
  (``SceneConfig``), one segment planned in :mod:`~graspsim.planning.scene_segments`, the
  worker processes in :mod:`~graspsim.planning.scene_workers` and reuse between frames in
  :mod:`~graspsim.planning.scene_reuse`.

May use: the base modules, geometry, primitives, grippers, grades, maps and perception
(never sim, tabletop or anything above). Nothing is imported here, so importing one
module of the package loads only what that module needs.
"""
