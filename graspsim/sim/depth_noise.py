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
from dataclasses import asdict, dataclass

import numpy as np

from graspsim.errors import InvalidParameterError

__all__ = ["DepthNoise", "surface_normals"]


@dataclass(frozen=True)
class DepthNoise:
    """Depth sensor noise. sigma0 [m] + sigma_z2 [1/m] x z^2: Gaussian depth error;
    max_incidence [deg]: pixels whose surface normal is farther than this from the
    viewing ray are dropped; edge_jump [m] (inf: off): a pixel whose 4-neighbour is farther by more
    than this is on a depth edge, dropped with probability ``edge_dropout``; dropout:
    fraction of all valid pixels dropped at random; quantisation [m]: depth step (0: none).
    """

    sigma0: float = 0.0005
    sigma_z2: float = 0.0036
    max_incidence: float = 80.0
    edge_jump: float = 0.02
    edge_dropout: float = 0.5
    dropout: float = 0.002
    quantisation: float = 0.001

    def __post_init__(self) -> None:
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and (math.isfinite(v) or k == "edge_jump") and v >= 0):
                raise InvalidParameterError(f"DepthNoise.{k} must be a finite number >= 0, got {v!r}")
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
                   dropout=0.0, quantisation=0.0)

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
            n = surface_normals(depth, rays)
            ray = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
            cos = np.abs(np.einsum("hwk,hwk->hw", n, ray))
            known = np.any(n != 0, axis=-1)
            drop |= valid & known & (cos < math.cos(math.radians(self.max_incidence)))
        if math.isfinite(self.edge_jump) and self.edge_dropout > 0:
            drop |= _edges(depth, self.edge_jump) & edge_u
        out = np.where(valid, depth + self.sigma(depth) * err, 0.0)
        if self.quantisation > 0:
            out = np.round(out / self.quantisation) * self.quantisation
        out[drop | ~valid | (out <= 0)] = 0.0
        return out.astype(np.float32)


def _edges(depth: np.ndarray, jump: float) -> np.ndarray:
    """(H, W) bool: valid pixels with a 4-neighbour farther by > ``jump`` or invalid."""
    d = np.where(depth > 0, depth, np.inf)
    p = np.pad(d, 1, mode="edge")
    far = np.zeros(depth.shape, bool)
    with np.errstate(invalid="ignore"):  # inf - inf where both are invalid: not an edge
        for nb in (p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]):
            far |= nb - d > jump
    return far & (depth > 0)


def surface_normals(depth: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Unit normals (H, W, 3), camera frame, from central differences of the back-projected
    depth image (zero where a neighbour is invalid)."""
    P = depth[..., None] * rays
    p = np.pad(P, ((1, 1), (1, 1), (0, 0)), mode="edge")
    du = p[1:-1, 2:] - p[1:-1, :-2]
    dv = p[2:, 1:-1] - p[:-2, 1:-1]
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    ok = (depth > 0)
    v = np.pad(ok, 1, mode="edge")
    ok &= v[:-2, 1:-1] & v[2:, 1:-1] & v[1:-1, :-2] & v[1:-1, 2:]
    return np.where(ok[..., None] & (norm > 0), n / np.maximum(norm, 1e-300), 0.0)
