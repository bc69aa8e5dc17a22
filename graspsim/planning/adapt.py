"""A user's object cloud -> adapted map: the one run-time path.

``graspsim adapt`` is a thin layer over these functions, and every experiment that
plans an object cloud to simulate it against a mesh (E09, ``experiments/bench_user_objects.py``)
calls them too, so a number they publish is the number a user's command gives:

* :func:`adapt_config` -- the planner settings of the command's options (mode, table,
  scaling, partial maps);
* :func:`adapt_cloud` -- plan one cloud (a file's :class:`~graspsim.perception.LoadedCloud`
  or an array) with a seed, its viewpoint when it is a single view; the input is first
  made canonical (:func:`~graspsim.perception.prepare.canonical_points`), so the same
  points read from a float32 PLY or a float64 NPY give the same map.

The map is then simulated with :func:`graspsim.sim.mapsim.simulate_map` (``graspsim trial``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from graspsim.errors import InvalidParameterError

__all__ = ["DEFAULT_UNSEEN_MARGIN", "adapt_config", "adapt_cloud"]

#: [m] The unseen margin ``graspsim adapt`` plans a single view with in robust mode (the
#: measured :data:`graspsim.maps.robust.UNSEEN_MARGIN`; ``--unseen-margin 0``: none). The
#: robust score's own default (``RobustConfig``) and the scene planner's stay without it.
#: Made the default on E09's development meshes (single views, robust mode: more of the
#: ten best placed, fewer start collisions; docs/planner.md); a full cloud
#: has no viewpoint and is planned as before.
from graspsim.maps.robust import UNSEEN_MARGIN as DEFAULT_UNSEEN_MARGIN  # noqa: E402


def adapt_config(*, mode: str = "robust", table: str | float | None = None,
                 table_normal: Sequence[float] = (0.0, 0.0, 1.0), table_clearance: float = 0.002,
                 repetitions: int = 10, theta: float = 0.5, scaling: str = "combined",
                 partial: bool = True, low_profile: float | None = None, unseen_margin: float | None = None,
                 restarts: int | None = None):
    """The :class:`~graspsim.planning.planner.PlannerConfig` of ``graspsim adapt``'s options:
    ``mode`` "robust" | "paper"; ``table`` None (no table, as the paper's maps), "auto"
    (the object's lowest point: :func:`~graspsim.maps.table_clearance.table_height`) or a height
    [m] along ``table_normal`` in the cloud's frame; ``scaling`` the scaling method of
    familiar parts; ``partial``: a map of the identified parts when clustering fails;
    ``low_profile``: the least contact depth [m] of a grasp lifted clear of the table
    (:attr:`PlannerConfig.low_profile <graspsim.planning.planner.PlannerConfig.low_profile>`'s
    ``min_depth``; None: the default :class:`~graspsim.maps.table_clearance.LowProfile`; "off":
    none lifted); ``unseen_margin`` [m]: the robust score's margin against the unseen back
    of a single view (:attr:`RobustConfig.unseen_margin <graspsim.maps.robust.RobustConfig.unseen_margin>`,
    ``graspsim adapt --unseen-margin``): None (default) :data:`DEFAULT_UNSEEN_MARGIN` in
    robust mode, none in paper mode; 0: none; it counts only where :func:`adapt_cloud` is
    given a viewpoint (a cloud seen all round has no unseen back: there it is set to 0);
    ``restarts``: robust mode, how many more times a cloud whose map holds no accepted
    grasp is identified (:attr:`PlannerConfig.restarts
    <graspsim.planning.planner.PlannerConfig.restarts>`; None: its default)."""
    from dataclasses import replace

    from graspsim.geometry.table import TablePlane
    from graspsim.maps.scaling import ScalingConfig
    from graspsim.perception import IdentifyConfig
    from graspsim.planning.planner import PlannerConfig

    plane = None
    if table is not None:
        if isinstance(table, str) and table != "auto":
            try:
                table = float(table)
            except ValueError:
                raise InvalidParameterError(f"table takes 'auto' or a height in metres, got {table!r}") from None
        plane = TablePlane(normal=tuple(table_normal), clearance=table_clearance,
                           height=None if table == "auto" else table)
    from graspsim.maps.table_clearance import LowProfile

    lift = {} if low_profile is None else {
        "low_profile": None if low_profile == "off" else LowProfile(min_depth=float(low_profile))}
    cfg = PlannerConfig(identify=IdentifyConfig.preset(mode, repetitions=repetitions, theta=theta),
                        scaling=ScalingConfig(method=scaling), partial=partial, table=plane, **lift,
                        **({} if restarts is None else {"restarts": restarts}))
    if unseen_margin is None:
        unseen_margin = DEFAULT_UNSEEN_MARGIN if mode == "robust" else 0.0
    if not (isinstance(unseen_margin, (int, float)) and 0 <= unseen_margin <= 0.1):
        raise InvalidParameterError(f"unseen_margin must be in [0, 0.1] m (0: none), got {unseen_margin!r}")
    return replace(cfg, robust=replace(cfg.robust, unseen_margin=float(unseen_margin)))


def adapt_cloud(cloud, *, db, config=None, seed: int = 0, source: str | None = None,
                viewpoint: np.ndarray | None = None):
    """The adapted map of an object cloud: a :class:`~graspsim.perception.LoadedCloud`
    (its viewpoint is used unless ``viewpoint`` is given) or (N, 3) points [m], planned
    against ``db`` with ``config`` (:func:`adapt_config`; default: its defaults) from
    ``np.random.default_rng(seed)``. ``viewpoint`` (3,): where a single view was seen
    from, cloud frame [m] (the robust score's occluded-space term; the table of
    ``--table auto`` then may lie under the identified shape); None: seen all round.
    Without a viewpoint the unseen margin is set to 0 (it is about the side the camera
    did not see; ``graspsim adapt`` refuses ``--unseen-margin`` without one). Returns the
    planner's :class:`~graspsim.planning.planner.PlanResult`; its map records the viewpoint
    (``meta.extra["viewpoint"]``) and the robust score's settings, the margin among them
    (``meta.extra["robust"]``)."""
    from graspsim.perception.cloud_input import LoadedCloud
    from graspsim.perception.prepare import canonical_points
    from graspsim.planning.planner import plan

    if isinstance(cloud, LoadedCloud):
        points = cloud.points
        viewpoint = cloud.viewpoint if viewpoint is None else viewpoint
        source = source or cloud.path
    else:
        points = cloud
    if viewpoint is not None:
        viewpoint = np.asarray(viewpoint, float).reshape(-1)
        if viewpoint.shape != (3,) or not np.all(np.isfinite(viewpoint)):
            raise InvalidParameterError(f"viewpoint must be three finite numbers [m], got {viewpoint!r}")
    config = config if config is not None else adapt_config()
    if viewpoint is None and config.robust.unseen_margin > 0:  # seen all round: no unseen back to keep clear of
        from dataclasses import replace

        config = replace(config, robust=replace(config.robust, unseen_margin=0.0))
    return plan(canonical_points(points), db=db, rng=np.random.default_rng(seed), config=config,
                source=source or "array", viewpoint=viewpoint)
