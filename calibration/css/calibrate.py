"""Calibrate a coarse-sun-sensor head from bench data, score it held out, and write its versioned JSON document.

:func:`calibrate_css` is the CSS family's counterpart of :func:`calibration.qd.evaluation.calibrate_qd`:

1. **Repeat groups**: rows of one Sun direction (within 0.03°) form a group; the dark rows one more; check rows
   never share a group with fitted rows (:func:`~calibration.css.diode_fit.direction_groups`).
2. **Every channel present** is fitted on the fitted (non-check) rows by :func:`~calibration.css.diode_fit.fit_diode`
   (its faults, rejected readings, temperature and field-of-view decisions, noise model, covariance). A faulty
   channel (stuck, dead, saturated, inverted, unlit) is excluded from the head's calibration with a warning; the
   others make the head model (:class:`~calibration.css.diode.HeadModel`).
3. **Held out**: the fitted directions are split into `folds` interleaved folds (directions sorted by zenith then
   azimuth, the i-th in fold i mod folds; a direction's repeats stay together, the dark rows are always fitted).
   Each fold is left out in turn, every valid channel refitted on the rest (from the full fit's values, with the
   same choice of what is fitted and the full fit's noise model), and scored on the left-out directions:

   * each detector's predicted signal: RMS residual [A or V] and RMS residual in noise sigmas;
   * the Sun's direction from the weighted least-squares estimator (:func:`~calibration.css.estimate.estimate_sun`)
     on every left-out reading with the fold's head model: RMS, 95th percentile and maximum of the angle to the
     true direction [°], and the RMS of that angle over the estimator's own 1σ (≈ 1 when the stated uncertainty
     is honest). Degenerate readings (fewer than two non-coplanar lit faces) are counted, not scored.

   The same figures at the fitted nodes (the full calibration on the rows it was fitted to) and on check rows
   (never fitted) sit beside them. Readings a fit rejected (glints, saturation) are left out of every score.
4. **Warnings in words**: faulty channels, each channel's own warnings, held-out figures much worse than the
   fitted ones, a stated uncertainty that is not honest.

The document (:func:`css_document`) is a plain dict of JSON types:

.. code-block:: text

    {"format": "sunbench-css-calibration", "version": 1, "family": "css", "sensor_id": str | null,
     "response": "kelly" | "power" | "spline", "reference_temperature_c": 25.0,
     "model": {"signal": str, "noise": str, "fov_edge": "linear", "fov_edge_width_deg": 2.0,
               "tilt_axes": {face: [u, v]}},
     "diodes": {channel: {"valid": bool, "fault": str | null, "unit": "a" | "v",
                          "parameters": {name: {"value": float | null, "sd": float | null, "fitted": bool}},
                          "spline_knots_deg": [float] (the spline law only),
                          "normal": {"zenith_deg", "azimuth_deg", "sd_deg"},
                          "covariance": {"names": [str], "matrix": [[float]]},
                          "noise": {"sigma0": float, "shot": float, "relative": float, "model": float,
                                    "source": str},
                          "full_scale": float | null,
                          "fit": {"chi2_dof", "rms", "rms_normalised", "n_points", "temperature_fitted",
                                  "fov_fitted"},
                          "warnings": [str], "statements": [str]}},
     "heldout": {...} | null, "uncertainty_scale": float ≥ 1,
     "warnings": [str], "rejected": [{"row", "channel", "zenith_deg", "azimuth_deg", "reason"}]}

``parameters`` names: scale, bias, tilt_u_deg, tilt_v_deg, kappa (Kelly) or power, fov_half_deg (null: no cut-off),
temp_coeff_per_c, bias_temp_coeff_per_c (:mod:`calibration.css.diode`); the spline law has no kappa or power but
spline_1 … spline_<K+1>, the free coefficients of its cubic B-spline in cos θ on the knots ``spline_knots_deg``
θ_0 = 0 … θ_K (:mod:`calibration.css.spline`: c = (0, spline_1 … spline_<K+1>, 1) from cos θ_K up to 1, R = 0
beyond θ_K, R = max(0, spline)), and fov_half_deg null. A faulty diode has ``valid`` false, its ``fault`` and no
parameters. :func:`apply_css_document` turns raw readings into Sun directions with nothing but the document.

References
----------
seed 000, eq. 3.1, ch. 5.3.2, digest §8.3 items 7–9 and §8.4 item 12 (fit each detector, compare estimators by
Monte Carlo, report honest errors); research note anchors-sunsensors §5 (Basilisk CSS parameters and faults) and §6
(held-out accuracy, covariance); DESIGN.md (fits report held-out figures; every calibration is a versioned JSON
document).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import CalibrationFormatError, InsufficientDataError
from ..plain import plain
from .data import CssBenchData
from .diode import (
    FOV_EDGE_WIDTH_DEG,
    REFERENCE_TEMPERATURE_C,
    RESPONSES,
    SHAPE_NAME,
    SPLINE,
    TILT_AXES,
    DiodeParameters,
    HeadModel,
)
from .diode_fit import DiodeFit, RejectedReading, direction_groups, fit_diode
from .estimate import estimate_sun
from .head import CHANNELS, UNITS, split_channel
from .spline import check_knots, n_free, spline_names

#: The document's format tag, version and family.
FORMAT = "sunbench-css-calibration"
CSS_FORMAT_VERSION = 1
FAMILY = "css"
#: Interleaved folds of the held-out scoring.
FOLDS = 5
#: Held-out RMS more than this × the fitted one is worth a word.
HELDOUT_WORSE = 3.0
#: Held-out angle errors over the stated 1σ with an RMS above this: the stated uncertainty is too small.
HONESTY_LIMIT = 2.0


@dataclass(frozen=True)
class SunErrorMetrics:
    """Angle between estimated and true Sun directions over some readings.

    Attributes
    ----------
    n_points : int
        Readings scored (not degenerate, an estimate found).
    n_degenerate : int
        Readings with fewer than two non-coplanar lit faces (not scored).
    n_failed : int
        Readings without an estimate (no lit detector).
    rms_deg, p95_deg, max_deg : float
        [°]
    normalised_rms : float
        RMS of angle / stated 1σ cone radius (≈ 1 when the stated uncertainty is honest).
    """

    n_points: int
    n_degenerate: int
    n_failed: int
    rms_deg: float
    p95_deg: float
    max_deg: float
    normalised_rms: float

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in self.__dict__.items()}


def sun_error_metrics(true_vectors, estimate) -> SunErrorMetrics:
    """Figures of :class:`SunErrorMetrics` for an estimate against the true unit vectors (N, 3).

    References
    ----------
    seed 003 eq. 13 (angle between directions); seed 000 digest §8.4 item 12 (error analysis of the estimators).
    """
    return _metrics(true_vectors, estimate.vector, estimate.sigma_deg, estimate.degenerate)


def _metrics(true_vectors, vector, sigma_deg, degenerate) -> SunErrorMetrics:
    t = np.asarray(true_vectors, float).reshape(-1, 3)
    v = np.asarray(vector, float)
    failed = ~np.all(np.isfinite(v), axis=1)
    degenerate = np.asarray(degenerate, bool) & ~failed
    ok = ~failed & ~degenerate
    if not ok.any():
        nan = float("nan")
        return SunErrorMetrics(0, int(degenerate.sum()), int(failed.sum()), nan, nan, nan, nan)
    err = np.degrees(np.arccos(np.clip(np.sum(t[ok] * v[ok], axis=1), -1.0, 1.0)))
    norm = err / np.asarray(sigma_deg, float)[ok]
    return SunErrorMetrics(int(ok.sum()), int(degenerate.sum()), int(failed.sum()), float(np.sqrt(np.mean(err**2))),
                           float(np.percentile(err, 95)), float(err.max()), float(np.sqrt(np.mean(norm**2))))


@dataclass(frozen=True)
class CssCalibrationOutcome:
    """Everything :func:`calibrate_css` found.

    Attributes
    ----------
    sensor_id : str or None
    response : str
    fits : dict of str to DiodeFit
        Every channel's fit on all fitted rows (faulty ones with their fault).
    head : HeadModel
        The valid channels' calibrated model (what the estimator uses).
    heldout : dict
        JSON types: {"scheme", "folds", "channels": {channel: {"at_nodes": {...}, "heldout": {...}}},
        "sun": {"at_nodes": {...}, "heldout": {...}, "check": {...} | null}} (module docstring step 3).
    sun_heldout, sun_at_nodes : SunErrorMetrics or None
    sun_check : SunErrorMetrics or None
    rejected : list of RejectedReading
    warnings : list of str
    """

    sensor_id: str | None
    response: str
    fits: dict
    head: HeadModel
    heldout: dict
    sun_heldout: SunErrorMetrics | None
    sun_at_nodes: SunErrorMetrics | None
    sun_check: SunErrorMetrics | None
    rejected: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def valid_channels(self) -> tuple:
        return self.head.channels

    @property
    def faulty(self) -> dict:
        """Channel → fault of the channels left out of the head's calibration."""
        return {c: f.fault for c, f in self.fits.items() if not f.valid}

    @property
    def document(self) -> dict:
        """The calibration document (module docstring)."""
        return css_document(self.fits, sensor_id=self.sensor_id, response=self.response, heldout=self.heldout,
                            warnings=self.warnings, rejected=self.rejected)

    def to_dict(self) -> dict:
        return {"sensor_id": self.sensor_id, "response": self.response,
                "fits": {c: f.to_dict() for c, f in self.fits.items()}, "heldout": self.heldout,
                "rejected": [r.to_dict() for r in self.rejected], "warnings": list(self.warnings)}


