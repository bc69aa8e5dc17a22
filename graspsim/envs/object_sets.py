"""Object sets of the environments: random primitives and compounds to put on the table.

Every draw takes the caller's ``numpy.random.Generator``. Dimensions are drawn
uniformly from ranges chosen so that (a) the HGPL-25-60 can grasp the object (chords
up to ~11 cm) and (b) every dimension lies within the planner's scaling range (factor
3) of the database's reference shape of that primitive (``PAPER_SHAPES``), so a
correctly identified object is always *familiar* or *known*, never missing.

(a) is the gripper's: the widths a grasp must span (a box's side edges, a cylinder's,
sphere's, cone's, mug's diameter) are drawn within :func:`size_limits` of the gripper,
from its stroke (the widest chord: largest opening minus the approach clearance on both
sides) down to its closed gap. The ranges above fit the HGPL-25-60 as they are, so its
draws are the same; a smaller gripper (the Franka hand: 70 mm) gets the same objects up
to what it can span.

The object frame of the drawn shape is the one the simulator rests on the table:
its +z stays up when that is stable (docs/design.md §3). A cylinder is stood upright or,
with probability ``lying``, laid on its side (a one-part :class:`Compound` whose part
is turned by 90 deg) -- the planner only ever sees the cloud, so that costs nothing.

Sets: the five kinds by name (``box``, ``cylinder``, ``sphere``, ``cone``,
``half_toroid``), the compounds by name (``bottle``: body and neck cylinders; ``mug``:
a cylinder with a half-toroid handle; ``hammer``: a lying cylinder handle with a box
head), ``primitives`` (the five kinds), ``compounds`` (the three compounds) and ``all``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graspsim.errors import GripperError, InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Primitive, Sphere
from graspsim.transforms import make_transform

__all__ = ["DrawnObject", "PRIMITIVE_KINDS", "COMPOUND_KINDS", "OBJECT_SETS", "resolve_object_set",
           "draw_object", "SizeLimits", "size_limits"]


@dataclass(frozen=True)
class SizeLimits:
    """The widths [m] a gripper can grasp across: ``widest`` (its largest opening minus
    the approach clearance on both sides), ``narrowest`` (its closed pad gap)."""

    widest: float
    narrowest: float

    def width(self, rng: np.random.Generator, lo: float, hi: float, what: str, per: float = 1.0) -> float:
        """A dimension drawn uniformly from [lo, hi] cut to the limits; ``per``: widths
        per unit of the dimension (2 for a radius)."""
        a, b = max(lo, self.narrowest / per), min(hi, self.widest / per)
        if a > b:
            raise GripperError(f"the gripper takes widths {1000 * self.narrowest:g}-{1000 * self.widest:g} mm; "
                               f"no {what} of the object set fits ({1000 * per * lo:g}-{1000 * per * hi:g} mm)")
        return float(rng.uniform(a, b))


def size_limits(gripper: GripperSpec | None = None) -> SizeLimits:
    """What ``gripper`` (default the HGPL-25-60) can span (see :class:`SizeLimits`)."""
    g = gripper or HGPL_25_60_A
    return SizeLimits(widest=g.max_opening - 2.0 * g.approach_clearance, narrowest=g.min_opening)


@dataclass(frozen=True)
class DrawnObject:
    """kind: the set member drawn (``"cylinder"``, ``"bottle"``, ...); shape: the
    Primitive or Compound, object frame +z up on the table; pose: ``"upright"`` or
    ``"lying"``."""

    kind: str
    shape: Primitive | Compound
    pose: str = "upright"

    def to_dict(self) -> dict:
        return {"kind": self.kind, "pose": self.pose, "shape": self.shape.to_dict()}


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _rot_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _lay_down(part: Primitive) -> Compound:
    """The part with its z axis turned horizontal (about x): lying on its side."""
    return Compound.from_parts([part], make_transform(_rot_x(math.pi / 2), np.zeros(3))[None])


def _box(rng, lying, lim):
    return Box(lim.width(rng, 0.03, 0.09, "box side"), lim.width(rng, 0.03, 0.09, "box side"),
               _u(rng, 0.04, 0.14)), "upright"


def _cylinder(rng, lying, lim):
    c = Cylinder(lim.width(rng, 0.012, 0.04, "cylinder diameter", 2.0), _u(rng, 0.07, 0.20))
    if rng.random() < lying:
        return _lay_down(c), "lying"
    return c, "upright"


def _sphere(rng, lying, lim):
    return Sphere(lim.width(rng, 0.02, 0.05, "sphere diameter", 2.0)), "upright"


def _cone(rng, lying, lim):
    rb = lim.width(rng, 0.025, 0.05, "cone base diameter", 2.0)
    return Cone(rb, rb * _u(rng, 0.3, 0.7), _u(rng, 0.06, 0.12)), "upright"


def _half_toroid(rng, lying, lim):
    R = _u(rng, 0.03, 0.06)
    return HalfToroid(R, _u(rng, 0.007, min(0.015, 0.3 * R))), "upright"


def _bottle(rng, lying, lim):
    # a slim bottle with a long neck: identification splits stouter ones rarely (the
    # split's volume ratio stays above theta = 0.5), and then fails on the whole
    rb, hb = _u(rng, 0.025, 0.032), _u(rng, 0.068, 0.085)
    rn, hn = _u(rng, 0.008, 0.011), _u(rng, 0.10, 0.13)
    parts = [Cylinder(rb, hb), Cylinder(rn, hn)]
    poses = [make_transform(np.eye(3), [0, 0, 0.5 * hb]), make_transform(np.eye(3), [0, 0, hb + 0.5 * hn])]
    return Compound.from_parts(parts, poses), "upright"


def _mug(rng, lying, lim):
    r, h = lim.width(rng, 0.03, 0.04, "mug diameter", 2.0), _u(rng, 0.08, 0.11)
    rm = _u(rng, 0.007, 0.01)
    handle = HalfToroid(_u(rng, 0.025, min(0.035, 0.5 * h - rm - 0.005)), rm)
    # the handle's ring lies in the mug's x-z plane and bulges out of +x: its geometric
    # x (the cut faces' axis) -> mug z, its y (the bulge) -> mug x, its axis z -> mug y;
    # the ring centre sits one tube radius inside the wall, so the cut faces are buried
    R_h = np.column_stack([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    centre = np.array([r - rm, 0.0, 0.5 * h])
    T_handle = make_transform(R_h, centre + R_h @ np.asarray(handle.com_geo))
    parts = [Cylinder(r, h), handle]
    return Compound.from_parts(parts, [make_transform(np.eye(3), [0, 0, 0.5 * h]), T_handle]), "upright"


def _hammer(rng, lying, lim):
    rh, lh = _u(rng, 0.012, 0.018), _u(rng, 0.14, 0.20)
    head = Box(_u(rng, 0.025, 0.035), _u(rng, 0.025, 0.035), _u(rng, 0.08, 0.11))
    # both parts lie on the table (z = 0 below them): the handle along x, the head's
    # long edge along y across the handle's end
    R_handle = np.column_stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # z -> x
    R_head = np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # z -> y
    poses = [make_transform(R_handle, [0.5 * lh, 0.0, rh]),
             make_transform(R_head, [lh + 0.5 * head.x - rh, 0.0, 0.5 * head.y])]
    return Compound.from_parts([Cylinder(rh, lh), head], poses), "upright"


_DRAW: dict[str, Callable] = {
    "box": _box, "cylinder": _cylinder, "sphere": _sphere, "cone": _cone,
    "half_toroid": _half_toroid, "bottle": _bottle, "mug": _mug, "hammer": _hammer,
}
PRIMITIVE_KINDS = ("box", "cylinder", "sphere", "cone", "half_toroid")
COMPOUND_KINDS = ("bottle", "mug", "hammer")
OBJECT_SETS: dict[str, tuple[str, ...]] = {
    "primitives": PRIMITIVE_KINDS, "compounds": COMPOUND_KINDS,
    "all": PRIMITIVE_KINDS + COMPOUND_KINDS, **{k: (k,) for k in _DRAW},
}


def resolve_object_set(objects: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The kinds of an object set name, or of a sequence of names (sets or kinds)."""
    names = (objects,) if isinstance(objects, str) else tuple(objects)
    if not names:
        raise InvalidParameterError(f"object set is empty; valid names: {sorted(OBJECT_SETS)}")
    kinds: list[str] = []
    for n in names:
        key = str(n).lower().replace("-", "_")
        if key not in OBJECT_SETS:
            raise InvalidParameterError(f"unknown object set {n!r}; valid: {sorted(OBJECT_SETS)}")
        kinds += [k for k in OBJECT_SETS[key] if k not in kinds]
    return tuple(kinds)


def draw_object(kinds: tuple[str, ...], rng: np.random.Generator, *, lying: float = 0.5,
                gripper: GripperSpec | None = None) -> DrawnObject:
    """A random member of ``kinds`` (uniform over kinds) with random dimensions, the
    widths within what ``gripper`` (default the HGPL-25-60) spans (:func:`size_limits`).
    lying: probability that a cylinder lies on its side."""
    kind = kinds[int(rng.integers(len(kinds)))]
    shape, pose = _DRAW[kind](rng, lying, size_limits(gripper))
    return DrawnObject(kind, shape, pose)
