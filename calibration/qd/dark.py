"""Dark current of each quadrant against temperature, and its subtraction (seed 002 §2.1).

The thesis models each quadrant's dark current as linear in the sensor's own temperature over −50…+50 °C:

.. math:: I^d_i = I^{d0}_i + k^d_i\\,t, \\qquad I^f_i = I_i - I^d_i

(its slope is called α^d_i there; renamed k_d here so it does not clash with the angle α). A silicon
photodiode's dark current roughly doubles every few kelvin, so over a wide range a straight line can be
poor; an exponential with an offset, I^d = a + c·exp(b (t − t_ref)), is fitted too and **chosen only when it
is clearly better**: when the sum over the four quadrants of the small-sample Akaike criterion

.. math:: \\mathrm{AIC_c} = n \\ln(\\mathrm{RSS}/n) + 2p + \\frac{2p(p+1)}{n-p-1}

is lower for it by more than :data:`EXPONENTIAL_AICC_MARGIN` (= 10: "essentially no support" for the other
model on Burnham & Anderson's scale), and the data have at least :data:`EXPONENTIAL_MIN_TEMPERATURES` distinct
temperatures and :data:`EXPONENTIAL_MIN_POINTS` readings. One temperature only gives a constant (k_d unknown,
said in the fit's note). Every model is fitted per quadrant by least squares, with the covariance of its
parameters scaled by the residual variance.

References
----------
seed 002, §2.1 (the linear dark-current model and I^f = I − I^d) and §5.1 (Fig. 3.3, no numbers given).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import CalibrationFormatError, InsufficientDataError

#: ΔAICc (summed over the four quadrants) by which the exponential must beat the line to be chosen.
EXPONENTIAL_AICC_MARGIN = 10.0
#: Fewest distinct temperatures (rounded to 0.01 °C) and readings for the exponential.
EXPONENTIAL_MIN_TEMPERATURES = 4
EXPONENTIAL_MIN_POINTS = 6

#: Parameter names of each model, in the order of a quadrant's parameter vector.
DARK_PARAMETERS = {
    "none": (),
    "constant": ("id0_a",),
    "linear": ("id0_a", "kd_a_per_c"),
    "exponential": ("a_a", "c_a", "b_per_c"),
}


@dataclass(frozen=True)
class DarkModel:
    """One dark-current model fitted to the four quadrants.

    Attributes
    ----------
    kind : str
        "none" (no dark data: zero), "constant", "linear" (the thesis') or "exponential".
    parameters : ndarray, shape (4, k)
        Per quadrant (row k−1 = quadrant k), in the order of ``DARK_PARAMETERS[kind]``:
        constant I^d = id0; linear I^d = id0 + kd·t; exponential I^d = a + c·exp(b (t − t_ref)). [A, A/°C, 1/°C]
    covariance : ndarray, shape (4, k, k)
        Covariance of each quadrant's parameters, scaled by its residual variance (NaN when there are no
        degrees of freedom left).
    residual_sd_a : ndarray, shape (4,)
        Residual standard deviation per quadrant [A].
    t_ref_c : float
        Reference temperature of the exponential [°C] (0 for the others).
    aicc : float
        AICc summed over the quadrants (module docstring); NaN when it cannot be computed.
    """

    kind: str
    parameters: np.ndarray
    covariance: np.ndarray
    residual_sd_a: np.ndarray
    t_ref_c: float = 0.0
    aicc: float = float("nan")

    def current(self, temperature_c) -> np.ndarray:
        """Dark current of each quadrant at `temperature_c` [A], shape (..., 4).

        References
        ----------
        seed 002, §2.1 (linear); module docstring (exponential).
        """
        t = np.asarray(temperature_c, dtype=float)[..., None]
        p = self.parameters
        if self.kind == "none":
            return np.zeros(t.shape[:-1] + (4,))
        if self.kind == "constant":
            return p[:, 0] + 0.0 * t
        if self.kind == "linear":
            return p[:, 0] + p[:, 1] * t  # seed 002 §2.1
        return p[:, 0] + p[:, 1] * np.exp(p[:, 2] * (t - self.t_ref_c))

    @property
    def sd(self) -> np.ndarray:
        """1σ of each parameter, shape (4, k)."""
        return np.sqrt(np.clip(np.diagonal(self.covariance, axis1=1, axis2=2), 0.0, None))

    def to_dict(self) -> dict:
        names = DARK_PARAMETERS[self.kind]
        quadrants = []
        for k in range(4):
            quadrants.append({name: {"value": float(self.parameters[k, j]), "sd": _finite_or_none(self.sd[k, j])}
                              for j, name in enumerate(names)})
        return {"model": self.kind, "t_ref_c": float(self.t_ref_c), "quadrants": quadrants,
                "residual_sd_a": [_finite_or_none(v) for v in self.residual_sd_a]}

    @classmethod
    def from_dict(cls, document: dict) -> DarkModel:
        """Rebuild from :meth:`to_dict` (the covariance keeps only the variances)."""
        try:
            kind = document["model"]
            names = DARK_PARAMETERS[kind]
            quadrants = document["quadrants"]
            if len(quadrants) != 4:
                raise ValueError("needs four quadrants")
            params = np.array([[float(q[name]["value"]) for name in names] for q in quadrants]).reshape(4, len(names))
            sd = np.array([[np.nan if q[name].get("sd") is None else float(q[name]["sd"]) for name in names]
                           for q in quadrants]).reshape(4, len(names))
            t_ref = float(document.get("t_ref_c", 0.0))
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationFormatError(f"the dark-current model of the calibration is malformed ({exc!r})") from exc
        if not np.all(np.isfinite(params)):
            raise CalibrationFormatError("the dark-current model holds a non-finite parameter")
        cov = np.zeros((4, len(names), len(names)))
        for k in range(4):
            cov[k] = np.diag(sd[k] ** 2)
        resid = [np.nan if v is None else float(v) for v in document.get("residual_sd_a", [None] * 4)]
        return cls(kind, params, cov, np.array(resid), t_ref)


def _finite_or_none(value):
    value = float(value)
    return value if np.isfinite(value) else None


@dataclass(frozen=True)
class DarkFit:
    """The chosen dark-current model and the candidates it was chosen from.

    Attributes
    ----------
    model : DarkModel
        The model used for subtraction.
    candidates : dict of str to DarkModel
        Every model fitted ("linear" always when the data allow it, the thesis' model).
    n_points : int
        Dark readings used.
    temperature_range_c : tuple of float
        Lowest and highest temperature of the dark readings [°C]; the model is not known outside.
    note : str
        How the model was chosen, in words.
    """

    model: DarkModel
    candidates: dict = field(default_factory=dict)
    n_points: int = 0
    temperature_range_c: tuple = (float("nan"), float("nan"))
    note: str = ""

    @property
    def kind(self) -> str:
        return self.model.kind

    def current(self, temperature_c) -> np.ndarray:
        """Dark current of each quadrant at `temperature_c` [A], shape (..., 4) (seed 002 §2.1)."""
        return self.model.current(temperature_c)

    def to_dict(self) -> dict:
        out = self.model.to_dict()
        out.update({"n_points": self.n_points,
                    "temperature_range_c": [_finite_or_none(v) for v in self.temperature_range_c], "note": self.note,
                    "aicc": {k: _finite_or_none(m.aicc) for k, m in self.candidates.items()}})
        return out

    @classmethod
    def from_dict(cls, document: dict) -> DarkFit:
        model = DarkModel.from_dict(document)
        rng = document.get("temperature_range_c") or [None, None]
        return cls(model, {model.kind: model}, int(document.get("n_points", 0)),
                   tuple(np.nan if v is None else float(v) for v in rng), str(document.get("note", "")))


#: No dark data: nothing subtracted.
NO_DARK = DarkFit(DarkModel("none", np.zeros((4, 0)), np.zeros((4, 0, 0)), np.full(4, np.nan)), {}, 0,
                  note="no dark readings: no dark current subtracted")


def _aicc(rss: np.ndarray, n: int, p: int, scale: np.ndarray) -> float:
    if n - p - 1 <= 0:
        return float("nan")
    floor = (1e-12 * scale) ** 2 * n + 1e-300  # exact synthetic data: ln(0) would be −∞ for both models
    return float(np.sum(n * np.log(np.maximum(rss, floor) / n) + 2 * p + 2.0 * p * (p + 1) / (n - p - 1)))


def _linear_fit(t: np.ndarray, currents: np.ndarray, columns) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per quadrant: coefficients (4, p), covariance s² (XᵀX)⁻¹ (4, p, p), RSS (4,) and residual SD s (4,)."""
    x = np.stack(columns, axis=1)
    n, p = x.shape
    coef, *_ = np.linalg.lstsq(x, currents, rcond=None)
    resid = currents - x @ coef
    rss = np.sum(resid**2, axis=0)
    s2 = rss / (n - p) if n > p else np.full(4, np.nan)
    xtx_inv = np.linalg.pinv(x.T @ x)
    cov = s2[:, None, None] * xtx_inv[None]
    return coef.T, cov, rss, np.sqrt(s2)


def fit_dark_linear(temperature_c, currents_a) -> DarkModel:
    """The thesis' model I^d_i = I^{d0}_i + k^d_i t fitted to each quadrant by linear least squares.

    Parameters
    ----------
    temperature_c : array_like, shape (N,)
        Sensor temperature of each dark reading [°C].
    currents_a : array_like, shape (N, 4)
        Quadrant currents with the light off [A].

    Returns
    -------
    DarkModel
        kind "linear"; covariance s² (XᵀX)⁻¹ per quadrant with s² = RSS / (N − 2).

    References
    ----------
    seed 002, §2.1.
    """
    t, currents = _check(temperature_c, currents_a)
    if len(np.unique(np.round(t, 2))) < 2:
        raise InsufficientDataError("a linear dark-current fit needs dark readings at two temperatures at least")
    coef, cov, rss, sd = _linear_fit(t, currents, [np.ones_like(t), t])
    return DarkModel("linear", coef, cov, sd, 0.0, _aicc(rss, len(t), 2, np.abs(currents).max(axis=0)))


def fit_dark_exponential(temperature_c, currents_a) -> DarkModel:
    """I^d = a + c·exp(b (t − t_ref)) fitted to each quadrant (t_ref: the mean temperature).

    For each quadrant the rate b is found first by a scan of the profile residual (a and c are linear given
    b), then (a, c, b) are refined together by ``scipy.optimize.least_squares``; the covariance is
    s² (JᵀJ)⁻¹ with s² = RSS / (N − 3).

    References
    ----------
    seed 002, §2.1 (the dark current depends on temperature through semiconductor effects; the thesis'
    straight line is this model's first-order expansion).
    """
    t, currents = _check(temperature_c, currents_a)
    n = len(t)
    if n < 4 or len(np.unique(np.round(t, 2))) < 3:
        raise InsufficientDataError("an exponential dark-current fit needs dark readings at three temperatures "
                                    "at least")
    t_ref = float(np.mean(t))
    span = float(np.ptp(t))
    rates = np.concatenate([-np.logspace(-3, np.log10(40.0), 40)[::-1], np.logspace(-3, np.log10(40.0), 40)]) / span
    params = np.zeros((4, 3))
    cov = np.zeros((4, 3, 3))
    rss_all = np.zeros(4)
    for k in range(4):
        y = currents[:, k]
        best = None
        for b in rates:
            e = np.exp(b * (t - t_ref))
            x = np.stack([np.ones_like(t), e], axis=1)
            coef, *_ = np.linalg.lstsq(x, y, rcond=None)
            rss = float(np.sum((y - x @ coef) ** 2))
            if best is None or rss < best[0]:
                best = (rss, coef[0], coef[1], b)
        _, a0, c0, b0 = best
        scale = max(float(np.max(np.abs(y))), 1e-15)  # a quadrant that reads 0 A dark (an ADC clipped at 0)

        def residual(p):  # called only by the least_squares just below, within this iteration
            return (p[0] + p[1] * np.exp(p[2] * (t - t_ref)) - y) / scale  # noqa: B023

        x_scale = [scale, max(abs(c0), scale * 1e-6), max(abs(b0), 1e-3 / span)]
        fit = least_squares(residual, [a0, c0, b0], x_scale=x_scale, method="lm", xtol=1e-14, ftol=1e-14,
                            gtol=1e-14, max_nfev=2000)
        rss = float(np.sum(fit.fun**2)) * scale**2
        jac = fit.jac * scale
        s2 = rss / (n - 3) if n > 3 else np.nan
        # columns scaled to unit norm first: a and c are in amperes, b in 1/°C, and JᵀJ unscaled spans 16
        # decades, where pinv's cut-off would throw b's information away
        norms = np.linalg.norm(jac, axis=0)
        norms = np.where(norms > 0, norms, 1.0)
        scaled = jac / norms
        params[k], cov[k], rss_all[k] = fit.x, s2 * np.linalg.pinv(scaled.T @ scaled) / np.outer(norms, norms), rss
    sd = np.sqrt(rss_all / (n - 3)) if n > 3 else np.full(4, np.nan)
    return DarkModel("exponential", params, cov, sd, t_ref, _aicc(rss_all, n, 3, np.abs(currents).max(axis=0)))


def _check(temperature_c, currents_a) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(temperature_c, dtype=float).ravel()
    currents = np.asarray(currents_a, dtype=float)
    if currents.ndim != 2 or currents.shape[1] != 4 or currents.shape[0] != t.size:
        raise InsufficientDataError(f"dark data need currents of shape (N, 4) and N temperatures, got {currents.shape} "
                                    f"and {t.size}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(currents))):
        raise InsufficientDataError("dark data hold a non-finite temperature or current")
    if t.size == 0:
        raise InsufficientDataError("no dark readings")
    return t, currents


def fit_dark(temperature_c, currents_a, *, models=("linear", "exponential")) -> DarkFit:
    """Fit the dark current of each quadrant against temperature and choose the model (module docstring).

    Parameters
    ----------
    temperature_c : array_like, shape (N,)
        Sensor temperature of each dark reading [°C].
    currents_a : array_like, shape (N, 4)
        Quadrant currents with the light off [A].
    models : tuple of str
        Candidates; the linear one (the thesis') is the default, the exponential replaces it only by the rule.

    Returns
    -------
    DarkFit

    References
    ----------
    seed 002, §2.1.
    """
    t, currents = _check(temperature_c, currents_a)
    n = t.size
    n_temps = len(np.unique(np.round(t, 2)))
    t_range = (float(t.min()), float(t.max()))
    if n_temps < 2:
        coef, cov, _, sd = _linear_fit(t, currents, [np.ones_like(t)])
        model = DarkModel("constant", coef, cov, sd)
        return DarkFit(model, {"constant": model}, n, t_range,
                       f"dark readings at one temperature only ({t[0]:.2f} °C): a constant dark current; its "
                       "temperature slope is unknown, so readings at other temperatures are corrected as if at "
                       "this one")
    candidates = {"linear": fit_dark_linear(t, currents)}
    chosen, note = candidates["linear"], "the thesis' linear model"
    if "exponential" in models:
        if n_temps >= EXPONENTIAL_MIN_TEMPERATURES and n >= EXPONENTIAL_MIN_POINTS:
            candidates["exponential"] = fit_dark_exponential(t, currents)
            gain = candidates["linear"].aicc - candidates["exponential"].aicc
            if np.isfinite(gain) and gain > EXPONENTIAL_AICC_MARGIN:
                chosen = candidates["exponential"]
                note = (f"exponential a + c·exp(b(t − {chosen.t_ref_c:.2f} °C)) chosen: its AICc is lower than the "
                        f"thesis' line's by {gain:.1f} (> {EXPONENTIAL_AICC_MARGIN:g})")
            else:
                if not np.isfinite(gain):
                    note += " kept (AICc not comparable)"
                elif gain > 0:
                    note += (f" kept: the exponential's AICc is lower by only {gain:.1f} "
                             f"(≤ {EXPONENTIAL_AICC_MARGIN:g})")
                else:
                    note += f" kept: the exponential's AICc is {-gain:.1f} higher"
        else:
            note += (f" (too few temperatures, {n_temps}, or readings, {n}, to test the exponential: it needs "
                     f"{EXPONENTIAL_MIN_TEMPERATURES} and {EXPONENTIAL_MIN_POINTS})")
    return DarkFit(chosen, candidates, n, t_range, note)


def subtract_dark(currents_a, temperature_c, fit: DarkFit | DarkModel) -> np.ndarray:
    """Photocurrents I^f = I − I^d(t) of each quadrant [A].

    Parameters
    ----------
    currents_a : array_like, shape (..., 4)
        Measured quadrant currents [A].
    temperature_c : numeric
        Sensor temperature of each reading [°C] (broadcast against the readings).
    fit : DarkFit or DarkModel

    Returns
    -------
    photocurrents_a : ndarray, shape (..., 4)

    References
    ----------
    seed 002, §2.1.
    """
    currents = np.asarray(currents_a, dtype=float)
    return currents - fit.current(temperature_c)
