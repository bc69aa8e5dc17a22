import json
import math

import pytest

from graspsim.errors import MapDatabaseError, PrimitiveError
from graspsim.maps.database import MapDatabase, map_bytes, size_grid
from graspsim.maps.map_config import MapConfig
from graspsim.maps.match import MatchKind
from graspsim.primitives import Cylinder, Sphere

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


def test_known_familiar_unknown(tmp_path):
    db = MapDatabase(tmp_path / "db", config=FAST)
    db.add(Cylinder(0.02, 0.10))
    assert db.lookup("cylinder", {"radius": 0.0205, "height": 0.102}).match == "known"  # within 3 %
    assert db.lookup("cylinder", {"radius": 0.025, "height": 0.105}).match == "familiar"  # x 1.25: scaled
    m = db.lookup("cylinder", {"radius": 0.035, "height": 0.10})
    assert m.match == "familiar" and m.max_diff == pytest.approx(0.015)
    assert m.entry["dims"] == {"radius": 0.02, "height": 0.10}
    assert db.lookup("sphere", {"radius": 0.03}).match is MatchKind.BUILD
    with pytest.raises(PrimitiveError):
        db.lookup("cylinder", {"radius": -1, "height": 0.1})


def test_get_builds_on_demand_and_build_resumes(tmp_path):
    db = MapDatabase(tmp_path, config=FAST)
    s = Sphere(0.03)
    assert not db.contains(s)
    m = db.get(s)
    assert db.contains(s) and len(m) > 0
    mtime = db.path(s).stat().st_mtime_ns
    recs = db.build([s, Sphere(0.02)])
    assert len(recs) == 2
    assert db.path(s).stat().st_mtime_ns == mtime  # not rebuilt
    with pytest.raises(MapDatabaseError):
        MapDatabase(tmp_path, config=MapConfig()).get(s, build=False)  # other settings


def test_damaged_index_is_reported(tmp_path):
    db = MapDatabase(tmp_path, config=FAST)
    db.index_path.write_text("{not json")
    with pytest.raises(MapDatabaseError, match="damaged"):
        db.entries()


def test_size_grid():
    g = size_grid(Cylinder(0.02, 0.2), [0.5, 2])
    assert [s.dims for s in g] == [{"radius": 0.01, "height": 0.1}, {"radius": 0.04, "height": 0.4}]
    with pytest.raises(MapDatabaseError):
        size_grid(Cylinder(0.02, 0.2), [0])


def test_index_is_json(tmp_path):
    db = MapDatabase(tmp_path, config=FAST)
    db.add(Sphere(0.025))
    data = json.loads(db.index_path.read_text())
    assert data["format"] == "graspsim-db-1" and data["maps"][0]["primitive"] == "sphere"


@pytest.mark.slow
def test_concurrent_builders_lose_no_index_record(tmp_path):
    from graspsim.executors import ProcessExecutor

    shapes = [Sphere(0.02), Sphere(0.025), Sphere(0.03), Cylinder(0.015, 0.06)]
    db = MapDatabase(tmp_path, config=FAST)
    with ProcessExecutor(2) as ex:  # two processes each build on demand and write the index
        ex.map(db.get, shapes)
    assert {e["key"] for e in db.entries()} == {db.key(s) for s in shapes}


def test_uncached_database_reads_every_time(tmp_path):
    db = MapDatabase(tmp_path, config=FAST, cache_size=0)
    s = Sphere(0.03)
    db.add(s)
    e = db.entries()[0]
    a = db.load_entry(e, accepted_only=True)
    b = db.load_entry(e, accepted_only=True)
    assert a is not b and len(a) == len(b) == e["accepted"]


def test_cache_bounded_by_maps_and_bytes(tmp_path):
    """The run-time cache keeps the maps planning reads (the same object again) up to
    ``cache_size`` maps and ``cache_bytes`` bytes, the least recently used leaving first;
    a map larger than the byte budget is read every time."""
    db = MapDatabase(tmp_path, config=FAST)
    shapes = [Sphere(0.02), Sphere(0.025), Sphere(0.03)]
    for s in shapes:
        db.add(s)
    es = sorted(db.entries(), key=lambda e: e["key"])
    sizes = [map_bytes(db.load_entry(e, accepted_only=True)) for e in es]

    def cached(d):
        return [d.load_entry(e, accepted_only=True) is d.load_entry(e, accepted_only=True) for e in es]

    assert cached(db) == [True, True, True]  # the defaults hold them all
    two = MapDatabase(tmp_path, config=FAST, cache_bytes=sizes[1] + sizes[2])
    first = [two.load_entry(e, accepted_only=True) for e in es]  # the first read leaves to make room
    assert two.load_entry(es[0], accepted_only=True) is not first[0]  # evicted: read again
    assert two.load_entry(es[0], accepted_only=True) is two.load_entry(es[0], accepted_only=True)
    assert two._cached_bytes <= sizes[1] + sizes[2]
    small = MapDatabase(tmp_path, config=FAST, cache_bytes=min(sizes) - 1)
    assert cached(small) == [False, False, False] and small._cached_bytes == 0
    one = MapDatabase(tmp_path, config=FAST, cache_size=1)
    one.load_entry(es[0], accepted_only=True)
    a = one.load_entry(es[1], accepted_only=True)
    assert one.load_entry(es[1], accepted_only=True) is a and len(one._cache) == 1


def test_linked_copy_shares_the_maps_and_keeps_its_own(tmp_path):
    coarse = MapConfig(surface_step=0.01, rotation_step=math.radians(30))
    base = MapDatabase(tmp_path / "base", config=coarse)
    base.add(Sphere(0.03))
    view = base.linked_copy(tmp_path / "view")
    assert [e["key"] for e in view.entries()] == [e["key"] for e in base.entries()]
    assert (tmp_path / "view" / base.entries()[0]["file"]).is_symlink()
    view.add(Sphere(0.05))  # built in the copy only
    assert len(view.entries()) == 2 and len(base.entries()) == 1
    with pytest.raises(FileExistsError):
        base.linked_copy(tmp_path / "view")


def test_entries_follow_every_rewrite_of_the_index(tmp_path):
    """entries() checks each record once per index content (not once per lookup), so a
    rewritten index -- a record spoiled in place at the same file size, one added -- is
    read as it is now, and a caller editing the records it got changes nothing stored."""
    db = MapDatabase(tmp_path, config=FAST)

    def rec(r):
        return {"key": f"cyl{r:+.2f}", "file": f"cylinder/c{r:+.2f}.h5", "accepted": 5, "primitive": "cylinder",
                "dims": {"radius": r, "height": 0.1}, "settings": db.settings_digest}

    def write(radii):
        db.index_path.write_text(json.dumps({"maps": [rec(r) for r in radii]}))
        return [e["key"] for e in db.entries()]

    assert write([0.02, 0.03]) == ["cyl+0.02", "cyl+0.03"]
    size = db.index_path.stat().st_size
    assert write([0.02, -0.3]) == ["cyl+0.02"]  # an impossible radius: skipped
    assert db.index_path.stat().st_size == size
    assert write([0.02, 0.03, 0.04]) == ["cyl+0.02", "cyl+0.03", "cyl+0.04"]
    db.entries()[0]["accepted"] = -1
    assert db.entries()[0]["accepted"] == 5
    assert db.match(Cylinder(0.04, 0.1)).match is MatchKind.KNOWN
