import json
import math

import h5py
import numpy as np

from graspsim.cli import main
from graspsim.primitives import Cylinder, synthetic_cloud
from graspsim.transforms import make_transform


def test_adapt_writes_map_with_cloud_transform(tmp_path, capsys):
    rng = np.random.default_rng(2)
    T = make_transform(np.eye(3), [0.3, 0.0, 0.1])
    c = synthetic_cloud(Cylinder(0.022, 0.15), rng, resolution=0.004, noise=0.0005, T_world_obj=T)
    np.save(tmp_path / "cloud.npy", c.points)
    db = tmp_path / "db"
    db.mkdir()
    # a coarse database so the first-use build stays quick
    assert main(["db", "build", "--primitives", "cylinder", "--db", str(db), "--surface-step", "0.01",
                 "--rotation-step-deg", "22", "--json"]) == 0
    capsys.readouterr()
    out = tmp_path / "a.h5"
    code = main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(out), "--db", str(db),
                 "--surface-step", "0.01", "--rotation-step-deg", "22", "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["status"] == "complete" and s["grasps"] > 0
    assert s["parts"][0]["primitive"] == "cylinder" and s["parts"][0]["match"] == "familiar"
    assert s["time_to_first_0.95"] is None or s["time_to_first_0.95"] <= s["seconds"]
    with h5py.File(out) as f:
        Tco = f["object/T_cloud_obj"][()]
    assert np.allclose(Tco[:3, 3], T[:3, 3], atol=0.002)
    assert math.isclose(abs(Tco[:3, 2] @ T[:3, 2]), 1.0, abs_tol=1e-3)
    # the same cloud standing on a table at its lowest point: poses below it are dropped
    out2 = tmp_path / "t.h5"
    code = main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(out2), "--db", str(db),
                 "--surface-step", "0.01", "--rotation-step-deg", "22", "--table", "auto", "--json"])
    t = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and t["table"]["dropped"] > 0 and t["grasps"] + t["table"]["dropped"] == s["grasps"]
    assert abs(t["table"]["height"] - (0.1 - 0.075)) < 0.002
    with h5py.File(out2) as f:
        assert json.loads(f["graspability/meta"][()])["extra"]["table"]["height"] == t["table"]["height"]
    assert main(["info", str(out2)]) == 0
    assert "poses dropped" in capsys.readouterr().out
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["table"] is None and info["source"].endswith("cloud.npy")
    code = main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(out2), "--db", str(db), "--table", "low"])
    assert code == 2 and "--table takes 'auto' or a height" in capsys.readouterr().err


def test_adapt_bad_cloud_file(tmp_path, capsys):
    (tmp_path / "bad.npy").write_bytes(b"nope")
    code = main(["adapt", str(tmp_path / "bad.npy"), "-o", str(tmp_path / "x.h5")])
    assert code == 2 and "error" in capsys.readouterr().err


def test_adapt_restarts_reach_the_planner_and_a_bad_count_is_one_line(tmp_path, capsys, monkeypatch):
    """--restarts N is PlannerConfig.restarts (default: the planner's); more than 10, or not a
    whole number, is refused with one error line (argparse's usage above it for a malformed
    one), and no map is written."""
    import graspsim.planning.adapt as adapt
    from graspsim.planning.planner import PlannerConfig

    seen = []
    real = adapt.adapt_config
    monkeypatch.setattr(adapt, "adapt_config", lambda **kw: seen.append(real(**kw).restarts) or real(**kw))
    np.save(tmp_path / "cloud.npy", np.zeros((5, 3)))  # too few points: planning fails after the config is made
    for flag, want in (([], PlannerConfig().restarts), (["--restarts", "0"], 0), (["--restarts", "5"], 5)):
        main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(tmp_path / "m.h5"), "--db", str(tmp_path / "db"),
              *flag])
        assert seen[-1] == want
    capsys.readouterr()
    for bad in ("11", "-1", "two"):
        try:
            code = main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(tmp_path / "m.h5"), "--restarts", bad])
        except SystemExit as e:  # argparse's own refusal
            code = e.code
        err = capsys.readouterr().err
        assert code == 2 and "restarts" in err.strip().splitlines()[-1] and "Traceback" not in err
    assert not (tmp_path / "m.h5").exists()