def _full_scale_of(full_scale, channel: str):
    if full_scale is None or isinstance(full_scale, (int, float)):
        return full_scale
    detector = split_channel(channel)[1]
    return full_scale.get(channel, full_scale.get(detector))


def heldout_folds(zenith_deg, azimuth_deg, groups, rows, *, folds: int = FOLDS) -> np.ndarray:
    """Fold of each row in `rows` (−1 for dark rows): directions sorted by zenith then azimuth, the i-th in fold
    i mod `folds`, a direction's repeats together.

    References
    ----------
    seed 002 §5.3 and digest §8 (validate between the nodes); research note anchors-sunsensors §6 (held-out
    accuracy).
    """
    rows = np.asarray(rows)
    g = np.asarray(groups)[rows]
    out = np.full(rows.size, -1)
    light = np.isfinite(np.asarray(zenith_deg, float)[rows])
    uniq = np.unique(g[light])
    if uniq.size == 0:
        return out
    first = {int(u): rows[light][np.flatnonzero(g[light] == u)[0]] for u in uniq}
    order = sorted(uniq, key=lambda u: (round(float(zenith_deg[first[int(u)]]), 2),
                                        round(float(azimuth_deg[first[int(u)]]), 2)))
    fold_of = {int(u): i % folds for i, u in enumerate(order)}
    out[light] = [fold_of[int(v)] for v in g[light]]
    return out


