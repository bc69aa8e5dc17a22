"""Two-jaw parallel gripper specification (Festo HGPL-25-60-A style by default).

One :class:`GripperSpec` drives both the planner's collision geometry and the MuJoCo
model, so the two can never disagree about the gripper.

Wrist frame (docs/design.md §3): origin at the centre of the housing's mounting face (the
flange), z = approach direction (towards the fingertips), x = jaw closing axis,
y = z × x. All parts are boxes aligned with the wrist frame:

* housing: ``housing_size`` (x, y, z), occupying z in [0, Hz];
* two jaws (carriages): ``jaw_size``, below the housing, z in [Hz, Hz + Jz];
* two flat fingers: ``finger_size`` (thickness x, width y, length z) below the jaws;
  their inner faces are the pads, at x = ±opening/2;
* an arm keep-out: the robot's wrist behind the flange, z in [-arm_length, 0], with
  the housing's x-y footprint (the planner must not put the arm inside the object).

No data sheet is at hand. Every value is a named parameter; the defaults below are
estimates for the HGPL-25-60-A (type code HGPL-<bore mm>-<stroke per jaw mm>) and for
home-made aluminium fingers, each with its derivation in the field's comment.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from graspsim.errors import GripperError

__all__ = ["GripperSpec", "CollisionBoxes", "HGPL_25_60_A"]


@dataclass(frozen=True)
class CollisionBoxes:
    """Wrist-frame boxes of the gripper at some opening.

    names: (B,) part names; centers, half_extents: (B, 3) [m] in the wrist frame.
    x_sign: (B,) -1/0/+1: the box's x centre moves by x_sign * opening / 2.
    """

    names: tuple[str, ...]
    centers: np.ndarray
    half_extents: np.ndarray
    x_sign: np.ndarray


@dataclass(frozen=True)
class GripperSpec:
    """A two-jaw parallel gripper with flat fingers. Lengths [m], masses [kg], SI."""

    name: str = "festo_hgpl_25_60_a"
    # Housing: ~180 mm long to carry two 60 mm strokes plus the 30 mm jaws
    # (2 * (60 + 30) = 180), 50 mm wide and 60 mm tall (estimated from the size-25 bore).
    housing_size: tuple[float, float, float] = (0.180, 0.050, 0.060)
    # Jaw carriages protruding 15 mm below the housing, full housing width, 30 mm long.
    jaw_size: tuple[float, float, float] = (0.030, 0.050, 0.015)
    # Flat aluminium fingers: 10 mm thick, 20 mm wide, 80 mm long below the jaw.
    finger_size: tuple[float, float, float] = (0.010, 0.020, 0.080)
    # Contact region of the finger's inner face, measured from the fingertip.
    pad_length: float = 0.040
    # Contacts closer than this to the tip or to the pad's upper end are not planned.
    contact_depth_margin: float = 0.005
    # 60 mm stroke per jaw (the "-60" of the type code).
    stroke_per_jaw: float = 0.060
    # Pad-to-pad gap with both jaws fully closed (fingers touching).
    closed_gap: float = 0.0
    # Extra opening on each side when the gripper is placed at the pose (pre-grasp).
    approach_clearance: float = 0.005
    # Grip force per jaw = efficiency * pressure * piston area (bore 25 mm, 6 bar).
    bore: float = 0.025
    pressure: float = 6.0e5
    efficiency: float = 0.85
    # Flow-limited closing speed of each jaw (a pneumatic gripper closes its 60 mm
    # stroke in roughly 0.3 s with standard throttles).
    closing_speed: float = 0.20
    # Masses: housing 1.3 kg (same order as the catalogue mass of this size), jaws
    # 80 g, fingers 43 g (aluminium 10 x 20 x 80 mm).
    housing_mass: float = 1.30
    jaw_mass: float = 0.08
    finger_mass: float = 0.043
    # Robot wrist behind the flange, kept out of the object by the planner.
    arm_length: float = 0.10
    # Grip force per jaw [N] as its maker rates it (an electric gripper); None: the
    # pneumatic efficiency x pressure x piston area above. Left out of ``to_dict`` when
    # None, so the digests of specs without it do not change.
    rated_force: float | None = None
    # The MuJoCo model that simulates this gripper as authored: a vendored folder
    # (``mjcf/<model>/``) or a model file's path (see graspsim.grippers); None: the box
    # model generated from this spec. Left out of ``to_dict`` when None.
    model: str | None = None
    # Contacts closer than this to the fingertip are not planned [m]; None: the
    # contact_depth_margin. For fingers that reach past their pads, or pads that move on
    # an arc (a linkage): the pad region is where the flat face lies at every opening
    # (measured from a model file, graspsim.grippers.model_file). Left out of ``to_dict``
    # when None.
    tip_margin: float | None = None
    # A linkage's pads move on an arc; the planner keeps the straight-line model (pads at
    # x = +-opening/2 and fixed heights, the planned contacts centred on the nominal TCP).
    # Its error [m]: the largest distance along the approach between a pad's centre and
    # the nominal TCP over the opening range, measured from a model file (per opening:
    # graspsim.grippers.model_file.straight_line_error). None: the pads move on a line.
    # Left out of ``to_dict`` when None.
    arc_error: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise GripperError(f"gripper name must be a non-empty string, got {self.name!r}")
        for f in fields(self)[1:]:
            v = getattr(self, f.name)
            if f.name in ("tip_margin", "arc_error") and v is not None:
                object.__setattr__(self, f.name, _checked(f.name, v, False))
            elif f.name == "model":
                if v is not None and not (isinstance(v, str) and (v.isidentifier() or (
                        v.lower().endswith((".xml", ".mjcf", ".urdf")) and ".." not in v.split("/")))):
                    raise GripperError(f"model must be a vendored model name like 'franka_hand', a model file "
                                       f"path (.xml, .urdf) or null, got {v!r}")
            elif not (f.name in _OPTIONAL and v is None):
                object.__setattr__(self, f.name, _checked(f.name, v, isinstance(f.default, tuple)))
        if not 0 < self.efficiency <= 1:
            raise GripperError(f"efficiency must be in (0, 1], got {self.efficiency!r}")
        if self.pad_length > self.finger_size[2]:
            raise GripperError(
                f"pad_length {self.pad_length} m exceeds the finger length {self.finger_size[2]} m"
            )
        if 2 * self.contact_depth_margin >= self.pad_length:
            raise GripperError(
                f"contact_depth_margin {self.contact_depth_margin} m leaves no pad: must be < "
                f"pad_length / 2 = {self.pad_length / 2} m"
            )
        if self.depth_lo >= self.depth_hi:
            raise GripperError(
                f"tip_margin {self.tip_margin} m and contact_depth_margin {self.contact_depth_margin} m leave "
                f"no pad of pad_length {self.pad_length} m")
        if self.finger_size[0] > self.jaw_size[0] or self.finger_size[1] > self.jaw_size[1]:
            raise GripperError("fingers must not be thicker or wider than the jaws they sit on")
        reach = self.max_opening / 2 + self.jaw_size[0]
        if reach > self.housing_size[0] / 2 + 1e-12:
            raise GripperError(
                f"housing length {self.housing_size[0]} m cannot carry the jaws at full opening: "
                f"needs >= {2 * reach:.4f} m"
            )

    # ------------------------------------------------------------------ derived
    @property
    def min_opening(self) -> float:
        """Smallest pad-to-pad gap [m]."""
        return self.closed_gap

    @property
    def max_opening(self) -> float:
        """Largest pad-to-pad gap [m]: closed gap + both strokes."""
        return self.closed_gap + 2.0 * self.stroke_per_jaw

    @property
    def grip_force(self) -> float:
        """Closing force per jaw [N]: ``rated_force`` if given, else the pneumatic
        efficiency * pressure * pi * bore^2 / 4."""
        if self.rated_force is not None:
            return self.rated_force
        return self.efficiency * self.pressure * math.pi * self.bore**2 / 4.0

    @property
    def jaw_base_z(self) -> float:
        """z of the jaws' lower face, where the fingers start [m]."""
        return self.housing_size[2] + self.jaw_size[2]

    @property
    def fingertip_z(self) -> float:
        """z of the fingertips in the wrist frame [m]."""
        return self.jaw_base_z + self.finger_size[2]

    @property
    def depth_lo(self) -> float:
        """Smallest planned contact depth from the fingertip [m] (the tip-side margin)."""
        return self.contact_depth_margin if self.tip_margin is None else self.tip_margin

    @property
    def depth_hi(self) -> float:
        """Largest planned contact depth from the fingertip [m]."""
        return self.pad_length - self.contact_depth_margin

    def contact_depth_count(self, step: float) -> int:
        """How many contact depths :meth:`contact_depths` samples at ``step`` [m]."""
        if not step > 0:
            raise GripperError(f"depth step must be > 0 m, got {step!r}")
        span = self.depth_hi - self.depth_lo
        return int(min(math.floor(span / step + 1e-9), 2.0**62)) + 1

    def contact_depths(self, step: float) -> np.ndarray:
        """Contact distances from the fingertip sampled along the pad [m]."""
        return self.depth_lo + step * np.arange(self.contact_depth_count(step))

    # ------------------------------------------------------------------ wrist <-> TCP
    # The TCP (grasp point) lies on the wrist z axis at every opening (symmetric jaws),
    # ``tcp_offset(depth)`` above the flange for contacts ``depth`` from the fingertips.
    def tcp_offset(self, depth: float | np.ndarray) -> np.ndarray:
        """z of the grasp point (TCP) in the wrist frame for a contact ``depth`` from the
        fingertip [m] (float or array, as ``depth``)."""
        return self.fingertip_z - np.asarray(depth, dtype=float)

    @property
    def nominal_depth(self) -> float:
        """Contact depth of the nominal TCP: mid-pad [m] (with a ``tip_margin``: the middle
        of the planned depths)."""
        return 0.5 * self.pad_length if self.tip_margin is None else 0.5 * (self.depth_lo + self.depth_hi)

    @property
    def nominal_tcp(self) -> np.ndarray:
        """(3,) the nominal TCP in the wrist frame [m]: on the axis at mid-pad, where
        execution noise pivots and the envs place the grasp point."""
        return np.array([0.0, 0.0, float(self.tcp_offset(self.nominal_depth))])

    def wrist_from_grasp_point(self, grasp_point: np.ndarray, approach: np.ndarray,
                               depth: float | np.ndarray) -> np.ndarray:
        """Wrist positions (N, 3) [m] holding grasp points (N, 3) at contact ``depth``
        (scalar or (N,)) from the fingertips, approach (wrist z) unit vectors (N, 3)."""
        off = self.fingertip_z - np.asarray(depth)
        return grasp_point - off[..., None] * approach

    def grasp_point_from_wrist(self, wrist_position: np.ndarray, approach: np.ndarray,
                               depth: float | np.ndarray) -> np.ndarray:
        """Inverse of :meth:`wrist_from_grasp_point`: grasp points (N, 3) [m]."""
        off = self.fingertip_z - np.asarray(depth)
        return wrist_position + off[..., None] * approach

    def contact_depth(self, grasp_point: np.ndarray, wrist_position: np.ndarray,
                      approach: np.ndarray) -> np.ndarray:
        """(N,) contact depth from the fingertips [m] of grasp points (N, 3) held by wrists
        at (N, 3) approaching along unit vectors (N, 3)."""
        return self.fingertip_z - np.einsum("ni,ni->n", grasp_point - wrist_position, approach)

    def check_opening(self, opening: float) -> None:
        if not (self.min_opening - 1e-12 <= opening <= self.max_opening + 1e-12):
            raise GripperError(
                f"opening {opening} m outside the gripper's range "
                f"[{self.min_opening}, {self.max_opening}] m"
            )

    def collision_boxes(self) -> CollisionBoxes:
        """Part boxes in the wrist frame; x centres move with the opening (``x_sign``)."""
        hx, hy, hz = (0.5 * v for v in self.housing_size)
        jx, jy, jz = (0.5 * v for v in self.jaw_size)
        fx, fy, fz = (0.5 * v for v in self.finger_size)
        Hz, Jb = self.housing_size[2], self.jaw_base_z
        names = ("arm", "housing", "jaw_neg", "jaw_pos", "finger_neg", "finger_pos")
        centers = np.array(
            [
                [0.0, 0.0, -0.5 * self.arm_length],
                [0.0, 0.0, hz],
                [-jx, 0.0, Hz + jz],
                [jx, 0.0, Hz + jz],
                [-fx, 0.0, Jb + fz],
                [fx, 0.0, Jb + fz],
            ]
        )
        half = np.array(
            [[hx, hy, 0.5 * self.arm_length], [hx, hy, hz], [jx, jy, jz], [jx, jy, jz],
             [fx, fy, fz], [fx, fy, fz]]
        )
        sign = np.array([0, 0, -1, 1, -1, 1])
        keep = half[:, 2] > 0
        return CollisionBoxes(
            tuple(n for n, k in zip(names, keep) if k), centers[keep], half[keep], sign[keep]
        )

    def boxes_at(self, opening: float) -> tuple[np.ndarray, np.ndarray]:
        """Box centres and half extents (B, 3) in the wrist frame at a pad gap."""
        self.check_opening(opening)
        b = self.collision_boxes()
        c = b.centers.copy()
        c[:, 0] += b.x_sign * 0.5 * opening
        return c, b.half_extents

    def pregrasp_opening(self, width: np.ndarray) -> np.ndarray:
        """Pad gap (N,) [m] at the pose: the contact width + 2 x approach clearance,
        clipped to the opening range (as the simulator opens the jaws)."""
        return np.clip(np.asarray(width, float) + 2.0 * self.approach_clearance,
                       self.min_opening, self.max_opening)

    def lowest_point(self, T_world_wrist: np.ndarray, opening: np.ndarray) -> np.ndarray:
        """(N,) lowest z [m] of any gripper box (arm keep-out included) at wrist poses
        (N, 4, 4) with pad gaps (N,): a pose with a table at z = 0 is reachable only if
        this is above 0."""
        T = np.asarray(T_world_wrist, float).reshape(-1, 4, 4)
        return self.lowest_along(T[:, 2, :3], T[:, 2, 3], opening)

    def lowest_along(self, up: np.ndarray, height: np.ndarray, opening: np.ndarray) -> np.ndarray:
        """(N,) lowest height [m] of any gripper box (arm keep-out included) along a unit
        direction whose components in each wrist frame are ``up`` (N, 3) (row 2 of
        R_world_wrist for world z), the wrist origin at ``height`` (N,) along it, pad
        gaps ``opening`` (N,). A box's lowest corner is its centre's height minus
        sum_i |up_i| x half extent_i, so no corner is enumerated: O(N x boxes)."""
        up = np.asarray(up, float).reshape(-1, 3)
        height = np.asarray(height, float).reshape(-1)
        opening = np.broadcast_to(np.asarray(opening, float), (len(up),))
        b = self.collision_boxes()
        z = b.centers @ up.T - b.half_extents @ np.abs(up).T  # (B, N): a reduction over rows is fast
        z += b.x_sign[:, None] * (0.5 * opening * up[:, 0])[None]  # the jaws and fingers open along x
        return z.min(axis=0) + height

    def points_between(self, T_wrist: np.ndarray, opening: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(N,) how many of ``points`` (M, 3) lie in each pose's closing region: between the
        pad faces at the pad gap ``opening`` (N,) [m] (strictly inside), across the finger
        width, along the pad (its ``pad_length`` up from the fingertips), at wrist poses
        ``T_wrist`` (N, 4, 4) in the points' frame -- what the pads would close on."""
        from graspsim.grippers.between_kernel import count_between  # numba: loaded on first use

        T = np.asarray(T_wrist, float).reshape(-1, 4, 4)
        half = np.ascontiguousarray(0.5 * np.broadcast_to(np.asarray(opening, float), (len(T),)))
        P = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 3))
        out = np.zeros(len(T), np.int64)
        if not len(P) or not len(T):
            return out
        count_between(np.ascontiguousarray(T[:, :3, :3]), np.ascontiguousarray(T[:, :3, 3]), half, P,
                      0.5 * float(self.finger_size[1]), float(self.fingertip_z - self.pad_length),
                      float(self.fingertip_z), out)
        return out

    # ------------------------------------------------------------------ storage
    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()
                if not (k in _OPTIONAL and v is None)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict) -> GripperSpec:
        if not isinstance(d, dict):
            raise GripperError(f"a gripper specification must be a dict, got {d!r}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise GripperError(f"unknown gripper parameters {unknown}; valid: {sorted(known)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})

    @classmethod
    def from_json(cls, text: str) -> GripperSpec:
        try:
            return cls.from_dict(json.loads(text))
        except json.JSONDecodeError as err:
            raise GripperError(f"gripper configuration is not valid JSON: {err}") from err


def _checked(name: str, v, triple: bool):
    """A field's value validated: three positive lengths (``triple``: the box sizes) or
    a finite number (> 0; >= 0 for the gap and the arm)."""
    if triple:
        if not isinstance(v, (tuple, list, np.ndarray)):
            raise GripperError(f"{name} must be three positive lengths [m], got {v!r}")
        try:
            t = tuple(float(x) for x in v)
        except (TypeError, ValueError):
            raise GripperError(f"{name} must be three positive lengths [m], got {v!r}") from None
        if len(t) != 3 or not all(math.isfinite(x) and x > 0 for x in t):
            raise GripperError(f"{name} must be three positive lengths [m], got {v!r}")
        return t
    try:
        fv = float(v)
    except (TypeError, ValueError):
        raise GripperError(f"{name} must be a number, got {v!r}") from None
    zero_ok = name in ("closed_gap", "arm_length")
    if not (math.isfinite(fv) and (fv >= 0 if zero_ok else fv > 0)):
        raise GripperError(f"{name} must be finite and {'>= 0' if zero_ok else '> 0'}, got {v!r}")
    return fv


_OPTIONAL = ("rated_force", "model", "tip_margin", "arc_error")

HGPL_25_60_A = GripperSpec()
