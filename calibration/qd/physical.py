"""A physical model of the QD sun sensor: the currents from the spot's overlap with each quadrant, past eq. 2.1.

Eq. 2.1 reads the spot's position as if a QD's ratio were linear in it; it is not (it saturates, and the
dead gap bends it near the centre), and the thesis' geometric model pays for that at the edge of the field
(2.5°, seed 002 §5.2). Here the currents are predicted from what the sensor is:

1. The Sun at projection angles (α, β) (body frame) is seen in the die's axes through the die's angular
   offsets α0, β0: by default a true rotation M = R_y(α0) R_x(−β0) of the body vector (``offsets="rotation"``),
   or, as eq. 2.2 writes them, subtracted from the angles (``"additive"``); the two agree to first order.
2. The spot is the diaphragm's shadow, a circle of the diaphragm's radius r centred at
   r_c = (x0, y0) − d (t_x, t_y), t = the Sun's tangents in the die's axes (eq. 2.2 inverted), and in the
   QD's own axes c = R(φ0)ᵀ r_c.
3. Quadrant k collects g_k · A_k(c) · cos θ · K, with A_k the exact area of the spot on the quadrant minus
   the dead cross of width g (:mod:`calibration.qd.overlap`), g_k its relative responsivity (g_1 = 1),
   θ the incidence on the die and K the irradiance × responsivity.

What is fitted and what is fixed (the degeneracies):

* the diaphragm radius r is fixed at its design value: multiplying r, d, x0, y0 and g by one factor changes
  no current, so only d/r, x0/r, y0/r and g/r are seen (as the thesis' lengths only relative to its L);
* the fit uses each quadrant's share I_k / Σ I, so K, the lamp's drift and the cos θ factor cancel; K and
  the cos law are checked afterwards from the sums (`responsivity_a_per_m2`, `cos_law_rms`);
* only relative gains are seen: g_1 = 1, and g_2, g_3, g_4 are fitted;
* the Sun disc's blur is second order in its 0.3 µm width (:mod:`calibration.qd.overlap`): not fitted;
* x0/α0 and y0/β0 are nearly degenerate as in eq. 2.2: both are fitted and their correlation reported.

Fitted: f = [x0, y0, α0, β0, φ0, d, g, g_2, g_3, g_4] by ``scipy.optimize.least_squares`` of the shares at
known directions, the covariance s² (JᵀJ)⁻¹ with s² = Σ r² / (3N − p) (three of the four shares are
independent). In use the model is inverted per reading: the spot centre c is found by a vectorised
Gauss–Newton on the shares (analytic derivatives of the areas) from the closed-form centre of a gapless
disc, then (α, β) follow in closed form.

References
----------
seed 002, §1.2.3 (QD: accuracy falls as the spot leaves the centre), §1.3 (diaphragm 20–100 µm), eqs.
2.1–2.2, §5.2 (the geometric model's 2.5° at the edge); digest §7 items 3, 9, 15.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from ..errors import FitError, InsufficientDataError
from ..pinhole import detector_rotation
from .angles import vector_from_projection_angles
from .design import DEFAULT_QD, QdDesign, quadrant_layout
from .geometric import correlation_statements, covariance_summary, fixed_parameters, initial_geometric
from .overlap import quadrant_areas, quadrant_areas_jacobian
from .spot import quadrant_fractions

#: Fitted parameters, in the order of the parameter vector.
PHYSICAL_PARAMETERS = ("x0_m", "y0_m", "alpha0_deg", "beta0_deg", "phi0_deg", "d_m", "gap_m", "gain2", "gain3",
                       "gain4")
#: Offset models of step 1 (module docstring).
OFFSET_MODELS = ("rotation", "additive")

#: What is held fixed and why, for reports.
FIXED_NOTES = (
    "radius_m is fixed at the design value: it sets the length scale, only d/r, x0/r, y0/r and g/r reach the currents",
    "the gain of quadrant 1 is 1: the shares see only relative gains",
    "irradiance × responsivity and cos(incidence) cancel in the shares; they are checked afterwards from the sums",
    "the Sun disc's blur is second order in its width (≈0.3 µm): the spot is a sharp disc of the diaphragm's radius",
)


@dataclass(frozen=True)
class PhysicalParameters:
    """The physical model's build (module docstring).

    Attributes
    ----------
    x0_m, y0_m : float
        Diaphragm offset from the QD centre, in the die's (unrotated) axes [m].
    alpha0_deg, beta0_deg : float
        Die's angular offsets [°].
    phi0_deg : float
        QD's in-plane rotation [°].
    d_m : float
        Diaphragm-to-QD distance [m].
    gap_m : float
        Width of the dead cross [m].
    gain2, gain3, gain4 : float
        Responsivity of quadrants 2–4 relative to quadrant 1 [unitless].
    radius_m : float
        Diaphragm (spot) radius [m], fixed.
    offsets : str
        "rotation" or "additive" (module docstring, step 1).
    layout : tuple
        Quadrant signs (:func:`calibration.qd.design.quadrant_layout`).
    """

    x0_m: float = 0.0
    y0_m: float = 0.0
    alpha0_deg: float = 0.0
    beta0_deg: float = 0.0
    phi0_deg: float = 0.0
    d_m: float = DEFAULT_QD.pinhole_height_m
    gap_m: float = DEFAULT_QD.gap_m
    gain2: float = 1.0
    gain3: float = 1.0
    gain4: float = 1.0
    radius_m: float = DEFAULT_QD.radius_m
    offsets: str = "rotation"
    layout: tuple = tuple(tuple(r) for r in quadrant_layout("thesis").astype(int).tolist())

    def __post_init__(self) -> None:
        if self.offsets not in OFFSET_MODELS:
            raise ValueError(f"`offsets` must be one of {OFFSET_MODELS}, got {self.offsets!r}")
        if not self.radius_m > 0 or not self.d_m > 0:
            raise ValueError("`radius_m` and `d_m` must be positive")
        object.__setattr__(self, "layout", tuple(tuple(int(v) for v in r) for r in quadrant_layout(self.layout)))

    @property
    def gains(self) -> np.ndarray:
        """Relative responsivities of quadrants 1–4."""
        return np.array([1.0, self.gain2, self.gain3, self.gain4])

    @property
    def signs(self) -> np.ndarray:
        return np.asarray(self.layout, dtype=float)

    def as_vector(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in PHYSICAL_PARAMETERS], dtype=float)

    def to_dict(self) -> dict:
        out = asdict(self)
        out["layout"] = [list(r) for r in self.layout]
        return out


def _offset_rotation(alpha0_deg: float, beta0_deg: float) -> np.ndarray:
    """M = R_y(α0) R_x(−β0): the die's axes in the body frame (columns); the CMOS detector's tilt without its
    in-plane turn (:func:`calibration.pinhole.detector_rotation`)."""
    return detector_rotation(alpha0_deg, beta0_deg, 0.0)


def die_tangents(alpha_deg, beta_deg, params: PhysicalParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Sun's tangents (t_x, t_y) = (s_x/s_z, s_y/s_z) in the die's axes, and cos of its incidence on the die.

    References
    ----------
    seed 002, eq. 2.2 (α0, β0: the die's angular offset relative to the housing); module docstring, step 1.
    """
    if params.offsets == "additive":
        tx = np.tan(np.radians(np.asarray(alpha_deg, float) - params.alpha0_deg))  # seed 002 eq. 2.2
        ty = np.tan(np.radians(np.asarray(beta_deg, float) - params.beta0_deg))
        return tx, ty, 1.0 / np.sqrt(1.0 + tx * tx + ty * ty)
    s = vector_from_projection_angles(alpha_deg, beta_deg) @ _offset_rotation(params.alpha0_deg, params.beta0_deg)
    return s[..., 0] / s[..., 2], s[..., 1] / s[..., 2], s[..., 2]