def _channel_scores(residual, sigma) -> dict:
    r = np.asarray(residual, float)
    ok = np.isfinite(r) & np.isfinite(sigma)
    if not ok.any():
        return {"n_points": 0, "rms": None, "rms_normalised": None}
    return {"n_points": int(ok.sum()), "rms": float(np.sqrt(np.mean(r[ok] ** 2))),
            "rms_normalised": float(np.sqrt(np.mean((r[ok] / sigma[ok]) ** 2)))}


def calibrate_css(data: CssBenchData, *, response: str = "kelly", folds: int = FOLDS, full_scale=None,
                  fit_temperature="auto", fit_fov="auto", channels=None, spline_knots_deg=None,
                  start: CssCalibrationOutcome | None = None) -> CssCalibrationOutcome:
    """Calibrate a CSS head from its bench data (module docstring, steps 1–4).

    Parameters
    ----------
    data : CssBenchData
        Light rows at known directions (with repeats), optionally dark rows and check rows.
    response : {"kelly", "power", "spline"}
        The angular response law of every detector's model (:mod:`calibration.css.diode`).
    folds : int
        Interleaved folds of the held-out scoring (0 or 1: none).
    full_scale : float or dict, optional
        The front ends' full scale [A or V]: one value, or by channel / by detector type (``"uv"``, ``"vis"``,
        ``"ir"``). Without it a clip level is detected from the data.
    fit_temperature, fit_fov :
        As :func:`~calibration.css.diode_fit.fit_diode`.
    channels : sequence of str, optional
        Fit only these (default every channel in the data).
    spline_knots_deg : sequence of float, optional
        The spline law's knots [°], the same for every detector (default: each detector's own, the grid's up to an
        end its readings choose: :func:`~calibration.css.diode_fit.fit_diode`).
    start : CssCalibrationOutcome, optional
        A calibration of the same data with another law: each detector's fit starts from its normal and
        temperature coefficient (the spline law's linear start then needs no search).

    Returns
    -------
    CssCalibrationOutcome

    Raises
    ------
    InsufficientDataError
        When no channel can be calibrated.

    References
    ----------
    seed 000, eq. 3.1, digest §8.3 items 7–8, §8.4 item 12; research note anchors-sunsensors §5–6.
    """
    if response not in RESPONSES:
        raise ValueError(f"no response law {response!r} (laws: {', '.join(RESPONSES)})")
    chans = tuple(c for c in data.channels if channels is None or c in set(channels))
    if not chans:
        raise InsufficientDataError("none of the channels asked for is in the data", column="channels")
    sun = data.sun_vectors
    groups = direction_groups(sun, data.dark, data.check)
    nodes = np.flatnonzero(~data.check)
    checks = np.flatnonzero(data.check)
    fits: dict = {}
    rejected: list = []
    warnings: list = []
    for c in chans:
        first = start.fits.get(c) if start is not None else None
        fit = fit_diode(c, sun[nodes], data.signal(c)[nodes], data.temperature_c[nodes], dark=data.dark[nodes],
                        groups=groups[nodes], response=response, row_id=data.row_id[nodes],
                        full_scale=_full_scale_of(full_scale, c), fit_temperature=fit_temperature, fit_fov=fit_fov,
                        spline_knots_deg=spline_knots_deg, initial=first.parameters if first is not None and
                        first.valid else None)
        fits[c] = fit
        rejected += list(fit.rejected)
        warnings += list(fit.warnings)
    valid = [c for c in chans if fits[c].valid]
    for c in chans:
        if not fits[c].valid:
            warnings.append(f"{c} is excluded from the head's calibration ({fits[c].fault})")
    if not valid:
        raise InsufficientDataError("no channel could be calibrated: " + "; ".join(
            f"{c}: {fits[c].fault}" for c in chans))
    head = HeadModel.from_parameters([fits[c].parameters for c in valid])
    # readings the fits rejected are left out of every score
    signals = data.signals.copy()
    row_index = {int(r): i for i, r in enumerate(data.row_id)}
    for r in rejected:
        if r.channel in data.channels and int(r.row_id) in row_index:
            signals[row_index[int(r.row_id)], data.channels.index(r.channel)] = np.nan
    light_nodes = nodes[~data.dark[nodes]]
    # at the nodes
    est = estimate_sun(head, signals[light_nodes], data.temperature_c[light_nodes], channels=data.channels)
    sun_at_nodes = sun_error_metrics(sun[light_nodes], est)
    sun_check = None
    if checks.size:
        est_c = estimate_sun(head, signals[checks], data.temperature_c[checks], channels=data.channels)
        sun_check = sun_error_metrics(sun[checks], est_c)
    channel_scores = {}
    for c in valid:
        f = fits[c]
        sig = f.parameters.noise_sd(data.signal(c)[nodes] - f.residual)
        channel_scores[c] = {"at_nodes": _channel_scores(f.residual, sig), "heldout": None}
    # held out
    sun_heldout = None
    fold = heldout_folds(data.zenith_deg, data.azimuth_deg, groups, nodes, folds=max(folds, 1))
    n_dirs = np.unique(groups[light_nodes]).size
    if folds >= 2 and n_dirs >= 2 * folds:
        resid = {c: np.full(nodes.size, np.nan) for c in valid}
        sigma = {c: np.full(nodes.size, np.nan) for c in valid}
        truth_rows, estimates = [], []
        excluded_in_folds = set()
        for k in range(folds):
            test = fold == k
            train = ~test
            fold_params = []
            for c in valid:
                full = fits[c]
                fp = full.parameters
                f = fit_diode(c, sun[nodes[train]], signals[nodes[train], data.channels.index(c)],
                              data.temperature_c[nodes[train]], dark=data.dark[nodes[train]],
                              groups=groups[nodes[train]], response=response, row_id=data.row_id[nodes[train]],
                              full_scale=fp.full_scale, fit_temperature=full.temperature_fitted,
                              fit_fov=True if full.fov_fitted else (fp.fov_half_deg or False), initial=fp,
                              noise=(fp.sigma0, fp.shot, fp.noise_rel, fp.model_sd))
                if not f.valid:
                    excluded_in_folds.add(c)
                    continue
                fold_params.append(f.parameters)
                rows_t = nodes[test]
                pred = f.predict(sun[rows_t], data.temperature_c[rows_t], dark=data.dark[rows_t])
                resid[c][test] = signals[rows_t, data.channels.index(c)] - pred
                sigma[c][test] = f.parameters.noise_sd(pred)
            if not fold_params:
                continue
            fold_head = HeadModel.from_parameters(fold_params)
            rows_t = nodes[test & ~data.dark[nodes]]
            estimates.append(estimate_sun(fold_head, signals[rows_t], data.temperature_c[rows_t],
                                          channels=data.channels))
            truth_rows.append(rows_t)
        for c in valid:
            channel_scores[c]["heldout"] = _channel_scores(resid[c], sigma[c])
        if estimates:
            sun_heldout = _merge_metrics(sun, truth_rows, estimates)
        if excluded_in_folds:
            warnings.append(f"{', '.join(sorted(excluded_in_folds))}: could not be calibrated without some fold's "
                            "directions (too few lit directions left): left out of that fold's scores")
    else:
        warnings.append(f"no held-out figures: {n_dirs} fitted directions are too few for {folds} folds; the "
                        "figures at the fitted nodes flatter the calibration")
    heldout = {"scheme": f"{folds} interleaved folds of directions (sorted by zenith, then azimuth), repeats kept "
                         "together, dark rows always fitted",
               "folds": int(folds), "channels": channel_scores,
               "sun": {"at_nodes": sun_at_nodes.to_dict(), "heldout": None if sun_heldout is None else
                       sun_heldout.to_dict(), "check": None if sun_check is None else sun_check.to_dict()}}
    warnings += _warnings(fits, valid, channel_scores, sun_at_nodes, sun_heldout, sun_check, data)
    return CssCalibrationOutcome(data.sensor_id, response, fits, head, heldout, sun_heldout, sun_at_nodes, sun_check,
                                 rejected, warnings)


