"""Executors: the same tasks give the same results locally and on Ray."""

import math
import sys

import numpy as np
import pytest

from graspsim.errors import DependencyNotInstalled, InvalidParameterError
from graspsim.executors import ProcessExecutor, SerialExecutor, make_executor
from graspsim.maps.database import MapDatabase
from graspsim.maps.io import load_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Cylinder, Sphere

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def ray_executor():
    pytest.importorskip("ray", reason="Ray tests need the [ray] extra; CI installs it")
    ex = make_executor("ray", workers=2)
    yield ex
    ex.close()


# workers import task functions by name, so tests use library (or builtin) functions
def test_serial_and_local_agree():
    tasks = list(range(8))
    with ProcessExecutor(2) as ex:
        assert ex.map(math.factorial, tasks) == SerialExecutor().map(math.factorial, tasks)


@pytest.mark.slow
def test_ray_agrees(ray_executor):
    tasks = list(range(8))
    assert ray_executor.map(math.factorial, tasks) == [math.factorial(t) for t in tasks]


@pytest.mark.slow
def test_database_build_local_and_ray_identical(tmp_path, ray_executor):
    shapes = [Cylinder(0.02, 0.1), Sphere(0.03)]
    a = MapDatabase(tmp_path / "a", config=FAST)
    a.build(shapes)  # serial, in this process
    b = MapDatabase(tmp_path / "b", config=FAST)
    b.build(shapes, executor=ray_executor)
    c = MapDatabase(tmp_path / "c", config=FAST)
    with ProcessExecutor(2) as ex:
        c.build(shapes, executor=ex)
    for s in shapes:
        ma = load_map(a.path(s))
        for other in (b, c):
            mb = load_map(other.path(s))
            for k, v in ma.columns().items():
                np.testing.assert_array_equal(v, getattr(mb, k))
    assert len(b.entries()) == 2 and len(c.entries()) == 2


def test_bad_executor_and_missing_ray(monkeypatch):
    with pytest.raises(InvalidParameterError, match="valid"):
        make_executor("cluster")
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(DependencyNotInstalled, match="pip install"):
        make_executor("ray")


def test_ray_workers_get_the_pinned_blas_kernels(monkeypatch):
    """A Ray cluster's workers are told graspsim._blas's OPENBLAS_CORETYPE (they import
    numpy before any task runs, so graspsim cannot pin them there)."""
    import types

    from graspsim.executors import RayExecutor

    seen = {}
    fake = types.SimpleNamespace(is_initialized=lambda: False, init=lambda **kw: seen.update(kw))
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setenv("OPENBLAS_CORETYPE", "Haswell")
    RayExecutor(address="ray://head:10001")
    assert seen["address"] == "ray://head:10001"
    assert seen["runtime_env"] == {"env_vars": {"OPENBLAS_CORETYPE": "Haswell"}}
    seen.clear()
    monkeypatch.delenv("OPENBLAS_CORETYPE")
    RayExecutor(num_cpus=1)
    assert "runtime_env" not in seen
