"""The ``spline`` angular response law of a CSS detector: a cubic B-spline in the cosine of the incidence.

A detector's relative response R (1 at normal incidence) is, for γ = cos θ,

    R(γ) = Σ_j c_j B_j(γ)   for γ > cos θ_K,        R(γ) = 0   for γ ≤ cos θ_K,

with B_j the clamped cubic B-splines on the breakpoints x_k = cos θ_k of fixed knots 0 = θ_0 < θ_1 < … < θ_K ≤ 90°,
K + 3 of them, ordered from γ = cos θ_K (j = 0) to γ = 1 (j = K + 2). Two of the coefficients are fixed by the
law's definition:

* c_{K+2} = 1: R(1) = 1, so the detector's scale S is its signal at normal incidence, as in the other laws;
* c_0 = 0: R(cos θ_K) = 0, so R is continuous where it ends, and the spline holds the field of view's cut-off
  itself (no separate θ_c and edge E).

The other K + 1 coefficients c_1 … c_{K+1} are the law's parameters, ``spline_1`` … ``spline_{K+1}`` (linear: the
signal is linear in them, so the fit stays fast and well conditioned). A detector's response is never negative:
where the spline dips below zero (its last cubic piece, closing on a cut-off that lies between two knots) R is 0,
R = max(0, Σ c_j B_j) — else a dark detector read there would stand thousands of noise sigmas off the model.

The knots are those of :data:`SPLINE_GRID_DEG` below the last one, θ_K (:func:`knots_ending_at`): every 10° up to
40°, where every detector's response is as smooth as a cosine, then every 2.5°, where windows, package caps and
fields of view shape it — as fine as a bench sweep's rings every 5° support (the tilt of a real normal spreads each
ring's incidences over ±1°); finer knots would be left to wiggle between the rings, where only directions off the
rings (the check directions) would see it. A knot is dropped where too few directions support its interval (a
coarser sweep). θ_K, the field's edge, is chosen per detector by the fit from its readings
(:func:`calibration.css.diode_fit.fit_diode`: the smallest χ² + 2 × coefficients over ends every
:data:`END_STEP_DEG`): a cut-off inside the hemisphere (a cap's shadow ends at 77–80° on the simulated head) then is
the spline's own end, and the readings beyond it, dark, are modelled exactly — a spline ending at 90° would have to
stay at zero over the last 10–15° and would ring there, thousands of noise sigmas on a dark photodiode. Its
roughness, λ ∫ (d²R/dθ²)² dθ (:data:`SPLINE_ROUGHNESS`), is a mild penalty of the fit that keeps any interval the
readings leave free regular.

A spline in γ rather than θ is smooth on the sphere at normal incidence (dR/dθ = −sin θ dR/dγ vanishes there by
itself) and its derivative dR/dγ, which the Sun-vector estimator needs, has no 1/sin θ.

For evaluation (here and in the exported C header) the spline is held in piecewise-polynomial form: on interval k
(x_k ≤ γ < x_{k+1}, breakpoints ascending in γ) R = a₀ + a₁ d + a₂ d² + a₃ d³ with d = γ − x_k, by Horner's rule.

References
----------
seed 000 Table C.1 (each detector's current tabulated against the incidence angle, 0–90° every 5°) and digest §8.3
item 7 (fit the angular response: a cosine^n, "or pchip through knots"); de Boor, *A Practical Guide to Splines*
(B-splines, their piecewise-polynomial form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.interpolate import PPoly

#: The spline law's knot grid θ [°] (module docstring): every 10° to 40°, then every 2.5° to 90°
SPLINE_STEP_DEG = 2.5
SPLINE_GRID_DEG: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0) + tuple(
    float(v) for v in np.arange(40.0, 90.0 + 1e-9, SPLINE_STEP_DEG))
#: Directions (their incidences) an interval of the knots must hold at least (:func:`knots_ending_at`)
MIN_SUPPORT = 4
#: Ends θ_K the fit tries: every END_STEP_DEG from END_MIN_DEG to 90° [°]
END_STEP_DEG = 0.5
END_MIN_DEG = 45.0


def knots_ending_at(end_deg: float, grid=SPLINE_GRID_DEG, support=None) -> tuple[float, ...]:
    """The knots of a spline ending at θ_K = `end_deg`: the grid's knots more than half the grid's step there
    below it, then θ_K [°] (so no interval is shorter than half a step).

    `support`: the incidences [°] of the directions that light the detector; a grid knot is then dropped where the
    interval it would close holds fewer than :data:`MIN_SUPPORT` of them (merged with the next), so that no
    interval is left to the roughness penalty alone — a sweep's rings every 15° leave a 2.5° grid free to wiggle
    between them, where only the check directions would see it.

    References
    ----------
    seed 000 Table C.1 (the response tabulated 0–90°), digest §3.2–3.3 (fields of view of 50–82°).
    """
    end = round(float(end_deg), 6)
    g = np.asarray(grid, float)
    if not 0.0 < end <= 90.0:
        raise ValueError(f"a spline ends between 0 and 90°, got {end_deg}°")
    above = g[g >= end]
    below = g[g < end]
    step = (above[0] if above.size else end) - (below[-1] if below.size else 0.0)
    step = max(step, float(np.diff(g[-2:])[0]) if g.size >= 2 else step)
    keep = [float(v) for v in below if v <= end - step / 2.0]
    keep = keep if keep and keep[0] == 0.0 else [0.0] + keep
    if support is not None:
        inc = np.sort(np.asarray(support, float))
        count = lambda a, b: int(np.searchsorted(inc, b) - np.searchsorted(inc, a))  # noqa: E731  [a, b)
        thinned = [0.0]
        for knot in keep[1:]:
            if count(thinned[-1], knot) >= MIN_SUPPORT:
                thinned.append(knot)
        while len(thinned) > 1 and count(thinned[-1], end) < MIN_SUPPORT:
            thinned.pop()
        keep = thinned
    return tuple(keep) + (end,)


#: The knots of a spline ending at 90° (no cut-off inside the hemisphere)
SPLINE_KNOTS_DEG: tuple[float, ...] = knots_ending_at(90.0)
#: Name of the spline law's k-th free coefficient (k from 1)
SPLINE_PREFIX = "spline_"
#: Weight λ of the fit's roughness penalty λ ∫ (d²R/dθ²)² dθ (θ in radians), in units of χ²: mild — a response
#: as curved as a real detector's (∫ (R'')² dθ ≈ 30–300 for the simulated head's, 0.8 for a cosine) costs a few
#: units of χ², nothing against readings whose noise is 10⁻³–10⁻⁵ of the scale, but it fixes the spline where the
#: readings leave it free (a gap in incidence between knots)
SPLINE_ROUGHNESS = 0.01
#: Step of the quadrature of that penalty [°]
_ROUGHNESS_STEP_DEG = 0.1


def spline_names(n_free: int) -> tuple[str, ...]:
    """``spline_1`` … ``spline_<n_free>``: the free coefficients' parameter names."""
    return tuple(f"{SPLINE_PREFIX}{k}" for k in range(1, n_free + 1))


