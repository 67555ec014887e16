"""JSON-safe copies of plain data (what ``--json`` prints and what result files keep)."""

from __future__ import annotations

import math
from pathlib import Path


def json_safe(obj):
    """JSON-safe copy: numpy scalars/arrays to Python, NaN/inf to None, paths to text."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if np is not None and isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if np is not None and isinstance(obj, np.generic):
        return json_safe(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj
