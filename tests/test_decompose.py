"""Robust identification: paper and robust presets, data-scaled acceptance, the
decomposition that keeps going (axial pieces, peeled handles, merges, scored
candidates), on synthetic compounds with known answers; a pure primitive is never
split."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from graspsim.errors import InvalidParameterError
from graspsim.perception import IdentificationStatus, IdentifyConfig, identify
from graspsim.perception.acceptance import band_rate, decomposition_score, inlier_band
from graspsim.perception.mlesac import fit_from
from graspsim.perception.profile import piecewise_linear, profile_segments
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Sphere, synthetic_cloud
from graspsim.transforms import make_transform, random_rotation


def _posed(shape, seed, **kw):
    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), rng.uniform(-0.3, 0.3, 3))
    return synthetic_cloud(shape, rng, T_world_obj=T, **({"resolution": 0.003, "noise": 0.001} | kw)).points


def short_neck_bottle() -> Compound:
    """The issue's bottle: body r 3 cm x 14 cm, neck r 1.2 cm x 4 cm on top."""
    return Compound.from_parts([Cylinder(0.03, 0.14), Cylinder(0.012, 0.04)],
                               [make_transform(np.eye(3), [0, 0, 0.07]), make_transform(np.eye(3), [0, 0, 0.16])])


def mug() -> Compound:
    """A mug: cylinder r 4 cm x 10 cm with a half-toroid handle (R 2.8 cm, r 0.7 cm) on its side."""
    handle = HalfToroid(0.028, 0.007)
    R = np.column_stack([[0, 0, 1], [1, 0, 0], [0, 1, 0]])  # ring in the xz plane, kept half towards +x
    return Compound.from_parts([Cylinder(0.04, 0.10), handle],
                               [make_transform(np.eye(3), [0, 0, 0.05]),
                                make_transform(R, np.array([0.037, 0, 0.05]) + R @ handle.com_geo)])


def rounded_box(size, radius: float, n: int, noise: float, rng: np.random.Generator) -> np.ndarray:
    """n points on a box of edges ``size`` [m] with edges and corners rounded to ``radius``."""
    half = np.asarray(size, float) / 2
    inner = half - radius
    box = trimesh.creation.box(extents=2 * half)
    f = rng.choice(len(box.faces), size=n, p=box.area_faces / box.area)
    tri = box.triangles[f]
    u, v = rng.random((2, n))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    q = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    c = np.clip(q, -inner, inner)
    d = q - c
    p = c + d / np.linalg.norm(d, axis=1, keepdims=True) * radius
    return p + rng.normal(0.0, noise, p.shape)


def _kinds(res) -> list[str]:
    return sorted(p.shape.value for p in res.parts)


# --- presets ---------------------------------------------------------------------------

def test_presets_name_the_mode_and_the_default_is_robust():
    assert IdentifyConfig().mode == "robust" and IdentifyConfig().is_robust
    paper = IdentifyConfig.preset("paper", repetitions=20)
    assert paper.mode == "paper" and paper.repetitions == 20 and paper.theta == 0.5 and paper.min_fit_rate == 0.85
    with pytest.raises(InvalidParameterError, match="mode"):
        IdentifyConfig.preset("clever")
    with pytest.raises(InvalidParameterError, match="approx_fit_rate"):
        IdentifyConfig(approx_fit_rate=0.9)


def test_the_result_records_its_mode():
    pts = _posed(Sphere(0.03), 0)
    for mode in ("paper", "robust"):
        res = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig.preset(mode))
        assert res.mode == mode and res.to_dict()["mode"] == mode and res.to_dict()["uncovered"] == []


# --- acceptance that scales with the data ----------------------------------------------

def test_the_inlier_band_grows_with_noise_and_spacing():
    assert inlier_band(0.001, 0.0) == pytest.approx(0.003)
    assert inlier_band(0.002, 0.0) > inlier_band(0.001, 0.0)
    assert inlier_band(0.001, 0.006) > inlier_band(0.001, 0.002) > inlier_band(0.001, 0.0)