def spline_index(name: str) -> int | None:
    """The 0-based index among the free coefficients of a name ``spline_<k>``, None for any other name."""
    if not name.startswith(SPLINE_PREFIX):
        return None
    tail = name[len(SPLINE_PREFIX):]
    return int(tail) - 1 if tail.isdigit() and int(tail) >= 1 else None


def check_knots(knots_deg) -> tuple[float, ...]:
    """The knots as a tuple of floats, or ValueError: at least two, strictly increasing, from 0 to at most 90°."""
    return _checked(tuple(float(v) for v in knots_deg))


@lru_cache(maxsize=4096)
def _checked(k: tuple) -> tuple:
    if len(k) < 2 or not all(math.isfinite(v) for v in k):
        raise ValueError(f"a spline needs at least two finite knots, got {list(k)}")
    if k[0] != 0.0 or k[-1] > 90.0 or any(b <= a for a, b in zip(k, k[1:])):
        raise ValueError(f"spline knots must rise strictly from 0 to at most 90°, got {list(k)}")
    return k


#: Leading coefficients fixed at zero (module docstring)
FIXED_LOW = 1


def n_free(knots_deg) -> int:
    """Free coefficients of a spline on these knots: K + 1 for the K + 1 knots θ_0 … θ_K (one per knot)."""
    return len(knots_deg)


