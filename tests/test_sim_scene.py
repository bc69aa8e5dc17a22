"""Scene assembly: objects as geoms, mass properties, resting pose, pinned settings."""

import mujoco
import numpy as np
import pytest

from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Sphere
from graspsim.sim import SimSettings, build_scene, object_from_shape, resting_pose
from graspsim.transforms import make_transform

SHAPES = [Box(0.06, 0.04, 0.1), Cylinder(0.02, 0.20), Sphere(0.035), Cone(0.04, 0.02, 0.10),
          HalfToroid(0.04, 0.01)]


def _bottle():
    return Compound.from_parts(
        [Cylinder(0.03, 0.12), Cylinder(0.012, 0.06)],
        [make_transform(np.eye(3), [0, 0, 0.06]), make_transform(np.eye(3), [0, 0, 0.15])])


@pytest.mark.parametrize("shape", SHAPES + [_bottle()], ids=lambda s: s.kind)
def test_objects_rest_on_the_table_and_step_warning_free(shape):
    obj = object_from_shape(shape, density=800.0)
    scene = build_scene(obj)
    m, d = scene.model, mujoco.MjData(scene.model)
    assert m.body("object").mass[0] == pytest.approx(800.0 * shape.volume)
    z0 = d.qpos[scene.qadr_obj + 2]
    lowest = obj.surface.vertices[:, 2].min()
    assert z0 + lowest == pytest.approx(0.0, abs=1e-9)  # bottom on the table top
    mujoco.mj_step(m, d, nstep=int(round(1.0 / m.opt.timestep)))  # 1 s, gripper hanging above
    assert all(w.number == 0 for w in d.warning)
    assert abs(d.qpos[scene.qadr_obj + 2] - z0) < 0.002  # stays where it was put


def test_settings_are_pinned_to_the_documented_defaults():
    s = SimSettings()
    m = build_scene(object_from_shape(Box(0.05, 0.05, 0.05)), settings=s).model
    assert m.opt.timestep == 0.001
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert m.opt.impratio == pytest.approx(100.0)
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_DIAGEXACT
    for name in ("finger_neg", "finger_pos", "object_0"):
        assert m.geom(name).condim[0] >= 4
    assert m.geom("finger_pos").friction[0] == pytest.approx(s.friction)


def test_half_toroid_pieces_follow_the_surface():
    ht = HalfToroid(0.04, 0.01)
    obj = object_from_shape(ht, pieces=12)
    assert len(obj.geoms) == 12
    v = np.concatenate([g.vertices for g in obj.geoms])
    assert np.max(np.abs(ht.sdf(v))) < 1e-9  # hull vertices lie on the surface


def test_compound_mass_and_inertia_add_up():
    b = _bottle()
    obj = object_from_shape(b, mass=0.5)
    assert obj.mass == 0.5
    assert np.allclose(obj.inertia, obj.inertia.T) and np.all(np.linalg.eigvalsh(obj.inertia) > 0)


def test_unstable_mesh_pose_is_replaced_by_a_stable_one():
    # a cone balanced on its tip: object +z up is not a resting pose
    obj = object_from_shape(Cone(0.0, 0.04, 0.08))
    T = resting_pose(obj)
    up = T[:3, :3] @ np.array([0.0, 0.0, 1.0])
    assert up[2] < 0.99  # turned over
    v = obj.surface.vertices @ T[:3, :3].T + T[:3, 3]
    assert v[:, 2].min() == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("kw", [dict(friction=0.0), dict(timestep=0.05), dict(cone="round"),
                                dict(condim=5), dict(grip_force=-3.0), dict(density=0.0),
                                dict(integrator="verlet")])
def test_bad_settings_name_the_problem(kw):
    with pytest.raises(InvalidParameterError, match=next(iter(kw))):
        SimSettings(**kw)


@pytest.mark.parametrize("kw", [dict(mass=0.0), dict(mass=-0.2), dict(mass=float("nan")),
                                dict(density=-5.0)])
def test_non_positive_mass_is_a_simulation_error(kw):
    with pytest.raises(SimulationError):
        object_from_shape(Box(0.05, 0.05, 0.05), **kw)


def test_resting_pose_keeps_a_given_up_direction():
    import numpy as np

    from graspsim.primitives import Cylinder
    from graspsim.sim import object_from_shape, resting_pose

    obj = object_from_shape(Cylinder(0.03, 0.1))
    T = resting_pose(obj, up=np.array([0.0, 0.0, -1.0]))  # the frame is upside down
    assert np.allclose(T[:3, 2], [0, 0, -1], atol=1e-9)
    assert abs(T[2, 3] - 0.05) < 1e-6
