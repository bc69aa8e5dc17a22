"""``graspsim identify``: JSON summary, human output, errors as exit status 2."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from graspsim.cli import main
from graspsim.primitives import Cylinder, synthetic_cloud
from graspsim.transforms import make_transform, random_rotation


@pytest.fixture
def cylinder_file(tmp_path):
    rng = np.random.default_rng(21)
    T = make_transform(random_rotation(rng), [0.1, 0.2, 0.5])
    cloud = synthetic_cloud(Cylinder(0.02, 0.12), rng, noise=0.001, T_world_obj=T)
    pts = np.vstack([cloud.points, np.full((5, 3), np.nan)])
    path = tmp_path / "cyl.xyz"
    np.savetxt(path, pts)
    return path


def _json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_json_summary(cylinder_file, capsys, tmp_path, monkeypatch):
    nodb = tmp_path / "nodb"
    monkeypatch.setenv("GRASPSIM_DB", str(nodb))  # no default database: no match, none built
    assert main(["identify", str(cylinder_file), "--json", "--seed", "3", "--repetitions", "10"]) == 0
    out = _json(capsys)
    assert out["status"] == "identified" and out["dropped_nonfinite"] == 5
    (part,) = out["parts"]
    assert set(part) == {"primitive", "dims", "pose", "match", "stored", "fit_rate", "points", "approximate",
                         "band_rate"}
    assert out["mode"] == "robust" and out["uncovered"] == [] and part["approximate"] is False
    assert part["primitive"] == "cylinder" and part["match"] is None
    assert out["database"] is None and not nodb.exists()
    assert part["dims"]["radius"] == pytest.approx(0.02, abs=0.002)
    assert np.asarray(part["pose"]).shape == (4, 4) and out["seconds"] > 0
    # same seed, same answer
    main(["identify", str(cylinder_file), "--json", "--seed", "3"])
    again = _json(capsys)
    assert again["parts"] == out["parts"]


def test_human_output(cylinder_file, capsys):
    assert main(["identify", str(cylinder_file), "--theta", "0.6"]) == 0
    text = capsys.readouterr().out
    assert "identified" in text and "cylinder" in text and "radius=" in text


def test_errors_exit_2(tmp_path, capsys):
    (tmp_path / "bad.pcd").write_bytes(b"VERSION 0.7\nFIELDS x y z\n")
    assert main(["identify", str(tmp_path / "bad.pcd")]) == 2
    assert "no DATA line" in capsys.readouterr().err
    np.savetxt(tmp_path / "ok.xyz", np.random.default_rng(0).normal(size=(50, 3)))
    assert main(["identify", str(tmp_path / "ok.xyz"), "--theta", "2"]) == 2
    assert "theta must be in (0, 1]" in capsys.readouterr().err


def test_db_option(cylinder_file, tmp_path, capsys):
    """With the FS map database installed an empty one matches nothing; without it,
    --db is a clear error."""
    rc = main(["identify", str(cylinder_file), "--db", str(tmp_path / "db"), "--json"])
    if importlib.util.find_spec("graspsim.maps.database") is None:
        assert rc == 2 and "graspsim.maps.database" in capsys.readouterr().err
    else:
        assert rc == 0 and _json(capsys)["parts"][0]["match"] is None


def test_match_column_uses_the_default_database_like_adapt(cylinder_file, tmp_path, monkeypatch,
                                                           capsys):
    """identify asks the default database (the one adapt uses) without --db when it exists."""
    from graspsim.maps.database import MapDatabase

    root = tmp_path / "db"
    db = MapDatabase(root)  # default settings, as adapt's
    (root / "index.json").write_text(json.dumps({"format": "graspsim-db-1", "maps": [
        {"primitive": "cylinder", "dims": {"radius": 0.02, "height": 0.12},
         "settings": db.settings_digest, "key": "k", "file": "cylinder/k.h5"}]}))
    monkeypatch.setenv("GRASPSIM_DB", str(root))
    assert main(["identify", str(cylinder_file), "--seed", "3"]) == 0
    rows = [r.split() for r in capsys.readouterr().out.splitlines() if "cylinder" in r.split()[1:2]]
    assert rows and rows[0][-3] == "known" and rows[0][-1].startswith("(x1.0")  # match, stored map (ratio)
    assert main(["identify", str(cylinder_file), "--seed", "3", "--json"]) == 0
    out = _json(capsys)
    assert out["parts"][0]["match"] == "known" and out["database"] == str(root)
    assert sorted(p.name for p in root.iterdir()) == ["index.json"]  # nothing built