@dataclass(frozen=True)
class SplineBasis:
    """The clamped cubic B-spline basis on fixed knots, in piecewise-polynomial form.

    Attributes
    ----------
    knots_deg : tuple of float
        θ_0 = 0 < … < θ_K [°].
    breakpoints : ndarray (K + 1,)
        x_k = cos θ ascending in γ: cos θ_K … cos θ_0 = 1.
    basis : ndarray (K + 3, K, 4)
        Polynomial coefficients (a₀ … a₃, powers of γ − x_k) of each B-spline j on each interval k.
    """

    knots_deg: tuple
    breakpoints: np.ndarray
    basis: np.ndarray

    @property
    def n_intervals(self) -> int:
        return self.breakpoints.size - 1

    @property
    def n_free(self) -> int:
        return self.basis.shape[0] - FIXED_LOW - 1

    def full_coefficients(self, free) -> np.ndarray:
        """(c_0 … c_{K+2}) = (0, free…, 1) (module docstring)."""
        free = np.asarray(free, float)
        if free.shape[-1] != self.n_free:
            raise ValueError(f"a spline on {len(self.knots_deg)} knots has {self.n_free} coefficients, got "
                             f"{free.shape[-1]}")
        shape = free.shape[:-1]
        return np.concatenate([np.zeros(shape + (FIXED_LOW,)), free, np.ones(shape + (1,))], axis=-1)

    def polynomial(self, free) -> np.ndarray:
        """The spline's piecewise-polynomial coefficients (K, 4) (or (..., K, 4) for (..., K + 1) coefficients)."""
        return np.einsum("...j,jkp->...kp", self.full_coefficients(free), self.basis)

    def interval(self, g) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(index k of each γ's interval, d = γ − x_k, inside: γ > x_0)."""
        g = np.asarray(g, float)
        k = np.clip(np.searchsorted(self.breakpoints, g, side="right") - 1, 0, self.n_intervals - 1)
        return k, g - self.breakpoints[k], g > self.breakpoints[0]

    def all_basis(self, g) -> tuple[np.ndarray, np.ndarray]:
        """Values and γ-derivatives of every B-spline B_0 … B_{K+2} at γ (N,): each (K + 3, N), 0 where
        γ ≤ cos θ_K."""
        g = np.asarray(g, float)
        k, d, inside = self.interval(g)
        rows = k[None, :] + np.arange(4)[:, None]  # on interval k only B_k … B_{k+3} are not zero
        p = self.basis[rows, k[None, :], :]  # (4, N, 4)
        value = np.zeros((self.basis.shape[0],) + g.shape)
        slope = np.zeros_like(value)
        cols = np.broadcast_to(np.arange(g.size), rows.shape)
        d, inside = d[None, :], inside[None, :]
        value[rows, cols] = np.where(inside, ((p[..., 3] * d + p[..., 2]) * d + p[..., 1]) * d + p[..., 0], 0.0)
        slope[rows, cols] = np.where(inside, (3.0 * p[..., 3] * d + 2.0 * p[..., 2]) * d + p[..., 1], 0.0)
        return value, slope

    def roughness(self) -> tuple[np.ndarray, np.ndarray]:
        """(L, l₀): the roughness ∫ (d²R/dθ²)² dθ over 0…θ_K (θ in radians) of the spline with free coefficients
        c is |L c + l₀|², L (K + 3, K + 1) — a square root of its quadratic form (midpoint quadrature every
        0.1°), l₀ the fixed coefficient's (c_{K+2} = 1) part.

        References
        ----------
        de Boor, *A Practical Guide to Splines* (smoothing splines: the integrated squared second derivative).
        """
        return _roughness(self.knots_deg)

    def free_basis(self, g) -> tuple[np.ndarray, np.ndarray]:
        """Values and γ-derivatives of the free B-splines B_1 … B_{K+1} at γ (N,): each (K + 1, N)."""
        value, slope = self.all_basis(g)
        return value[FIXED_LOW:-1], slope[FIXED_LOW:-1]


@lru_cache(maxsize=512)
def spline_basis(knots_deg: tuple = SPLINE_KNOTS_DEG) -> SplineBasis:
    """The basis of :class:`SplineBasis` on `knots_deg` (cached: the knots are fixed).

    References
    ----------
    de Boor, *A Practical Guide to Splines* (the clamped B-spline basis, its piecewise-polynomial form).
    """
    knots = check_knots(knots_deg)
    x = np.cos(np.radians(np.array(knots[::-1])))
    x[-1] = 1.0
    if knots[-1] == 90.0:
        x[0] = 0.0
    t = np.r_[[x[0]] * 4, x[1:-1], [x[-1]] * 4]
    n_basis = t.size - 4
    basis = np.empty((n_basis, x.size - 1, 4))
    for j in range(n_basis):
        c = np.zeros(n_basis)
        c[j] = 1.0
        pp = PPoly.from_spline((t, c, 3))
        keep = np.diff(pp.x) > 0
        basis[j] = pp.c[::-1, keep].T  # lowest power first, one row per non-empty interval
    return SplineBasis(knots, x, basis)


@lru_cache(maxsize=512)
def _roughness(knots_deg: tuple) -> tuple[np.ndarray, np.ndarray]:
    basis = spline_basis(knots_deg)
    n = max(1, int(round(knots_deg[-1] / _ROUGHNESS_STEP_DEG)))
    theta = np.radians((np.arange(n) + 0.5) * knots_deg[-1] / n)
    g = np.cos(theta)
    k, d, _ = basis.interval(g)
    p = basis.basis[:, k, :]
    slope = (3.0 * p[..., 3] * d + 2.0 * p[..., 2]) * d + p[..., 1]
    curve = 6.0 * p[..., 3] * d + 2.0 * p[..., 2]
    # R(θ) = f(cos θ): R'' = f''(γ) sin²θ − f'(γ) cos θ, each B-spline's at the quadrature's nodes (K + 3, n)
    d2 = (curve * np.sin(theta) ** 2 - slope * np.cos(theta)) * np.sqrt(np.radians(knots_deg[-1]) / n)
    gram = d2 @ d2.T  # the roughness' quadratic form over all K + 3 coefficients
    w, v = np.linalg.eigh(gram)
    root = (v * np.sqrt(np.clip(w, 0.0, None))).T  # root.T @ root = gram
    return root[:, FIXED_LOW:-1], root[:, -1]


def evaluate(breakpoints, polynomial, g) -> tuple[np.ndarray, np.ndarray]:
    """R = max(0, spline) and dR/dγ of splines in piecewise-polynomial form at γ (0 at and below the first
    breakpoint).

    Parameters
    ----------
    breakpoints : ndarray (K + 1,)
        Ascending in γ (:attr:`SplineBasis.breakpoints`).
    polynomial : ndarray (K, 4) or (m, K, 4)
        One spline, or m splines on those breakpoints.
    g : ndarray (...,) for one spline, (..., m) for m
        Cosines of the incidence.

    References
    ----------
    de Boor, *A Practical Guide to Splines* (piecewise-polynomial evaluation by Horner's rule).
    """
    x = np.asarray(breakpoints, float)
    g = np.asarray(g, float)
    poly = np.asarray(polynomial, float)
    k = np.clip(np.searchsorted(x, g, side="right") - 1, 0, x.size - 2)
    d = g - x[k]
    p = poly[k] if poly.ndim == 2 else poly[np.arange(poly.shape[0]), k]
    value = ((p[..., 3] * d + p[..., 2]) * d + p[..., 1]) * d + p[..., 0]
    slope = (3.0 * p[..., 3] * d + 2.0 * p[..., 2]) * d + p[..., 1]
    on = (g > x[0]) & (value > 0.0)  # R = max(0, spline) beyond nothing (module docstring)
    return np.where(on, value, 0.0), np.where(on, slope, 0.0)


class SplineSet:
    """m splines in piecewise-polynomial form, each on its own breakpoints, evaluated at once on the last axis of
    an array of cosines (one searchsorted over all: each spline's breakpoints shifted by 4 × its index, apart
    from every other's since γ ∈ [−1, 1]).

    Parameters
    ----------
    splines : sequence of (breakpoints (K_i + 1,), polynomial (K_i, 4))
    """

    def __init__(self, splines):
        self.m = len(splines)
        shift = 4.0 * np.arange(self.m)
        self.shift = shift
        self.raw = np.concatenate([np.asarray(x, float) for x, _ in splines])
        self.breakpoints = np.concatenate([np.asarray(x, float) + shift[i] for i, (x, _) in enumerate(splines)])
        self.polynomial = np.concatenate([np.asarray(p, float) for _, p in splines])
        sizes = np.array([len(x) for x, _ in splines])
        self.point_start = np.r_[0, np.cumsum(sizes)[:-1]]
        self.interval_start = self.point_start - np.arange(self.m)
        self.n_intervals = sizes - 1
        self.first = np.array([x[0] for x, _ in splines], float)

    def evaluate(self, g) -> tuple[np.ndarray, np.ndarray]:
        """R = max(0, spline) and dR/dγ of every spline at γ (..., m) (0 at and below each one's first
        breakpoint)."""
        g = np.asarray(g, float)
        key = np.clip(g, -1.5, 1.5) + self.shift
        k = np.searchsorted(self.breakpoints, key, side="right") - 1 - self.point_start
        k = np.clip(k, 0, self.n_intervals - 1)
        d = g - self.raw[self.point_start + k]
        p = self.polynomial[self.interval_start + k]
        value = ((p[..., 3] * d + p[..., 2]) * d + p[..., 1]) * d + p[..., 0]
        slope = (3.0 * p[..., 3] * d + 2.0 * p[..., 2]) * d + p[..., 1]
        on = (g > self.first) & (value > 0.0)
        return np.where(on, value, 0.0), np.where(on, slope, 0.0)


@lru_cache(maxsize=512)
def _cosine_start(knots_deg: tuple) -> tuple:
    basis = spline_basis(knots_deg)
    theta = np.linspace(0.0, knots_deg[-1], 721)
    g = np.cos(np.radians(theta))
    b, _ = basis.free_basis(g)
    k, d, _ = basis.interval(g)
    last = basis.basis[-1][k]
    fixed = ((last[:, 3] * d + last[:, 2]) * d + last[:, 1]) * d + last[:, 0]
    coef, *_ = np.linalg.lstsq(b.T, g - fixed, rcond=None)
    return tuple(float(v) for v in coef)


def cosine_coefficients(knots_deg: tuple = SPLINE_KNOTS_DEG) -> tuple[float, ...]:
    """Free coefficients of the spline nearest (least squares over 0…θ_K) the plain cosine: a neutral start.

    References
    ----------
    seed 000 digest §8.1 item 1 (b) (the ideal cosine detector).
    """
    return _cosine_start(check_knots(knots_deg))
