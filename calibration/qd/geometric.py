"""The thesis' geometric ("main") model: spot centre → Sun angles, and its least-squares fit (seed 002 eq. 2.2).

.. math::

    \\begin{pmatrix} x_r \\\\ y_r \\end{pmatrix} = R(φ) \\begin{pmatrix} x_c \\\\ y_c \\end{pmatrix}, \\qquad
    α = \\arctan\\frac{x_0 - x_r}{d} + α_0, \\qquad β = \\arctan\\frac{y_0 - y_r}{d} + β_0

with R(φ) the in-plane rotation [[cos φ, −sin φ], [sin φ, cos φ]]. The vector from the spot to the pinhole
points at the Sun, so tan(α − α0) = s_x/s_z (digest §2.3); the inverse is x_r = x0 − d tan(α − α0),
y_r = y0 − d tan(β − β0), (x_c, y_c) = R(φ)ᵀ (x_r, y_r).

Six parameters f = [x0, y0, α0, β0, φ0, d] are fitted by nonlinear least squares of Φ = Σ (α_i − α_i^s)² +
(β_i − β_i^s)² against the known angles (thesis §3.1), with any of them fixable. Near the boresight
arctan((x0 − x_r)/d) + α0 ≈ (x0 − x_r)/d + α0, so x0/d and α0 (and y0/d and β0) are almost the same constant
offset; only the arctan's curvature at large angles separates them. The fit reports the correlation matrix
and says so in words when a pair exceeds :data:`CORRELATION_LIMIT`.

Only d/L, x0/L and y0/L are identifiable (multiplying x_c, y_c, x0, y0 and d by one factor leaves the angles
unchanged): the lengths mean something only with the L used in eq. 2.1.

References
----------
seed 002, eqs. 2.1–2.2 and §3.1 (parameters, f0, the functional Φ); digest §2.3, §2.5 and §7 items 4, 5, 15.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import FitError, InsufficientDataError

#: The thesis' parameter vector f, in its order.
GEOMETRIC_PARAMETERS = ("x0_m", "y0_m", "alpha0_deg", "beta0_deg", "phi0_deg", "d_m")
#: |correlation| above which a pair of parameters is reported as nearly degenerate.
CORRELATION_LIMIT = 0.95


@dataclass(frozen=True)
class GeometricParameters:
    """The six calibration parameters of eq. 2.2.

    Attributes
    ----------
    x0_m, y0_m : float
        Offset of the diaphragm relative to the QD centre, in the rotated (housing) axes [m].
    alpha0_deg, beta0_deg : float
        Angular offsets of the QD relative to the housing [°].
    phi0_deg : float
        In-plane rotation φ of the QD [°].
    d_m : float
        Distance from the QD surface to the diaphragm [m].
    """

    x0_m: float = 0.0
    y0_m: float = 0.0
    alpha0_deg: float = 0.0
    beta0_deg: float = 0.0
    phi0_deg: float = 0.0
    d_m: float = 1e-3

    def __post_init__(self) -> None:
        if not self.d_m > 0:
            raise ValueError(f"`d_m` must be positive, got {self.d_m}")

    def as_vector(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in GEOMETRIC_PARAMETERS], dtype=float)

    @classmethod
    def from_vector(cls, values) -> GeometricParameters:
        return cls(**{n: float(v) for n, v in zip(GEOMETRIC_PARAMETERS, values)})

    def to_dict(self) -> dict:
        return asdict(self)


def rotate_spot(xc_m, yc_m, phi_deg) -> tuple[np.ndarray, np.ndarray]:
    """(x_r, y_r) = R(φ)(x_c, y_c): the spot centre in the housing axes [m].

    References
    ----------
    seed 002, eq. 2.2 (the rotation matrix).
    """
    c, s = np.cos(np.radians(phi_deg)), np.sin(np.radians(phi_deg))
    x, y = np.asarray(xc_m, dtype=float), np.asarray(yc_m, dtype=float)
    return c * x - s * y, s * x + c * y


def angles_from_spot(xc_m, yc_m, params: GeometricParameters) -> tuple[np.ndarray, np.ndarray]:
    """Sun angles (α, β) from the spot centre (x_c, y_c) on the QD [°].

    Parameters
    ----------
    xc_m, yc_m : numeric
        Spot centre from eq. 2.1 [m].
    params : GeometricParameters

    Returns
    -------
    alpha_deg, beta_deg : ndarray
        [°].

    References
    ----------
    seed 002, eq. 2.2.
    """
    xr, yr = rotate_spot(xc_m, yc_m, params.phi0_deg)
    alpha = np.degrees(np.arctan((params.x0_m - xr) / params.d_m)) + params.alpha0_deg  # seed 002 eq. 2.2
    beta = np.degrees(np.arctan((params.y0_m - yr) / params.d_m)) + params.beta0_deg
    return alpha, beta


def spot_from_angles(alpha_deg, beta_deg, params: GeometricParameters) -> tuple[np.ndarray, np.ndarray]:
    """Spot centre (x_c, y_c) on the QD [m] of the Sun at (α, β): the inverse of eq. 2.2.

    .. math:: x_r = x_0 - d \\tan(α - α_0), \\quad y_r = y_0 - d \\tan(β - β_0), \\quad
              (x_c, y_c) = R(φ)^T (x_r, y_r)

    References
    ----------
    seed 002, eq. 2.2 (inverted; digest §2.3).
    """
    xr = params.x0_m - params.d_m * np.tan(np.radians(np.asarray(alpha_deg, dtype=float) - params.alpha0_deg))
    yr = params.y0_m - params.d_m * np.tan(np.radians(np.asarray(beta_deg, dtype=float) - params.beta0_deg))
    return rotate_spot(xr, yr, -params.phi0_deg)


def initial_geometric(xc_m, yc_m, alpha_deg, beta_deg) -> GeometricParameters:
    """A start for the fit in closed form: (tan α, tan β) regressed affinely on (x_c, y_c).

    With α0 = β0 = 0, eq. 2.2 reads (tan α, tan β) = (x0, y0)/d − R(φ)(x_c, y_c)/d, an affine map whose
    linear part is −R(φ)/d. A linear least squares of (tan α, tan β) on (1, x_c, y_c) gives that map; its
    rotation-like part gives φ and d, its constant term x0 and y0. It needs no guess and is exact for data
    with α0 = β0 = 0 and no noise.

    References
    ----------
    seed 002, eq. 2.2 and §3.1 (the initial approximation f0, whose values the thesis does not give).
    """
    x, y = np.asarray(xc_m, dtype=float).ravel(), np.asarray(yc_m, dtype=float).ravel()
    ta = np.tan(np.radians(np.asarray(alpha_deg, dtype=float).ravel()))
    tb = np.tan(np.radians(np.asarray(beta_deg, dtype=float).ravel()))
    design = np.stack([np.ones_like(x), x, y], axis=1)
    coef, *_ = np.linalg.lstsq(design, np.stack([ta, tb], axis=1), rcond=None)
    b, a = coef[0], coef[1:].T  # a[i, j]: d(tan angle i)/d(spot coordinate j)
    # −a·d = R(φ) = [[c, −s], [s, c]]: the closest rotation-times-scale to −a
    c_part = -(a[0, 0] + a[1, 1]) / 2.0
    s_part = -(a[1, 0] - a[0, 1]) / 2.0
    scale = float(np.hypot(c_part, s_part))
    if not np.isfinite(scale) or scale <= 0:
        raise FitError("the spot does not move with the Sun angles: no initial guess for eq. 2.2")
    d = 1.0 / scale
    phi = float(np.degrees(np.arctan2(s_part, c_part)))
    return GeometricParameters(x0_m=float(b[0] * d), y0_m=float(b[1] * d), alpha0_deg=0.0, beta0_deg=0.0,
                               phi0_deg=phi, d_m=float(d))


@dataclass(frozen=True)
class GeometricFit:
    """Eq. 2.2 fitted to bench data.

    Attributes
    ----------
    parameters : GeometricParameters
    free : tuple of str
        The fitted parameters (the others were fixed), in the order of `covariance`.
    sd : dict of str to float
        1σ of each free parameter (scaled by the residual variance) [its unit]; fixed ones are absent.
    covariance : ndarray, shape (p, p)
    correlation : ndarray, shape (p, p)
    residual_deg : ndarray, shape (N, 2)
        Fitted minus known (α, β) at each point [°].
    rms_deg, max_deg : float
        RMS and largest |residual| over both angles [°].
    dof : int
        2N − p.
    statements : list of str
        Nearly degenerate pairs (|corr| > limit), in words.
    """

    parameters: GeometricParameters
    free: tuple
    sd: dict
    covariance: np.ndarray
    correlation: np.ndarray
    residual_deg: np.ndarray
    rms_deg: float
    max_deg: float
    dof: int
    statements: list = field(default_factory=list)

    def correlation_of(self, a: str, b: str) -> float:
        """Correlation of two free parameters."""
        return float(self.correlation[self.free.index(a), self.free.index(b)])

    def apply(self, xc_m, yc_m) -> tuple[np.ndarray, np.ndarray]:
        """(α, β) [°] of spot centres (eq. 2.2 with the fitted parameters)."""
        return angles_from_spot(xc_m, yc_m, self.parameters)


#: Why each near-degenerate pair is so, for the statements.
_PAIR_REASONS = {
    frozenset({"x0_m", "alpha0_deg"}): "x0/d and α0 are nearly the same constant offset of α (arctan(u) ≈ u); "
                                       "only the arctan's curvature at large α separates them",
    frozenset({"y0_m", "beta0_deg"}): "y0/d and β0 are nearly the same constant offset of β (arctan(u) ≈ u); "
                                      "only the arctan's curvature at large β separates them",
}


def correlation_statements(names, correlation, limit: float = CORRELATION_LIMIT) -> list[str]:
    """Words for each pair of parameters whose |correlation| exceeds `limit`.

    References
    ----------
    seed 002, §3.1; digest §2.5 (x0/α0 and y0/β0 nearly degenerate) and §8 (report the correlations).
    """
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            r = float(correlation[i, j])
            if np.isfinite(r) and abs(r) > limit:
                why = _PAIR_REASONS.get(frozenset({names[i], names[j]}), "the data hardly tell them apart")
                out.append(f"{names[i]} and {names[j]} are correlated at {r:+.3f}: {why}. Their sum is well "
                           f"determined, each alone poorly; fix one (e.g. {names[j]}) if its 1σ is too large for use.")
    return out


def covariance_summary(jac: np.ndarray, residual: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Covariance s² (JᵀJ)⁻¹ of least-squares parameters (s² = Σ r² / (m − p)) and their correlation.

    `jac` is the Jacobian in internal units, `scale` converts internal to physical units per parameter.

    References
    ----------
    research note anchors-sunsensors §6 (fits report their parameter uncertainties); the usual Gauss–Newton
    covariance of nonlinear least squares.
    """
    m, p = jac.shape
    dof = m - p
    s2 = float(np.sum(residual**2) / dof) if dof > 0 else np.nan
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    tol = sv.max() * max(m, p) * np.finfo(float).eps if sv.size else 0.0
    inv = np.where(sv > tol, 1.0 / np.where(sv > tol, sv, 1.0) ** 2, np.inf)
    cov_internal = (vt.T * inv) @ vt if np.all(np.isfinite(inv)) else np.full((p, p), np.inf)
    cov = s2 * cov_internal * np.outer(scale, scale)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov / np.outer(sd, sd)
    return cov, corr, dof


