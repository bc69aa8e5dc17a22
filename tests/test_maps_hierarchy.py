"""The collision sample hierarchy's patches (:mod:`graspsim.maps.hierarchy`): the
compiled patch measurement gives numpy's answer (the hierarchy decides which poses
collide, and a scene plan must not change with how it is computed: the same order and
patch starts exactly, the patch sizes to a few units in the last place, as numpy's SIMD
paths differ between CPUs), and every child lies within its parent's patch."""

import numpy as np
import pytest

from graspsim.maps.hierarchy import _patches, build_levels, clusters
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Cone, Cylinder


def _numpy_patches(parents, children, parent_normals, grow, parent):
    """The numpy implementation the compiled one replaced (the reference)."""
    order = np.argsort(parent, kind="stable")
    parent = parent[order]
    d = children[order] - parents[parent]
    n = parent_normals[parent]
    h = np.sum(d * n, axis=1)
    rt = np.linalg.norm(d - h[:, None] * n, axis=1)
    P = len(parents)
    g = np.broadcast_to(np.asarray(grow, float), (len(children),))[order]
    counts = np.bincount(parent, minlength=P)
    RT, HN = np.zeros(P), np.zeros(P)
    has = counts > 0
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])[has]
    RT[has] = np.maximum.reduceat(rt + g, first)
    HN[has] = np.maximum.reduceat(np.abs(h) + g, first)
    return order, RT, HN, np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


@pytest.mark.parametrize("shape", [Cylinder(0.031, 0.093), Box(0.021, 0.047, 0.066), Cone(0.03, 0.018, 0.07)])
def test_compiled_patches_equal_numpy(shape):
    coarse, mid = shape.surface_samples(0.01), shape.surface_samples(0.004)
    rng = np.random.default_rng(1)
    cases = [(coarse.points, mid.points, coarse.normals, 0.0, coarse.locate(mid)),
             (coarse.points, mid.points, coarse.normals, rng.random(len(mid)) * 1e-3, coarse.locate(mid))]
    # a parent with no children, and children given out of parent order
    parent = rng.integers(1, len(coarse), len(mid))
    cases.append((coarse.points, mid.points, coarse.normals, 0.0, parent))
    for args in cases:
        got, want = _patches(*args), _numpy_patches(*args)
        for a, b in zip(got, want):
            assert a.dtype == b.dtype
            if a.dtype.kind == "f":
                np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-16)
            else:
                np.testing.assert_array_equal(a, b)
    order, RT, HN, start = _patches(*cases[2])
    assert RT[0] == HN[0] == 0.0 and start[1] == 0
    assert np.all(np.diff(parent[order]) >= 0)  # grouped by parent, stable within
    assert all(np.all(np.diff(order[start[p]:start[p + 1]]) > 0) for p in range(len(coarse)))


def test_every_fine_sample_lies_within_its_parents_patch():
    lv = build_levels(Cylinder(0.02, 0.06), MapConfig())
    counts = np.diff(lv["fstart"])
    M, NM = np.repeat(lv["M"], counts, axis=0), np.repeat(lv["NM"], counts, axis=0)
    d = lv["F"] - M
    h = np.sum(d * NM, axis=1)
    tangential = np.linalg.norm(d - h[:, None] * NM, axis=1)
    assert np.all(tangential <= np.repeat(lv["RTM"], counts) + 1e-12)
    assert np.all(np.abs(h) <= np.repeat(lv["HNM"], counts) + 1e-12)


def _python_clusters(points, reach, size=16, margin=1e-5):
    """The numpy implementation the compiled one replaced (the reference)."""
    points = np.asarray(points, float)
    leaves, todo = [], [np.arange(len(points))]
    while todo:
        ids = todo.pop()
        if len(ids) <= size:
            leaves.append(ids)
            continue
        half = np.argsort(points[ids, int(np.argmax(np.ptp(points[ids], axis=0)))], kind="stable")
        todo += [ids[half[len(ids) // 2:]], ids[half[:len(ids) // 2]]]
    leaves = [x for x in leaves if len(x)]
    order = np.concatenate(leaves).astype(np.int64) if leaves else np.zeros(0, np.int64)
    start = np.concatenate([[0], np.cumsum([len(x) for x in leaves])]).astype(np.int64)
    centre = np.array([0.5 * (points[x].min(axis=0) + points[x].max(axis=0)) for x in leaves]).reshape(-1, 3)
    radius = np.array([np.sqrt(np.max(np.sum((points[x] - c) ** 2, axis=1))) for x, c in zip(leaves, centre)])
    reach_max = np.array([np.max(reach[x]) for x in leaves])
    return order, start, centre, radius + margin, reach_max + margin


def test_compiled_clusters_equal_numpy_to_the_bit():
    """The sweep's clusters decide which samples it passes over: the compiled tree must
    give numpy's order, leaves, centres, radii and reaches exactly (ties in the sort
    and in the widest extent included)."""
    rng = np.random.default_rng(3)
    cases = []
    for shape in (Cylinder(0.031, 0.093), Box(0.021, 0.047, 0.066), Cone(0.03, 0.018, 0.07)):
        s = shape.surface_samples(0.004)
        cases.append((s.points, s.tangent_radius + s.normal_height))
    cases += [(rng.normal(size=(n, 3)) * rng.uniform(1e-3, 1.0, 3), rng.random(n)) for n in (0, 1, 16, 17, 999)]
    cases.append((np.round(rng.normal(size=(400, 3)), 1), rng.random(400)))  # many equal coordinates
    cases.append((np.repeat(rng.normal(size=(1, 3)), 40, axis=0), rng.random(40)))  # no extent at all
    for points, reach in cases:
        for a, b in zip(clusters(points, reach), _python_clusters(points, reach)):
            assert a.dtype == b.dtype and a.shape == b.shape
            assert a.tobytes() == b.tobytes()


def test_compiled_regroup_equals_the_numpy_gather():
    """build_levels puts the fine samples in their middle parents' new order with the
    compiled regroup: the same rows and offsets as numpy's gather (the reference),
    parents without children included."""
    from graspsim.maps._hierarchy_kernel import regroup

    rng = np.random.default_rng(5)
    K, P = 5000, 400
    parent = rng.integers(0, P, K)
    parent[parent == 7] = 8  # a parent with no child
    order = np.argsort(parent, kind="stable").astype(np.int64)
    fstart = np.concatenate([[0], np.cumsum(np.bincount(parent, minlength=P))]).astype(np.int64)
    m_order = rng.permutation(P).astype(np.int64)
    pts, nrm, rt, hn = rng.random((K, 3)), rng.random((K, 3)), rng.random(K), rng.random(K)
    counts = np.diff(fstart)[m_order]
    start_new = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    within = np.arange(start_new[-1]) - np.repeat(start_new[:-1], counts)
    fsel = order[np.repeat(fstart[:-1][m_order], counts) + within]
    got = regroup(order, fstart, m_order, pts, nrm, rt, hn)
    for a, b in zip(got, (pts[fsel], nrm[fsel], rt[fsel], hn[fsel], start_new)):
        assert a.dtype == b.dtype and np.array_equal(a, b)
