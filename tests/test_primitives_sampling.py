"""Disk sampling (:func:`graspsim.primitives._sampling.disk_samples`): the samples of
all rings made in one pass are those of the ring-by-ring construction (every collision
hierarchy, and so every map and scene plan, is built on them; to the bit on the builds
this was written on, to a few units in the last place here, as numpy's SIMD sin and cos
differ between CPUs), and the layout finds each sample's own cell."""

import math

import numpy as np
import pytest

from graspsim.primitives._sampling import disk_samples


def _ring_by_ring(center, u, v, radius, step):
    """The reference: each ring's samples made on their own (the former implementation)."""
    nr = math.ceil(radius / step - 1e-9) or 1
    dr = radius / nr
    pts, areas, uv = [], [], []
    for k in range(nr):
        rho = (k + 0.5) * dr
        nt = max(3, math.ceil(2.0 * math.pi * (rho + dr / 2) / step - 1e-9))
        dt = 2.0 * math.pi / nt
        th = (np.arange(nt) + 0.5) * dt
        pts.append(center + rho * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v))
        areas.append(np.full(nt, 2.0 * math.pi * rho * dr / nt))
        uv.append(np.column_stack([np.full(nt, rho), th]))
    return np.concatenate(pts), np.concatenate(areas), np.concatenate(uv)


@pytest.mark.parametrize("radius,step", [(0.037, 0.0006), (0.02, 0.0013), (0.051, 0.004), (0.004, 0.011)])
def test_disk_samples_equal_the_ring_by_ring_construction(radius, step):
    center = np.array([0.01, -0.02, 0.066])
    u, v = np.array([0.6, 0.0, 0.8]), np.array([0.0, 1.0, 0.0])  # off the axes: every product counts
    s = disk_samples(center, u, v, radius, step)
    pts, areas, uv = _ring_by_ring(center, u, v, radius, step)
    for got, want in ((s.points, pts), (s.areas, areas), (s.uv, uv)):
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-16)
    assert math.isclose(s.areas.sum(), math.pi * radius**2, rel_tol=1e-12)
    assert np.all(np.linalg.norm(s.points - center, axis=1) <= radius)
    np.testing.assert_array_equal(s.grids[0].locate(s.uv), np.arange(len(s)))  # each sample in its own cell
    assert np.all(s.tangent_radius <= s.cover_radius) and s.cover_radius <= step


@pytest.mark.parametrize("shape", ["box", "cylinder", "cone", "half_toroid"])
def test_locate_finds_the_same_cells_in_any_sample_order(shape):
    """A sampling laid out patch by patch (as the samplers make it) is located on each
    patch's slice; shuffled, patch by patch with masks: the same cell for every sample,
    and each cell lies on the sample's own patch."""
    from dataclasses import replace

    from graspsim.primitives import make_primitive

    dims = {"box": dict(x=0.03, y=0.05, z=0.08), "cylinder": dict(radius=0.02, height=0.07),
            "cone": dict(bottom_radius=0.03, top_radius=0.01, height=0.06),
            "half_toroid": dict(major_radius=0.04, minor_radius=0.01)}[shape]
    prim = make_primitive(shape, **dims)
    coarse, fine = prim.surface_samples(0.01), prim.surface_samples(0.003)
    assert fine._patch_spans() is not None  # the samplers' layout: the slice path
    cells = coarse.locate(fine)
    perm = np.random.default_rng(0).permutation(len(fine))
    shuffled = replace(fine, points=fine.points[perm], patch=fine.patch[perm], uv=fine.uv[perm])
    assert shuffled._patch_spans() is None  # the mask path
    np.testing.assert_array_equal(coarse.locate(shuffled), cells[perm])
    np.testing.assert_array_equal(coarse.patch[cells], fine.patch)


def test_assembled_patches_equal_the_concatenation_of_their_own_samples():
    """assemble() makes several patches' samples straight into one set of arrays: the
    same arrays, patch indices, cell layouts and cover as concatenating each patch's
    own samples (every primitive's sampling, and so every collision hierarchy, is made
    this way)."""
    from graspsim.primitives._sampling import assemble, disk_part, rect_part, revolution_part
    from graspsim.primitives.samples import SurfaceSamples

    def profile(s):
        return 0.02 + 0.1 * s, s, np.full_like(s, 0.99), np.full_like(s, -0.1)

    x, y, z = np.eye(3)
    parts = [revolution_part(profile, 0.05, 0.002), disk_part(np.array([0.0, 0.0, 0.05]), x, y, 0.025, 0.002),
             rect_part(np.array([0.01, 0.0, -0.02]), y, z, 0.03, 0.017, 0.002),
             revolution_part(profile, 0.04, 0.003, sweep=math.pi)]
    got = assemble(parts)
    want = SurfaceSamples.concat([assemble([p]) for p in parts])
    for f in ("points", "normals", "areas", "tangent_radius", "normal_height", "patch", "uv"):
        a, b = getattr(got, f), getattr(want, f)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), f
    assert got.grids == want.grids and got.cover_radius == want.cover_radius
    assert len({g.offset for g in got.grids}) == 4
