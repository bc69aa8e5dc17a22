"""The simulated depth camera: intrinsics, frames, metric depth against known geometry,
back-projection round trips, the noise model, cloud files."""

import json
import math

import numpy as np
import pytest

from graspsim.errors import GraspsimError, InvalidParameterError, OutputPathError
from graspsim.geometry.camera import Camera, DepthFrame, Intrinsics, backproject, fuse, look_at, to_world
from graspsim.perception.cloud_input import read_camera, read_point_cloud
from graspsim.tabletop.cloud_io import save_cloud, save_view
from graspsim.tabletop.depth_noise import DepthNoise
from graspsim.tabletop.depth_render import render_depth

XML = """<mujoco><visual><global offwidth="640" offheight="480"/></visual><worldbody>
<geom name="box" type="box" size="0.05 0.04 0.05" pos="0.02 -0.01 0.05"/>
<geom name="table" type="plane" size="2 2 .1"/></worldbody></mujoco>"""


@pytest.fixture(scope="module")
def world():
    import mujoco

    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    try:
        mujoco.Renderer(m, 8, 8).close()
    except Exception as err:
        pytest.skip(f"no headless OpenGL: {err}")
    return m, d


def test_d435_preset_values():
    k = Intrinsics.preset("d435")
    assert (k.width, k.height) == (640, 480)
    assert k.hfov == pytest.approx(87.0)
    assert k.fx == pytest.approx(320 / math.tan(math.radians(43.5))) and k.fy == k.fx
    assert (k.cx, k.cy) == (319.5, 239.5)
    assert np.allclose(k.K, [[k.fx, 0, k.cx], [0, k.fy, k.cy], [0, 0, 1]])


@pytest.mark.parametrize("kw", [dict(width=0), dict(height=-3), dict(width=2.5), dict(fx=0.0), dict(fy=-1.0),
                                dict(cx=float("nan")), dict(cx=700.0), dict(cy=-2.0), dict(width=10**5, height=10**5)])
def test_bad_intrinsics_rejected(kw):
    base = dict(width=64, height=48, fx=50.0, fy=50.0, cx=31.5, cy=23.5) | kw
    with pytest.raises(InvalidParameterError):
        Intrinsics(**base)


def test_bad_preset_and_pose_rejected():
    with pytest.raises(GraspsimError, match="d435"):
        Intrinsics.preset("kinect9")
    with pytest.raises(InvalidParameterError):
        Camera(Intrinsics.preset("d435"), np.diag([1.0, 1.0, 2.0, 1.0]))
    with pytest.raises(InvalidParameterError):
        look_at([0, 0, 1], [0, 0, 1])


def test_look_at_frame_convention():
    T = look_at([1.0, 0.0, 0.5], [0.0, 0.0, 0.5])  # level, looking along -x
    assert np.allclose(T[:3, 2], [-1, 0, 0])  # z forward
    assert np.allclose(T[:3, 1], [0, 0, -1])  # y down
    assert np.allclose(T[:3, 0], [0, 1, 0])  # x right (looking along -x, right is +y)
    assert np.allclose(T[:3, 3], [1, 0, 0.5])
    down = look_at([0, 0, 1], [0, 0, 0])  # straight down: still a rotation
    assert np.allclose(down[:3, :3] @ down[:3, :3].T, np.eye(3)) and np.allclose(down[:3, 2], [0, 0, -1])


def test_pixel_ray_consistency():
    k = Intrinsics(80, 60, 70.0, 65.0, 37.0, 31.0)
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(-0.2, 0.2, 50), rng.uniform(-0.2, 0.2, 50), rng.uniform(0.3, 2.0, 50)])
    uv = k.project(p)
    rays = k.rays()
    r = rays[np.round(uv[:, 1]).astype(int).clip(0, 59), np.round(uv[:, 0]).astype(int).clip(0, 79)]
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= 79) & (uv[:, 1] >= 0) & (uv[:, 1] <= 59)
    err = np.abs(r[inside, :2] - p[inside, :2] / p[inside, 2:]) * [k.fx, k.fy]
    assert inside.sum() > 10 and err.max() <= 0.5 + 1e-9  # within half a pixel of the nearest centre
    depth = np.zeros((60, 80), np.float32)
    depth[10, 20] = 1.5
    v = backproject(DepthFrame(depth, Camera(k, np.eye(4))))
    assert np.allclose(k.project(v.points), [[20, 10]]) and np.allclose(v.points[0, 2], 1.5)


@pytest.mark.parametrize("intr,eye", [(Intrinsics.preset("d435"), [0.0, 0.0, 0.8]),
                                      (Intrinsics(320, 240, 300.0, 280.0, 140.0, 130.0), [0.4, -0.3, 0.5])])
