"""The map database as fuzzed content: a corrupted stored map, a damaged or lying index,
junk and stale files in the folder; then ``graspsim adapt`` (which reads, scales and
may rebuild stored maps), ``graspsim db check --repair`` and ``graspsim db check``.

Properties: every command ends cleanly; adapt stores no invalid map and writes a
valid map or nothing (an existing output kept); after ``--repair`` the check passes
and every map the index lists loads and validates.
"""

from __future__ import annotations

import json
import shutil

from hypothesis import strategies as st

from . import corrupt
from .assets import FAST_FLAGS, assets
from .harness import assert_clean, count, database_problems, run_cli
from .props_cli import run_checked
from .registry import register

_FIELDS = {
    "dims": [{"radius": float("nan"), "height": 0.2}, {"radius": -1, "height": 0.2}, {}, "x",
             {"radius": 0.02, "height": 1e300}, {"radius": 0.0, "height": 0.2}, {"side": 1}, None],
    "file": ["../../outside.h5", "/etc/passwd", "cylinder/missing.h5", "index.json", "", 5, None, "cylinder"],
    "accepted": [-1, 10**12, 0, "x", 1.5, None, 2**70],
    "grasps": [-1, 10**12, 0, "x", None],
    "primitive": ["sphere", "torus", "", None, 7, "compound"],
    "key": ["", None, "other", "../x"],
    "settings": ["", "0000000000", None],
}


def _index_op(draw):
    kind = draw(st.sampled_from(["field", "field", "field", "text", "duplicate", "extra", "maps", "none"]))
    if kind == "field":
        name = draw(st.sampled_from(sorted(_FIELDS)))
        return ("field", name, draw(st.sampled_from(_FIELDS[name])))
    if kind == "text":
        return ("text", draw(st.sampled_from(["", "{", "[]", '{"maps": 5}', "null", '{"format": 1}'])))
    if kind == "maps":
        return ("maps", draw(st.sampled_from([[], [1, "x", None], {"a": 1}])))
    return (kind,)


@st.composite
def database_cases(draw) -> dict:
    map_ops = draw(st.one_of(st.just([]), corrupt.corruptions().map(lambda c: c["ops"])))
    index_ops = [_index_op(draw) for _ in range(draw(st.integers(0, 2)))]
    return {"label": f"map {[o[:2] for o in map_ops]} index {index_ops}", "map_ops": map_ops,
            "index_ops": index_ops, "cloud": draw(st.sampled_from(["known", "known", "familiar"])),
            "junk": draw(st.sampled_from([None, "random.h5", "stale tmp", "empty.h5"])),
            "existing_out": draw(st.booleans())}


def _damage_index(path, ops) -> None:
    for op in ops:
        if op[0] == "text":
            path.write_text(op[1])
            continue
        try:
            data = json.loads(path.read_text())
            recs = data["maps"]
        except (ValueError, KeyError, TypeError):
            continue
        if not isinstance(recs, list):
            continue
        if op[0] == "field" and recs and isinstance(recs[0], dict):
            recs[0][op[1]] = op[2]
        elif op[0] == "duplicate" and recs:
            recs.append(recs[0])
        elif op[0] == "extra" and recs and isinstance(recs[0], dict):
            recs.append({**recs[0], "key": recs[0].get("key", "") + "x", "file": "cylinder/extra.h5"})
        elif op[0] == "maps":
            data["maps"] = op[1]
        path.write_text(json.dumps(data))


def _junk(db, what) -> None:
    folder = db / "cylinder"
    if what == "random.h5":
        (folder / "random.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 4)
    elif what == "empty.h5":
        (folder / "empty.h5").write_bytes(b"")
    elif what == "stale tmp":
        import os
        import time

        tmp = folder / ".x.h5.99999999.abcd.tmp.h5"
        tmp.write_bytes(b"half a map")
        old = time.time() - 7200
        os.utime(tmp, (old, old))


@register("database", "database content (CLI: adapt, db check)", database_cases, 30, per_case=3)
def check_database_case(case: dict) -> str:
    """adapt on a damaged database, then db check --repair and db check."""
    from graspsim.maps.io import load_map
    from graspsim.maps.validate import map_problems

    count("database content (CLI: adapt, db check)", 3)
    a = assets()
    folder = a.fresh()
    try:
        db = folder / "db"
        shutil.copytree(a.db, db)
        (stored,) = db.glob("cylinder/*.h5")
        if case["map_ops"]:
            tmp = folder / "damaged.h5"
            corrupt.apply(stored, tmp, case["map_ops"])
            stored.unlink()
            shutil.move(str(tmp), stored)
        _damage_index(db / "index.json", case["index_ops"])
        _junk(db, case["junk"])
        cloud = folder / "cloud.npy"
        shutil.copyfile(a.known_cloud if case["cloud"] == "known" else a.familiar_cloud, cloud)
        out = folder / "out.h5"
        if case["existing_out"]:
            shutil.copyfile(a.hand_map, out)
        label, _ = run_checked(["adapt", str(cloud), "-o", str(out), "--db", str(db), "--threads", "1",
                                *FAST_FLAGS, "--json"], folder, inputs=("cloud.npy",))
        repair = run_cli(["db", "check", "--db", str(db), "--repair", "--json"], cwd=folder)
        assert_clean(repair)
        check = run_cli(["db", "check", "--db", str(db), "--json"], cwd=folder)
        assert assert_clean(check) == "ok", f"db check after --repair: {check.out[-2000:]}"
        records = json.loads((db / "index.json").read_text())["maps"] if (db / "index.json").exists() else []
        problems = database_problems(db, {r["file"] for r in records})
        assert not problems, f"invalid maps listed after the repair: {problems}"
        for r in records:
            gmap = load_map(db / r["file"])
            assert map_problems(gmap) == [] and len(gmap) == r["grasps"], r
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)
