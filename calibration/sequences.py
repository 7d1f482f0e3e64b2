"""Low-discrepancy sequences: points spread evenly and the same every run, for check directions a plan measures
but never fits (a resumed run measures the same ones)."""

from __future__ import annotations

import numpy as np


def halton(i: int, base: int) -> float:
    """The `i`-th element (from 1) of van der Corput's sequence in `base` (Halton 1960), in [0, 1)."""
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


def halton_points(n: int, *, start: int = 1) -> np.ndarray:
    """`n` points of the 2-D Halton sequence (bases 2 and 3) from its `start`-th element, shape (n, 2) in [0, 1)²
    (J. H. Halton, Numer. Math. 2 (1960) 84–90)."""
    return np.array([[halton(i, 2), halton(i, 3)] for i in range(start, start + n)], float).reshape(n, 2)