def _merge_metrics(sun, rows_list, estimates) -> SunErrorMetrics:
    """One :class:`SunErrorMetrics` over several folds' estimates."""
    return _metrics(np.concatenate([sun[r] for r in rows_list]), np.concatenate([e.vector for e in estimates]),
                    np.concatenate([e.sigma_deg for e in estimates]), np.concatenate([e.degenerate for e in estimates]))


def _warnings(fits, valid, scores, at_nodes, heldout, check, data: CssBenchData) -> list:
    out = []
    worse = []
    for c in valid:
        a, h = scores[c]["at_nodes"], scores[c]["heldout"]
        if h and h["rms"] is not None and a["rms"] and h["rms"] > HELDOUT_WORSE * a["rms"]:
            worse.append(f"{c} ({h['rms'] / a['rms']:.1f}×)")
    if worse:
        out.append("held out, these detectors' residuals are much larger than at the fitted directions: "
                   + ", ".join(worse) + " — the model follows the fitted points more than the detector; use more "
                   "directions or check the angular law")
    if heldout is not None and heldout.n_points:
        if at_nodes.n_points and heldout.rms_deg > HELDOUT_WORSE * max(at_nodes.rms_deg, 1e-6):
            out.append(f"the Sun's direction is {heldout.rms_deg / at_nodes.rms_deg:.1f}× worse held out "
                       f"({heldout.rms_deg:.3f}° RMS) than at the fitted directions ({at_nodes.rms_deg:.3f}°)")
        if np.isfinite(heldout.normalised_rms) and heldout.normalised_rms > HONESTY_LIMIT:
            out.append(f"held out, the Sun direction's error is {heldout.normalised_rms:.1f}× its stated 1σ (RMS): the "
                       "stated uncertainty counts the reading noise only, and the model's misfit dominates")
        if heldout.n_degenerate:
            out.append(f"{heldout.n_degenerate} held-out reading(s) light fewer than two non-coplanar faces: their "
                       "direction is not determined (flagged degenerate, not scored)")
    if not data.check.any():
        out.append("no check rows: held-out figures come from leaving directions out only")
    if not data.dark.any():
        out.append("no dark rows (light off): the offsets come from unlit directions only")
    return out


