"""The arm's reachability verdicts do not move when its IK gets faster.

``data/reach_verdicts.json`` holds 16 of the benchmark's grasps (experiments/bench_reach.py:
the paper's box resting on the table, the coarse FS map of the Franka hand, the 100 best by
the robust ranking, the Panda at its default base; four of each verdict it found), each
with the capability map's seed, the jaw opening, and the verdict, failing stage and plan
outcome that the code before the speed-up (commit efa4157) gave them. Regenerate with
``python tests/test_reach_verdicts.py`` only when a verdict is meant to change, and say why.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from graspsim.grippers import get_gripper
from graspsim.maps.database import PAPER_SHAPES
from graspsim.robots import ArmLiftPlace, build_arm_scene, check_reach, plan_grasp
from graspsim.sim import object_from_shape

DATA = Path(__file__).parent / "data" / "reach_verdicts.json"
PER_VERDICT = 4


@pytest.fixture(scope="module")
def recorded():
    return json.loads(DATA.read_text())


@pytest.fixture(scope="module")
def box():
    scene = build_arm_scene(object_from_shape(PAPER_SHAPES["box"]), get_gripper("franka_hand"))
    return scene, scene.kinematics()


def _judge(scene, kin, g) -> dict:
    T = np.array(g["T_world_wrist"])
    seeds = () if g["seed"] is None else (np.array(g["seed"]),)
    jaws = (scene.drive.qadr, scene.drive.joint_positions([g["opening"]])[0])
    chk = check_reach(kin, T, jaws=jaws, seeds=seeds)
    plan = plan_grasp(scene, kin, T, g["opening"], ArmLiftPlace(), seeds=seeds)
    return {"reach": chk.reach.label, "stage": chk.stage,
            "outcome": None if plan.outcome is None else plan.outcome.name, "plan_stage": plan.stage}


def test_the_verdicts_of_fixed_grasps_are_the_recorded_ones(box, recorded):
    scene, kin = box
    grasps = recorded["grasps"]
    assert {g["expect"]["reach"] for g in grasps} == {"reachable", "no_ik", "table", "start"}
    got = [_judge(scene, kin, g) for g in grasps]
    assert got == [g["expect"] for g in grasps]


def test_the_fast_joint_limit_is_minks_configuration_limit(box):
    import mink

    from graspsim.robots.reach import _joint_limit

    _, kin = box
    model = kin._cfg.model
    ref, fast = mink.ConfigurationLimit(model), _joint_limit(model)
    cfg = mink.Configuration(model)
    rng = np.random.default_rng(5)
    lo, hi = model.jnt_range.T
    for _ in range(20):  # inside the limits and beyond them
        q = model.qpos0.copy()
        span = np.where(model.jnt_limited.astype(bool), hi - lo, 1.0)
        q[model.jnt_qposadr] = lo + span * rng.uniform(-0.2, 1.2, model.njnt)
        cfg.update(q)
        a, b = ref.compute_qp_inequalities(cfg, 1.0), fast.compute_qp_inequalities(cfg, 1.0)
        np.testing.assert_array_equal(a.G, b.G)
        np.testing.assert_array_equal(a.h, b.h)


def _record() -> None:
    """Write DATA from the benchmark's inputs (run with the code whose verdicts count)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    from _common import map_config

    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.robust import executed_width, ranking
    from graspsim.robots import PANDA, CapabilityConfig, base_transform, build_robot_model, capability_map

    gripper = get_gripper("franka_hand")
    shape = PAPER_SHAPES["box"]
    gmap = generate_fs_map(shape, gripper, config=map_config(True))
    scene = build_arm_scene(object_from_shape(shape), gripper)
    kin = scene.kinematics()
    cmap = capability_map(build_robot_model(PANDA, gripper), PANDA, base_transform(), CapabilityConfig(samples=500_000),
                          cache_dir=False)
    order = ranking(gmap, "robust")[:100]
    T_world = scene.T_world_obj @ gmap.T_obj_wrist[order]
    seeds = cmap.lookup(T_world)[1]
    openings = gripper.pregrasp_opening(executed_width(gmap.select(order)))
    grasps, count = [], {}
    for T, s, w in zip(T_world, seeds, openings):
        g = {"T_world_wrist": T.tolist(), "seed": None if np.isnan(s).any() else s.tolist(), "opening": float(w)}
        g["expect"] = _judge(scene, kin, g)
        k = g["expect"]["reach"]
        if count.get(k, 0) < PER_VERDICT:
            count[k] = count.get(k, 0) + 1
            grasps.append(g)
    DATA.write_text(json.dumps({"source": "tests/test_reach_verdicts.py (_record), experiments/bench_reach.py's "
                                          "box inputs", "counts": count, "grasps": grasps}, indent=1) + "\n")
    print(count)


if __name__ == "__main__":
    _record()