def fixed_parameters(fixed, names) -> dict:
    """The parameters to hold fixed as ``{name: value or None}`` (None: at the start value), checked against
    `names`; `fixed` is None, a sequence of names or such a dict.

    References
    ----------
    seed 002, §3.1 (the fitted parameter vector f); digest §2.5 (any parameter fixable).
    """
    if fixed is None:
        return {}
    if isinstance(fixed, dict):
        out = dict(fixed)
    else:
        out = {name: None for name in fixed}
    unknown = sorted(set(out) - set(names))
    if unknown:
        raise ValueError(f"unknown parameters to fix {unknown}; the parameters are {list(names)}")
    return out


def fit_geometric(xc_m, yc_m, alpha_deg, beta_deg, *, initial: GeometricParameters | None = None,
                  fixed=None, sigma_deg=None, loss: str = "linear", f_scale: float = 1.0,
                  correlation_limit: float = CORRELATION_LIMIT) -> GeometricFit:
    """Fit the six parameters of eq. 2.2 to spot centres at known Sun angles (thesis §3.1).

    Parameters
    ----------
    xc_m, yc_m : array_like, shape (N,)
        Spot centres from eq. 2.1 [m].
    alpha_deg, beta_deg : array_like, shape (N,)
        Known Sun angles at each point (from the table through :mod:`calibration.mount`) [°].
    initial : GeometricParameters, optional
        f0; default :func:`initial_geometric`.
    fixed : sequence of str or dict, optional
        Parameters held fixed: names (at their `initial` value) or ``{name: value}``.
    sigma_deg : array_like, optional
        1σ of each point's angles [°] (weights 1/σ); default equal weights, as Φ.
    loss, f_scale
        ``scipy.optimize.least_squares`` loss (``"soft_l1"`` for robustness to a glint) and its scale [°];
        with a robust loss the covariance is only indicative.
    correlation_limit : float
        |corr| above which a pair is stated as nearly degenerate.

    Returns
    -------
    GeometricFit

    References
    ----------
    seed 002, eq. 2.2 and §3.1 (Φ, f, f0); digest §2.5 (correlations, fixable parameters).
    """
    x = np.asarray(xc_m, dtype=float).ravel()
    y = np.asarray(yc_m, dtype=float).ravel()
    a_true = np.asarray(alpha_deg, dtype=float).ravel()
    b_true = np.asarray(beta_deg, dtype=float).ravel()
    if not (x.size == y.size == a_true.size == b_true.size):
        raise InsufficientDataError("xc, yc, alpha and beta must have the same length")
    if not np.all(np.isfinite(np.concatenate([x, y, a_true, b_true]))):
        raise InsufficientDataError("the geometric fit was given a non-finite spot or angle")
    fixed = fixed_parameters(fixed, GEOMETRIC_PARAMETERS)
    free = tuple(n for n in GEOMETRIC_PARAMETERS if n not in fixed)
    if 2 * x.size <= len(free):
        raise InsufficientDataError(f"the geometric fit of {len(free)} parameters needs more than {len(free) // 2} "
                                    f"points, got {x.size}")
    start = initial or initial_geometric(x, y, a_true, b_true)
    values = start.to_dict()
    for name, value in fixed.items():
        if value is not None:
            values[name] = float(value)
    if not values["d_m"] > 0:
        raise FitError("the initial pinhole height d is not positive")
    weight = np.ones_like(x) if sigma_deg is None else 1.0 / np.broadcast_to(np.asarray(sigma_deg, float), x.shape)
    # internal units: lengths in units of the starting d, angles in degrees
    length = abs(values["d_m"])
    scale = np.array([length if n.endswith("_m") else 1.0 for n in free])

    def params_of(p) -> GeometricParameters:
        v = dict(values)
        v.update({n: float(p[i] * scale[i]) for i, n in enumerate(free)})
        return GeometricParameters(**v)

    def residual(p):
        v = dict(values)
        v.update({n: p[i] * scale[i] for i, n in enumerate(free)})
        if v["d_m"] <= 0:
            return np.full(2 * x.size, 1e3)
        xr, yr = rotate_spot(x, y, v["phi0_deg"])
        ra = np.degrees(np.arctan((v["x0_m"] - xr) / v["d_m"])) + v["alpha0_deg"] - a_true  # seed 002 eq. 2.2
        rb = np.degrees(np.arctan((v["y0_m"] - yr) / v["d_m"])) + v["beta0_deg"] - b_true
        return np.concatenate([ra * weight, rb * weight])

    p0 = np.array([values[n] for n in free]) / scale
    fit = least_squares(residual, p0, loss=loss, f_scale=f_scale, method="trf" if loss != "linear" else "lm",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000 * (len(free) + 1))
    if not np.all(np.isfinite(fit.x)):
        raise FitError(f"the geometric fit did not converge ({fit.message})")
    params = params_of(fit.x)
    r = residual(fit.x)
    cov, corr, dof = covariance_summary(fit.jac, r, scale)
    sd = {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(free)}
    a_fit, b_fit = angles_from_spot(x, y, params)
    res = np.stack([a_fit - a_true, b_fit - b_true], axis=1)
    return GeometricFit(params, free, sd, cov, corr, res, float(np.sqrt(np.mean(res**2))), float(np.max(np.abs(res))),
                        dof, correlation_statements(free, corr, correlation_limit))
