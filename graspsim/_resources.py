"""Files installed with the package: the vendored MuJoCo models (``graspsim/mjcf``), the
mesh objects scenes draw (``graspsim/assets``) and fitted data (``graspsim/data``).

Found through :mod:`importlib.resources`, so they are where the installed package is (a
wheel, an editable install or a checkout on ``PYTHONPATH``), never relative to a
repository root.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["package_path"]


def package_path(*parts: str) -> Path:
    """The installed file or folder ``graspsim/<parts...>`` as a file-system path
    (graspsim is installed as plain files, not zipped: MuJoCo and trimesh read paths)."""
    return Path(str(resources.files("graspsim").joinpath(*parts)))
