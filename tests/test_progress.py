"""Progress bars on stderr (graspsim._progress): drawn only on a terminal and only once
their delay has passed, so cached work stays quiet; the mesh preparation and the FS map
builds of ``graspsim/ClutterClear-v0``'s resets draw them (``progress=True``, the
default), and leave a bar the caller set alone."""

from __future__ import annotations

import io
import math
import sys
import time

import gymnasium as gym
import pytest

import graspsim  # noqa: F401  (registers the environments)
from graspsim._progress import map_build_bar, progress
from graspsim.envs import CLUTTER_CLEAR_ID
from graspsim.maps.database import BUILD_PROGRESS
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _terminal(monkeypatch) -> _Terminal:
    """stderr as a terminal, for the rest of the test (set in the test itself: pytest's
    output capture replaces sys.stderr again after fixtures are set up)."""
    out = _Terminal()
    monkeypatch.setattr(sys, "stderr", out)
    return out


def test_a_bar_is_drawn_on_a_terminal_only_and_not_before_its_delay(monkeypatch):
    terminal = _terminal(monkeypatch)
    with progress(3, "quick", unit="step", delay=30.0, tick=0.01) as bar:
        bar.set_postfix_str("a", refresh=False)
        time.sleep(0.05)  # the redraw thread ticks, the delay has not passed
        bar.update(3)
    with map_build_bar(Box(0.05, 0.05, 0.05), delay=30.0) as report:
        report(0.5)
        report(1.0)
    assert terminal.getvalue() == ""
    with progress(3, "slow", unit="step") as bar:
        bar.update(3)
    assert "slow" in terminal.getvalue()
    with map_build_bar(Box(0.05, 0.05, 0.05)) as report:
        report(0.5)
    assert "building the FS map of box" in terminal.getvalue()
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # not a terminal: nothing
    with progress(3, "piped", unit="step") as bar:
        bar.update(3)
    assert sys.stderr.getvalue() == ""


def test_a_folder_of_meshes_is_prepared_behind_a_bar(tmp_path, monkeypatch):
    import trimesh

    from graspsim.tabletop.scene_objects import prepare_objects

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))
    d = tmp_path / "objs"
    d.mkdir()
    trimesh.creation.box([0.05, 0.04, 0.08]).export(d / "box.stl")
    terminal = _terminal(monkeypatch)
    assert prepare_objects(str(d), progress=True, delay=60.0) == ["box"]
    assert terminal.getvalue() == ""  # quick: under its delay
    assert prepare_objects(str(d), progress=True) == ["box"]
    assert "preparing meshes" in terminal.getvalue()


@pytest.fixture
def no_caller_bar():
    """BUILD_PROGRESS unset for the test (a command run in this process before sets it for
    the rest of the process, as ``graspsim`` does on a terminal), restored after."""
    token = BUILD_PROGRESS.set(None)
    yield
    BUILD_PROGRESS.reset(token)


@pytest.mark.parametrize("on", [True, False])
def test_the_clutter_env_shows_its_map_builds_unless_told_not_to(on, tmp_path, monkeypatch, no_caller_bar):
    """A first reset on an empty database builds maps of new sizes: with ``progress`` each
    build is a bar (the delay set to 0 here), without it stderr stays empty; a bar the
    caller set through BUILD_PROGRESS is the one used, either way."""
    import graspsim.envs.clutter_clear as cc

    monkeypatch.setattr(cc, "_BAR_DELAY", 0.0)
    terminal = _terminal(monkeypatch)
    env = gym.make(CLUTTER_CLEAR_ID, n_objects=1, kind="packed", object_set="primitives", db_root=str(tmp_path / "db"),
                   map_config=FAST, n_candidates=4, cloud_size=64, progress=on).unwrapped
    env.reset(seed=5)
    assert ("building the FS map of" in terminal.getvalue()) is on
    assert BUILD_PROGRESS.get() is None  # set for the reset only
    env.close()

    seen = []

    def mine(shape):
        seen.append(shape)
        return map_build_bar(shape, delay=1e9)

    token = BUILD_PROGRESS.set(mine)
    try:
        env = gym.make(CLUTTER_CLEAR_ID, n_objects=1, kind="packed", object_set="primitives",
                       db_root=str(tmp_path / "db2"), map_config=FAST, n_candidates=4, cloud_size=64,
                       progress=on).unwrapped
        env.reset(seed=5)
        env.close()
    finally:
        BUILD_PROGRESS.reset(token)
    assert seen  # the caller's own bar, not replaced
