"""Turning results into plain JSON values (one converter for the CLI, reports, files)."""

from __future__ import annotations

import math
from dataclasses import asdict, is_dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["to_jsonable"]


def to_jsonable(o: Any) -> Any:
    """Dataclasses (via ``to_dict`` if they have one), numpy scalars and arrays, paths,
    enums (their value) and non-finite floats (-> null) to plain JSON values, recursively."""
    if is_dataclass(o) and not isinstance(o, type):
        return to_jsonable(o.to_dict() if hasattr(o, "to_dict") else asdict(o))
    if isinstance(o, dict):
        return {str(k): to_jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [to_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return to_jsonable(o.tolist())
    if isinstance(o, np.generic):
        return to_jsonable(o.item())
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, Enum):
        return to_jsonable(o.value)
    return o
