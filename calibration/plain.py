"""Calibration documents as plain JSON values: numpy arrays and scalars to lists and Python numbers, a non-finite
number to None (JSON has no NaN), mapping keys to strings. Shared by the families' versioned documents."""

from __future__ import annotations

import numpy as np


def plain(value):
    """`value` with every numpy array, tuple and scalar turned into JSON's lists and numbers (NaN, ±inf → None)."""
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value