def spot_centre(alpha_deg, beta_deg, params: PhysicalParameters) -> tuple[np.ndarray, np.ndarray]:
    """Centre (c_x, c_y) of the spot in the QD's axes [m] for the Sun at (α, β).

    References
    ----------
    seed 002, eq. 2.2 inverted (digest §2.3); module docstring, step 2.
    """
    tx, ty, _ = die_tangents(alpha_deg, beta_deg, params)
    return _centre_from_tangents(tx, ty, params)


def _centre_from_tangents(tx, ty, params: PhysicalParameters) -> tuple[np.ndarray, np.ndarray]:
    rx, ry = params.x0_m - params.d_m * tx, params.y0_m - params.d_m * ty
    c, s = np.cos(np.radians(params.phi0_deg)), np.sin(np.radians(params.phi0_deg))
    return c * rx + s * ry, -s * rx + c * ry


def angles_from_centre(cx_m, cy_m, params: PhysicalParameters) -> tuple[np.ndarray, np.ndarray]:
    """(α, β) [°] of the Sun whose spot is centred at (c_x, c_y) in the QD's axes: inverse of :func:`spot_centre`.

    References
    ----------
    seed 002, eq. 2.2; module docstring, steps 1–2.
    """
    c, s = np.cos(np.radians(params.phi0_deg)), np.sin(np.radians(params.phi0_deg))
    cx, cy = np.asarray(cx_m, float), np.asarray(cy_m, float)
    rx, ry = c * cx - s * cy, s * cx + c * cy
    tx, ty = (params.x0_m - rx) / params.d_m, (params.y0_m - ry) / params.d_m
    if params.offsets == "additive":
        return np.degrees(np.arctan(tx)) + params.alpha0_deg, np.degrees(np.arctan(ty)) + params.beta0_deg
    v = np.stack([tx, ty, np.ones_like(tx)], axis=-1) @ _offset_rotation(params.alpha0_deg, params.beta0_deg).T
    return np.degrees(np.arctan2(v[..., 0], v[..., 2])), np.degrees(np.arctan2(v[..., 1], v[..., 2]))