# --- the document -------------------------------------------------------------------------------------------------
def _diode_entry(fit: DiodeFit) -> dict:
    unit = UNITS[split_channel(fit.channel)[1]]
    entry = {"valid": fit.valid, "fault": fit.fault, "unit": unit, "warnings": list(fit.warnings),
             "statements": list(fit.statements)}
    if not fit.valid:
        return entry
    p = fit.parameters
    entry.update({
        "parameters": {k: {"value": v, "sd": fit.sd.get(k), "fitted": k in fit.free} for k, v in fit.values.items()},
        "normal": {"zenith_deg": fit.normal_zenith_deg, "azimuth_deg": fit.normal_azimuth_deg,
                   "sd_deg": fit.normal_sd_deg},
        "covariance": {"names": list(fit.free), "matrix": np.asarray(fit.covariance)},
        "noise": {"sigma0": p.sigma0, "shot": p.shot, "relative": p.noise_rel, "model": p.model_sd,
                  "source": fit.noise_source},
        "full_scale": p.full_scale,
        **({"spline_knots_deg": list(p.spline_knots_deg)} if p.response == SPLINE else {}),
        "fit": {"chi2_dof": fit.chi2_dof, "rms": fit.rms, "rms_normalised": fit.rms_normalised,
                "n_points": fit.n_points, "temperature_fitted": fit.temperature_fitted, "fov_fitted": fit.fov_fitted},
    })
    return entry


