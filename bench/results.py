"""What a run's results look like through its calibrations: mean spots per point and residuals per point.

The dashboard draws these (spot map, zenith against radius, residuals); they are computed here, with the
calibration core, so ``web/`` holds no science.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from calibration.geometry import angular_error_deg, azimuth_measured_deg, spot_radius_px, wrap_deg
from calibration.models import calibration_from_dict


class NoCalibration(LookupError):
    """The run has no calibration of the method asked for."""


def point_means(catalogue, run_id: int) -> list[dict]:
    """The run's points in recording order, each with `n_ok` and the mean spot (`x_px`, `y_px`) of its good
    readings (None when it has none)."""
    catalogue.run(run_id)  # "no run N" rather than an empty list
    spots = defaultdict(list)
    for reading in catalogue.readings(run_id):
        if reading["status"] == "ok" and reading["x_px"] is not None:
            spots[reading["point_id"]].append((reading["x_px"], reading["y_px"]))
    points = []
    for point in catalogue.points(run_id):
        good = spots.get(point["id"], [])
        mean = [sum(c) / len(good) for c in zip(*good)] if good else [None, None]
        points.append({**point, "n_ok": len(good), "x_px": mean[0], "y_px": mean[1]})
    return points


def _finite(values) -> list:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float)]


def fit_residuals(catalogue, run_id: int, method: str | None = None) -> dict:
    """Each point with a spot, seen through one calibration (default: the chosen one): its radius and its
    measured azimuth about the calibration's centre (seed 003 eqs. 7, 10), the direction the calibration gives
    and the residuals (eq. 13).

    Raises :class:`NoCalibration` when the run has no such calibration; the calibration's own format errors
    (:class:`calibration.errors.CalibrationFormatError`) pass through.
    """
    points = [p for p in point_means(catalogue, run_id) if p["x_px"] is not None]
    matches = [c for c in catalogue.calibrations(run_id) if (c["method"] == method if method else c["chosen"])]
    if not matches:
        raise NoCalibration(f"run {run_id} has no {method or 'chosen'} calibration")
    record = matches[-1]
    calibration = calibration_from_dict(record["document"])
    x0, y0 = float(calibration.x0_px), float(calibration.y0_px)
    x = np.array([p["x_px"] for p in points], dtype=float)
    y = np.array([p["y_px"] for p in points], dtype=float)
    zenith = np.array([p["zenith_deg"] for p in points], dtype=float)
    azimuth = np.array([p["azimuth_body_deg"] for p in points], dtype=float)
    if points:
        radius = spot_radius_px(x, y, x0, y0)
        azimuth_spot = azimuth_measured_deg(x, y, x0, y0)
        with np.errstate(invalid="ignore"):
            zenith_fit, azimuth_fit = (np.asarray(a, dtype=float) for a in calibration.apply(x, y))
            error = angular_error_deg(zenith_fit, azimuth_fit, zenith, azimuth)
    else:
        radius = azimuth_spot = zenith_fit = azimuth_fit = error = np.empty(0)
    columns = zip(points, radius, azimuth_spot, _finite(zenith_fit), _finite(azimuth_fit),
                  _finite(zenith_fit - zenith), _finite(wrap_deg(azimuth_fit - azimuth)), _finite(error), strict=True)
    data = [{"id": p["id"], "stage": p["stage"], "zenith_deg": p["zenith_deg"], "azimuth_deg": p["azimuth_body_deg"],
             "x_px": p["x_px"], "y_px": p["y_px"], "radius_px": float(r), "azimuth_spot_deg": float(a),
             "zenith_fit_deg": zf, "azimuth_fit_deg": af, "zenith_residual_deg": dz, "azimuth_residual_deg": da,
             "error_deg": e}
            for p, r, a, zf, af, dz, da, e in columns]
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]), "x0_px": x0,
            "y0_px": y0, "data": data, "count": len(data)}