def test_the_score_pays_for_a_part_only_when_it_explains_points():
    rng = np.random.default_rng(0)
    body, neck = Cylinder(0.03, 0.14), Cylinder(0.012, 0.04)
    pts = synthetic_cloud(short_neck_bottle(), rng, resolution=0.003, noise=0.001).points
    T = short_neck_bottle().poses
    fb = fit_from("cylinder", pts, T[0][:3, :3], T[0][:3, 3], [body.radius, body.height], sigma=0.001, refine=False)
    fn = fit_from("cylinder", pts, T[1][:3, :3], T[1][:3, 3], [neck.radius, neck.height], sigma=0.001, refine=False)
    band = inlier_band(0.001, 0.003)
    assert decomposition_score([fb, fn], pts, band) < decomposition_score([fb], pts, band)
    # a duplicate part explains nothing more: it costs its parameters
    assert decomposition_score([fb, fn, fn], pts, band) > decomposition_score([fb, fn], pts, band)
    assert band_rate(fb, pts, band) < 0.95 < max(band_rate(fb, pts, band) + band_rate(fn, pts, band), 1.0)


# --- the radius profile ------------------------------------------------------------------

def test_piecewise_linear_finds_the_known_breaks():
    x = np.linspace(0, 1, 30)
    y = np.where(x < 0.5, 3.0, np.where(x < 0.6, 3.0 - 18 * (x - 0.5), 1.2))
    fits = piecewise_linear(x, y, np.ones_like(x), 4)
    assert fits[3][0] < 1e-3 * fits[1][0]
    cuts = x[fits[3][1]]
    assert np.all(np.abs(np.sort(cuts) - [0.5, 0.6]) < 0.05)


def test_a_cylinder_profile_is_one_piece_and_a_bottle_profile_is_not():
    rng = np.random.default_rng(2)
    cyl = synthetic_cloud(Cylinder(0.03, 0.15), rng, resolution=0.003, noise=0.001).points
    axis = np.array([0.0, 0.0, 1.0])
    assert profile_segments(cyl, np.zeros(3), axis, spacing=0.003, scale=0.0015) is None
    bot = synthetic_cloud(short_neck_bottle(), rng, resolution=0.003, noise=0.001).points
    segs = profile_segments(bot, np.zeros(3), axis, spacing=0.003, scale=0.0015)
    assert segs is not None and 2 <= len(segs) <= 3
    top = max(segs, key=lambda s: bot[s, 2].mean())
    assert np.quantile(np.linalg.norm(bot[top, :2], axis=1), 0.5) < 0.02  # the neck


# --- compounds with known answers --------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1])
def test_a_bottle_with_a_short_neck_is_two_or_three_cylinders(seed):
    pts = _posed(short_neck_bottle(), seed)
    res = identify(pts, rng=np.random.default_rng(seed))
    assert res.status is IdentificationStatus.IDENTIFIED
    assert 2 <= len(res.parts) <= 3 and all(k in ("cylinder", "cone") for k in _kinds(res))
    assert _kinds(res).count("cylinder") >= 2
    radii = sorted(p.dims.get("radius", 0.0) for p in res.parts)
    assert radii[0] == pytest.approx(0.012, abs=0.003) and radii[-1] == pytest.approx(0.03, abs=0.003)


@pytest.mark.slow
def test_a_mug_is_a_cylinder_and_a_half_toroid():
    """Over eight poses: the paper accepts the body and forgets the handle; robust mode
    peels the handle off every time, as a half-toroid at least six times in eight (its
    points fit a box about as well in the others; before the noise estimate was made
    robust, three in eight)."""
    toroids = 0
    for seed in range(8):
        pts = _posed(mug(), seed)
        if seed < 2:
            paper = identify(pts, rng=np.random.default_rng(seed), config=IdentifyConfig.preset("paper"))
            assert _kinds(paper) == ["cylinder"]
        res = identify(pts, rng=np.random.default_rng(seed))
        assert len(res.parts) == 2 and "cylinder" in _kinds(res)
        for handle in [p for p in res.parts if p.shape.value == "half_toroid"]:
            toroids += 1
            assert handle.dims["major_radius"] == pytest.approx(0.028, abs=0.004)
            assert handle.dims["minor_radius"] == pytest.approx(0.007, abs=0.002)
    assert toroids >= 6


def test_a_rounded_box_is_a_box_in_robust_mode_only():
    pts = rounded_box((0.06, 0.06, 0.09), 0.012, 2000, 0.001, np.random.default_rng(1))
    paper = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig.preset("paper"))
    assert paper.status is IdentificationStatus.FAILED
    res = identify(pts, rng=np.random.default_rng(0))
    assert res.status is IdentificationStatus.IDENTIFIED and _kinds(res) == ["box"]
    assert sorted(res.parts[0].dims.values()) == pytest.approx([0.06, 0.06, 0.09], abs=0.004)
    assert res.parts[0].band_rate >= 0.85 > res.parts[0].fit_rate - 0.2