def css_document(fits, *, sensor_id: str | None = None, response: str = "kelly", heldout: dict | None = None,
                 warnings=(), rejected=()) -> dict:
    """Assemble a CSS calibration document (module docstring) from the diodes' fits.

    Parameters
    ----------
    fits : dict of str to DiodeFit, or iterable of DiodeFit
    sensor_id : str or None
    response : {"kelly", "power", "spline"}
    heldout : dict, optional
        :attr:`CssCalibrationOutcome.heldout`.
    warnings : sequence of str
    rejected : sequence of RejectedReading

    References
    ----------
    DESIGN.md (every calibration is a versioned JSON document); seed 000 eq. 3.1, digest §8.3 items 7–9.
    """
    items = fits.values() if isinstance(fits, dict) else fits
    diodes = {f.channel: _diode_entry(f) for f in sorted(items, key=lambda f: CHANNELS.index(f.channel))}
    doc = {"format": FORMAT, "version": CSS_FORMAT_VERSION, "family": FAMILY, "sensor_id": sensor_id,
           "response": response, "reference_temperature_c": REFERENCE_TEMPERATURE_C,
           "model": {"signal": "scale·(1 + temp_coeff_per_c·(T − 25))·R(n·s)·E(θ) + bias"
                               " + bias_temp_coeff_per_c·(T − 25)",
                     "response": {"kelly": "γ(1 − exp(−γ²/κ))/(1 − exp(−1/κ)), γ > 0",
                                  "power": "γ^p, γ > 0",
                                  "spline": "Σ c_j B_j(γ), the clamped cubic B-splines in γ on the breakpoints "
                                            "cos(spline_knots_deg), c = (0, spline_1 … spline_<K+1>, 1) from "
                                            "γ = cos(θ_K) up to 1, R = max(0, that); 0 for γ ≤ cos(θ_K)"}[response],
                     "noise": "σ² = sigma0² + shot·|m| + (relative·m)²",
                     "fov_edge": "linear", "fov_edge_width_deg": FOV_EDGE_WIDTH_DEG,
                     "tilt_axes": {f: [list(u), list(v)] for f, (u, v) in TILT_AXES.items()},
                     "normal": "n ∝ n0 + tan(tilt_u)·u + tan(tilt_v)·v"},
           "diodes": diodes, "heldout": heldout, "uncertainty_scale": uncertainty_scale(heldout),
           "warnings": [str(w) for w in warnings],
           "rejected": [r.to_dict() if isinstance(r, RejectedReading) else r for r in rejected]}
    doc = plain(doc)
    validate_css_document(doc)
    return doc


