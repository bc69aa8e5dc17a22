"""Trial recordings (`graspsim trial --record`): the trajectories the trials computed,
kept at 25 fps in a small atomic file, and refused cleanly when they cannot be written
or read."""

import json

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.errors import MapFileError
from graspsim.maps import read_sim_results, save_map
from graspsim.primitives import Cylinder
from graspsim.sim.recording import load_recording


def _map(tmp_path, n=3):
    """n side grasps of a standing cylinder (all lift it) and one from below (starts
    inside the table: START_COLLISION, not simulated, so not recorded)."""
    ang = np.linspace(0.0, np.pi / 2, n)
    T = [grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0]) for a in ang]
    T.append(grasp_pose([0, 0, -0.09], [0, 0, 1], [1, 0, 0]))
    m = hand_made_map(Cylinder(0.02, 0.20), np.stack(T), np.full(n + 1, 0.04),
                      grades=np.linspace(0.6, 0.9, n + 1))
    return save_map(m, tmp_path / "cyl.h5")


def test_record_keeps_each_simulated_trial_and_its_motion(tmp_path, capsys):
    path, rec_path = _map(tmp_path), tmp_path / "trials.npz"
    assert main(["trial", str(path), "--threads", "1", "--record", str(rec_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["record"] == str(rec_path)
    rec = load_recording(rec_path)
    stored = read_sim_results(path)
    feasible = np.flatnonzero(stored["outcome"] != 1)  # START_COLLISION = 1 is not simulated
    assert sorted(rec.rows.tolist()) == feasible.tolist() and len(rec) == 3
    assert np.array_equal(rec.outcome, stored["outcome"][rec.rows])
    # 25 frames per second over the whole protocol, from t = 0
    duration = sum(v for k, v in rec.protocol.items() if k.endswith("_time"))
    assert rec.time[0] == 0.0 and abs(len(rec.time) - 25 * duration) <= 2
    assert np.allclose(np.diff(rec.time), 0.04, atol=1e-9)
    # the recorded object rises with the gripper by the lift height, then is put back
    z = rec.obj_pos[:, :, 2] - rec.obj_pos[:, :1, 2]
    assert np.all(z.max(axis=1) > rec.protocol["lift_height"] - 0.02)
    assert np.all(np.abs(z[:, -1]) < 0.01)
    assert np.allclose(np.linalg.norm(rec.wrist_quat, axis=-1), 1.0, atol=1e-4)
    # the jaws close on the object: from width + 2 x clearance (5 mm) to about the width
    closed = int(np.searchsorted(rec.time, rec.protocol["settle_time"] + rec.protocol["close_time"]))
    gap = rec.jaws.sum(axis=2)
    assert np.allclose(gap[:, 0], 0.05, atol=1e-3) and np.all(gap[:, closed] < 0.042)
    assert rec.vertices.shape[1] == 3 and rec.faces.max() < len(rec.vertices)
    assert rec.gripper_spec.name == "festo_hgpl_25_60_a"
    assert rec_path.stat().st_size < 100_000  # small
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary left behind


def test_record_to_an_unwritable_path_fails_before_simulating(tmp_path, capsys):
    path = _map(tmp_path)
    code = main(["trial", str(path), "--threads", "1", "--record", str(tmp_path / "no" / "x.npz")])
    assert code == 2
    err = capsys.readouterr().err
    assert "trial recording" in err and "does not exist" in err and "Traceback" not in err
    assert read_sim_results(path) == {}  # nothing was simulated


@pytest.mark.parametrize("content", [b"", b"not a zip", None])
def test_unreadable_recordings_raise_map_file_error(tmp_path, content):
    p = tmp_path / "r.npz"
    if content is None:
        np.savez(p, a=np.zeros(3))  # an npz, not a recording
    else:
        p.write_bytes(content)
    with pytest.raises(MapFileError, match="not a"):
        load_recording(p)
    with pytest.raises(MapFileError, match="does not exist"):
        load_recording(tmp_path / "missing.npz")
