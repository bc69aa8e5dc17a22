"""The one rule for where graspsim's caches live (graspsim._cache), and the caches that use it."""

from __future__ import annotations

import pytest

from graspsim._cache import user_cache


@pytest.fixture
def env(monkeypatch, tmp_path):
    monkeypatch.delenv("GRASPSIM_CACHE_DIR", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    return monkeypatch, tmp_path


def test_rule_order(env):
    mp, tmp = env
    assert user_cache("reach") == tmp / "home" / ".cache" / "graspsim" / "reach"
    mp.setenv("XDG_CACHE_HOME", "relative/cache")  # not absolute: ignored, as the XDG rule says
    assert user_cache("reach") == tmp / "home" / ".cache" / "graspsim" / "reach"
    mp.setenv("XDG_CACHE_HOME", str(tmp / "xdg"))
    assert user_cache("coacd") == tmp / "xdg" / "graspsim" / "coacd"
    mp.setenv("GRASPSIM_CACHE_DIR", str(tmp / "own"))  # the project's own setting wins
    assert user_cache("grippers") == tmp / "own" / "grippers"


def test_caches_share_the_rule(env):
    from graspsim.grippers import model_file
    from graspsim.robots.capability import default_cache_dir as reach_cache
    from graspsim.sim.meshes import default_cache_dir as mesh_cache

    mp, tmp = env
    mp.setenv("XDG_CACHE_HOME", str(tmp / "xdg"))
    assert mesh_cache() == tmp / "xdg" / "graspsim" / "coacd"
    assert reach_cache() == tmp / "xdg" / "graspsim" / "reach"
    model_file._measured.cache_clear()  # measure again in this process: the result goes to the cache folder
    model_file.vendored_gripper("franka_hand")
    assert list((tmp / "xdg" / "graspsim" / "grippers").glob("*.json"))
    model_file._measured.cache_clear()  # later tests measure with their own environment
