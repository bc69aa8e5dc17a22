"""Atomic writes: several outputs committed together, leftovers of killed writers removed,
output paths checked before any work (graspsim/_atomic.py)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from graspsim._atomic import (
    STALE_SECONDS,
    atomic_path,
    atomic_paths,
    check_folder,
    check_output,
    remove_stale_temps,
    staged_folder,
)
from graspsim.errors import MapFileError, OutputPathError

REPO = Path(__file__).resolve().parents[1]


def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_sigkilled_writer_leaves_a_temp_that_the_next_write_removes(tmp_path):
    target = tmp_path / "m.h5"
    target.write_bytes(b"old")
    code = ("import sys, time\n"
            "from graspsim._atomic import atomic_path\n"
            f"with atomic_path({str(target)!r}) as tmp:\n"
            "    tmp.write_bytes(b'half a map')\n"
            "    print('ready', flush=True)\n"
            "    time.sleep(120)\n")
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=env, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        os.kill(proc.pid, signal.SIGKILL)  # no cleanup handler runs
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    left = _temps(tmp_path)
    assert len(left) == 1 and left[0].startswith(f".m.h5.{proc.pid}.")  # the writer's pid is in the name
    assert target.read_bytes() == b"old"  # the killed write never replaced the target
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new" and _temps(tmp_path) == []


def test_temps_of_live_writers_are_kept_and_old_ones_removed(tmp_path):
    target = tmp_path / "m.h5"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f".m.h5.{sleeper.pid}.abc123.tmp.h5"
        live.write_bytes(b"being written")
        legacy_fresh = tmp_path / ".m.h5.k2j3h4g5.tmp"  # earlier versions: no pid in the name
        legacy_old = tmp_path / ".m.h5.x9y8z7w6.tmp"
        other_target = tmp_path / ".n.h5.1.abc.tmp.h5"
        for p in (legacy_fresh, legacy_old, other_target):
            p.write_bytes(b"x")
        past = time.time() - STALE_SECONDS - 60
        os.utime(legacy_old, (past, past))
        os.utime(other_target, (past, past))
        removed = remove_stale_temps(target)
        assert removed == [legacy_old]
        assert live.exists() and legacy_fresh.exists() and other_target.exists()
    finally:
        sleeper.kill()
        sleeper.wait()
    assert tmp_path / f".m.h5.{sleeper.pid}.abc123.tmp.h5" in remove_stale_temps(target)


def test_several_outputs_are_committed_together_or_not_at_all(tmp_path):
    a, b = tmp_path / "map.h5", tmp_path / "plot.png"
    a.write_text("old map")
    with pytest.raises(RuntimeError):
        with atomic_paths([a, b]) as (ta, tb):
            ta.write_text("new map")
            raise RuntimeError("the plot failed")
    assert a.read_text() == "old map" and not b.exists() and _temps(tmp_path) == []
    with atomic_paths([a, b]) as (ta, tb):
        assert ta.suffix == ".h5" and tb.suffix == ".png"  # format-by-extension writers work
        ta.write_text("new map")
        tb.write_text("new plot")
    assert a.read_text() == "new map" and b.read_text() == "new plot"


def test_writers_inside_an_atomic_block_write_its_temporary_directly(tmp_path):
    """save_map / plot_map called on a command's temporary make no second, nested one
    (which no later write of the target would recognise as its leftover)."""
    target = tmp_path / "m.h5"
    with atomic_paths([target]) as (tmp,):
        with atomic_path(tmp) as inner:
            assert inner == tmp
            inner.write_text("map")
            assert _temps(tmp_path) == [tmp.name]
    assert target.read_text() == "map" and _temps(tmp_path) == []


def test_written_files_get_normal_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "new.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert (tmp_path / "new.txt").stat().st_mode & 0o777 == 0o644  # not mkstemp's 0o600


def test_check_output_refuses_what_cannot_be_written(tmp_path):
    (tmp_path / "adir").mkdir()
    with pytest.raises(OutputPathError, match="is a directory"):
        check_output(tmp_path / "adir", "map")
    with pytest.raises(OutputPathError, match="folder .* does not exist"):
        check_output(tmp_path / "nodir" / "x.png", "plot")
    assert check_output(tmp_path / "ok.h5") == tmp_path / "ok.h5"
    assert list(tmp_path.iterdir()) == [tmp_path / "adir"]  # the probe left nothing
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OutputPathError, match="not a folder"):
        check_folder(tmp_path / "afile" / "renders")
    assert check_folder(tmp_path / "new" / "renders") == tmp_path / "new" / "renders"
    assert not (tmp_path / "new").exists()  # checked, not created
    with pytest.raises(MapFileError, match="does not exist"):
        with atomic_path(tmp_path / "nodir" / "m.h5"):
            pass


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs Linux /proc")
def test_check_output_tries_the_folder_rather_than_trusting_permission_bits():
    with pytest.raises(OutputPathError, match="cannot write"):  # even root cannot create files here
        check_output("/proc/graspsim-test.h5", "map")


def test_a_staged_folder_reaches_its_target_only_when_the_block_succeeds(tmp_path):
    """Outputs written while a command runs (scene's per-step figures) land in the target
    folder on success only: a failure leaves no new folder, no new file and no replaced
    one, and no staging folder behind."""
    target = tmp_path / "new" / "figures"
    with pytest.raises(RuntimeError), staged_folder(target) as stage:
        (stage / "step00.png").write_text("a")
        raise RuntimeError("the run failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # not even the parent
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "step00.png").write_text("old")
    with pytest.raises(RuntimeError), staged_folder(kept) as stage:
        (stage / "step00.png").write_text("new")
        raise RuntimeError("the run failed")
    assert [p.name for p in kept.iterdir()] == ["step00.png"] and (kept / "step00.png").read_text() == "old"
    with staged_folder(target) as stage:
        (stage / "sub").mkdir()
        (stage / "step00.png").write_text("a")
        (stage / "sub" / "x.json").write_text("b")
    assert (target / "step00.png").read_text() == "a" and (target / "sub" / "x.json").read_text() == "b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept", "new"]  # the staging folder is gone
