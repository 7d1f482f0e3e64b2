"""Accuracy of a calibration in the columns of seed 003 Table 4.1, at the fitted points and held out.

Held-out accuracy is leave-one-azimuth-out: every bench azimuth in turn is removed, the model is fitted
to the rest, and the removed points are predicted. Each off-normal point is predicted once by a model
that never saw its azimuth, so the figure says how the calibration does between the measured azimuths,
where a flight sensor will see the Sun — not how well it reproduces its own nodes.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .data import BenchData
from .design import DEFAULT_SENSOR, SensorDesign
from .errors import CalibrationError, InsufficientDataError
from .geometry import angular_error_deg, wrap_deg
from .models import METHODS, Calibration


@dataclass(frozen=True)
class AccuracyMetrics:
    """Accuracy of predicted directions against the true ones (seed 003 Table 4.1 columns and more).

    Attributes
    ----------
    n_points : int
        Points evaluated.
    rms_zenith_deg : float
        RMS of the zenith error [°].
    rms_azimuth_deg : float
        RMS of the azimuth error, wrapped to ±180°, over the off-normal points (the azimuth is undefined at
        normal incidence) [°].
    rms_vector_deg : float
        RMS of the angle between the true and the measured direction (eq. 13) [°].
    bound95_deg : float
        The 95 % bound as the thesis quotes it, 2 × `rms_vector_deg` [°].
    p95_vector_deg : float
        Empirical 95th percentile of the vector error [°].
    max_vector_deg : float
        Largest vector error [°].
    rms_vector_below40_deg : float
        RMS vector error of the points with zenith below 40° (seed 003 §4.3 quotes this range too) [°].
    """

    n_points: int
    rms_zenith_deg: float
    rms_azimuth_deg: float
    rms_vector_deg: float
    bound95_deg: float
    p95_vector_deg: float
    max_vector_deg: float
    rms_vector_below40_deg: float

    def to_dict(self) -> dict:
        return asdict(self)


def _rms(values) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def accuracy_metrics(data: BenchData, zenith_deg, azimuth_deg) -> AccuracyMetrics:
    """Compare predicted directions with the true ones of `data`.

    References
    ----------
    seed 003, eqs. 12–13 and Table 4.1 (RMS zenith, RMS azimuth, RMS vector; 95 % = 2 × RMS).
    """
    zenith_deg = np.asarray(zenith_deg, dtype=float)
    azimuth_deg = np.asarray(azimuth_deg, dtype=float)
    vector = angular_error_deg(data.zenith_deg, data.azimuth_deg, zenith_deg, azimuth_deg)  # eq. 13
    off = ~data.normal_incidence
    low = data.zenith_deg < 40.0
    rms_vector = _rms(vector)
    return AccuracyMetrics(
        n_points=len(data),
        rms_zenith_deg=_rms(zenith_deg - data.zenith_deg),
        rms_azimuth_deg=_rms(wrap_deg(azimuth_deg[off] - data.azimuth_deg[off])),
        rms_vector_deg=rms_vector,
        bound95_deg=2.0 * rms_vector,
        p95_vector_deg=float(np.percentile(vector, 95)) if vector.size else float("nan"),
        max_vector_deg=float(vector.max()) if vector.size else float("nan"),
        rms_vector_below40_deg=_rms(vector[low]),
    )


def holdout_predictions(method: str, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, **fit_options):
    """Leave-one-azimuth-out predictions of every off-normal point.

    `fit_options` go to the method's ``fit`` (for example ``glass_index`` for ``physical``).

    Returns
    -------
    evaluated : BenchData
        The off-normal points, in their original order.
    zenith_deg, azimuth_deg : ndarray
        What a model fitted without the point's azimuth says [°].
    """
    groups = data.azimuth_groups()
    labels = sorted(set(groups[groups >= 0].tolist()))
    if len(labels) < 3:
        raise CalibrationError(f"held-out evaluation needs at least 3 bench azimuths, the data have {len(labels)}")
    zenith = np.full(len(data), np.nan)
    azimuth = np.full(len(data), np.nan)
    for label in labels:
        out = groups == label
        calibration = METHODS[method].fit(data.subset(~out), design, **fit_options)
        zenith[out], azimuth[out] = calibration.apply(data.x_px[out], data.y_px[out])
    keep = groups >= 0
    return data.subset(keep), zenith[keep], azimuth[keep]


@dataclass(frozen=True)
class MethodReport:
    """One method fitted to one data set.

    Attributes
    ----------
    method : str
    calibration : Calibration or None
        Fitted to all the data; None when the method could not be fitted.
    fitted : AccuracyMetrics or None
        At the fitted points.
    heldout : AccuracyMetrics or None
        Leave-one-azimuth-out.
    error : str or None
        Why the method could not be fitted or evaluated.
    """

    method: str
    calibration: Calibration | None
    fitted: AccuracyMetrics | None
    heldout: AccuracyMetrics | None
    error: str | None = None

    def to_dict(self) -> dict:
        return {"method": self.method, "error": self.error,
                "fitted": self.fitted.to_dict() if self.fitted else None,
                "heldout": self.heldout.to_dict() if self.heldout else None}


def evaluate_method(method: str, data: BenchData, design: SensorDesign = DEFAULT_SENSOR,
                    **fit_options) -> MethodReport:
    """Fit one method to all the data and evaluate it at the nodes and held out.

    The repeats of each bench direction are averaged first (:meth:`BenchData.direction_means`), as seed 003
    §4.3 does before fitting and before its Table 4.1.
    """
    data = data.direction_means()
    try:
        calibration = METHODS[method].fit(data, design, **fit_options)
    except CalibrationError as exc:
        return MethodReport(method, None, None, None, str(exc))
    fitted = accuracy_metrics(data, *calibration.apply(data.x_px, data.y_px))
    try:
        evaluated, zenith, azimuth = holdout_predictions(method, data, design, **fit_options)
        heldout = accuracy_metrics(evaluated, zenith, azimuth)
    except CalibrationError as exc:
        return MethodReport(method, calibration, fitted, None, f"no held-out figure: {exc}")
    return MethodReport(method, calibration, fitted, heldout)


def compare_methods(data: BenchData, methods=None, design: SensorDesign = DEFAULT_SENSOR,
                    fit_options: dict[str, dict] | None = None) -> list[MethodReport]:
    """Evaluate every method (default: all of :data:`calibration.models.METHODS`) on the same data.

    `fit_options` maps a method name to keyword arguments of its ``fit``, e.g.
    ``{"physical": {"glass_index": 1.77, "fit_index": True}}``.

    Data that no method could fit (one azimuth, fewer bench directions than the least any method needs) are
    refused up front with one :class:`~calibration.errors.InsufficientDataError`.
    """
    means = data.direction_means()
    need = min(m.min_points for m in METHODS.values())
    if len(means) < need:
        raise InsufficientDataError(f"too few bench directions, {len(means)} (from {len(data)} frames); "
                                    f"a calibration needs at least {need}")
    means.require_spread(min_points=need, method="calibration")
    fit_options = fit_options or {}
    return [evaluate_method(m, data, design, **fit_options.get(m, {})) for m in (methods or list(METHODS))]


def best_method(reports: list[MethodReport]) -> MethodReport:
    """The report with the lowest held-out vector RMS (the fitted one when none could be held out)."""
    usable = [r for r in reports if r.calibration is not None]
    if not usable:
        raise CalibrationError("no method could be fitted: " + "; ".join(str(r.error) for r in reports))
    if any(r.heldout for r in usable):
        return min((r for r in usable if r.heldout), key=lambda r: r.heldout.rms_vector_deg)
    return min(usable, key=lambda r: r.fitted.rms_vector_deg)
