"""Geometry below maps and perception that both use: a cloud's point spacing
(:mod:`~graspsim.geometry.spacing`, with its compiled kernel) and the table plane an object
stands on (:mod:`~graspsim.geometry.table`).

May use: the base modules only (errors, transforms) and numba for the kernel."""