def uncertainty_scale(heldout: dict | None) -> float:
    """The factor :func:`apply_css_document` multiplies the estimator's stated 1σ by: the held-out Sun direction
    error's RMS in units of its stated 1σ, when above 1 (else 1, and 1 without held-out figures).

    The estimator's 1σ counts the reading noise and each detector's model error; where the model misses the
    detector in ways those do not capture (an angular law unlike the detector's), the held-out directions show it,
    and the stated uncertainty is widened to match what they showed.

    References
    ----------
    research note anchors-sunsensors §6 (held-out accuracy); DESIGN.md (fits report what they achieve held out).
    """
    try:
        value = heldout["sun"]["heldout"]["normalised_rms"]
    except (KeyError, TypeError):
        return 1.0
    return float(value) if value is not None and np.isfinite(value) and value > 1.0 else 1.0


_PARAMS = ("scale", "bias", "tilt_u_deg", "tilt_v_deg", "fov_half_deg", "temp_coeff_per_c", "bias_temp_coeff_per_c")


def _number(value, what: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise CalibrationFormatError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _knots(entry: dict, channel: str) -> tuple:
    """A spline diode's knots [°], checked."""
    knots = entry.get("spline_knots_deg")
    if not isinstance(knots, list) or not all(isinstance(k, (int, float)) and not isinstance(k, bool) for k in knots):
        raise CalibrationFormatError(f"diode {channel}: the spline law needs `spline_knots_deg`, a list of numbers")
    try:
        return check_knots(knots)
    except ValueError as exc:
        raise CalibrationFormatError(f"diode {channel}: {exc}") from None


def validate_css_document(doc) -> None:
    """Raise :class:`~calibration.errors.CalibrationFormatError` (naming the problem) unless `doc` is a CSS
    calibration this version reads.

    References
    ----------
    DESIGN.md (versioned calibration documents; typed errors).
    """
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CalibrationFormatError(f"not a CSS calibration (expected \"format\": \"{FORMAT}\")")
    if doc.get("family") != FAMILY:
        raise CalibrationFormatError(f"not a CSS calibration (family {doc.get('family')!r})")
    if doc.get("version") != CSS_FORMAT_VERSION:
        raise CalibrationFormatError(f"CSS calibration version {doc.get('version')!r} is not supported (this sunbench "
                                     f"reads version {CSS_FORMAT_VERSION})")
    response = doc.get("response")
    if response not in RESPONSES:
        raise CalibrationFormatError(f"unknown response law {response!r} (laws: {', '.join(RESPONSES)})")
    if doc.get("reference_temperature_c") != REFERENCE_TEMPERATURE_C:
        raise CalibrationFormatError(f"reference_temperature_c must be {REFERENCE_TEMPERATURE_C}, got "
                                     f"{doc.get('reference_temperature_c')!r}")
    scale = doc.get("uncertainty_scale", 1.0)
    if _number(scale, "uncertainty_scale") < 1.0:
        raise CalibrationFormatError(f"uncertainty_scale must be at least 1, got {scale!r}")
    diodes = doc.get("diodes")
    if not isinstance(diodes, dict) or not diodes:
        raise CalibrationFormatError("CSS calibration without \"diodes\"")
    n_valid = 0
    for channel, entry in diodes.items():
        if channel not in CHANNELS:
            raise CalibrationFormatError(f"unknown channel {channel!r} in \"diodes\"")
        if not isinstance(entry, dict) or not isinstance(entry.get("valid"), bool):
            raise CalibrationFormatError(f"diode {channel}: no \"valid\" flag")
        if not entry["valid"]:
            continue
        n_valid += 1
        params = entry.get("parameters")
        if not isinstance(params, dict):
            raise CalibrationFormatError(f"diode {channel}: no \"parameters\"")
        law_names = (SHAPE_NAME[response],) if response != SPLINE else spline_names(n_free(_knots(entry, channel)))
        for name in _PARAMS + law_names:
            if not isinstance(params.get(name), dict) or "value" not in params[name]:
                raise CalibrationFormatError(f"diode {channel}: parameter `{name}` missing")
            value = _number(params[name]["value"], f"diode {channel}: parameter `{name}`",
                            allow_none=name == "fov_half_deg")
            if name in ("tilt_u_deg", "tilt_v_deg") and abs(value) >= 90:
                raise CalibrationFormatError(f"diode {channel}: `{name}` {value}° is not a tilt of the face's normal")
        if _number(params["scale"]["value"], "scale") == 0:
            raise CalibrationFormatError(f"diode {channel}: zero scale")
        if response != SPLINE and _number(params[SHAPE_NAME[response]]["value"], "shape") <= 0:
            raise CalibrationFormatError(f"diode {channel}: `{SHAPE_NAME[response]}` must be positive")
        noise = entry.get("noise")
        if not isinstance(noise, dict):
            raise CalibrationFormatError(f"diode {channel}: no \"noise\" model")
        for name in ("sigma0", "shot", "relative", "model"):
            if _number(noise.get(name), f"diode {channel}: noise `{name}`") < 0:
                raise CalibrationFormatError(f"diode {channel}: noise `{name}` is negative")
        if noise["sigma0"] == 0 and noise["shot"] == 0 and noise["relative"] == 0:
            raise CalibrationFormatError(f"diode {channel}: a noise model of zero cannot weight a reading")
        _number(entry.get("full_scale"), f"diode {channel}: `full_scale`", allow_none=True)
    if n_valid == 0:
        raise CalibrationFormatError("CSS calibration without a valid diode")


def diode_parameters_from_document(doc: dict) -> list[DiodeParameters]:
    """The valid diodes' :class:`~calibration.css.diode.DiodeParameters` of a document, in channel order.

    References
    ----------
    seed 000 eq. 3.1; DESIGN.md (a calibration applied from its document alone).
    """
    validate_css_document(doc)
    response = doc["response"]
    out = []
    for channel in CHANNELS:
        entry = doc["diodes"].get(channel)
        if not entry or not entry["valid"]:
            continue
        v = {k: p["value"] for k, p in entry["parameters"].items()}
        noise = entry["noise"]
        if response == SPLINE:
            knots = _knots(entry, channel)
            law = {"spline_knots_deg": knots, "spline": tuple(v[n] for n in spline_names(n_free(knots)))}
        else:
            law = {"shape": v[SHAPE_NAME[response]]}
        out.append(DiodeParameters(channel, response, scale=v["scale"], bias=v["bias"], tilt_u_deg=v["tilt_u_deg"],
                                   tilt_v_deg=v["tilt_v_deg"], fov_half_deg=v["fov_half_deg"],
                                   temp_coeff_per_c=v["temp_coeff_per_c"],
                                   bias_temp_coeff_per_c=v["bias_temp_coeff_per_c"], sigma0=noise["sigma0"],
                                   shot=noise["shot"], noise_rel=noise["relative"], full_scale=entry.get("full_scale"),
                                   model_sd=noise.get("model", 0.0), **law))
    return out


def head_model_from_document(doc: dict) -> HeadModel:
    """The head model of a document's valid diodes.

    References
    ----------
    seed 000 ch. 5.3.1 (the head), eq. 3.1; DESIGN.md (versioned documents).
    """
    return HeadModel.from_parameters(diode_parameters_from_document(doc))


def apply_css_document(doc: dict, signals, channels, temperature_c, *, albedo=None, irradiance=1.0):
    """Sun directions from raw readings and the head's temperature, with the document alone.

    Parameters
    ----------
    doc : dict
        A CSS calibration document.
    signals : array_like (..., C)
        Raw readings [A or V] (NaN: no reading).
    channels : sequence of str
        The channels of `signals`' columns (those the document lacks or holds invalid are ignored).
    temperature_c : float or array_like (...)
        Head temperature [°C].
    albedo : AlbedoScene, callable or array_like, optional
        The Earth's signal (:func:`calibration.css.estimate.estimate_sun`).
    irradiance : float or array_like
        Relative to the calibration's reference.

    Returns
    -------
    SunEstimate
        Its stated uncertainty multiplied by the document's ``uncertainty_scale`` (:func:`uncertainty_scale`).

    References
    ----------
    seed 000 digest §8.3 item 8 (least-squares source vector), eq. 3.2 (albedo); DESIGN.md.
    """
    est = estimate_sun(head_model_from_document(doc), signals, temperature_c, channels=channels,
                       irradiance=irradiance, albedo=albedo)
    return est.scaled(doc.get("uncertainty_scale", 1.0) or 1.0)
