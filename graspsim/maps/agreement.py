"""Whether an adapted grasp is borne out by the observed cloud (robust mode).

An adapted map's grasps are made on the identified primitives, and a primitive is only
as good as its fit. Where a decomposition's parts are coarse -- a half-toroid laid over a
ring's hole, a sphere over a knobbly end, a box over a rounded body -- the map can offer
grasps whose contacts lie centimetres from any observed point: the fingers close on air
(NO_CONTACT), or touch the real surface where it slopes and the object turns in the hand
(PLACE_FAILED) or slides out (DROPPED). In E09 (full clouds, robust identification) every
failed trial of the published run had such contacts; the contacts of the successful ones
lay within the noise of the cloud.

A contact is *observed* when a cloud point lies within ``tol`` of it. Where none does,
the finger closing along the line goes on past it, and the cloud says where it will
touch: the first observed point within ``tol`` of the closing line, probed inwards from
the contact to the grasp's middle. A contact is *borne out* where the cloud shows the
finger's touch -- at its place or further in along the closing path -- with the cloud's
own surface normal there (PCA over the ``k`` nearest points) within the friction cone
about the closing line: the condition the map's grade assumed for the primitive's
normal. A shown touch whose normal lies outside the cone is evidence *against* the
grasp (the finger meets a slope, and the object turns or slides). A contact whose
closing path meets no observed point is *unobserved*. In a single view that is no
evidence either way -- the far side, which the camera never saw, is where the second
contact of most grasps lies --; in a cloud seen all round it is: the finger closes on
air (E09's mug, full cloud: a half-toroid laid over the rim put one contact of each of
its 10 best grasps 9-11 mm above the rim, where the pads met only the rim's edge with
their corners, and 8 of the 10 dropped). A grasp is kept when no contact is evidence
against it and at least ``min_observed`` contacts are borne out: the planner asks 1 of
a single view, 2 of a cloud seen all round (:class:`graspsim.planning.observed.ObservedChecks`).

With the ``viewpoint`` of a single view, the cloud's normals are oriented: a surface the
camera saw faces it, so its outward normal points to the camera's side. A finger must
meet a surface from outside: where the touch it is shown is the back of a seen surface
-- the finger would close from inside the object, e.g. on the hidden far face of a thin
slab fitted to one seen face of a box -- the touch is evidence against the grasp.
Without a viewpoint a normal's sign is unknown and either side counts.

Why the closing path, not the contact's place: in E09 (single views, robust
identification) a coarse part's contacts lie 20-30 mm out in the air over a rounded
body, and the fingers, closing on, meet the observed surface and hold; requiring the
contact observed at its place dropped every grasp of ten objects of 42. Where the path
meets a slope instead, the normal decides.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError

__all__ = ["ObservedSurface"]


class ObservedSurface:
    """The observed points (N, 3) [m] of one plan, indexed once for every batch."""

    def __init__(self, points: np.ndarray, *, k: int = 16, viewpoint: np.ndarray | None = None) -> None:
        p = np.asarray(points, float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InvalidParameterError(f"points must be (N, 3), got shape {p.shape}")
        from graspsim.maps.occlusion import check_viewpoint

        self.viewpoint = check_viewpoint(viewpoint)
        self.points = p[np.all(np.isfinite(p), axis=1)]
        self.k = int(min(k, max(len(self.points) - 1, 1)))
        self.tree = cKDTree(self.points) if len(self.points) else None
        self._normals: dict[int, np.ndarray] = {}

    def normals_at(self, index: np.ndarray) -> np.ndarray:
        """(M, 3) unit normals (sign arbitrary) of the surface at cloud points ``index``
        (M,): the least-variance axis of each point's k nearest points."""
        index = np.asarray(index, np.int64)
        _, nb = self.tree.query(self.points[index], k=self.k + 1)
        q = self.points[nb]
        q = q - q.mean(axis=1, keepdims=True)
        _, vecs = np.linalg.eigh(np.matmul(q.transpose(0, 2, 1), q))
        return vecs[:, :, 0]

    def borne_out(self, contacts: np.ndarray, *, tol: float, max_angle: float,
                  min_observed: int) -> np.ndarray:
        """(G,) bool for grasps with ``contacts`` (G, 2, 3) in the cloud's frame [m]: see
        the module docstring. tol [m]; max_angle: the friction cone's half-angle [rad];
        min_observed: 1 or 2."""
        if min_observed not in (1, 2):
            raise InvalidParameterError(f"min_observed must be 1 or 2, got {min_observed!r}")
        agree, borne = self.evidence(contacts, tol=tol, max_angle=max_angle)
        return agree & (borne >= min_observed)

    def evidence(self, contacts: np.ndarray, *, tol: float, max_angle: float) -> tuple[np.ndarray, np.ndarray]:
        """What the cloud says of grasps with ``contacts`` (G, 2, 3) [m, cloud frame]:
        (agree (G,) bool: no contact is evidence against the grasp; borne (G,) int: its
        contacts borne out, 0-2). :meth:`borne_out` keeps ``agree & (borne >=
        min_observed)``. No cloud: nothing agrees."""
        c = np.asarray(contacts, float)
        if not len(c) or self.tree is None:
            return np.zeros(len(c), bool), np.zeros(len(c), int)
        d, j = self.tree.query(c.reshape(-1, 3), k=1, distance_upper_bound=tol)
        shown = np.isfinite(d)  # (G * 2,) flat index g * 2 + side
        u = c[:, 1] - c[:, 0]
        half = 0.5 * np.linalg.norm(u, axis=1)
        u /= np.maximum(2.0 * half, 1e-12)[:, None]
        self._probe(c, u, half, tol, shown, j, np.ones(shown.size, bool))
        agree = np.ones(shown.size, bool)
        flat = np.flatnonzero(shown)
        if len(flat):
            uniq, inv = np.unique(j[flat], return_inverse=True)
            n = self.normals_at(uniq)
            inward = np.repeat(u, 2, axis=0)[flat] * np.where(flat % 2 == 0, 1.0, -1.0)[:, None]
            if self.viewpoint is None:  # sign unknown: either side of the surface
                cos = np.abs(np.einsum("ij,ij->i", n[inv.reshape(-1)], inward))
            else:  # outward = towards the camera; the finger moving inward must meet it head-on
                n = n * np.where(np.einsum("ij,ij->i", n, self.viewpoint - self.points[uniq]) < 0, -1.0, 1.0)[:, None]
                cos = -np.einsum("ij,ij->i", n[inv.reshape(-1)], inward)
            agree[flat] = cos >= np.cos(max_angle)
        borne = (shown & agree).reshape(-1, 2).sum(axis=1)
        return np.all(agree.reshape(-1, 2), axis=1), borne

    def _probe(self, c: np.ndarray, u: np.ndarray, half: np.ndarray, tol: float,
               shown: np.ndarray, j: np.ndarray, live: np.ndarray) -> None:
        """For the unobserved contacts still in question (``shown`` False, ``live``
        True; flat index g * 2 + side), the
        first cloud point within ``tol`` of the closing line inwards of the contact, up
        to the grasp's middle: ``shown`` set and ``j`` (the nearest point's index)
        replaced where there is one. In place."""
        miss = np.flatnonzero(~shown & live)
        if not len(miss):
            return
        g, side = miss // 2, miss % 2
        inward = np.where(side[:, None] == 0, u[g], -u[g])
        steps = np.arange(1, int(np.ceil(half[g].max() / tol)) + 1) * tol  # (S,)
        probe = c[g, side][:, None, :] + steps[None, :, None] * inward[:, None, :]  # (M, S, 3)
        within = steps[None, :] <= half[g][:, None]
        dd, jj = self.tree.query(probe.reshape(-1, 3), k=1, distance_upper_bound=tol)
        hit = (np.isfinite(dd).reshape(probe.shape[:2]) & within)
        any_hit = hit.any(axis=1)
        first = np.argmax(hit, axis=1)
        shown[miss[any_hit]] = True
        j[miss[any_hit]] = jj.reshape(probe.shape[:2])[any_hit, first[any_hit]]