def test_rendered_depth_recovers_known_geometry(world, intr, eye):
    m, d = world
    cam = Camera(intr, look_at(eye, [0.0, 0.0, 0.05]))
    frame = render_depth(m, d, cam)
    assert frame.depth.shape == (intr.height, intr.width) and frame.depth.dtype == np.float32
    v = backproject(frame)
    w = v.world()
    table = v.segmentation == m.geom("table").id
    box = v.segmentation == m.geom("box").id
    assert table.sum() > 1000 and box.sum() > 500
    assert np.abs(w[table, 2]).max() < 1e-4  # the table plane z = 0
    lo, hi = np.array([-0.03, -0.05, 0.0]), np.array([0.07, 0.03, 0.1])  # the box
    assert np.all(w[box] > lo - 1e-4) and np.all(w[box] < hi + 1e-4)
    top = box & (w[:, 2] > 0.1 - 1e-4)
    assert top.sum() > 100  # its top face seen at the right height
    # projecting the recovered points lands on their own pixels
    assert np.abs(intr.project(v.points) - v.uv).max() < 1e-3


def test_noise_is_seeded_and_grows_with_depth(world):
    m, d = world
    cam = Camera(Intrinsics(160, 120, 90.0, 90.0, 79.5, 59.5), look_at([0, 0, 0.8], [0, 0, 0]))
    clean = render_depth(m, d, cam, segmentation=False)
    noise = DepthNoise(quantisation=0.0)
    a = render_depth(m, d, cam, noise=noise, rng=np.random.default_rng(5), segmentation=False)
    b = render_depth(m, d, cam, noise=noise, rng=np.random.default_rng(5), segmentation=False)
    c = render_depth(m, d, cam, noise=noise, rng=np.random.default_rng(6), segmentation=False)
    assert np.array_equal(a.depth, b.depth) and not np.array_equal(a.depth, c.depth)
    assert 0 < (a.depth == 0).mean() < 0.1  # some dropouts, not most of the image
    # the error's spread grows with z^2: a synthetic plane at two distances
    rays = Intrinsics(200, 200, 150.0, 150.0, 99.5, 99.5).rays()
    rng = np.random.default_rng(0)
    sd = []
    for z in (0.5, 1.5):
        out = noise.apply(np.full((200, 200), z), rays, rng)[50:150, 50:150]
        sd.append(np.std(out[out > 0] - z))
    assert sd[1] / sd[0] == pytest.approx(noise.sigma(1.5) / noise.sigma(0.5), rel=0.1)
    q = DepthNoise(quantisation=0.001).apply(np.full((10, 10), 0.6), rays[:10, :10], rng)
    assert np.allclose(np.round(q[q > 0] / 0.001) * 0.001, q[q > 0], atol=1e-6)
    assert np.array_equal(DepthNoise.none().apply(clean.depth, cam.intrinsics.rays(), rng), clean.depth)


def test_grazing_surfaces_and_edges_drop_out():
    k = Intrinsics(200, 200, 150.0, 150.0, 99.5, 99.5)
    rays = k.rays()
    tilted = 1.0 + 0.02 * (np.arange(200)[None, :] - 100) * np.ones((200, 1))  # a steep ramp
    n = DepthNoise(sigma0=0, sigma_z2=0, max_incidence=60.0, dropout=0, edge_dropout=0, quantisation=0)
    assert (n.apply(tilted, rays, np.random.default_rng(0)) == 0).mean() > 0.9
    step = np.where(np.arange(200)[None, :] < 100, 0.5, 1.0) * np.ones((200, 1))
    e = DepthNoise(sigma0=0, sigma_z2=0, dropout=0, edge_dropout=1.0, quantisation=0, edge_jump=0.05,
                   max_incidence=90.0)
    out = e.apply(step, rays, np.random.default_rng(0))
    assert np.all(out[:, 99] == 0) and np.all(out[:, 100] > 0)  # the near side of the edge goes
    with pytest.raises(InvalidParameterError):
        DepthNoise(dropout=1.5)


def test_noisy_render_needs_a_generator(world):
    m, d = world
    cam = Camera(Intrinsics(64, 48, 50.0, 50.0, 31.5, 23.5), look_at([0, 0, 0.8], [0, 0, 0]))
    with pytest.raises(InvalidParameterError, match="rng"):
        render_depth(m, d, cam, noise=DepthNoise())