def predict_shares(alpha_deg, beta_deg, params: PhysicalParameters) -> np.ndarray:
    """Each quadrant's share g_k A_k / Σ g_j A_j of the photocurrent for the Sun at (α, β), shape (..., 4).

    References
    ----------
    seed 002, eq. 2.1 (its normalisation by the sum); module docstring, step 3.
    """
    cx, cy = spot_centre(alpha_deg, beta_deg, params)
    weighted = quadrant_areas(cx, cy, params.radius_m, params.gap_m, params.signs) * params.gains
    return weighted / weighted.sum(axis=-1, keepdims=True)


def predict_currents(alpha_deg, beta_deg, params: PhysicalParameters, responsivity_a_per_m2: float) -> np.ndarray:
    """Photocurrents g_k A_k cos θ K of quadrants 1–4 [A] for the Sun at (α, β), shape (..., 4).

    Parameters
    ----------
    responsivity_a_per_m2 : float
        K: irradiance × responsivity, the current per m² of lit quadrant at normal incidence [A/m²].

    References
    ----------
    seed 002, eq. 2.1 (I^f_k); module docstring, step 3 (cos θ: the diaphragm passes the beam's
    cross-section, the spot keeps the hole's area).
    """
    tx, ty, cos_inc = die_tangents(alpha_deg, beta_deg, params)
    cx, cy = _centre_from_tangents(tx, ty, params)
    areas = quadrant_areas(cx, cy, params.radius_m, params.gap_m, params.signs)
    return responsivity_a_per_m2 * np.asarray(cos_inc)[..., None] * areas * params.gains


def _gapless_centre(ratio, radius):
    """Centre offset of a gapless round spot from its normalised difference (2/π)(asin t + t√(1 − t²))."""
    t = np.clip(np.asarray(ratio, dtype=float) * np.pi / 4.0, -0.95, 0.95)  # the slope at 0 is 4/π
    target = np.clip(ratio, -0.999, 0.999)
    for _ in range(8):
        root = np.sqrt(np.maximum(1.0 - t * t, 1e-12))
        f = (2.0 / np.pi) * (np.arcsin(t) + t * root) - target
        t = np.clip(t - f / ((4.0 / np.pi) * root), -0.999, 0.999)
    return t * radius


