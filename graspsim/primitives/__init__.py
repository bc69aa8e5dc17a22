"""Shape primitives: Box, Cylinder, Sphere, Cone (frustum), HalfToroid, and compounds.

May use: the base modules and geometry only.
"""

from __future__ import annotations

from graspsim.errors import PrimitiveError
from graspsim.primitives.base import Primitive
from graspsim.primitives.box import Box
from graspsim.primitives.cone import Cone
from graspsim.primitives.cylinder import Cylinder
from graspsim.primitives.samples import SurfaceSamples
from graspsim.primitives.sphere import Sphere
from graspsim.primitives.toroid import HalfToroid

__all__ = [
    "Primitive",
    "SurfaceSamples",
    "Box",
    "Cylinder",
    "Sphere",
    "Cone",
    "HalfToroid",
    "PRIMITIVES",
    "make_primitive",
    "primitive_from_dict",
]

PRIMITIVES: dict[str, type[Primitive]] = {
    cls.kind: cls for cls in (Box, Cylinder, Sphere, Cone, HalfToroid)
}


def make_primitive(kind: str, **dims: float) -> Primitive:
    """Build a primitive by name (``box``, ``cylinder``, ``sphere``, ``cone``,
    ``half_toroid``; ``half-toroid`` and ``halftoroid`` accepted) from named dims [m]."""
    if not isinstance(kind, str):
        raise PrimitiveError(f"a primitive name must be a string, got {kind!r}; valid: {sorted(PRIMITIVES)}")
    key = kind.lower().replace("-", "_")
    key = {"halftoroid": "half_toroid", "torus": "half_toroid", "frustum": "cone"}.get(key, key)
    cls = PRIMITIVES.get(key)
    if cls is None:
        raise PrimitiveError(f"unknown primitive {kind!r}; valid: {sorted(PRIMITIVES)}")
    missing = [n for n in cls.dim_names if n not in dims]
    extra = sorted(set(dims) - set(cls.dim_names))
    if missing or extra:
        raise PrimitiveError(
            f"{key} takes dims {list(cls.dim_names)}; missing {missing}, unexpected {extra}"
        )
    return cls(**{n: dims[n] for n in cls.dim_names})


def primitive_from_dict(d: dict) -> Primitive:
    """Inverse of ``Primitive.to_dict``."""
    try:
        return make_primitive(d["primitive"], **d["dims"])
    except (KeyError, TypeError, AttributeError) as err:  # not a dict, no dims mapping, ...
        raise PrimitiveError(f"not a primitive description: {d!r}") from err

from graspsim.primitives.clouds import SyntheticCloud, synthetic_cloud  # noqa: E402
from graspsim.primitives.compound import Compound  # noqa: E402

__all__ += ["Compound", "SyntheticCloud", "synthetic_cloud"]


def shape_from_dict(d: dict):
    """A Primitive or Compound from ``to_dict()`` output (the ``object`` of a map)."""
    if d.get("primitive") == "compound":
        try:
            parts = [primitive_from_dict(p) for p in d["parts"]]
            return Compound(tuple(parts), __import__("numpy").asarray(d["poses"], float))
        except (KeyError, TypeError, ValueError) as err:
            raise PrimitiveError(f"not a compound description: {d!r}") from err
    return primitive_from_dict(d)


__all__ += ["shape_from_dict"]
