"""Files installed with the package: the vendored MuJoCo models (``mjcf/``), the mesh
objects scenes draw (``assets/``) and fitted data (``graspsim/data``).

``mjcf/`` and ``assets/`` sit at the repository's top level beside ``graspsim/``; a wheel
installs them inside the package (``graspsim/mjcf``, ``graspsim/assets``: pyproject's
package-dir mapping). :func:`package_path` looks inside the installed package first
(:mod:`importlib.resources`: a wheel) and then beside it (a checkout on ``PYTHONPATH`` or
an editable install, whose package is the checkout's ``graspsim/``), never relative to
the working directory.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["TOP_LEVEL", "package_path"]

#: Data folders kept at the repository's top level and installed inside the package.
TOP_LEVEL = ("mjcf", "assets")


def package_path(*parts: str) -> Path:
    """The installed file or folder ``graspsim/<parts...>`` as a file-system path
    (graspsim is installed as plain files, not zipped: MuJoCo and trimesh read paths);
    for ``mjcf`` and ``assets``, the top-level folder of a checkout when the package does
    not hold them."""
    inside = Path(str(resources.files("graspsim")))
    if parts and parts[0] in TOP_LEVEL and not (inside / parts[0]).is_dir():
        return inside.parent.joinpath(*parts)
    return inside.joinpath(*parts)