def centre_from_currents(photocurrents_a, params: PhysicalParameters, *, iterations: int = 12):
    """Spot centre (c_x, c_y) in the QD's axes [m] from the four photocurrents (the model inverted).

    Starts from the gapless disc's closed form per axis (each axis' normalised difference depends only on
    that axis' centre) and takes `iterations` Gauss–Newton steps on the shares, each step's length limited to
    r/4; vectorised over readings.

    Returns
    -------
    cx_m, cy_m : ndarray
    ok : ndarray of bool
        False where the shares do not fix the centre (a quadrant pair unlit, a sum ≤ 0) or did not converge.

    References
    ----------
    seed 002, eq. 2.1 (the four currents → the spot); module docstring.
    """
    r, g, signs = params.radius_m, params.gap_m, params.signs
    shares = quadrant_fractions(np.asarray(photocurrents_a, float) / params.gains, invalid="nan")
    shape = shares.shape[:-1]
    shares = shares.reshape(-1, 4)
    valid = np.all(np.isfinite(shares), axis=1)
    shares = np.where(valid[:, None], shares, 0.25)
    cx = _gapless_centre(shares @ signs[:, 0], r)
    cy = _gapless_centre(shares @ signs[:, 1], r)
    det = np.zeros_like(cx)
    for _ in range(iterations):
        areas, ax, ay, _ = quadrant_areas_jacobian(cx, cy, r, g, signs)
        total = areas.sum(axis=1, keepdims=True)
        model = areas / total
        jx = (ax - model * ax.sum(axis=1, keepdims=True)) / total
        jy = (ay - model * ay.sum(axis=1, keepdims=True)) / total
        res = model - shares
        a11, a12, a22 = (jx * jx).sum(1), (jx * jy).sum(1), (jy * jy).sum(1)
        b1, b2 = (jx * res).sum(1), (jy * res).sum(1)
        det = a11 * a22 - a12 * a12
        safe = np.where(det > 0, det, 1.0)
        dx = np.where(det > 0, -(a22 * b1 - a12 * b2) / safe, 0.0)
        dy = np.where(det > 0, -(a11 * b2 - a12 * b1) / safe, 0.0)
        step = np.hypot(dx, dy)
        limit = np.where(step > 0.25 * r, 0.25 * r / np.maximum(step, 1e-300), 1.0)
        cx, cy = cx + dx * limit, cy + dy * limit
    areas = quadrant_areas(cx, cy, r, g, signs)
    res = areas / areas.sum(axis=1, keepdims=True) - shares
    scale = (4.0 / (np.pi * r)) ** 2  # det of a well-placed spot is about this
    ok = valid & (det > 1e-6 * scale) & (np.max(np.abs(res), axis=1) < 0.05)
    return cx.reshape(shape), cy.reshape(shape), ok.reshape(shape)


def invert_physical(photocurrents_a, params: PhysicalParameters, *, iterations: int = 12):
    """Sun angles (α, β) [°] from the four photocurrents through the physical model.

    Returns
    -------
    alpha_deg, beta_deg : ndarray
        NaN where `ok` is False.
    ok : ndarray of bool

    References
    ----------
    seed 002, eqs. 2.1–2.2 (currents → spot → angles), with the spot's exact overlap in place of eq. 2.1.
    """
    cx, cy, ok = centre_from_currents(photocurrents_a, params, iterations=iterations)
    alpha, beta = angles_from_centre(cx, cy, params)
    return np.where(ok, alpha, np.nan), np.where(ok, beta, np.nan), ok


@dataclass(frozen=True)
class PhysicalFit:
    """The physical model fitted to photocurrents at known directions.

    Attributes
    ----------
    parameters : PhysicalParameters
    free : tuple of str
        Fitted parameters, in the order of `covariance`.
    sd : dict of str to float
        1σ of each free parameter [its unit].
    covariance, correlation : ndarray, shape (p, p)
    residual_rms : float
        RMS of the share residuals [unitless].
    point_residual : ndarray, shape (N,)
        RMS over the four shares of each point's residual [unitless].
    dof : int
        3N − p.
    responsivity_a_per_m2 : float
        K from the sums (median of Σ I / Σ g A cos θ) [A/m²].
    cos_law_rms : float
        Relative RMS of Σ I against K Σ g A cos θ: small when the currents follow the cos law [unitless].
    statements : list of str
        Near-degenerate pairs, in words.
    fixed : dict
        Parameters held fixed, with their values.
    notes : tuple of str
        What the model fixes by construction and why (:data:`FIXED_NOTES`).
    """

    parameters: PhysicalParameters
    free: tuple
    sd: dict
    covariance: np.ndarray
    correlation: np.ndarray
    residual_rms: float
    point_residual: np.ndarray
    dof: int
    responsivity_a_per_m2: float
    cos_law_rms: float
    statements: list = field(default_factory=list)
    fixed: dict = field(default_factory=dict)
    notes: tuple = FIXED_NOTES

    def apply(self, photocurrents_a):
        """(α, β, ok) from photocurrents (:func:`invert_physical`)."""
        return invert_physical(photocurrents_a, self.parameters)


