"""Reading depth images from disk: what an RGB-D camera's driver writes, as z-depth in metres.

A one-channel PNG or TIFF (16-bit millimetres, as RealSense and most RGB-D drivers write
them; 32-bit integer or float too) or a ``.npy`` (H, W) array. Back-projection with the
camera's intrinsics is :func:`graspsim.geometry.camera.backproject`'s (``graspsim plan-scene
DEPTH --camera d435``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from graspsim.errors import PointCloudError

__all__ = ["read_depth_image", "DEPTH_SUFFIXES", "MAX_DEPTH", "MAX_PIXELS"]

#: Depth image files :func:`read_depth_image` reads.
DEPTH_SUFFIXES = (".png", ".tif", ".tiff", ".npy")

#: The farthest median depth [m] a table-top depth image is taken to have (a wrong
#: ``scale`` -- millimetres read as metres -- gives hundreds).
MAX_DEPTH = 10.0

#: The most pixels a depth image may have (4096 x 4096): a depth camera gives at most a
#: few million; a larger file is refused before its pixels are read (a 20000 x 20000
#: image would take GBs once back-projected).
MAX_PIXELS = 4096 * 4096


def _too_big(path: Path, shape) -> PointCloudError:
    return PointCloudError(f"{path.name}: {shape[1]} x {shape[0]} pixels is not a depth camera's image (at most "
                           f"{MAX_PIXELS:,} pixels, e.g. 4096 x 4096)")


def read_depth_image(path: str | Path, *, scale: float | None = None) -> tuple[np.ndarray, float]:
    """A depth image file as z-depth (H, W) [m], 0 where nothing valid was seen, and the
    scale used: a 16-bit (or 32-bit integer or float) one-channel PNG or TIFF, or a
    ``.npy`` (H, W) array, each value times ``scale`` metres (default: 0.001 for integer
    images -- millimetres, as RealSense and most RGB-D drivers write them -- and 1 for
    float arrays). Values that are not finite or not above 0 are invalid. A depth too far
    for a table-top view (median of the valid pixels beyond :data:`MAX_DEPTH`) is refused
    as a wrong scale."""
    path = Path(path)
    if scale is not None and not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise PointCloudError(f"the depth scale must be a positive number of metres per unit, got {scale!r}")
    if not path.is_file():
        raise PointCloudError(f"depth image {str(path)!r} does not exist or is not a file")
    suffix = path.suffix.lower()
    if suffix not in DEPTH_SUFFIXES:
        raise PointCloudError(f"{path.name}: unknown depth image format {suffix!r}; valid: {list(DEPTH_SUFFIXES)}")
    try:
        if suffix == ".npy":
            lazy = np.load(path, allow_pickle=False, mmap_mode="r")  # the header first: its size
            if lazy.ndim == 2 and lazy.shape[0] * lazy.shape[1] > MAX_PIXELS:
                raise _too_big(path, lazy.shape)
            raw = np.array(lazy)
            del lazy
        else:
            import warnings

            from PIL import Image

            with warnings.catch_warnings():  # PIL warns of damaged files (corrupt EXIF ...): an error here
                warnings.simplefilter("error")
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # the size is checked here
                try:
                    im = Image.open(path)
                except Image.DecompressionBombError as err:
                    raise PointCloudError(f"{path.name}: not a depth camera's image (at most {MAX_PIXELS:,} "
                                          f"pixels): {err}") from None
                with im:
                    if im.size[0] * im.size[1] > MAX_PIXELS:
                        raise _too_big(path, im.size[::-1])
                    if len(im.getbands()) != 1:
                        raise PointCloudError(f"a depth image has one channel; this one has {len(im.getbands())} "
                                              f"({im.mode}): is it the colour image?")
                    raw = np.asarray(im)
    except PointCloudError as err:
        msg = str(err)
        raise PointCloudError(msg if msg.startswith(path.name) else f"{path.name}: {msg}") from None
    except (OSError, ValueError, EOFError, SyntaxError, Warning) as err:  # SyntaxError: PIL's broken-file error
        raise PointCloudError(f"{path.name}: cannot read {suffix} depth image: {err}") from err
    if raw.ndim != 2 or raw.dtype.kind not in "uif" or min(raw.shape) < 2:
        raise PointCloudError(f"{path.name}: a depth image is an (H, W) array of numbers, got shape {raw.shape} "
                              f"of {raw.dtype}")
    used = float(scale) if scale is not None else 1.0 if raw.dtype.kind == "f" else 0.001
    depth = raw.astype(np.float64) * used
    valid = np.isfinite(depth) & (depth > 0)
    depth[~valid] = 0.0
    if not valid.any():
        raise PointCloudError(f"{path.name}: no pixel has a valid depth (all 0, negative or NaN)")
    median = float(np.median(depth[valid]))
    if median > MAX_DEPTH:
        raise PointCloudError(f"{path.name}: the median depth is {median:.4g} m at {used:g} m per unit, implausible "
                              f"for a table-top view (at most {MAX_DEPTH:g} m); is the depth scale right?")
    return depth, used
