"""Outcome enum and motion metrics on synthetic records."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graspsim.sim.outcomes import Record, TrialOutcome, pads_touching, relative_motion, unstable


def _record(n=3, S=50, seed=0):
    rng = np.random.default_rng(seed)
    t = np.tile((np.arange(S) + 1) * 0.002, (n, 1))
    wq = Rotation.random(n, random_state=1).as_quat(scalar_first=True)
    wq = np.repeat(wq[:, None], S, axis=1)
    wp = rng.normal(size=(n, 1, 3)) + np.linspace(0, 0.1, S)[None, :, None] * [0, 0, 1]
    # object rigidly attached 10 cm in front of the wrist
    R = Rotation.from_quat(wq.reshape(-1, 4), scalar_first=True)
    op = wp + R.apply(np.tile([0, 0, 0.1], (n * S, 1))).reshape(n, S, 3)
    pads = np.zeros((n, S, 2, 4))
    pads[..., 0] = 1
    pads[..., 1] = 250.0
    return Record(time=t, wrist_pos=wp, wrist_quat=wq, obj_pos=op, obj_quat=wq.copy(),
                  obj_vel=np.zeros((n, S, 6)), jaws=np.full((n, S, 2), 0.03), pads=pads)


def test_rigidly_carried_object_does_not_move_in_the_gripper_frame():
    rec = _record()
    lin, ang = relative_motion(rec, 0, 49)
    np.testing.assert_allclose(lin, 0.0, atol=1e-12)
    np.testing.assert_allclose(ang, 0.0, atol=1e-6)
    assert not unstable(rec, max_speed=5, max_spin=100, max_distance=1,
                        start_pos=rec.obj_pos[:, 0]).any()
    assert pads_touching(rec, 10).tolist() == [2, 2, 2]


def test_slip_in_the_gripper_frame_is_measured():
    rec = _record()
    obj = rec.obj_pos.copy()
    obj[1, 30:] -= [0.0, 0.0, 0.02]  # drops 2 cm in the world = in the hand
    rec2 = Record(**{**rec.__dict__, "obj_pos": obj})
    lin, _ = relative_motion(rec2, 0, 49)
    assert lin[1] == pytest.approx(0.02) and lin[0] < 1e-12


@pytest.mark.parametrize("break_it", ["nan", "reset", "fast", "far"])
def test_diverged_records_are_unstable(break_it):
    rec = _record()
    d = dict(rec.__dict__)
    if break_it == "nan":
        d["obj_pos"] = rec.obj_pos.copy()
        d["obj_pos"][0, 20, 1] = np.nan
    elif break_it == "reset":  # MuJoCo's automatic reset after a bad qacc: time restarts
        d["time"] = rec.time.copy()
        d["time"][0, 20:] -= rec.time[0, 19]
    elif break_it == "fast":
        d["obj_vel"] = rec.obj_vel.copy()
        d["obj_vel"][0, 5, 0] = 1e3
    else:
        d["obj_pos"] = rec.obj_pos.copy()
        d["obj_pos"][0, 40:] += 100.0
    bad = unstable(Record(**d), max_speed=50, max_spin=2000, max_distance=20,
                   start_pos=rec.obj_pos[:, 0])
    assert bad.tolist() == [True, False, False]


def test_outcome_codes_are_stable():
    # codes are stored in map files: never renumber
    assert [o.value for o in TrialOutcome] == list(range(10))
    assert TrialOutcome.SUCCESS.label == "success"
    assert TrialOutcome(6) is TrialOutcome.SIM_UNSTABLE