def initial_physical(alpha_deg, beta_deg, photocurrents_a, design: QdDesign = DEFAULT_QD, *,
                     offsets: str = "rotation") -> PhysicalParameters:
    """A start for :func:`fit_physical`: gapless-disc centres per reading, then eq. 2.2's closed-form start.

    References
    ----------
    seed 002, eq. 2.2 and §3.1 (f0); :func:`calibration.qd.geometric.initial_geometric`.
    """
    signs = design.layout_signs
    shares = quadrant_fractions(photocurrents_a)
    cx = _gapless_centre(shares @ signs[:, 0], design.radius_m)
    cy = _gapless_centre(shares @ signs[:, 1], design.radius_m)
    # eq. 2.2 with x_c = R(φ)ᵀ r_c is the same geometry as step 2 (additive offsets = 0)
    g = initial_geometric(cx, cy, alpha_deg, beta_deg)
    return PhysicalParameters(x0_m=g.x0_m, y0_m=g.y0_m, phi0_deg=g.phi0_deg, d_m=g.d_m, gap_m=design.gap_m,
                              radius_m=design.radius_m, offsets=offsets,
                              layout=tuple(tuple(r) for r in signs.astype(int).tolist()))


def fit_physical(alpha_deg, beta_deg, photocurrents_a, *, design: QdDesign = DEFAULT_QD,
                 initial: PhysicalParameters | None = None, fixed=None, offsets: str = "rotation",
                 loss: str = "linear", f_scale: float | None = None, correlation_limit: float = 0.95) -> PhysicalFit:
    """Fit the physical model to photocurrents at known Sun angles (module docstring).

    Parameters
    ----------
    alpha_deg, beta_deg : array_like, shape (N,)
        Known Sun angles [°].
    photocurrents_a : array_like, shape (N, 4)
        Dark-corrected currents of quadrants 1–4 [A].
    design : QdDesign
        Radius (fixed), nominal gap and layout.
    initial : PhysicalParameters, optional
        Start; default :func:`initial_physical`.
    fixed : sequence of str or dict, optional
        Parameters held fixed (names at their `initial` value, or ``{name: value}``).
    offsets : {"rotation", "additive", "auto"}
        The die offsets' model (module docstring, step 1); "auto" fits both and keeps the lower cost.
    loss, f_scale
        ``least_squares`` loss and its scale in shares (default for a robust loss: 1.4826 × the median
        absolute residual of a first plain fit). With a robust loss the covariance is only indicative (it is
        computed as for plain least squares); refit the kept points with ``"linear"`` for uncertainties.
    correlation_limit : float

    Returns
    -------
    PhysicalFit

    References
    ----------
    seed 002, §3.1 (least squares against known angles), here in the space of the measured shares.
    """
    if offsets == "auto":
        fits = [fit_physical(alpha_deg, beta_deg, photocurrents_a, design=design,
                             initial=None if initial is None else replace(initial, offsets=o), fixed=fixed,
                             offsets=o, loss=loss, f_scale=f_scale, correlation_limit=correlation_limit)
                for o in OFFSET_MODELS]
        return min(fits, key=lambda f: f.residual_rms)
    a = np.asarray(alpha_deg, float).ravel()
    b = np.asarray(beta_deg, float).ravel()
    currents = np.asarray(photocurrents_a, float).reshape(-1, 4)
    if not (a.size == b.size == currents.shape[0]):
        raise InsufficientDataError("alpha, beta and the currents must have the same number of points")
    shares = quadrant_fractions(currents)
    if not np.all(np.isfinite(shares)) or not np.all(np.isfinite(a) & np.isfinite(b)):
        raise InsufficientDataError("the physical fit was given non-finite angles or currents")
    start = initial if initial is not None else initial_physical(a, b, currents, design, offsets=offsets)
    start = replace(start, offsets=offsets)
    values = {n: getattr(start, n) for n in PHYSICAL_PARAMETERS}
    fixed = fixed_parameters(fixed, PHYSICAL_PARAMETERS)
    for name, value in fixed.items():
        if value is not None:
            values[name] = float(value)
    free = tuple(n for n in PHYSICAL_PARAMETERS if n not in fixed)
    if 3 * a.size <= len(free):
        raise InsufficientDataError(f"the physical fit of {len(free)} parameters needs more than {len(free) // 3} "
                                    f"points, got {a.size}")
    r = start.radius_m
    scale = np.array([r if n.endswith("_m") else 1.0 for n in free])
    # internal units: lengths in radii, angles in degrees, gains as they are; d > 0, 0 ≤ g < r, gains > 0
    lower = np.array([1e-3 if n == "d_m" else 0.0 if n == "gap_m" else 1e-2 if n.startswith("gain") else -np.inf
                      for n in free])
    upper = np.array([0.999 if n == "gap_m" else np.inf for n in free])

    def params_of(p) -> PhysicalParameters:
        v = dict(values)
        v.update({n: float(p[i] * scale[i]) for i, n in enumerate(free)})
        return replace(start, **v)

    def residual(p):
        return (predict_shares(a, b, params_of(p)) - shares).ravel()

    p0 = np.array([values[n] for n in free]) / scale
    p0 = np.clip(p0, lower + 1e-9, np.where(np.isfinite(upper), upper - 1e-9, np.inf))
    tight = dict(xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200 * (len(free) + 1))
    # MINPACK's Levenberg–Marquardt first (fast); the bounded trust region only if it leaves the physical region
    fit = least_squares(residual, p0, method="lm", x_scale=np.where([n.startswith("gain") for n in free], 0.01, 1.0),
                        **tight)
    if not (np.all(fit.x >= lower) and np.all(fit.x <= upper)) or not np.all(np.isfinite(fit.x)):
        fit = least_squares(residual, p0, bounds=(lower, upper), x_scale="jac", **tight)
    if loss != "linear":
        if f_scale is None:
            point = np.sqrt(np.mean(fit.fun.reshape(-1, 4) ** 2, axis=1))
            f_scale = max(1.4826 * float(np.median(point)), 1e-9)
        fit = least_squares(residual, np.clip(fit.x, lower + 1e-9, np.where(np.isfinite(upper), upper - 1e-9, np.inf)),
                            bounds=(lower, upper), loss=loss, f_scale=f_scale, x_scale="jac", xtol=1e-10, ftol=1e-10,
                            gtol=1e-10, max_nfev=tight["max_nfev"])
    if not np.all(np.isfinite(fit.x)):
        raise FitError(f"the physical fit did not converge ({fit.message})")
    params = params_of(fit.x)
    res = residual(fit.x)
    # the 4 shares sum to 1: 3N independent observations
    cov, corr, _ = covariance_summary(fit.jac, res, scale)
    dof = 3 * a.size - len(free)
    cov *= (res.size - len(free)) / max(dof, 1)
    sd = {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(free)}
    point = np.sqrt(np.mean(res.reshape(-1, 4) ** 2, axis=1))
    # the sums: K and the cos law
    ratio = currents.sum(axis=1) / predict_currents(a, b, params, 1.0).sum(axis=1)
    k = float(np.median(ratio))
    cos_rms = float(np.sqrt(np.mean((ratio / k - 1.0) ** 2))) if k > 0 else float("nan")
    return PhysicalFit(params, free, sd, cov, corr, float(np.sqrt(np.mean(res**2))), point, dof, k, cos_rms,
                       correlation_statements(free, corr, correlation_limit),
                       {n: values[n] for n in fixed})
