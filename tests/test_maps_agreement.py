"""Whether the observed cloud bears out a grasp's contacts (robust-mode planner filter)."""

import math

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps.agreement import ObservedSurface
from graspsim.primitives import Box

CONE = math.atan(0.5)  # the friction cone of mu = 0.5


@pytest.fixture(scope="module")
def box_cloud():
    rng = np.random.default_rng(4)
    box = Box(0.04, 0.06, 0.10)
    p = box.surface_samples(0.003).points
    return box, p + rng.normal(0.0, 0.001, p.shape)


def _check(surface, contacts, min_observed=1):
    return surface.borne_out(np.asarray(contacts, float), tol=0.004, max_angle=CONE, min_observed=min_observed)


def test_contacts_on_the_observed_faces_along_their_normal_are_borne_out(box_cloud):
    _, p = box_cloud
    s = ObservedSurface(p)
    across_x = [[-0.02, 0.0, 0.01], [0.02, 0.0, 0.01]]
    across_y = [[0.005, -0.03, -0.02], [0.005, 0.03, -0.02]]
    assert _check(s, [across_x, across_y], min_observed=2).all()


def test_contacts_beside_the_object_or_across_a_slope_are_not(box_cloud):
    _, p = box_cloud
    s = ObservedSurface(p)
    beside = [[-0.04, 0.05, 0.01], [0.04, 0.05, 0.01]]  # closing 2 cm beside the box: on nothing
    # on the x faces, but closing at 45 deg to their normal: outside the friction cone
    slanted = [[-0.02, -0.02, 0.0], [0.02, 0.02, 0.0]]
    assert not _check(s, [beside, slanted]).any()
    # the same slanted line with the cone widened past 45 deg passes: the angle decides
    assert s.borne_out(np.asarray([slanted]), tol=0.004, max_angle=math.radians(50), min_observed=2).all()


def test_contacts_in_the_air_are_borne_out_where_the_closing_fingers_meet_the_faces(box_cloud):
    """A coarse part's contacts 2 cm out in the air over both x faces: the fingers close
    on to the faces, which the cloud shows square to the closing line -- both contacts
    borne out, though no point lies near either (the rule E09's single views needed)."""
    _, p = box_cloud
    s = ObservedSurface(p)
    in_air = [[-0.04, 0.0, 0.01], [0.04, 0.0, 0.01]]
    assert _check(s, [in_air], min_observed=2).all()
    # the faces cut away where the fingers would meet them: nothing shown, nothing borne out
    hole = ObservedSurface(p[(np.abs(p[:, 1]) > 0.01) | (np.abs(p[:, 2] - 0.01) > 0.01)])
    assert not _check(hole, [in_air]).any()


def test_one_unseen_contact_is_allowed_only_off_approximate_parts(box_cloud):
    _, p = box_cloud
    half = ObservedSurface(p[p[:, 0] < 0.0])  # a view that saw only the -x half
    grasp = [[[-0.02, 0.0, 0.01], [0.02, 0.0, 0.01]]]
    assert _check(half, grasp, min_observed=1).all()
    assert not _check(half, grasp, min_observed=2).any()
    assert _check(half, np.zeros((0, 2, 3))).shape == (0,)
    with pytest.raises(InvalidParameterError, match="min_observed"):
        _check(half, grasp, min_observed=3)
    with pytest.raises(InvalidParameterError, match=r"\(N, 3\)"):
        ObservedSurface(np.zeros((4, 2)))


def test_an_unobserved_contact_is_judged_where_the_closing_finger_meets_the_cloud(box_cloud):
    """A contact 12 mm in the air (a coarse part's surface beyond the object's): the
    finger closes on past it to the observed surface, whose normal decides."""
    _, p = box_cloud
    near = p[p[:, 0] < 0.0]  # the -x half, and the +x side as a patch sloped at 45 deg
    y, z = np.meshgrid(np.arange(-0.015, 0.015, 0.002), np.arange(-0.01, 0.03, 0.002))
    slope = np.column_stack([0.02 + y.ravel(), y.ravel(), z.ravel()])
    flat = np.column_stack([np.full(y.size, 0.02), y.ravel(), z.ravel()])
    grasp = [[[-0.02, 0.0, 0.01], [0.032, 0.0, 0.01]]]
    assert not _check(ObservedSurface(np.vstack([near, slope])), grasp).any()
    assert _check(ObservedSurface(np.vstack([near, flat])), grasp).all()
    assert _check(ObservedSurface(near), grasp).all()  # not seen at all: the far side of a view


def test_with_the_viewpoint_a_touch_on_the_back_of_a_seen_surface_counts_against(box_cloud):
    """One camera at +x sees the box's +x face. A thin slab fitted to that face alone
    offers a grasp across its 3 mm: one finger would close on the face from inside the
    box. Knowing where the camera was, the face's outward normal is known and that touch
    is evidence against; the grasp across the whole box (its far contact unseen) stays."""
    _, p = box_cloud
    eye = np.array([0.5, 0.0, 0.01])
    face = p[p[:, 0] > 0.019]
    slab = [[[0.017, 0.0, 0.01], [0.02, 0.0, 0.01]]]  # contact 0 on the slab's hidden back face
    whole = [[[-0.02, 0.0, 0.01], [0.02, 0.0, 0.01]]]
    blind, seen = ObservedSurface(face), ObservedSurface(face, viewpoint=eye)
    assert _check(blind, slab).all() and not _check(seen, slab).any()
    assert _check(blind, whole).all() and _check(seen, whole).all()
    flipped = [[[0.02, 0.0, 0.01], [0.017, 0.0, 0.01]]]  # the same with the jaws swapped
    assert not _check(seen, flipped).any()
    with pytest.raises(InvalidParameterError, match="viewpoint"):
        ObservedSurface(face, viewpoint=[0.0, np.nan, 0.0])