@pytest.mark.parametrize("suffix", [".pcd", ".ply", ".npy"])
def test_cloud_files_round_trip_with_the_camera(tmp_path, suffix):
    rng = np.random.default_rng(2)
    pts = rng.uniform(-0.2, 0.2, (300, 3)) + [0, 0, 0.7]
    cam = Camera(Intrinsics.preset("d435"), look_at([0.3, 0.2, 0.6], [0, 0, 0]))
    labels = rng.integers(-1, 5, 300)
    paths = save_cloud(tmp_path / f"view{suffix}", pts, camera=cam, labels=labels)
    back = read_point_cloud(tmp_path / f"view{suffix}")
    assert np.allclose(back.points, pts, atol=1e-6)
    cam2, frame = read_camera(tmp_path / f"view{suffix}")
    assert frame == "camera" and np.allclose(cam2.T_world_camera, cam.T_world_camera)
    assert cam2.intrinsics == cam.intrinsics
    assert json.loads(paths[-1].read_text())["points"] == 300
    if suffix == ".pcd":
        head = (tmp_path / "view.pcd").read_bytes().split(b"DATA")[0].decode()
        vp = np.array(head.split("VIEWPOINT")[1].split("\n")[0].split(), float)
        assert np.allclose(vp[:3], cam.T_world_camera[:3, 3])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries left


def test_save_rejects_bad_input(tmp_path):
    with pytest.raises(OutputPathError):
        save_cloud(tmp_path / "x.obj", np.zeros((5, 3)))
    with pytest.raises(GraspsimError):
        save_cloud(tmp_path / "x.ply", np.full((5, 3), np.nan))
    assert list(tmp_path.iterdir()) == []


def test_fuse_two_views_covers_more_and_agrees(world, tmp_path):
    m, d = world
    k = Intrinsics(160, 120, 100.0, 100.0, 79.5, 59.5)
    cams = [Camera(k, look_at([0.5, 0.0, 0.5], [0, 0, 0.05])), Camera(k, look_at([-0.5, 0.1, 0.5], [0, 0, 0.05]))]
    frames = [render_depth(m, d, c) for c in cams]
    pts, labels = fuse(frames)
    assert labels is None  # frames from render_depth carry geom ids, not scene labels
    box = np.concatenate([backproject(f).segmentation == m.geom("box").id for f in frames])
    xs = pts[box, 0]
    assert xs.max() > 0.069 and xs.min() < -0.029  # both the +x and the -x faces are seen
    v, _ = fuse(frames, voxel=0.01)
    assert len(v) < len(pts)
    assert np.allclose(to_world(backproject(frames[0]).points, cams[0].T_world_camera), backproject(frames[0]).world())
    save_view(tmp_path / "v.ply", backproject(frames[0]), frame="world")
    assert read_camera(tmp_path / "v.ply")[1] == "world"


def test_orbit_and_rig_look_at_the_target():
    from graspsim.geometry.camera import orbit, rig

    T = orbit([0.1, 0.0, 0.03], distance=0.7, elevation=55.0, azimuth=-90.0)
    assert np.isclose(np.linalg.norm(T[:3, 3] - [0.1, 0, 0.03]), 0.7) and T[1, 3] < 0 and T[2, 3] > 0.5
    cams = rig(3, target=(0.0, 0.0, 0.03))
    k = cams[0].intrinsics
    for c in cams:  # the target projects onto the principal point
        p = np.linalg.inv(c.T_world_camera) @ [0.0, 0.0, 0.03, 1.0]
        assert np.allclose(k.project(p[None, :3]), [[k.cx, k.cy]])
    az = [np.degrees(np.arctan2(c.T_world_camera[1, 3], c.T_world_camera[0, 3])) for c in cams]
    assert np.allclose(np.diff(np.sort(az)), 120.0)
    with pytest.raises(InvalidParameterError):
        rig(0)


def test_stereo_shadow_lies_left_of_a_near_object_and_has_the_predicted_width():
    k = Intrinsics(200, 100, 150.0, 150.0, 99.5, 49.5)
    depth = np.full((100, 200), 1.0)
    depth[:, 100:140] = 0.5  # a near slab in front of a wall
    n = DepthNoise(sigma0=0, sigma_z2=0, max_incidence=90.0, edge_dropout=0, dropout=0, quantisation=0,
                   baseline=0.05)
    out = n.apply(depth, k.rays(), np.random.default_rng(0))
    band = np.flatnonzero(out[50] == 0)
    width = 150.0 * 0.05 * (1 / 0.5 - 1 / 1.0)  # f b (1/z1 - 1/z2) = 7.5 px
    assert band.max() == 99 and len(band) == int(width)  # just left of the slab: the s < 7.5 columns
    assert np.all(out[:, 140:] > 0) and np.all(out[:, 100:140] > 0)  # its right side and itself stay
    off = DepthNoise(sigma0=0, sigma_z2=0, max_incidence=90.0, edge_dropout=0, dropout=0, quantisation=0, baseline=0)
    assert np.all(off.apply(depth, k.rays(), np.random.default_rng(0)) > 0)
