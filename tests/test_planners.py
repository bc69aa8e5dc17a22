"""The planner interface of the clutter benchmark (graspsim.tabletop.planners) and the per-seed
statistics (graspsim.tabletop.clutter_stats)."""

import sys
import textwrap

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError, PlannerError
from graspsim.grippers import get_gripper
from graspsim.tabletop.clutter import ClutterResult
from graspsim.tabletop.clutter_stats import per_seed
from graspsim.tabletop.planners import Observation, Proposals, antipodal, load_planner, plan_frame

FRANKA = get_gripper("franka_hand")

#: the README's adapter: a GraspNet-style planner (GraspGroup rows in the camera frame) in <= 30 lines;
#: here its network is a stand-in that proposes one top-down grasp over the highest point seen
ADAPTER = '''
import numpy as np
from graspsim.maps.formats import graspnet_to_wrist
from graspsim.tabletop.planners import Proposals


def my_network(depth, intrinsics, cloud_camera):  # stand-in: (K, 17) GraspGroup rows, camera frame
    top = cloud_camera[np.argmin(cloud_camera[:, 2])]        # nearest the camera looking down
    R = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # x_G along the camera's z
    return np.concatenate([[0.9, 0.07, 0.02, 0.02], R.ravel(), top + [0, 0, 0.01], [0]])[None]


def plan(obs):
    T_wc = obs.T_world_camera
    cloud_camera = (obs.cloud - T_wc[:3, 3]) @ T_wc[:3, :3]
    a = my_network(obs.depth, obs.intrinsics, cloud_camera)
    R = T_wc[:3, :3] @ a[:, 4:13].reshape(-1, 3, 3)           # camera -> world
    t = a[:, 13:16] @ T_wc[:3, :3].T + T_wc[:3, 3]
    T = graspnet_to_wrist(R, t, a[:, 3], obs.gripper)          # GraspNet's gripper frame -> wrist
    order = np.argsort(-a[:, 0])
    return Proposals(T[order], a[order, 1], a[order, 0])
'''


def _box_on_table(rng, size=(0.05, 0.05, 0.08)):
    """A cloud of a box standing on a table at z = 0 seen from above and the side."""
    hx, hy, hz = np.asarray(size) / 2
    table = np.c_[rng.uniform(-0.2, 0.2, (3000, 2)), np.zeros(3000)]
    table = table[(np.abs(table[:, 0]) > hx) | (np.abs(table[:, 1]) > hy)]
    top = np.c_[rng.uniform(-hx, hx, 400), rng.uniform(-hy, hy, 400), np.full(400, 2 * hz)]
    side = np.c_[np.full(400, hx), rng.uniform(-hy, hy, 400), rng.uniform(0, 2 * hz, 400)]
    side2 = np.c_[rng.uniform(-hx, hx, 400), np.full(400, -hy), rng.uniform(0, 2 * hz, 400)]
    return np.concatenate([table, top, side, side2])


def _observation(cloud, rng):
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # looking down
    T[:3, 3] = [0.3, -0.3, 0.6]
    return Observation(np.zeros((4, 4)), None, T, cloud, FRANKA, rng)


def test_proposals_are_checked():
    with pytest.raises(InvalidParameterError, match="poses"):
        Proposals(np.eye(4)[None], [0.05, 0.06], [1.0])
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(InvalidParameterError, match="orthonormal"):
        Proposals(bad[None], [0.05], [1.0])
    assert len(Proposals(np.zeros((0, 4, 4)), [], [])) == 0


def test_load_planner_names_and_errors(tmp_path, monkeypatch):
    assert load_planner("antipodal") is antipodal
    (tmp_path / "my_adapter.py").write_text(textwrap.dedent(ADAPTER))
    monkeypatch.syspath_prepend(str(tmp_path))
    assert callable(load_planner("my_adapter:plan"))
    for bad in ("nonsense", "no_such_module:plan", "my_adapter:missing"):
        with pytest.raises(InvalidParameterError, match="--planner"):
            load_planner(bad)


