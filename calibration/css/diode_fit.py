"""Fit one coarse-sun-sensor detector's model (:mod:`calibration.css.diode`) to its bench readings.

:func:`fit_diode` takes one channel's readings at known Sun directions (and, optionally, with the light off) and
returns a :class:`DiodeFit`:

1. **Faults first** (nothing is fitted to a broken channel, and the words say why):

   * *saturated* readings — at the front end's full scale when it is given, or at a top value that
     :data:`CLIP_REPEATS` or more readings share exactly although their incidences differ by more than
     :data:`CLIP_SPREAD_DEG` (a clip level, not a measurement) — are rejected and named; a channel saturated in
     more than half of its lit readings is faulty;
   * *stuck*: every reading the same value; *dead*: the readings do not change with the Sun's direction (the
     rise from no light to normal incidence is under :data:`DEAD_SIGMAS` × the noise); *inverted*: they fall as
     the light rises; *unlit*: fewer than :data:`MIN_LIT_DIRECTIONS` directions within
     :data:`LIT_INCIDENCE_DEG` of the nominal normal.

2. **What is fitted**: S, b, the two tilts, κ (or p); θ_c only when some reading lies beyond
   :data:`FOV_EVIDENCE_DEG` of incidence (otherwise no cut-off, and a warning); c_T and b_T only when the readings
   span :data:`MIN_TEMPERATURE_SPAN_C` or more. A parameter that ends on its bound is fixed there and said so (θ_c
   at its upper bound: no cut-off inside the hemisphere). The ``spline`` law fits its coefficients ``spline_1`` …
   instead of a shape and never θ_c (its spline ends at its last knot: it holds the cut-off itself).
3. **Noise**, provisional: from the scatter of repeats (rows of one direction, :func:`direction_groups`) about a
   model-free description of the readings (a cubic in the nominal cos γ, with the temperature), else from that
   description's residual.
4. **Start** from the nominal normal and a grid of shapes (and cut-offs), S and b (and c_T, b_T) solved by
   weighted linear least squares at each. The spline law's signal is linear in S·c_j, b and b_T for a given normal
   and c_T: they are solved by weighted linear least squares at the nominal normal (or at the normal and c_T of a
   fit of another law passed as `initial`: :func:`calibration.css.calibrate.calibrate_css` with `start` passes the
   Kelly fit's), then c_T from that response, and the spline again; its end θ_K, the field's edge, is the one of
   smallest χ² + 2 p among ends every 0.5° (:func:`_spline_end`; again after the robust fit and after the first
   round of step 7, at the fitted normal).
5. **Robust fit** (soft-L1 on residuals whitened by the noise, scale :data:`ROBUST_SCALE_SIGMAS` σ); a reading
   whose whitened residual stands more than :data:`OUTLIER_SIGMAS` robust sigmas from its 8 nearest directions'
   is rejected and named (a glint, a spike: the model's smooth misfit is shared by the neighbours and never
   rejected); if more than :data:`SCREEN_MAX_SHARE` of the readings would go, none is, with a warning. The spline
   law's misfit is a function of the incidence that can turn sharply at a cap shadow's edges: its neighbours are the
   8 readings nearest in incidence, and a reading its own repeats agree with is never rejected.
6. **Noise model** σ² = σ₀² + q|m| + (r m)² from the scatter of the residuals within each repeat group
   (:func:`fit_noise_model`, a Gamma likelihood, so a pair's variance counts for one degree of freedom), or from
   the residuals themselves when there are no repeats (then χ²/dof ≈ 1 by construction, said so). σ₀ is floored at
   the readings' resolution / √12 when they are quantised. When the residual of the lit readings exceeds that
   noise (χ²/dof more than :data:`MODEL_ERROR_SIGMAS` √(2/dof) above 1: an angular law unlike the detector's), a
   model error τ is added to their noise (:func:`model_error`, Σ r²/(σ² + τ²) = dof), in the fit's weights and in
   the estimator's, and said so.
7. **Weighted least squares** (plain loss), alternating with the noise model for :data:`NOISE_ITERATIONS` rounds;
   θ_c is then profiled (others held) and the fit restarted where the profile finds a clearly lower χ² (the ramp
   makes χ²(θ_c) piecewise, flat between the readings' incidences). The spline law's model error applies where the
   reading or the model is lit (its spline may be wrong where a detector reads dark), its roughness penalty
   (:data:`calibration.css.spline.SPLINE_ROUGHNESS`) joins the residuals, and Levenberg–Marquardt solves it (its
   bounds checked after).
8. **Covariance** (JᵀJ)⁻¹ of the whitened residuals, scaled by χ²/dof when that exceeds 1; standard deviations and
   the correlation matrix. θ_c's 1σ is at least the half-width of its profile's Δχ² ≤ 1 interval; when no reading
   lies inside its ramp the profile is flat between two readings and θ_c is that interval's centre, ±half of it.

With a given noise model (the held-out folds of :func:`calibration.css.calibrate.calibrate_css` pass the full
fit's) steps 3, 5 and 6 are skipped (and the spline law keeps the full fit's knots).

References
----------
seed 000, eq. 3.1, §3.2–3.4 (temperature coefficients), §4 (noise), digest §8.1 item 1, §8.3 items 7–8 (fit scale,
offset, normal, angular law), §8.1 item 3 (shot noise); research note anchors-sunsensors §5 (Basilisk's
coarseSunSensor parameters: scale, bias, normal, Kelly κ, FOV; faults OFF, STUCK, saturation) and §6 (robust fits,
covariance, held-out accuracy).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq, least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import BenchDataError
from .diode import (
    FOV_EDGE_WIDTH_DEG,
    REFERENCE_TEMPERATURE_C,
    RESPONSES,
    SHAPE_NAME,
    SPLINE,
    DiodeParameters,
    face_axes,
    normal_angles,
    relative_response,
    signal_partials,
)
from .head import split_channel, vector_angles
from .spline import END_MIN_DEG, END_STEP_DEG, FIXED_LOW, SPLINE_ROUGHNESS, knots_ending_at, spline_basis

#: A reading farther than this many robust sigmas from its neighbours' residual is an outlier.
OUTLIER_SIGMAS = 6.0
#: The soft-L1 loss's scale, in noise sigmas.
ROBUST_SCALE_SIGMAS = 3.0
#: If the screen would reject more than this share of the readings, it rejects none.
SCREEN_MAX_SHARE = 0.05
#: c_T and b_T are fitted only when the readings span at least this [°C].
MIN_TEMPERATURE_SPAN_C = 3.0
#: θ_c is fitted only when some lit-side reading lies beyond this incidence [°].
FOV_EVIDENCE_DEG = 70.0
#: A direction within this of the nominal normal counts as lighting the detector [°].
LIT_INCIDENCE_DEG = 60.0
#: Fewer lit directions than this: not calibrated.
MIN_LIT_DIRECTIONS = 4
#: The rise from no light to normal incidence must exceed this many noise sigmas, or the detector is dead.
DEAD_SIGMAS = 10.0
#: A top value shared exactly by this many readings (of incidences spread over CLIP_SPREAD_DEG) is a clip level.
CLIP_REPEATS = 3
#: See CLIP_REPEATS [°].
CLIP_SPREAD_DEG = 10.0
#: Readings of one direction: within this angle of each other [°] (above a table's read-back jitter of 1′).
DIRECTION_TOLERANCE_DEG = 0.03
#: χ²/dof above this (a residual 2× the noise) says the model does not describe the detector.
CHI2_WARNING = 4.0
#: A fitted normal farther than this from the face's nominal one is worth a word [°].
TILT_WARNING_DEG = 5.0
#: |correlation| above this between two fitted parameters is worth a word.
CORRELATION_WARNING = 0.98
#: Bounds of the fitted parameters.
BOUNDS = {"tilt_u_deg": (-30.0, 30.0), "tilt_v_deg": (-30.0, 30.0), "kappa": (1e-3, 1e3), "power": (0.2, 10.0),
          "fov_half_deg": (20.0, 91.0), "temp_coeff_per_c": (-0.1, 0.1)}
#: A reading more than this many noise sigmas above the offset is lit (:func:`lit_reading`).
LIT_SIGMAS = 5.0
#: χ²/dof more than this many √(2/dof) above 1 gets a model error (:func:`model_error`).
MODEL_ERROR_SIGMAS = 5.0
#: Rounds of reweighting that make the spline law's soft-L1 fit (:meth:`_Problem.solve`).
ROBUST_ROUNDS = 4
#: Rounds of noise estimate and weighted fit.
NOISE_ITERATIONS = 4
#: Ends of the spline law whose criterion (χ² + 2 p) is within this of the best are as good (:func:`_spline_end`).
END_TOLERANCE = 2.0
#: Step of θ_c's profile [°].
FOV_PROFILE_STEP_DEG = 0.1
#: A fitted θ_c above this is no cut-off inside the hemisphere [°].
FOV_NONE_ABOVE_DEG = 90.0

#: Starting grids of the shape parameter
_SHAPE_GRID = {"kelly": (0.003, 0.03, 0.1, 0.3, 1.0, 3.0, 30.0), "power": (0.7, 1.0, 1.3, 1.7, 2.2, 3.0, 4.0)}


@dataclass(frozen=True)
class RejectedReading:
    """A reading left out of a fit, and why.

    Attributes
    ----------
    row_id : int
        The row's name.
    channel : str or None
        The channel whose reading was left out (None: the whole row).
    zenith_deg, azimuth_deg : float
        Its Sun direction (NaN on a dark row) [°].
    reason : str
    """

    row_id: int
    channel: str | None
    zenith_deg: float
    azimuth_deg: float
    reason: str

    def to_dict(self) -> dict:
        nan = lambda v: None if not np.isfinite(v) else float(v)  # noqa: E731
        return {"row": self.row_id, "channel": self.channel, "zenith_deg": nan(self.zenith_deg),
                "azimuth_deg": nan(self.azimuth_deg), "reason": self.reason}

    def describe(self) -> str:
        where = "" if not np.isfinite(self.zenith_deg) else (f" (zenith {self.zenith_deg:.2f}°, azimuth "
                                                              f"{self.azimuth_deg:.2f}°)")
        what = f"{self.channel} " if self.channel else ""
        return f"row {self.row_id}{where}: {what}{self.reason}"


@dataclass(frozen=True)
class DiodeFit:
    """One detector's calibration (module docstring).

    Attributes
    ----------
    channel : str
    response : {"kelly", "power", "spline"}
    parameters : DiodeParameters or None
        The fitted model with its noise model; None when the channel is faulty.
    free : tuple of str
        Fitted parameter names in the covariance's order (``kappa``/``power`` for the shape; ``spline_1`` … for the
        spline law's coefficients).
    values, sd : dict of str to float
        Every parameter's value, and the 1σ of the fitted ones (NaN where the covariance is singular).
    covariance, correlation : ndarray (p, p)
    chi2_dof : float
        χ² of the whitened residuals per degree of freedom.
    rms : float
        RMS residual of the readings used [A or V].
    rms_normalised : float
        RMS of the whitened residuals [σ].
    n_points, n_dof : int
    noise_source : {"repeats", "residuals", "none"}
    temperature_fitted, fov_fitted : bool
    fault : str or None
        ``saturated``, ``stuck``, ``dead``, ``inverted`` or ``unlit``.
    rejected : tuple of RejectedReading
    warnings : tuple of str
        What looks wrong, in words.
    statements : tuple of str
        What was fitted and fixed, and why.
    residual : ndarray (N,)
        Reading − model for the readings used [A or V], NaN elsewhere (aligned with the input rows).
    used : ndarray of bool (N,)
    normal_zenith_deg, normal_azimuth_deg : float
        The fitted normal's body zenith and azimuth [°].
    normal_sd_deg : float
        1σ of the normal's direction: √(σ²(t_u) + σ²(t_v)) [°].
    resolution : float or None
        The readings' quantisation step when they are quantised [A or V].
    model_sd : float
        RMS model error added to the noise when the residual exceeds it (:func:`model_error`) [A or V].
    """

    channel: str
    response: str
    parameters: DiodeParameters | None
    free: tuple = ()
    values: dict = field(default_factory=dict)
    sd: dict = field(default_factory=dict)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    correlation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    chi2_dof: float = float("nan")
    rms: float = float("nan")
    rms_normalised: float = float("nan")
    n_points: int = 0
    n_dof: int = 0
    noise_source: str = "none"
    temperature_fitted: bool = False
    fov_fitted: bool = False
    fault: str | None = None
    rejected: tuple = ()
    warnings: tuple = ()
    statements: tuple = ()
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    used: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    normal_zenith_deg: float = float("nan")
    normal_azimuth_deg: float = float("nan")
    normal_sd_deg: float = float("nan")
    resolution: float | None = None
    model_sd: float = 0.0

    @property
    def valid(self) -> bool:
        """The channel is calibrated (no fault)."""
        return self.fault is None and self.parameters is not None

    def predict(self, sun_vectors, temperature_c=REFERENCE_TEMPERATURE_C, *, dark=None) -> np.ndarray:
        """Model signal [A or V] at unit sun vectors (N, 3) (dark rows: the offset only).

        References
        ----------
        seed 000 eq. 3.1; research note anchors-sunsensors §5.
        """
        if self.parameters is None:
            raise ValueError(f"{self.channel} has no model: {self.fault}")
        s = np.atleast_2d(np.asarray(sun_vectors, float))
        t = np.broadcast_to(np.asarray(temperature_c, float), (s.shape[0],))
        lit = np.ones(s.shape[0], bool) if dark is None else ~np.asarray(dark, bool)
        return signal_partials(self.parameters, np.where(lit[:, None], np.nan_to_num(s), 0.0), t, lit)[0]

    def to_dict(self) -> dict:
        """JSON types: the report of this fit (parameters with sd, covariance, noise, warnings)."""
        p = self.parameters
        plain = lambda v: None if v is None or not np.isfinite(v) else float(v)  # noqa: E731
        return {"channel": self.channel, "response": self.response, "valid": self.valid, "fault": self.fault,
                "parameters": {k: {"value": plain(v), "sd": plain(self.sd.get(k)), "fitted": k in self.free}
                               for k, v in self.values.items()},
                "covariance": {"names": list(self.free), "matrix": [[plain(x) for x in row]
                                                                     for row in np.asarray(self.covariance)]},
                "correlation": [[plain(x) for x in row] for row in np.asarray(self.correlation)],
                "noise": None if p is None else {"sigma0": p.sigma0, "shot": p.shot, "relative": p.noise_rel,
                                                 "model": p.model_sd, "source": self.noise_source},
                "normal": {"zenith_deg": plain(self.normal_zenith_deg), "azimuth_deg": plain(self.normal_azimuth_deg),
                           "sd_deg": plain(self.normal_sd_deg)},
                "chi2_dof": plain(self.chi2_dof), "rms": plain(self.rms), "rms_normalised": plain(self.rms_normalised),
                "n_points": self.n_points, "n_dof": self.n_dof, "temperature_fitted": self.temperature_fitted,
                "fov_fitted": self.fov_fitted, "resolution": plain(self.resolution),
                "rejected": [r.to_dict() for r in self.rejected], "warnings": list(self.warnings),
                "statements": list(self.statements)}


# --- helpers everyone uses ------------------------------------------------------------------------------------------
def direction_groups(sun_vectors, dark=None, check=None, *, tolerance_deg: float = DIRECTION_TOLERANCE_DEG):
    """Group label of each row: rows whose Sun directions lie within `tolerance_deg` of each other (chained) share
    one; all dark rows share one; check rows never share a group with fitted rows.

    References
    ----------
    seed 000 digest §8.3 item 7 (sweeps repeated per temperature); seed 002 §4 (readings at known table angles,
    repeat passes).
    """
    s = np.asarray(sun_vectors, float).reshape(-1, 3)
    n = s.shape[0]
    dark = np.zeros(n, bool) if dark is None else np.asarray(dark, bool)
    check = np.zeros(n, bool) if check is None else np.asarray(check, bool)
    labels = np.full(n, -1)
    chord = 2.0 * np.sin(np.radians(tolerance_deg) / 2.0)
    next_label = 0
    for part in (~dark & ~check, ~dark & check):
        idx = np.flatnonzero(part & np.all(np.isfinite(s), axis=1))
        if idx.size == 0:
            continue
        pairs = cKDTree(s[idx]).query_pairs(chord, output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(idx.size, idx.size))
        count, comp = connected_components(graph, directed=False)
        labels[idx] = comp + next_label
        next_label += count
    if dark.any():
        labels[dark] = next_label
    return labels


def quantisation_step(values) -> float | None:
    """The step of readings that sit on a lattice (an ADC's resolution) [their unit], None when they do not.

    References
    ----------
    seed 000 §3.6 (ADuC842 ADC, 16-sample average), digest §8.1 item 1 (ADC bits and reference).
    """
    v = np.unique(np.asarray(values, float)[np.isfinite(values)])
    if v.size < 3:
        return None
    steps = np.diff(v)
    step = float(steps.min())
    if step <= 0 or step < 1e-12 * max(abs(v).max(), 1e-300):
        return None
    ratio = (v - v[0]) / step
    if np.mean(np.abs(ratio - np.round(ratio)) < 1e-3) >= 0.99 and np.median(steps) / step < 1e4:
        return step
    return None


def clip_level(signal, cos_incidence) -> float | None:
    """The top value at which readings are clipped, detected from the data (module docstring step 1), or None.

    References
    ----------
    seed 000 digest §3.6 ⚠ and §8.1 item 1 (the BPW's Sun signal would saturate the front end: model clipping).
    """
    y = np.asarray(signal, float)
    g = np.asarray(cos_incidence, float)
    ok = np.isfinite(y)
    if ok.sum() < CLIP_REPEATS:
        return None
    top = y[ok].max()
    at = ok & (y == top)
    if at.sum() < CLIP_REPEATS:
        return None
    inc = np.degrees(np.arccos(np.clip(g[at & np.isfinite(g)], -1, 1)))
    if inc.size >= CLIP_REPEATS and np.ptp(inc) >= CLIP_SPREAD_DEG:
        return float(top)
    return None


def fit_noise_model(variance, level, dof, *, floor: float = 0.0, terms: str = "all") -> tuple[float, float, float]:
    """(σ₀, q, r) of σ² = σ₀² + q|m| + (r m)² from sample variances of groups of readings.

    Maximum likelihood with each group's variance Gamma-distributed (its `dof` = readings − 1 degrees of freedom:
    a pair's variance counts once), over the logarithms of σ₀², q and r² (Fisher scoring from a few starts: the
    floor from the faintest groups, the relative term from the brightest).

    Parameters
    ----------
    variance : ndarray (G,)
        Sample variance of each group [unit²].
    level : ndarray (G,)
        The group's signal (model or mean) [unit].
    dof : ndarray (G,)
    floor : float
        Lower limit of σ₀ [unit] (the readings' resolution / √12).
    terms : {"all", "constant"}
        Fit only σ₀ with ``"constant"``.

    References
    ----------
    seed 000 §4 (noise floor), digest §4.4 and §8.1 item 3 (shot noise ∝ current); research note
    anchors-sunsensors §6 (weights from repeat scatter).
    """
    s2 = np.asarray(variance, float)
    m = np.abs(np.asarray(level, float))
    d = np.asarray(dof, float)
    ok = np.isfinite(s2) & np.isfinite(m) & (d > 0)
    s2, m, d = s2[ok], m[ok], d[ok]
    if s2.size == 0 or not np.any(s2 > 0):
        return float(floor), 0.0, 0.0
    constant = max(float(np.sqrt(np.sum(d * s2) / np.sum(d))), floor)
    if terms == "constant" or s2.size < 6 or np.ptp(m) <= 0:
        return constant, 0.0, 0.0
    top_v = float(np.max(s2))
    top_m = float(np.max(m))
    t, x = s2 / top_v, m / top_m
    cols = np.column_stack([np.ones_like(x), x, x * x])
    lo, hi = -70.0, 5.0

    def nll(u):
        v = cols @ np.exp(u) + 1e-30
        return float(np.sum((d / 2.0) * (np.log(v) + t / v)))

    def scoring(u):
        """Fisher scoring in the logarithms, with step halving and the bounds [lo, hi]."""
        f = nll(u)
        for _ in range(100):
            k = np.exp(u)
            v = cols @ k + 1e-30
            dv = cols * k  # ∂v/∂u
            score = dv.T @ ((d / 2.0) * (t - v) / v**2)
            info = (dv * ((d / 2.0) / v**2)[:, None]).T @ dv + 1e-12 * np.eye(3)
            step = np.linalg.solve(info, score)
            for _ in range(30):
                trial = np.clip(u + step, lo, hi)
                f_trial = nll(trial)
                if f_trial <= f:
                    break
                step = step / 2.0
            else:
                return u, f
            done = f - f_trial < 1e-10 * (1.0 + abs(f))
            u, f = trial, f_trial
            if done:
                break
        return u, f

    faint = x <= np.quantile(x, 0.2)
    bright = x >= np.quantile(x, 0.8)
    a0 = max(float(np.median(t[faint])), 1e-12)
    c0 = max(float(np.median(t[bright] / x[bright] ** 2)), 1e-12)
    b0 = max(float(np.median(t / np.maximum(x, 1e-12))) * 0.1, 1e-12)
    best_u, best_f = None, np.inf
    for start in ((a0, b0, c0), (a0, 1e-12, c0), (a0, b0, 1e-12), (float(np.mean(t)), 1e-12, 1e-12)):
        u, f = scoring(np.clip(np.log(start), lo, hi))
        if f < best_f:
            best_u, best_f = u, f
    k = np.where(best_u <= lo + 1.0, 0.0, np.exp(best_u))
    sigma0_sq, q, r_sq = k[0] * top_v, k[1] * top_v / top_m, k[2] * top_v / top_m**2
    return max(float(np.sqrt(sigma0_sq)), floor), float(q), float(np.sqrt(r_sq))


# --- the fit ----------------------------------------------------------------------------------------------------
def _public(name: str, response: str) -> str:
    return SHAPE_NAME[response] if name == "shape" else name


def _bounds(name: str, response: str) -> tuple[float, float]:
    return BOUNDS.get(_public(name, response), (-np.inf, np.inf))


def _robust_sigma(values) -> float:
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    return float(1.4826 * np.median(np.abs(values - np.median(values)))) if values.size else float("nan")


def _group_scatter(values, groups, rows):
    """Within-group sample variances, group means and degrees of freedom of `values` over `rows`."""
    g = groups[rows]
    v = values[rows]
    ok = g >= 0
    g, v = g[ok], v[ok]
    if g.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)
    uniq, inv, counts = np.unique(g, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, v)
    means = sums / counts
    dev = v - means[inv]
    ss = np.bincount(inv, dev**2)
    keep = counts >= 2
    return ss[keep] / (counts[keep] - 1), means[keep], counts[keep] - 1, dev[keep[inv]]


def _initial(params: DiodeParameters, s, t, lit, y, free, fov_candidates, weights=None):
    """Start: nominal normal; grid over shape (and θ_c) with S, b (and c_T, b_T) solved linearly."""
    n0 = face_axes(params.face)[0]
    g = np.where(lit, s @ n0, 0.0)
    dt = t - REFERENCE_TEMPERATURE_C
    shapes = np.array(_SHAPE_GRID[params.response] if "shape" in free else (params.shape,), float)
    fovs = np.array([np.nan if f is None else f for f in fov_candidates], float)
    laws = np.where(lit, relative_response(g[None, :], params.response, shapes[:, None]), 0.0)  # (k, N)
    edges = relative_response(np.where(lit, g, 0.0)[None, :], "power", 0.0, fovs[:, None])  # (j, N): E alone
    edges = np.where(lit & (g > 0), edges, 1.0)
    f = (laws[:, None, :] * edges[None, :, :]).reshape(-1, y.size)  # (k·j, N)
    f2 = f * f
    w2 = np.ones_like(y) if weights is None else np.asarray(weights, float) ** 2
    if "temp_coeff_per_c" in free:  # columns [f, 1, f ΔT, ΔT]: the normal equations from matrix–vector products
        s_ff, s_ffd, s_ffdd = f2 @ w2, f2 @ (w2 * dt), f2 @ (w2 * dt * dt)
        s_f, s_fd, s_fdd = f @ w2, f @ (w2 * dt), f @ (w2 * dt * dt)
        k1, kd, kdd = float(w2.sum()), float(w2 @ dt), float(w2 @ (dt * dt))
        ata = np.stack([np.stack([s_ff, s_f, s_ffd, s_fd], -1),
                        np.stack([s_f, np.full_like(s_f, k1), s_fd, np.full_like(s_f, kd)], -1),
                        np.stack([s_ffd, s_fd, s_ffdd, s_fdd], -1),
                        np.stack([s_fd, np.full_like(s_f, kd), s_fdd, np.full_like(s_f, kdd)], -1)], -2)
        aty = np.stack([f @ (w2 * y), np.full_like(s_f, w2 @ y), f @ (w2 * dt * y),
                        np.full_like(s_f, (w2 * dt) @ y)], -1)
    else:
        s_ff, s_f = f2 @ w2, f @ w2
        ata = np.stack([np.stack([s_ff, s_f], -1), np.stack([s_f, np.full_like(s_f, float(w2.sum()))], -1)], -2)
        aty = np.stack([f @ (w2 * y), np.full_like(s_f, w2 @ y)], -1)
    ata = ata + 1e-300 * np.eye(ata.shape[-1])
    try:
        coef = np.linalg.solve(ata, aty[..., None])[..., 0]
    except np.linalg.LinAlgError:
        coef = np.einsum("icd,id->ic", np.linalg.pinv(ata), aty)
    coef = coef.reshape(shapes.size, fovs.size, -1)
    aty = aty.reshape(shapes.size, fovs.size, -1)
    ss = float((w2 * y) @ y) - np.einsum("kjc,kjc->kj", coef, aty)
    ss = np.where(np.isfinite(ss), ss, np.inf)
    ik, ij = np.unravel_index(int(np.argmin(ss)), ss.shape)
    c = coef[ik, ij]
    fov = None if np.isnan(fovs[ij]) else float(fovs[ij])
    values = {"shape": float(shapes[ik]), "fov_half_deg": fov, "scale": float(c[0]), "bias": float(c[1]),
              "tilt_u_deg": 0.0, "tilt_v_deg": 0.0}
    if "temp_coeff_per_c" in free and c[0] != 0:
        values["temp_coeff_per_c"] = float(np.clip(c[2] / c[0], -0.05, 0.05))
        values["bias_temp_coeff_per_c"] = float(c[3])
    return replace(params, **values)


def _initial_spline(params: DiodeParameters, s, t, lit, y, free, weights=None, *,
                    estimate_c_t: bool = True) -> tuple[DiodeParameters, float]:
    """Start of the spline law at the normal and c_T of `params` (module docstring step 4), and its χ² (the
    weighted residuals' and the roughness penalty's): the signal (1 + c_T ΔT)·Σ (S c_j) B_j + S B_{K+2} + b
    (+ b_T ΔT) is linear in S·c_j, S, b and b_T; with c_T 0, the temperature fitted and `estimate_c_t`, c_T comes
    from that first response (columns f, 1, f ΔT, ΔT) and the spline is solved again with it."""
    basis = spline_basis(params.spline_knots_deg)
    g = np.where(lit, s @ params.normal, 0.0)
    dt = t - REFERENCE_TEMPERATURE_C
    b_all, _ = basis.all_basis(g)
    b_all = np.where(lit, b_all, 0.0)
    w = np.ones_like(y) if weights is None else np.asarray(weights, float)
    fit_t = "temp_coeff_per_c" in free

    # the roughness penalty's rows (module docstring of calibration.css.spline), in units of S·c
    root, fixed = basis.roughness()
    level = max(float(np.ptp(y[lit])) if lit.any() else 0.0, 1e-300)
    pen = np.sqrt(SPLINE_ROUGHNESS) / level * np.column_stack([root, fixed] + [np.zeros(root.shape[0])] * (
        2 if fit_t else 1))

    def solve(c_t):
        gain = 1.0 + c_t * dt
        cols = [*(gain * b_all[FIXED_LOW:]), np.ones_like(y)] + ([dt] if fit_t else [])
        a = np.vstack([np.column_stack(cols) * w[:, None], pen])
        rhs = np.r_[y * w, np.zeros(pen.shape[0])]
        ata = a.T @ a
        d = np.sqrt(np.diag(ata))
        d = np.where(d > 0, d, 1.0)
        try:  # the normal equations, equilibrated (the penalty keeps them regular)
            coef = np.linalg.solve(ata / np.outer(d, d), (a.T @ rhs) / d) / d
        except np.linalg.LinAlgError:
            coef = np.linalg.lstsq(a, rhs, rcond=None)[0]
        scale = coef[basis.n_free]
        if not np.isfinite(scale) or scale == 0:
            return None, np.inf
        return ({"spline": tuple(float(v) for v in coef[:basis.n_free] / scale), "scale": float(scale),
                 "bias": float(coef[basis.n_free + 1]),
                 "bias_temp_coeff_per_c": float(coef[basis.n_free + 2]) if fit_t else params.bias_temp_coeff_per_c},
                float(np.sum((a @ coef - rhs) ** 2)))

    c_t = params.temp_coeff_per_c if fit_t else 0.0
    values, chi2 = solve(c_t)
    if values is None:
        return params, np.inf
    out = replace(params, **values)
    if fit_t and params.temp_coeff_per_c == 0.0 and estimate_c_t:
        f = np.where(lit, out.relative_response(g), 0.0)
        a = np.column_stack([f, np.ones_like(y), f * dt, dt])
        coef, *_ = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)
        if coef[0] != 0 and np.isfinite(coef[0]):
            c_t = float(np.clip(coef[2] / coef[0], -0.05, 0.05))
            values, chi2_t = solve(c_t)
            if values is not None:
                out, chi2 = replace(params, **values, temp_coeff_per_c=c_t), chi2_t
    return out, chi2


def _with_spline(free, params: DiodeParameters) -> list:
    """`free` with the spline's coefficient names replaced by those of `params` (in their place)."""
    names = list(params.spline_names)
    out, placed = [], False
    for name in free:
        if name.startswith("spline_"):
            if not placed:
                out += names
                placed = True
        else:
            out.append(name)
    return out if placed else out[:4] + names + out[4:]


def _spline_end(params: DiodeParameters, s, t, lit, y, free, weights, *, near: float | None = None
                ) -> tuple[DiodeParameters, float]:
    """The spline's end θ_K (:func:`calibration.css.spline.knots_ending_at`, its knots thinned where too few of the
    directions' incidences on the normal of `params` support them) with the smallest χ² + 2 p of the linear start
    (:func:`_initial_spline`, the normal and c_T of `params` held; p its coefficients, Akaike's criterion: a later
    end has more knots, and would win on χ² alone where the readings cannot tell): every 5° from
    :data:`~calibration.css.spline.END_MIN_DEG` to 90°, then every :data:`~calibration.css.spline.END_STEP_DEG`
    within 5° of the best (`near`: only within 2.5° of that end, found before). Where the criterion stays within
    :data:`END_TOLERANCE` of its minimum over a run of ends (no reading between the last lit incidence and the
    first dark one tells them apart), the run's middle is taken, as θ_c's interval centre is. Returns that start
    and its criterion."""
    tried: dict = {}
    directions = np.unique(np.round(s[lit], 9), axis=0) if lit.any() else np.zeros((0, 3))
    support = np.degrees(np.arccos(np.clip(directions @ params.normal, -1.0, 1.0)))
    support = support[support < 90.0]

    def at(end):
        end = round(float(end), 6)
        if end not in tried:
            knots = knots_ending_at(end, support=support)
            trial = replace(params, spline_knots_deg=knots, spline=(0.0,) * len(knots))  # _initial_spline sets them
            start, chi2 = _initial_spline(trial, s, t, lit, y, _with_spline(free, trial), weights,
                                          estimate_c_t=False)
            tried[end] = start, chi2 + 2.0 * len(start.spline)
        return tried[end]

    if near is None:
        best, window = min(np.arange(END_MIN_DEG, 90.0 + 1e-9, 5.0), key=lambda e: at(e)[1]), 5.0
    else:
        best, window = float(near), 2.5
    fine = np.arange(max(END_MIN_DEG, best - window), min(90.0, best + window) + 1e-9, END_STEP_DEG)
    crit = np.array([at(e)[1] for e in fine])
    i = int(np.argmin(crit))
    flat = crit <= crit[i] + END_TOLERANCE
    a = b = i
    while a > 0 and flat[a - 1]:
        a -= 1
    while b < fine.size - 1 and flat[b + 1]:
        b += 1
    return at(fine[(a + b) // 2])


class _Problem:
    """The whitened residuals of one detector's readings and their Jacobian over the free parameters; for the
    spline law, the roughness penalty's rows after them (:data:`calibration.css.spline.SPLINE_ROUGHNESS`)."""

    def __init__(self, base: DiodeParameters, free, s, t, lit, y, sigma):
        self.base, self.free = base, tuple(free)
        self.s, self.t, self.lit, self.y, self.sigma = s, t, lit, y, sigma
        self.penalty = None
        names = base.spline_names
        if names and all(n in self.free for n in names):
            root, fixed = spline_basis(base.spline_knots_deg).roughness()
            weight = np.sqrt(SPLINE_ROUGHNESS)
            self.penalty = (np.array([self.free.index(n) for n in names]), weight * root, weight * fixed)

    def params(self, x) -> DiodeParameters:
        return self.base.with_values(**dict(zip(self.free, (float(v) for v in x))))

    def x0(self, params: DiodeParameters) -> np.ndarray:
        return np.array([params.get(n) for n in self.free], float)

    def _evaluate(self, x):
        key = np.asarray(x, float).tobytes()
        if getattr(self, "_key", None) != key:
            self._key, self._value = key, signal_partials(self.params(x), self.s, self.t, self.lit)
        return self._value

    def data_residuals(self, x):
        m, _ = self._evaluate(x)
        return (self.y - m) / self.sigma

    def residuals(self, x):
        r = self.data_residuals(x)
        if self.penalty is None:
            return r
        idx, root, fixed = self.penalty
        return np.concatenate([r, root @ np.asarray(x, float)[idx] + fixed])

    def jacobian(self, x):
        _, partials = self._evaluate(x)
        jac = -np.column_stack([partials[n] for n in self.free]) / self.sigma[:, None]
        if self.penalty is None:
            return jac
        idx, root, _ = self.penalty
        rows = np.zeros((root.shape[0], jac.shape[1]))
        rows[:, idx] = root
        return np.vstack([jac, rows])

    def solve(self, params: DiodeParameters, *, loss="linear", f_scale=1.0):
        lo = np.array([_bounds(n, self.base.response)[0] for n in self.free])
        hi = np.array([_bounds(n, self.base.response)[1] for n in self.free])
        margin = np.where(np.isfinite(hi - lo), 1e-9 * (hi - lo), 0.0)
        x0 = np.clip(self.x0(params), lo + margin, hi - margin)
        if self.penalty is not None and loss in ("linear", "soft_l1"):
            # the spline law: Levenberg–Marquardt (MINPACK's own QR, far cheaper than the trust region's SVD of a
            # Jacobian this wide, and no threaded LAPACK to wait on), its bounds checked after it (a step beyond one
            # falls back to the bounded solver); the soft-L1 loss by reweighting: w = (1 + (r/f)²)^(−1/2), the loss'
            # own weight, for ROBUST_ROUNDS rounds
            sigma = self.sigma
            x = x0
            try:
                for _ in range(1 if loss == "linear" else ROBUST_ROUNDS):
                    if loss != "linear":
                        r = self.data_residuals(x) * (self.sigma / sigma)
                        self.sigma = sigma * (1.0 + (r / f_scale) ** 2) ** 0.25
                    sol = least_squares(self.residuals, x, jac=self.jacobian, x_scale="jac", method="lm",
                                        xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=400)
                    x = sol.x
            finally:
                self.sigma = sigma
            if np.all((sol.x >= lo) & (sol.x <= hi)):
                return self.params(sol.x), sol
        sol = least_squares(self.residuals, x0, jac=self.jacobian, bounds=(lo, hi), loss=loss, f_scale=f_scale,
                            x_scale="jac", method="trf", xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=400)
        return self.params(sol.x), sol


def _neighbour_outliers(z, s, lit, rows, incidence=None, groups=None, temperature=None):
    """Readings whose whitened residual stands out from their 8 nearest directions' (module docstring step 5).

    The spline law (`incidence` [°], `groups`, `temperature` [°C]): from the 8 readings nearest in incidence, and
    from its repeats (its direction's other readings within 1 °C) when it has some — the law's misfit, a function of
    the incidence that can be sharp near a cap's shadow or the cut-off, is shared by the repeats, a spike is not."""
    z = np.asarray(z, float)
    dev = np.zeros(rows.size)
    light = lit[rows]
    if light.sum() >= 10:
        idx = rows[light]
        k = min(10, idx.size)
        points = s[idx] if incidence is None else np.asarray(incidence, float)[idx][:, None]
        _, nb = cKDTree(points).query(points, k=k)
        own = np.arange(idx.size)[:, None]
        others = np.where(nb == own, -1, nb)
        # the first 8 neighbours that are not the reading itself
        order = np.argsort(others < 0, axis=1, kind="stable")
        others = np.take_along_axis(others, order, axis=1)[:, :min(8, k - 1)]
        zn = z[light][others]
        dev[light] = np.abs(z[light] - np.median(zn, axis=1))
    if (~light).sum() >= 5:
        zd = z[~light]
        dev[~light] = np.abs(zd - np.median(zd))
    scale = max(1.0, 1.4826 * float(np.median(dev)))
    bad = dev > OUTLIER_SIGMAS * scale
    if groups is not None and bad.any():
        g = np.asarray(groups)[rows]
        temp = np.zeros(rows.size) if temperature is None else np.asarray(temperature, float)[rows]
        for i in np.flatnonzero(bad & light):
            mates = np.flatnonzero((g == g[i]) & (np.arange(rows.size) != i) & (np.abs(temp - temp[i]) <= 1.0)) \
                if g[i] >= 0 else []
            if len(mates) and abs(z[i] - np.median(z[mates])) <= OUTLIER_SIGMAS * scale:
                bad[i] = False
    return bad, dev / scale


def _covariance(problem: _Problem, x, chi2_dof):
    jac = problem.jacobian(x)
    jtj = jac.T @ jac
    d = np.sqrt(np.diag(jtj))
    d = np.where(d > 0, d, 1.0)
    scaled = jtj / np.outer(d, d)
    try:
        w, v = np.linalg.eigh(scaled)
    except np.linalg.LinAlgError:
        return np.full_like(jtj, np.nan), False
    if w.min() <= 1e-13 * w.max():
        return np.full_like(jtj, np.nan), False
    cov = (v / w) @ v.T / np.outer(d, d)
    return cov * max(1.0, chi2_dof), True


def model_error(residual, noise, dof: int) -> float:
    """The RMS model error τ [unit of the residual] that makes Σ r² / (σ² + τ²) = dof, 0 when the residual is
    consistent with the noise (χ²/dof within :data:`MODEL_ERROR_SIGMAS` of its spread √(2/dof) of 1).

    The Paule–Mandel estimate of an extra variance: a misfit the model cannot follow is treated as a noise of its
    own, so the fit and the estimator weight each reading by what the model can promise there.

    References
    ----------
    research note anchors-sunsensors §6 (report what a fit achieves); seed 000 digest §8.3 item 7 (the angular
    response of a real detector against its model).
    """
    r2 = np.asarray(residual, float) ** 2
    s2 = np.asarray(noise, float) ** 2
    chi2 = float(np.sum(r2 / s2))
    if chi2 <= dof * (1.0 + MODEL_ERROR_SIGMAS * np.sqrt(2.0 / dof)):
        return 0.0
    hi = 10.0 * float(np.sum(r2)) / dof
    return float(np.sqrt(brentq(lambda tau2: float(np.sum(r2 / (s2 + tau2))) - dof, 0.0, hi, xtol=1e-30,
                                rtol=1e-6)))


def lit_reading(params: DiodeParameters, signal, temperature_c, light, noise) -> np.ndarray:
    """Readings more than :data:`LIT_SIGMAS` noise sigmas above the detector's offset (the light on): the ones a
    model error applies to (an unlit detector reads its offset whatever its angular law).

    References
    ----------
    seed 000 §5.1 (a face is lit or not), digest §8.3 item 7.
    """
    dark = params.bias + params.bias_temp_coeff_per_c * (np.asarray(temperature_c, float) - REFERENCE_TEMPERATURE_C)
    return np.asarray(light, bool) & (np.asarray(signal, float) - dark > LIT_SIGMAS * np.asarray(noise, float))


def _fov_profile(problem: _Problem, params: DiodeParameters, step: float = FOV_PROFILE_STEP_DEG):
    """χ² of the kept readings against θ_c on a grid, every other parameter held: (grid [°], χ²)."""
    free_params = replace(params, fov_half_deg=None)
    m_open, _ = signal_partials(free_params, problem.s, problem.t, problem.lit)
    dark = params.bias + params.bias_temp_coeff_per_c * (problem.t - REFERENCE_TEMPERATURE_C)
    light = m_open - dark
    g = np.where(problem.lit, problem.s @ params.normal, 0.0)
    on = problem.lit & (g > 0) & (light != 0)
    theta = np.degrees(np.arccos(np.clip(g[on], -1.0, 1.0)))
    grid = np.arange(_bounds("fov_half_deg", params.response)[0], FOV_NONE_ABOVE_DEG + step / 2, step)
    edge = np.clip((grid[:, None] + FOV_EDGE_WIDTH_DEG / 2.0 - theta[None, :]) / FOV_EDGE_WIDTH_DEG, 0.0, 1.0)
    w = 1.0 / problem.sigma
    base = float(np.sum(((problem.y[~on] - m_open[~on]) * w[~on]) ** 2))
    chi2 = base + np.sum(((problem.y[on] - dark[on] - light[on] * edge) * w[on]) ** 2, axis=1)
    return grid, chi2


def _escape_fov(problem: _Problem, params: DiodeParameters) -> DiodeParameters:
    """Move θ_c out of a local minimum: when the profile (others held) finds a clearly lower χ² elsewhere, start
    the fit again from there (the ramp makes χ²(θ_c) piecewise, with flats between the readings' incidences)."""
    for _ in range(3):
        grid, chi2 = _fov_profile(problem, params)
        current = float(np.sum(problem.data_residuals(problem.x0(params)) ** 2))
        best = int(np.argmin(chi2))
        if not chi2[best] < current - 1.0:
            break
        params, _ = problem.solve(replace(params, fov_half_deg=float(grid[best])))
    return params


def _fov_interval(problem: _Problem, params: DiodeParameters, cov, ok, chi2_eff):
    """θ_c's honest uncertainty: the interval where the profile χ² stays within max(1, χ²/dof) of its minimum.

    When no reading lies inside the edge's ramp the profile is flat between two readings' incidences and the
    Jacobian sees no slope: θ_c is then the interval's centre, its 1σ half the interval, the other parameters
    refitted with it held; otherwise the larger of the Jacobian's and the profile's 1σ is kept."""
    grid, chi2 = _fov_profile(problem, params)
    i = int(np.argmin(chi2))
    inside = chi2 <= chi2[i] + max(1.0, chi2_eff)
    a = i
    while a > 0 and inside[a - 1]:
        a -= 1
    b = i
    while b < grid.size - 1 and inside[b + 1]:
        b += 1
    half = (grid[b] - grid[a]) / 2.0 + FOV_PROFILE_STEP_DEG / 2.0
    k = problem.free.index("fov_half_deg")
    jac_sd = float(np.sqrt(cov[k, k])) if ok else float("nan")
    if ok and (b - a <= 2 or half <= 2.0 * jac_sd):  # sharper than the profile's grid, or a parabola
        if b - a > 2 and half > jac_sd:
            scale = np.ones(len(problem.free))
            scale[k] = half / jac_sd
            cov = cov * np.outer(scale, scale)
        return params, cov, ok, None
    centre = float((grid[a] + grid[b]) / 2.0)
    others = [f for f in problem.free if f != "fov_half_deg"]
    held = _Problem(replace(params, fov_half_deg=centre), others, problem.s, problem.t, problem.lit, problem.y,
                    problem.sigma)
    params, _ = held.solve(replace(params, fov_half_deg=centre))
    sub, sub_ok = _covariance(held, held.x0(params), chi2_eff)
    p = len(problem.free)
    cov = np.zeros((p, p))
    idx = [problem.free.index(f) for f in others]
    cov[np.ix_(idx, idx)] = sub if sub_ok else np.nan
    cov[k, k] = half**2
    note = (f"θ_c is bounded by these data only to {grid[a] - FOV_PROFILE_STEP_DEG / 2:.1f}…"
            f"{grid[b] + FOV_PROFILE_STEP_DEG / 2:.1f}° (no reading inside its {FOV_EDGE_WIDTH_DEG:g}° ramp between "
            "those incidences): the interval's centre is given, half the interval as its 1σ")
    return params, cov, sub_ok, note


def _knot_words(knots) -> str:
    """The knots in words: "every 10° from 0 to 40°, every 2.5° to 75°, 76.5°"."""
    k = np.asarray(knots, float)
    steps = np.round(np.diff(k), 6)
    parts, i = [], 0
    while i < steps.size:
        j = i
        while j + 1 < steps.size and steps[j + 1] == steps[i]:
            j += 1
        if j > i:
            parts.append(f"every {steps[i]:g}° " + (f"from {k[i]:g} " if not parts else "") + f"to {k[j + 1]:g}°")
        else:
            parts.append((f"{k[i]:g}°, " if not parts else "") + f"{k[j + 1]:g}°")
        i = j + 1
    return ", ".join(parts)


def fit_diode(channel: str, sun_vectors, signal, temperature_c, *, dark=None, groups=None, response: str = "kelly",
              row_id=None, full_scale: float | None = None, fit_temperature="auto", fit_fov="auto",
              initial: DiodeParameters | None = None, noise=None, spline_knots_deg=None) -> DiodeFit:
    """Fit one detector's model to its readings (module docstring, steps 1–7).

    Parameters
    ----------
    channel : str
        ``<face>_<detector>``, e.g. ``"px_vis"``.
    sun_vectors : array_like (N, 3)
        Unit Sun vectors in the head's body frame (ignored on dark rows).
    signal : array_like (N,)
        The channel's raw readings [A or V]; NaN: no reading.
    temperature_c : array_like (N,)
        Head temperature [°C].
    dark : array_like of bool (N,), optional
        Readings with the light off.
    groups : array_like of int (N,), optional
        Repeat groups (readings of one direction; −1 none). Default :func:`direction_groups`.
    response : {"kelly", "power", "spline"}
    row_id : array_like of int (N,), optional
        Row names for messages. Default 1…N.
    full_scale : float, optional
        The front end's full scale [A or V]; readings at or above it are saturated.
    fit_temperature : "auto" or bool
        Fit c_T and b_T ("auto": when the readings span ≥ :data:`MIN_TEMPERATURE_SPAN_C`).
    fit_fov : "auto", bool or float
        Fit θ_c ("auto": when a reading lies beyond :data:`FOV_EVIDENCE_DEG`); a float fixes it there; False: no
        cut-off. The spline law takes "auto" or False only (its spline holds the cut-off).
    initial : DiodeParameters, optional
        Start here instead of the grid (the held-out folds start from the full fit); a fit of another law gives the
        spline law its start's normal and c_T.
    noise : (σ₀, q, r, model_sd), optional
        A noise model to use as it is (the held-out folds use the full fit's): no screening, no noise estimate.
    spline_knots_deg : sequence of float, optional
        The spline law's knots [°], held. Default: `initial`'s when it is a spline fit, else those of
        :data:`calibration.css.spline.SPLINE_GRID_DEG` up to an end the readings choose (module docstring step 4).

    Returns
    -------
    DiodeFit

    References
    ----------
    seed 000, eq. 3.1, §4, digest §8.3 items 7–8; research note anchors-sunsensors §5–6.
    """
    face, detector = split_channel(channel)
    if response not in RESPONSES:
        raise ValueError(f"no response law {response!r} (laws: {', '.join(RESPONSES)})")
    spline = response == SPLINE
    adaptive = spline and spline_knots_deg is None and not (initial is not None and initial.response == SPLINE)
    if spline and not (fit_fov == "auto" or fit_fov is False):
        raise ValueError(f"the spline law has no separate field-of-view cut-off (its spline ends at its last knot), "
                         f"got fit_fov={fit_fov!r}")
    if spline_knots_deg is None and spline and initial is not None and initial.response == SPLINE:
        spline_knots_deg = initial.spline_knots_deg
    y_all = np.asarray(signal, float).ravel()
    n = y_all.size
    s_all = np.asarray(sun_vectors, float).reshape(-1, 3)
    t_all = np.broadcast_to(np.asarray(temperature_c, float), (n,)).astype(float)
    if s_all.shape[0] != n:
        raise BenchDataError(f"{channel}: {s_all.shape[0]} Sun vectors for {n} readings", column="sun_vectors")
    dark = np.zeros(n, bool) if dark is None else np.asarray(dark, bool).ravel()
    row_id = np.arange(1, n + 1) if row_id is None else np.asarray(row_id).ravel()
    finite_s = np.all(np.isfinite(s_all), axis=1)
    usable = np.isfinite(y_all) & np.isfinite(t_all) & (dark | finite_s)
    lit_rows = ~dark
    s_safe = np.where(lit_rows[:, None] & finite_s[:, None], s_all, 0.0)
    groups = direction_groups(s_all, dark) if groups is None else np.asarray(groups).ravel()
    n0 = face_axes(face)[0]
    g_nom = np.where(lit_rows, s_safe @ n0, 0.0)
    zen, az = vector_angles(s_safe)
    zen, az = np.where(dark, np.nan, zen), np.where(dark, np.nan, az)
    rejected: list = []
    warnings: list = []
    statements: list = []
    unit = "V" if detector == "ir" else "A"

    def reject(i, reason):
        rejected.append(RejectedReading(int(row_id[i]), channel, float(zen[i]), float(az[i]), reason))

    def faulty(kind, message):
        warnings.append(f"{channel}: {message}")
        return DiodeFit(channel, response, None, fault=kind, rejected=tuple(rejected), warnings=tuple(warnings),
                        statements=tuple(statements), residual=np.full(n, np.nan), used=np.zeros(n, bool),
                        n_points=int(usable.sum()))

    if usable.sum() == 0:
        return faulty("unlit", "no reading")
    y = y_all
    # stuck: one value throughout (before the clip test, which would take it for a clip level)
    values = y[usable]
    if np.ptp(values) == 0:
        return faulty("stuck", f"every reading is {values[0]:.6g} {unit} — a stuck channel (the readings do not "
                      "change with the Sun's direction)")
    # 1. saturation
    level = full_scale if full_scale is not None else clip_level(np.where(usable, y_all, np.nan), g_nom)
    lit_dir = usable & lit_rows & (g_nom > np.cos(np.radians(LIT_INCIDENCE_DEG)))
    if level is not None:
        sat = usable & (y_all >= level)
        if sat.any():
            for i in np.flatnonzero(sat):
                reject(i, f"at the front end's full scale ({level:.4g} {unit}) — saturated")
            share = sat[lit_dir].mean() if lit_dir.any() else 1.0
            if share > 0.5:
                return faulty("saturated", f"{int(sat.sum())} of {int(usable.sum())} readings are at the front end's "
                              f"full scale ({level:.4g} {unit}) — saturated; not calibrated")
            warnings.append(f"{channel}: {int(sat.sum())} reading(s) at the front end's full scale ({level:.4g} "
                            f"{unit}) — saturated; left out of the fit")
            usable &= ~sat
            lit_dir &= ~sat
    values = y[usable]
    # 3. lit coverage
    n_lit = np.unique(groups[lit_dir]).size if lit_dir.any() else 0
    if n_lit < MIN_LIT_DIRECTIONS:
        return faulty("unlit", f"lit within {LIT_INCIDENCE_DEG:.0f}° of its normal at {n_lit} direction(s) only "
                      f"(needs {MIN_LIT_DIRECTIONS}): not calibrated")
    # 4. dead / inverted: the rise from no light to normal incidence against the noise, from a model-free
    # description of the readings (a cubic in the nominal cos γ, with the temperature when it spans enough)
    rows = np.flatnonzero(usable)
    t_span = float(np.ptp(t_all[usable]))
    gp = np.maximum(g_nom[rows], 0.0)
    dt_rows = t_all[rows] - REFERENCE_TEMPERATURE_C
    cols = [np.ones(rows.size), gp, gp**2, gp**3]
    if t_span >= MIN_TEMPERATURE_SPAN_C:
        cols += [dt_rows, gp * dt_rows]
    a = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(a, y[rows], rcond=None)
    described = np.full(n, np.nan)
    described[rows] = y[rows] - a @ coef
    s2, _, dof, dev = _group_scatter(described, groups, rows)
    noise_level = _robust_sigma(dev) * np.sqrt(np.mean((dof + 1) / np.maximum(dof, 1))) if dev.size >= 6 else np.nan
    if not np.isfinite(noise_level) or noise_level <= 0:
        noise_level = _robust_sigma(described[rows])
    resolution = quantisation_step(values)
    if resolution is not None:
        noise_level = max(noise_level, resolution / np.sqrt(12.0))
    noise_level = max(noise_level, 1e-12 * float(np.max(np.abs(values))))
    rise = float(coef[1] + coef[2] + coef[3])
    if rise < -DEAD_SIGMAS * noise_level:
        return faulty("inverted", f"the readings fall as the light rises ({rise:.3g} {unit} from no light to normal "
                      "incidence) — an inverted or swapped channel; not calibrated")
    if rise < DEAD_SIGMAS * noise_level:
        return faulty("dead", f"the readings do not change with the Sun's direction — a stuck or dead diode (a rise "
                      f"of {rise:.3g} {unit} from no light to normal incidence, {rise / noise_level:.1f}× its noise)")
    # 2. what is fitted
    fit_t = (t_span >= MIN_TEMPERATURE_SPAN_C) if fit_temperature == "auto" else bool(fit_temperature)
    base = DiodeParameters(channel, response, spline_knots_deg=tuple(spline_knots_deg or ()) if spline else ())
    free = ["scale", "bias", "tilt_u_deg", "tilt_v_deg"] + (list(base.spline_names) if spline else ["shape"])
    if fit_t:
        free += ["temp_coeff_per_c", "bias_temp_coeff_per_c"]
        statements.append(f"c_T and b_T fitted: the readings span {t_span:.1f} °C")
    else:
        statements.append(f"c_T and b_T not fitted (held at 0): the readings span {t_span:.1f} °C, under "
                          f"{MIN_TEMPERATURE_SPAN_C:g} °C" if fit_temperature == "auto" else
                          "c_T and b_T not fitted (held at 0), as asked")
    inc_nom = np.degrees(np.arccos(np.clip(g_nom, -1, 1)))
    beyond = usable & lit_rows & (g_nom > 0) & (inc_nom > FOV_EVIDENCE_DEG)
    fixed_fov = None
    if spline:
        fit_f = False
    elif isinstance(fit_fov, bool) or fit_fov == "auto":
        fit_f = bool(beyond.any()) if fit_fov == "auto" else bool(fit_fov)
        if fit_fov == "auto" and not fit_f:
            warnings.append(f"{channel}: the FOV cut-off is not constrained: no reading beyond "
                            f"{FOV_EVIDENCE_DEG:.0f}° incidence — no cut-off assumed")
    else:
        fit_f, fixed_fov = False, float(fit_fov)
        statements.append(f"θ_c held at {fixed_fov:g}°, as asked")
    if fit_f:
        free.append("fov_half_deg")
    base = replace(base, fov_half_deg=fixed_fov)
    s_rows, t_rows, lit_r, y_rows = s_safe[rows], t_all[rows], lit_rows[rows], y[rows]
    # 3. provisional noise, from the scatter of repeats about the model-free description (or its residual)
    floor = 0.0 if resolution is None else resolution / np.sqrt(12.0)
    if s2.size:
        sigma0, shot, rel = fit_noise_model(s2, _group_scatter(np.where(usable, y, np.nan), groups, rows)[1], dof,
                                            floor=floor)
    else:
        sigma0, shot, rel = max(_robust_sigma(described[rows]), floor), 0.0, 0.0
    tiny = 1e-9 * float(np.max(np.abs(y_rows))) + 1e-300
    sigma0 = max(sigma0, tiny)
    # 4. start
    weights = 1.0 / np.sqrt(sigma0**2 + shot * np.abs(y_rows) + (rel * y_rows) ** 2)
    if spline:
        same = initial is not None and initial.response == SPLINE and initial.spline_knots_deg == \
            base.spline_knots_deg
        start = base if initial is None else replace(
            base, tilt_u_deg=initial.tilt_u_deg, tilt_v_deg=initial.tilt_v_deg,
            temp_coeff_per_c=initial.temp_coeff_per_c if fit_t else 0.0,
            bias_temp_coeff_per_c=initial.bias_temp_coeff_per_c if fit_t else 0.0)
        if same:
            start = replace(start, scale=initial.scale, bias=initial.bias, spline=initial.spline)
        else:
            start, _ = _initial_spline(start, s_rows, t_rows, lit_r, y_rows, free, weights)
            if adaptive:  # the spline's end from the readings (calibration.css.spline)
                start, _ = _spline_end(start, s_rows, t_rows, lit_r, y_rows, free, weights)
                base = replace(base, spline_knots_deg=start.spline_knots_deg, spline=start.spline)
                free = _with_spline(free, start)
    elif initial is not None and initial.response == response and (not fit_f or initial.fov_half_deg is not None):
        start = replace(initial, channel=channel, response=response,
                        fov_half_deg=initial.fov_half_deg if fit_f else fixed_fov)
        if not fit_t:
            start = replace(start, temp_coeff_per_c=0.0, bias_temp_coeff_per_c=0.0)
    else:
        fov_grid = tuple(np.arange(30.0, 90.25, 0.5)) + (None,) if fit_f else (fixed_fov,)
        start = _initial(base, s_rows, t_rows, lit_r, y_rows, free, fov_grid, weights)
        if fit_f and start.fov_half_deg is None:
            start = replace(start, fov_half_deg=89.0)

    def sigmas(params, k0, q, r):
        m, _ = signal_partials(params, s_rows, t_rows, lit_r)
        return np.sqrt(k0**2 + q * np.abs(m) + (r * m) ** 2)

    # 5. robust fit and screen (skipped with a given noise model: those readings were screened already)
    keep = np.ones(rows.size, bool)
    problem = _Problem(base, free, s_rows, t_rows, lit_r, y_rows, sigmas(start, sigma0, shot, rel))
    if noise is None:
        params, _ = problem.solve(start, loss="soft_l1", f_scale=ROBUST_SCALE_SIGMAS)
        problem.sigma = sigmas(params, sigma0, shot, rel)
        if adaptive:  # the spline's end again, at the robust fit's normal
            moved, _ = _spline_end(params, s_rows, t_rows, lit_r, y_rows, free, 1.0 / problem.sigma,
                                   near=params.spline_knots_deg[-1])
            if moved.spline_knots_deg != params.spline_knots_deg:
                base = replace(base, spline_knots_deg=moved.spline_knots_deg, spline=moved.spline)
                free = _with_spline(free, moved)
                problem = _Problem(base, free, s_rows, t_rows, lit_r, y_rows, sigmas(moved, sigma0, shot, rel))
                params, _ = problem.solve(moved)  # plain: a glint stays the reading its repeats disagree with
                problem.sigma = sigmas(params, sigma0, shot, rel)
        z = problem.data_residuals(problem.x0(params))
        bad, score = _neighbour_outliers(z, s_rows, lit_r, np.arange(rows.size), incidence=np.degrees(np.arccos(
            np.clip(s_rows @ params.normal, -1.0, 1.0))) if spline else None, groups=groups[rows] if spline else None,
            temperature=t_rows)
        if bad.any():
            if bad.mean() > SCREEN_MAX_SHARE:
                warnings.append(f"{channel}: {int(bad.sum())} of {rows.size} readings stand out from their "
                                "neighbours far beyond the noise: too many to be glints, none rejected (stray light? "
                                "a moving source?)")
            else:
                for i in np.flatnonzero(bad):
                    reject(rows[i], f"its reading stands {score[i]:.0f} robust sigmas off its neighbours' residual "
                           "(a glint, stray light or a bad reading)")
                keep = ~bad
    else:
        params = start
    # 6–7. noise model, then the final weighted fit (with a model error when the residual exceeds the noise)
    kept = rows[keep]
    problem = _Problem(base, free, s_rows[keep], t_rows[keep], lit_r[keep], y_rows[keep], problem.sigma[keep])
    noise_source = "repeats" if noise is None else "given"
    model_sd = 0.0

    def noise_at(params):
        m = signal_partials(params, problem.s, problem.t, problem.lit)[0]
        return m, np.sqrt(sigma0**2 + shot * np.abs(m) + (rel * m) ** 2)

    # with a given noise model one pass is enough for the spline law, whose start (the full fit's) is linear-close
    for it in range(NOISE_ITERATIONS if noise is None else 1 if spline else 2):
        m_fit, _ = signal_partials(params, problem.s, problem.t, problem.lit)
        if noise is None:  # the noise from the current fit's residuals (the weights change the fit, the fit them)
            resid_all = np.full(n, np.nan)
            resid_all[kept] = problem.y - m_fit
            level_all = np.full(n, np.nan)
            level_all[kept] = m_fit
            gv, _, gdof, _ = _group_scatter(resid_all, groups, kept)
            if gv.size:
                glevel = _group_scatter(level_all, groups, kept)[1]
                sigma0, shot, rel = fit_noise_model(gv, glevel, gdof, floor=floor)
            else:
                noise_source = "residuals"
                infl = kept.size / max(kept.size - len(free), 1)
                sigma0, shot, rel = fit_noise_model((problem.y - m_fit) ** 2 * infl, m_fit, np.ones(kept.size),
                                                    floor=floor)
            sigma0 = max(sigma0, tiny)
        else:
            sigma0, shot, rel, model_sd = (float(v) for v in noise)
        m_fit, noise_now = noise_at(params)
        lit_now = lit_reading(params, problem.y, problem.t, problem.lit, noise_now)
        if spline:
            lit_now |= lit_reading(params, m_fit, problem.t, problem.lit, noise_now)
        if noise_source == "repeats" and it >= 1 and lit_now.sum() > len(free):
            model_sd = model_error((problem.y - m_fit)[lit_now], noise_now[lit_now], int(lit_now.sum()) - len(free))
        problem.sigma = np.sqrt(noise_now**2 + np.where(lit_now, model_sd**2, 0.0))
        params, _ = problem.solve(params)
        if "fov_half_deg" in free:
            params = _escape_fov(problem, params)
        if adaptive and it == 1:  # the spline's end again, at the fitted normal, weighted by the noise and τ
            moved, chi2_moved = _spline_end(params, problem.s, problem.t, problem.lit, problem.y, free,
                                            1.0 / problem.sigma, near=params.spline_knots_deg[-1])
            if moved.spline_knots_deg != params.spline_knots_deg and chi2_moved < float(np.sum(problem.residuals(
                    problem.x0(params)) ** 2)) + 2.0 * len(params.spline) - 1.0:
                base = replace(base, spline_knots_deg=moved.spline_knots_deg, spline=moved.spline)
                free = _with_spline(free, moved)
                problem = _Problem(base, free, problem.s, problem.t, problem.lit, problem.y, problem.sigma)
                params, _ = problem.solve(moved)
    # bounds: fix what ended on one and fit again
    at_bound = []
    for name in list(free):
        lo, hi = _bounds(name, response)
        v = params.get(name)
        span = (hi - lo) if np.isfinite(hi - lo) else max(abs(v), 1.0)
        if name == "fov_half_deg" and v > FOV_NONE_ABOVE_DEG:
            at_bound.append(name)
            params = replace(params, fov_half_deg=None)
            statements.append(f"θ_c ran to {v:.1f}°: no cut-off inside the hemisphere, none modelled")
        elif (np.isfinite(lo) and v - lo < 1e-6 * span) or (np.isfinite(hi) and hi - v < 1e-6 * span):
            at_bound.append(name)
            statements.append(f"{_public(name, response)} ended on its bound ({v:.4g}) and is held there"
                              + (": the response is a plain cosine to the data's precision"
                                 if name == "shape" and response == "kelly" and v <= lo * 1.01 else ""))
    if at_bound:
        free = [f for f in free if f not in at_bound]
        problem = _Problem(replace(params), free, problem.s, problem.t, problem.lit, problem.y, problem.sigma)
        params, _ = problem.solve(params)
    fov_fitted = "fov_half_deg" in free
    x = problem.x0(params)
    n_pts, p = problem.y.size, len(free)
    n_dof = max(n_pts - p, 1)
    m_fit, noise = noise_at(params)
    chi2_dof = float(np.sum(((problem.y - m_fit) / noise) ** 2) / n_dof)  # against the noise alone
    chi2_eff = float(np.sum(problem.residuals(x) ** 2) / n_dof)  # against noise and model error (≈ 1 with one)
    cov, ok = _covariance(problem, x, chi2_eff)
    if fov_fitted:
        params, cov, ok, note = _fov_interval(problem, params, cov, ok, chi2_eff)
        if note:
            statements.append(note)
        x = problem.x0(params)
        m_fit, noise = noise_at(params)
    if spline:
        end = params.spline_knots_deg[-1]
        statements.append(f"the spline law's {len(params.spline)} coefficients fitted on knots "
                          + _knot_words(params.spline_knots_deg) + ("" if end >= 90.0 else
                                                                    f"; it ends at {end:g}°, beyond which the detector "
                                                                    "is dark") + " (the spline holds the field-of-view "
                          "cut-off: no θ_c)" + (", its end chosen by the readings' χ²" if adaptive else ""))
    if model_sd > 0:
        unit_word = "V" if detector == "ir" else "A"
        statements.append(f"the residual exceeds the repeat noise (χ²/dof = {chi2_dof:.1f}): a model error of "
                          f"{model_sd:.3g} {unit_word} RMS is added to the noise of lit readings in the fit's weights "
                          "and in the estimator's")
    params = replace(params, sigma0=float(sigma0), shot=float(shot), noise_rel=float(rel), full_scale=level,
                     model_sd=float(model_sd))
    z = (problem.y - m_fit) / noise
    sd_vec = np.sqrt(np.diag(cov)) if ok else np.full(p, np.nan)
    corr = cov / np.outer(sd_vec, sd_vec) if ok else np.full((p, p), np.nan)
    names = tuple(_public(f, response) for f in free)
    sd = dict(zip(names, (float(v) for v in sd_vec)))
    if not ok:
        warnings.append(f"{channel}: the fitted parameters ({', '.join(names)}) cannot all be told apart by these "
                        "data (singular covariance): no uncertainties")
    residual = np.full(n, np.nan)
    residual[kept] = problem.y - m_fit
    used = np.zeros(n, bool)
    used[kept] = True
    # the normal and its uncertainty
    zen_n, az_n = (float(v) for v in normal_angles(face, params.tilt_u_deg, params.tilt_v_deg))
    var_t = sum(sd.get(k, 0.0) ** 2 for k in ("tilt_u_deg", "tilt_v_deg"))
    normal_sd = float(np.sqrt(var_t)) if ok else float("nan")
    tilt = float(np.degrees(np.arccos(np.clip(params.normal @ n0, -1, 1))))
    # words
    if noise_source == "residuals":
        warnings.append(f"{channel}: no repeated directions: the noise is estimated from the residuals, so χ²/dof ≈ 1 "
                        "by construction and cannot judge the model; repeat directions to let the fit check itself")
    elif chi2_dof > CHI2_WARNING:
        warnings.append(f"{channel}: the residual is {np.sqrt(chi2_dof):.1f}× the repeat noise (χ²/dof = "
                        f"{chi2_dof:.1f}): the {response} model does not describe this detector to its noise (an "
                        "angular response unlike the law, stray light, the lamp drifting between repeats)")
    if tilt > TILT_WARNING_DEG:
        warnings.append(f"{channel}: the fitted normal is {tilt:.1f}° from the face's: check the detector's mounting "
                        "and the head's alignment on the table")
    if ok:
        for i in range(p):
            for j in range(i + 1, p):
                if abs(corr[i, j]) > CORRELATION_WARNING:
                    statements.append(f"{names[i]} and {names[j]} are correlated (ρ = {corr[i, j]:+.3f}): the data "
                                      "tell their combination better than either")
    values = {k: (None if v is None else float(v)) for k, v in params.values().items()}
    return DiodeFit(channel, response, params, names, values, sd, cov, corr, chi2_dof,
                    float(np.sqrt(np.mean((problem.y - m_fit) ** 2))), float(np.sqrt(np.mean(z**2))), int(n_pts),
                    int(n_dof), noise_source, fit_t, fov_fitted, None, tuple(rejected), tuple(warnings),
                    tuple(statements), residual, used, zen_n, az_n, normal_sd, resolution, float(model_sd))
