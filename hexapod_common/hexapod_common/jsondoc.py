"""Result documents as strict JSON (the commands' slip.json, energy.json, residuals.json).

Core module: numpy only.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ['json_safe']


def json_safe(obj: Any) -> Any:
    """``obj`` with numpy arrays and scalars as Python lists and numbers, dict keys as strings,
    and every non-finite float as None (strict JSON has no NaN or Infinity)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(float(obj)) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    return obj