def test_a_cluster_explained_only_approximately_is_flagged_and_listed():
    # a 6 x 6 x 9 cm box with 2.5 cm rounding: no primitive is within the band everywhere
    pts = rounded_box((0.06, 0.06, 0.09), 0.025, 2000, 0.001, np.random.default_rng(3))
    res = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(settle_rate=0.999))
    assert res.parts, "something must be used"
    if res.status is IdentificationStatus.PARTIAL:
        assert res.uncovered and all(u["points"] > 0 and u["reason"] for u in res.uncovered)
        flagged = [p for p in res.parts if p.approximate]
        assert all(0.6 <= p.band_rate < 0.85 for p in flagged)
    else:
        assert not any(p.approximate for p in res.parts) and res.uncovered == []


# --- property: a pure primitive is never split ---------------------------------------------

_PRIMS = st.one_of(
    st.builds(Box, st.floats(0.03, 0.08), st.floats(0.03, 0.08), st.floats(0.03, 0.12)),
    st.builds(Cylinder, st.floats(0.015, 0.045), st.floats(0.04, 0.15)),
    st.builds(Sphere, st.floats(0.02, 0.05)),
    st.builds(lambda r, f, h: Cone(r, f * r, h), st.floats(0.025, 0.045), st.floats(0.2, 0.6), st.floats(0.05, 0.12)),
)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(shape=_PRIMS, seed=st.integers(0, 2**16))
def test_a_pure_primitive_is_never_split(shape, seed):
    pts = _posed(shape, seed, resolution=0.004)
    res = identify(pts, rng=np.random.default_rng(seed))
    assert len(res.parts) == 1 and not res.unidentified, [p.shape.value for p in res.parts]


def test_over_split_neighbours_of_one_kind_are_merged():
    from scipy.spatial import cKDTree

    from graspsim.perception import decompose as dc
    from graspsim.perception.identify import _prepare

    cfg = IdentifyConfig()
    pts = _posed(Cylinder(0.03, 0.12), 4)
    cloud = _prepare(pts, cfg, cfg.max_points)[0]
    spacing = float(np.median(cKDTree(cloud.points).query(cloud.points, k=2)[0][:, 1]))
    ctx = dc._Ctx(cloud, np.random.default_rng(0), cfg, spacing, inlier_band(cloud.noise, spacing))
    axis = np.linalg.svd(cloud.points - cloud.points.mean(0))[2][0]
    z = (cloud.points - cloud.points.mean(0)) @ axis
    halves = [np.flatnonzero(z < 0), np.flatnonzero(z >= 0)]
    parts = [dc._leaf(ctx, h) for h in halves]
    assert [p.shape.value for p in parts] == ["cylinder", "cylinder"]
    merged = dc._merged(ctx, [(p, None) for p in parts])
    assert len(merged) == 1 and merged[0][0].shape.value == "cylinder"
    assert merged[0][0].dims["height"] == pytest.approx(0.12, abs=0.006)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_noise_check_passes_a_thin_body_and_refuses_a_noisy_one_in_robust_mode(seed):
    """Issue 15: E09's domino (and lego, mug, teddy) got no grasp in robust mode: the
    noise estimate, inflated by thin walls, failed the check (noise <= 3 % of the
    cluster's size). Paper mode keeps the paper's estimate and refuses it as before; a
    cloud that really is too noisy is refused in both."""
    rng = np.random.default_rng(seed)
    p = Box(0.00635, 0.0254, 0.0508).surface_samples(0.001).points
    p = p[rng.choice(len(p), 400, replace=False)]
    clean, loud = p + rng.normal(0.0, 0.001, p.shape), p + rng.normal(0.0, 0.0027, p.shape)
    robust = identify(clean, rng=np.random.default_rng(0), config=IdentifyConfig.preset("robust"))
    assert robust.status is IdentificationStatus.IDENTIFIED and robust.parts[0].shape.value == "box"
    for mode, cloud in (("paper", clean), ("robust", loud)):
        r = identify(cloud, rng=np.random.default_rng(0), config=IdentifyConfig.preset(mode))
        assert r.status is IdentificationStatus.FAILED and "too large" in r.unidentified[0].reason


def test_robust_decomposition_keeps_the_dense_clouds_noise():
    """The decomposition re-identifies a dense cloud thinned to ``robust_points``; the
    sensor's noise is the dense cloud's (thinning keeps real points), not a new estimate
    on the sparse one, which wider neighbourhoods inflate (a mug: 1.6 -> 5.5 mm)."""
    p = _posed(short_neck_bottle(), 0, resolution=0.002)
    r = identify(p, rng=np.random.default_rng(0), config=IdentifyConfig.preset("robust"))
    assert r.downsampling is not None and r.downsampling.used_points <= 1200
    assert 0.6e-3 <= r.noise <= 1.1e-3


def test_two_halves_of_one_body_are_merged_though_a_fresh_fit_of_their_union_fails(monkeypatch):
    """E09's random_008: a body split lengthwise, each half fitted with the whole body's
    cylinder -- two overlapping parts, and the combined map dropped every grasp of each
    as colliding with the other. Either part's own model, refined on the union, explains
    it: merged even where a fresh identification of the union draws badly (forced here)."""
    from dataclasses import replace

    from scipy.spatial import cKDTree

    from graspsim.perception import decompose as dc
    from graspsim.perception.classify import Shape
    from graspsim.perception.identify import _prepare

    cfg = IdentifyConfig.preset("robust")
    pts = _posed(Cylinder(0.03, 0.12), 7)
    cloud = _prepare(pts, cfg, cfg.max_points)[0]
    spacing = float(np.median(cKDTree(cloud.points).query(cloud.points, k=2)[0][:, 1]))
    ctx = dc._Ctx(cloud, np.random.default_rng(0), cfg, spacing, inlier_band(cloud.noise, spacing))
    whole = dc._leaf(ctx, np.arange(len(cloud.points)))
    assert whole.shape.value == "cylinder"
    axis = whole.T_world_obj[:3, 2]
    side = np.cross(axis, [1.0, 0.0, 0.0])
    x = (cloud.points - whole.T_world_obj[:3, 3]) @ (side / np.linalg.norm(side))
    halves = [np.flatnonzero(x < 0), np.flatnonzero(x >= 0)]  # lengthwise, through the axis
    parts = [replace(whole, indices=cloud.kept[h]) for h in halves]  # each the whole cylinder
    real_leaf = dc._leaf
    monkeypatch.setattr(dc, "_leaf", lambda c, i: replace(real_leaf(c, i), shape=Shape.UNIDENTIFIED))
    merged = dc._merged(ctx, [(p, None) for p in parts])
    assert len(merged) == 1 and merged[0][0].shape.value == "cylinder"
    assert merged[0][0].n_points == len(cloud.points)
    assert merged[0][0].dims["radius"] == pytest.approx(0.03, abs=0.003)


def test_a_cluster_nothing_explains_is_split_even_where_the_split_gains_no_volume(monkeypatch):
    """Robust mode gives up on no cluster while it can be split: an L of two blocks, with
    every split refused by its volume gain (theta and max_theta near 0), no single model let
    stand for it (approx_fit_rate at the paper's 85 %) and the other candidates (axial pieces,
    a peeled handle) not offered, still comes out as parts -- the irregular object's case
    (E09's random_017, whose whole cloud no model explains and whose best split gained too
    little) -- where it came out as nothing before."""
    from graspsim.perception import decompose as dc

    monkeypatch.setattr(dc, "_peel", lambda *a: None)
    monkeypatch.setattr(dc, "_axial", lambda *a: None)
    L = Compound.from_parts([Box(0.10, 0.03, 0.03), Box(0.03, 0.03, 0.07)],
                            [make_transform(np.eye(3), [0, 0, 0]), make_transform(np.eye(3), [0.035, 0, 0.05])])
    pts = _posed(L, 2)
    cfg = IdentifyConfig(theta=0.01, max_theta=0.01, approx_fit_rate=0.85)
    res = identify(pts, rng=np.random.default_rng(0), config=cfg)
    assert res.status is not IdentificationStatus.FAILED and res.parts, _kinds(res)
    assert sum(len(p.indices) for p in res.parts) >= 0.8 * len(pts)  # (pieces merged again where one box does)
