"""A depth sensor's errors, applied to a clean metric depth image (pure numpy).

Structured-light and active-stereo cameras (the RealSense D400 family) have an RMS depth
error that grows with the square of the distance, ``sigma(z) = sigma0 + sigma_z2 * z^2``
(stereo: sigma = z^2 * subpixel / (f * baseline); a D435 at 848 px has f ~ 430 px, a
5 cm baseline and ~0.08 px subpixel error: ~0.0036 z^2 [m]), lose pixels where the
surface is seen at a grazing angle and along depth discontinuities (the projector's
shadow and stereo occlusion), and report depth in steps (the D435's depth unit is 1 mm).
Invalid pixels are 0, as a RealSense reports them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from graspsim.checks import NON_NEGATIVE, Rule, check_fields
from graspsim.errors import InvalidParameterError

__all__ = ["DepthNoise"]

#: Every setting of the noise model is a finite number >= 0 but ``edge_jump``, which may
#: be inf (no depth edges at all).
_FINITE = NON_NEGATIVE.saying("a finite number >= 0")
_EDGE_JUMP = Rule(lambda v: isinstance(v, (int, float)) and v >= 0, _FINITE.says)


@dataclass(frozen=True)
class DepthNoise:
    """Depth sensor noise. sigma0 [m] + sigma_z2 [1/m] x z^2: Gaussian depth error;
    max_incidence [deg]: pixels whose surface normal is farther than this from the
    viewing ray are dropped; edge_jump [m] (inf: off): a pixel whose 4-neighbour is farther by more
    than this is on a depth edge, dropped with probability ``edge_dropout`` (what a
    sensor's flying-pixel filter removes); baseline [m] (0: off): the stereo baseline
    (the second imager at +x): background the second imager cannot see past a nearer
    surface to its right is invalid (the shadow band left of objects, f b (1/z1 - 1/z2)
    pixels wide); dropout: fraction of all valid pixels dropped at random;
    quantisation [m]: depth step (0: none).
    """

    sigma0: float = 0.0005
    sigma_z2: float = 0.0036
    max_incidence: float = 80.0
    edge_jump: float = 0.02
    edge_dropout: float = 0.5
    dropout: float = 0.002
    quantisation: float = 0.001
    baseline: float = 0.05

    def __post_init__(self) -> None:
        check_fields(self, _FINITE, *(f.name for f in fields(self) if f.name != "edge_jump"), owner="DepthNoise")
        check_fields(self, _EDGE_JUMP, "edge_jump", owner="DepthNoise")
        for k in ("edge_dropout", "dropout"):
            if getattr(self, k) > 1:
                raise InvalidParameterError(f"DepthNoise.{k} is a probability in [0, 1], got {getattr(self, k)!r}")
        if not 0 < self.max_incidence <= 90:
            raise InvalidParameterError(f"DepthNoise.max_incidence must be in (0, 90] deg, got {self.max_incidence!r}")
        if not self.edge_jump > 0:
            raise InvalidParameterError("DepthNoise.edge_jump must be > 0 m (inf: no edge dropouts)")

    @classmethod
    def none(cls) -> DepthNoise:
        """A perfect sensor: no error, no dropouts, no quantisation."""
        return cls(sigma0=0.0, sigma_z2=0.0, max_incidence=90.0, edge_jump=math.inf, edge_dropout=0.0,
                   dropout=0.0, quantisation=0.0, baseline=0.0)

    def to_dict(self) -> dict:
        return asdict(self)

    def sigma(self, z: np.ndarray) -> np.ndarray:
        """RMS depth error [m] at depth ``z`` [m]."""
        return self.sigma0 + self.sigma_z2 * np.square(z)

    def apply(self, depth: np.ndarray, rays: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A noisy copy of ``depth`` (H, W) [m] (0 = invalid). rays: (H, W, 3) viewing rays
        with z = 1 in the camera frame (``Intrinsics.rays``). Draws from ``rng`` in a fixed
        order (dropout, edges, error), so one seed gives one image."""
        depth = np.asarray(depth, np.float64)
        valid = depth > 0
        drop = rng.random(depth.shape) < self.dropout
        edge_u = rng.random(depth.shape) < self.edge_dropout
        err = rng.standard_normal(depth.shape)
        if self.max_incidence < 90:
            n, ok = _normal_components(depth, rays)
            dot = n[0] * rays[..., 0] + n[1] * rays[..., 1] + n[2]  # rays have z = 1
            nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
            rr = rays[..., 0] ** 2 + rays[..., 1] ** 2 + 1.0
            c = math.cos(math.radians(self.max_incidence))
            drop |= ok & (nn > 0) & (dot * dot < c * c * nn * rr)  # cos(normal, ray) < c
        if math.isfinite(self.edge_jump) and self.edge_dropout > 0:
            drop |= _edges(depth, self.edge_jump) & edge_u
        if self.baseline > 0:
            drop |= _stereo_shadow(depth, self.baseline / (rays[0, 1, 0] - rays[0, 0, 0]))
        out = np.where(valid, depth + self.sigma(depth) * err, 0.0)
        if self.quantisation > 0:
            out = np.round(out / self.quantisation) * self.quantisation
        out[drop | ~valid | (out <= 0)] = 0.0
        return out.astype(np.float32)


def _stereo_shadow(depth: np.ndarray, fb: float) -> np.ndarray:
    """(H, W) bool: pixels hidden from a second imager ``fb`` = focal length [px] x
    baseline [m] to the right: a pixel at depth z is hidden by a pixel s columns to its
    right at depth z' < z when s < fb (1/z' - 1/z) (its disparity overtakes ours)."""
    valid = depth > 0
    hidden = np.zeros(depth.shape, bool)
    if not valid.any():
        return hidden
    inv = np.where(valid, 1.0 / np.where(valid, depth, 1.0), 0.0)  # 1/z, 0 = nothing
    reach = int(math.ceil(fb * (inv.max() - inv[valid].min())))  # the widest possible band
    for s in range(1, min(reach + 1, depth.shape[1])):
        gain = inv[:, s:] - inv[:, :-s]  # 1/z' - 1/z of the pixel s to the right
        hidden[:, :-s] |= (depth[:, s:] > 0) & (gain * fb > s)
    return hidden & (depth > 0)


def _edges(depth: np.ndarray, jump: float) -> np.ndarray:
    """(H, W) bool: valid pixels with a 4-neighbour farther by > ``jump`` or invalid."""
    d = np.where(depth > 0, depth, np.inf)
    p = np.pad(d, 1, mode="edge")
    far = np.zeros(depth.shape, bool)
    with np.errstate(invalid="ignore"):  # inf - inf where both are invalid: not an edge
        for nb in (p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]):
            far |= nb - d > jump
    return far & (depth > 0)


def _normal_components(depth: np.ndarray, rays: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Unnormalised normals (3 arrays (H, W), float32, camera frame) from central
    differences of the back-projected image, and where they are valid (all 4 neighbours)."""
    P = [np.pad((depth * rays[..., i]).astype(np.float32), 1, mode="edge") for i in range(3)]
    du = [c[1:-1, 2:] - c[1:-1, :-2] for c in P]
    dv = [c[2:, 1:-1] - c[:-2, 1:-1] for c in P]
    n = [du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2], du[0] * dv[1] - du[1] * dv[0]]
    v = np.pad(depth > 0, 1, mode="edge")
    ok = (depth > 0) & v[:-2, 1:-1] & v[2:, 1:-1] & v[1:-1, :-2] & v[1:-1, 2:]
    return n, ok