FAULTY = '''
import numpy as np


def boom(obs):
    raise RuntimeError("model weights not found")


def nothing(obs):
    return None


def ragged(obs):
    return np.eye(4)[None], np.zeros(2), np.zeros(1)


def two(obs, extra):
    return None


class NoGpu:
    def __init__(self):
        raise OSError("no GPU")
'''


def test_a_faulty_planner_is_one_error_naming_it(tmp_path, monkeypatch):
    """A user's planner that cannot be made, takes the wrong arguments, raises, or returns
    something other than grasps: an InvalidParameterError (when loaded) or a PlannerError
    (when called), one line naming the planner and its fault -- the CLI prints it without
    a traceback."""
    from graspsim.geometry.camera import Camera, DepthFrame, Intrinsics

    (tmp_path / "faulty.py").write_text(FAULTY)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(InvalidParameterError, match="one argument, the Observation"):
        load_planner("faulty:two")
    with pytest.raises(InvalidParameterError, match="NoGpu.. failed: OSError: no GPU"):
        load_planner("faulty:NoGpu")
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[2, 3] = 0.5
    frame = DepthFrame(np.full((48, 64), 0.5, np.float32), Camera(Intrinsics(64, 48, 60.0, 60.0, 32.0, 24.0), T))
    rng = np.random.default_rng(0)
    for name, message in (("boom", "boom raised RuntimeError: model weights not found"),
                          ("nothing", "nothing returned NoneType"), ("ragged", "ragged returned grasps of the wrong")):
        with pytest.raises(PlannerError, match=message):
            plan_frame(load_planner(f"faulty:{name}"), frame, FRANKA, rng)


@pytest.mark.slow
def test_antipodal_baseline_closes_across_the_box():
    """Every proposal: the TCP inside the box's footprint, the jaws opened fully and
    closing across a 5 cm face pair, ranked by clearance. Mutation caught: the TCP put
    a pad length below the wrist origin instead of ``tcp_offset`` from it."""
    rng = np.random.default_rng(0)
    props = antipodal(_observation(_box_on_table(rng), np.random.default_rng(1)), samples=60)
    assert len(props) >= 3
    assert np.all(np.diff(props.score) <= 0)
    T = props.T_world_wrist
    tcp = T[:, :3, 3] + FRANKA.tcp_offset(FRANKA.nominal_depth) * T[:, :3, 2]
    assert np.all(np.abs(tcp[:, :2]) <= 0.03) and np.all((tcp[:, 2] > 0.0) & (tcp[:, 2] < 0.09))
    assert np.allclose(props.opening, FRANKA.max_opening)


def test_per_seed_gsr_dr_mean_and_std():
    def result(placed, removed, ok, n):
        r = ClutterResult(placed, (), removed, "cleared", 0, 0, 0.0)
        object.__setattr__(r, "attempts", tuple(type("A", (), {"success": i < ok, "cause": ""})() for i in range(n)))
        return r

    s = per_seed({1: [result(5, 5, 5, 5)], 2: [result(5, 3, 3, 6), result(5, 4, 4, 4)]})
    assert [r["gsr"] for r in s["per_seed"]] == [1.0, 0.7]
    assert [r["dr"] for r in s["per_seed"]] == [1.0, 0.7]
    assert s["gsr"]["mean"] == pytest.approx(0.85) and s["gsr"]["std"] == pytest.approx(np.std([1, 0.7], ddof=1))
    assert s["gsr_text"] == "85.0 ± 21.2 %"


@pytest.mark.slow
def test_a_third_party_planner_runs_the_benchmark_through_the_cli(tmp_path, monkeypatch, capsys):
    import json

    from graspsim.cli import main

    (tmp_path / "my_adapter.py").write_text(textwrap.dedent(ADAPTER))
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["scene", "--objects", "2", "--planner", "my_adapter:plan", "--max-attempts", "2",
                 "--db", str(tmp_path / "db"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["planner"] == "my_adapter:plan" and s["attempts"] >= 1
    assert s["seeds"]["per_seed"][0]["grasps"] == s["attempts"]
    assert len(sys.modules["my_adapter"].__dict__) and all(a["segments"] == 0 for a in s["details"][0]["steps"])
    assert s["per_source"] == {} and not any("source" in a for a in s["details"][0]["steps"])  # not known
