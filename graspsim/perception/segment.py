"""Objects of a scene: Euclidean clustering of the points left above the table.

Two points belong to one object when a chain of points links them with no step longer
than ``radius``: the connected components of the radius graph (scipy's ``cKDTree``
pairs, ``connected_components``). The radius is set by the smallest gap between objects
that must stay apart, less a margin for sensor noise (:data:`DEFAULT_RADIUS`: 7 mm for
the 1 cm gaps of packed scenes), not by the cloud's spacing: on a dense cloud a radius
of a few spacings breaks one object wherever a single view shows it with a crevice (a
tab against a ball) and gains nothing, as objects 1 cm apart stay apart at 7 mm.
Components with fewer than ``min_points`` points (sensor speckle, slivers of the table's
edge) are noise (label -1). Labels are numbered by size, largest first; the numbering is
fixed by the points, not by the order of the scan.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError

__all__ = ["DEFAULT_RADIUS", "euclidean_clusters"]

#: The default linking radius [m]: 3 mm under the 1 cm gap packed scenes keep between
#: objects (the closest points of two such objects seen by the D435-like camera of E10,
#: depth noise on, were 9.9 mm apart over 100 scenes; ``experiments/study_segmentation.py``).
DEFAULT_RADIUS = 0.007


def euclidean_clusters(points: np.ndarray, *, radius: float, min_points: int = 40) -> np.ndarray:
    """(N,) int labels of points (N, 3) [m]: 0, 1, ... by component size (largest
    first; ties by the lowest point index), -1 for components smaller than
    ``min_points``."""
    if not (np.isfinite(radius) and radius > 0):
        raise InvalidParameterError(f"radius must be > 0 m, got {radius!r}")
    if isinstance(min_points, bool) or not isinstance(min_points, (int, np.integer)) or min_points < 1:
        raise InvalidParameterError(f"min_points must be an integer >= 1, got {min_points!r}")
    pts = np.asarray(points, float)
    n = len(pts)
    labels = np.full(n, -1, np.int64)
    if n == 0:
        return labels
    pairs = cKDTree(pts).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp)
    first = np.full(len(sizes), n)
    np.minimum.at(first, comp, np.arange(n))
    keep = np.flatnonzero(sizes >= min_points)
    order = keep[np.lexsort((first[keep], -sizes[keep]))]
    new = np.full(len(sizes), -1, np.int64)
    new[order] = np.arange(len(order))
    return new[comp]
