"""Objects of a scene: Euclidean clustering of the points left above the table.

Two points belong to one object when a chain of points links them with no step longer
than ``radius``: the connected components of the radius graph (scipy's ``cKDTree``
pairs, ``connected_components``). The radius follows the cloud's spacing (the median
distance of a point to its nearest neighbour) and is capped below the smallest gap
between objects that must stay apart (1 cm in the issue's packed scenes). Components
with fewer than ``min_points`` points (sensor speckle, slivers of the table's edge) are
noise (label -1). Labels are numbered by size, largest first; the numbering is fixed by
the points, not by the order of the scan.

Where the user knows the least gap between any two objects (objects placed apart: a
packed shelf, a kitting tray), components closer than :data:`GAP_LINK` x that gap are
then joined (``link``): from one view, an object's own parts can be parted by more than
the spacing rule bridges (the crevice between a ball and a tab beside it, the shadow one
part casts on another), and anything shorter than the known gap, less a margin for depth
noise, is within one object. Only components that are objects join: noise stays noise,
and a component's points stay the spacing rule's.

Touching objects (a pile) are joined by the spacing rule wherever their surfaces meet. Seen
from one viewpoint, where two objects meet the surface mostly folds inwards: a *concave
crease*, while an object's own surface is mostly convex or flat. With ``crease_angle``
(and the ``viewpoint`` that orients the normals outwards, towards the camera), every
link across which the surface folds inwards by more than that angle -- the two normals
turn towards each other, ``(n_i - n_j) . (p_i - p_j) / |p_i - p_j| < -2 sin(angle / 2)``,
the local convexity test of LCCP (Stein et al. 2014) -- marks both its points as crease
points; the components of the other points are the objects, and each crease point joins
the component of its nearest linked kept point, ring by ring (a cut removes a band of
points, not single links, which depth noise would bridge). Normals are the local PCA planes of the
:data:`NORMAL_K` nearest points. A piece under ``min_points`` rejoins the neighbour it
shares most links with. An object whose own surface folds inwards that sharply (a duck's
neck, a mug's handle) is split there: the price of parting touching objects.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError

__all__ = ["GAP_LINK", "NORMAL_K", "point_spacing", "cluster_radius", "gap_link", "euclidean_clusters",
           "view_normals", "crease_cuts"]

#: Neighbours of a point whose PCA plane is its normal (crease cutting): on the 3 mm
#: grid, a patch about 6 mm in radius, wider than a D435's depth noise at 0.7 m.
NORMAL_K = 24
#: Kept points a piece needs to take in the crease points near it (fewer: it is noise).
CORE_POINTS = 5

#: With a known least gap g [m] between objects, components are joined across gaps up to
#: GAP_LINK x g: the margin covers depth noise bringing two objects' surfaces closer (a
#: D435-like sensor at 0.7 m: sigma ~ 2.3 mm per pixel; in E10's packed scenes, 1 cm
#: apart, the closest points of two objects seen from one camera are 9.5 mm apart).
GAP_LINK = 0.8


def point_spacing(points: np.ndarray, *, sample: int = 2000) -> float:
    """Median distance [m] from a point to its nearest neighbour, over at most
    ``sample`` points spread evenly through the cloud (N, 3); 0 for fewer than two."""
    pts = np.asarray(points, float)
    if len(pts) < 2:
        return 0.0
    probe = pts[np.linspace(0, len(pts) - 1, min(sample, len(pts))).astype(int)]
    d, _ = cKDTree(pts).query(probe, k=2)
    return float(np.median(d[:, 1]))


def cluster_radius(points: np.ndarray, *, factor: float = 2.5, min_radius: float = 0.003,
                   max_radius: float = 0.007) -> float:
    """The linking radius [m]: ``factor`` x the spacing, within [min_radius, max_radius]
    (``max_radius`` below the smallest gap to keep: two objects 1 cm apart stay two)."""
    if not (0 < min_radius <= max_radius and factor > 0):
        raise InvalidParameterError(f"need factor > 0 and 0 < min_radius <= max_radius, got {factor!r}, "
                                    f"{min_radius!r}, {max_radius!r}")
    return float(np.clip(factor * point_spacing(points), min_radius, max_radius))


def gap_link(min_gap: float | None) -> float | None:
    """The distance [m] across which components join, given ``min_gap`` [m], the least
    gap known to part any two objects: :data:`GAP_LINK` x ``min_gap`` (None: none)."""
    if min_gap is None:
        return None
    if isinstance(min_gap, bool) or not isinstance(min_gap, (int, float)) or not 0 < min_gap <= 0.1:
        raise InvalidParameterError(f"min_gap must be in (0, 0.1] m or None, got {min_gap!r}")
    return float(GAP_LINK * min_gap)


def _components(points: np.ndarray, radius: float, pairs: np.ndarray | None = None) -> np.ndarray:
    n = len(points)
    if pairs is None:
        pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def view_normals(points: np.ndarray, viewpoint, *, k: int = NORMAL_K) -> np.ndarray:
    """(N, 3) unit normals of points (N, 3): the smallest principal axis of each point's
    ``k`` nearest neighbours, turned towards ``viewpoint`` (3,) (what one camera sees
    faces it)."""
    pts = np.asarray(points, float)
    k = min(k, len(pts))
    _, idx = cKDTree(pts).query(pts, k=k)
    nb = pts[idx.reshape(len(pts), -1)]
    nb = nb - nb.mean(1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    n = np.linalg.eigh(cov)[1][:, :, 0]
    flip = np.einsum("ni,ni->n", n, np.asarray(viewpoint, float) - pts) < 0
    n[flip] *= -1
    return n


def crease_cuts(points: np.ndarray, normals: np.ndarray, pairs: np.ndarray, angle: float) -> np.ndarray:
    """(P,) bool: the links ``pairs`` (P, 2) across which the surface folds inwards by
    more than ``angle`` [deg] (see the module docstring)."""
    d = points[pairs[:, 0]] - points[pairs[:, 1]]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    fold = np.einsum("pi,pi->p", normals[pairs[:, 0]] - normals[pairs[:, 1]], d)
    return fold < -2.0 * np.sin(np.radians(angle) / 2.0)


def _cut_components(pts: np.ndarray, radius: float, min_points: int, viewpoint, angle: float) -> np.ndarray:
    """Components of the radius graph with the crease points taken out (both ends of
    every link across a concave crease sharper than ``angle``), each point taken out
    then given to the component of its nearest kept point within ``radius`` (repeated
    outwards); a component under ``min_points`` rejoins the neighbour it shares most
    links with."""
    n = len(pts)
    pairs = cKDTree(pts).query_pairs(radius, output_type="ndarray")
    if not len(pairs):
        return np.arange(n)
    a, b = pairs[:, 0], pairs[:, 1]
    cut = crease_cuts(pts, view_normals(pts, viewpoint), pairs, angle)
    crease = np.zeros(n, bool)
    crease[a[cut]] = crease[b[cut]] = True
    comp = _components(pts, radius, pairs[~crease[a] & ~crease[b]])
    core = ~crease & (np.bincount(comp, weights=~crease)[comp] >= CORE_POINTS)
    for _ in range(8):  # the others join the piece of their nearest linked core point, ring by ring
        if not core.any() or core.all():
            break
        d, j = cKDTree(pts[core]).query(pts[~core], distance_upper_bound=radius)
        reach = np.isfinite(d)
        if not reach.any():
            break
        rest = np.flatnonzero(~core)
        comp[rest[reach]] = comp[np.flatnonzero(core)[j[reach]]]
        core[rest[reach]] = True
    comp[~core] += n  # unreached: pieces of their own
    comp = np.unique(comp, return_inverse=True)[1].reshape(-1)
    for _ in range(4):  # small pieces rejoin (a piece may need its neighbour to rejoin first)
        size = np.bincount(comp)
        ca, cb = comp[a], comp[b]
        keep = (ca != cb) & ((size[ca] < min_points) | (size[cb] < min_points))
        if not keep.any():
            break
        ca, cb = ca[keep], cb[keep]
        lo = np.where(size[ca] <= size[cb], ca, cb)  # the smaller piece joins the larger
        hi = np.where(size[ca] <= size[cb], cb, ca)
        edges, counts = np.unique(np.stack([lo, hi], 1), axis=0, return_counts=True)
        order = np.lexsort((edges[:, 1], -counts, edges[:, 0]))  # per piece: most links first
        pieces, first = np.unique(edges[order, 0], return_index=True)
        target = np.arange(len(size))
        target[pieces] = edges[order[first], 1]
        settled = size >= min_points
        target[settled] = np.flatnonzero(settled)  # objects stay
        for _ in range(8):  # follow chains of small pieces to a settled one
            target = target[target]
        comp = target[comp]
    return np.unique(comp, return_inverse=True)[1].reshape(-1)


def euclidean_clusters(points: np.ndarray, *, radius: float, min_points: int = 40,
                       link: float | None = None, viewpoint=None, crease_angle: float | None = None) -> np.ndarray:
    """(N,) int labels of points (N, 3) [m]: 0, 1, ... by component size (largest
    first; ties by the lowest point index), -1 for components smaller than
    ``min_points``. ``link`` [m]: components (of at least ``min_points``) whose closest
    points are nearer than this are then one object; ``crease_angle`` [deg] with
    ``viewpoint`` (3,): links across concave creases sharper than it are cut first (see
    the module docstring)."""
    if not (np.isfinite(radius) and radius > 0):
        raise InvalidParameterError(f"radius must be > 0 m, got {radius!r}")
    if link is not None and not (np.isfinite(link) and link > 0):
        raise InvalidParameterError(f"link must be > 0 m or None, got {link!r}")
    if isinstance(min_points, bool) or not isinstance(min_points, (int, np.integer)) or min_points < 1:
        raise InvalidParameterError(f"min_points must be an integer >= 1, got {min_points!r}")
    pts = np.asarray(points, float)
    n = len(pts)
    if n == 0:
        return np.full(0, -1, np.int64)
    if crease_angle is not None and viewpoint is not None and n > 3:
        comp = _cut_components(pts, radius, min_points, viewpoint, float(crease_angle))
    else:
        comp = _components(pts, radius)
    big = np.bincount(comp)[comp] >= min_points
    if link is not None and link > radius and big.any():
        joined = _components(pts[big], link)  # components of objects' points only: noise joins nothing
        comp[big] = comp.max() + 1 + joined
        comp = np.unique(comp, return_inverse=True)[1].reshape(-1)
    sizes = np.bincount(comp)
    first = np.full(len(sizes), n)
    np.minimum.at(first, comp, np.arange(n))
    keep = np.flatnonzero(sizes >= min_points)
    order = keep[np.lexsort((first[keep], -sizes[keep]))]
    new = np.full(len(sizes), -1, np.int64)
    new[order] = np.arange(len(order))
    return new[comp]
