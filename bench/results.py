"""What a run's results look like through its calibrations: mean spots per point and residuals per point.

The dashboard draws these (spot map, zenith against radius, residuals); they are computed here, with the
calibration core, so ``web/`` holds no science. So is which points the fit left out, and why: a point whose
every spot was clipped at the detector's edge (:func:`bench.runner.bench_data` never fits those), or whose
every frame the calibration rejected (its document's ``rejected``, ``row`` = reading id). Table 4.1 is
computed without them; a plot that drew them as the others would show a worst point the table does not have.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from calibration.geometry import angular_error_deg, azimuth_measured_deg, spot_radius_px, wrap_deg
from calibration.models import calibration_from_dict

from .runner import EDGE_REASON, clipped, has_spot


class NoCalibration(LookupError):
    """The run has no calibration of the method asked for."""


class WrongFamilyRun(ValueError):
    """The run measured another family's sensor: its results have another view."""


def family_run(catalogue, run_id: int, family: str) -> dict:
    """The run (``"no run N"`` first), or :class:`WrongFamilyRun` when it measured another family's sensor."""
    run = catalogue.run(run_id)
    measured = run.get("family", "cmos")
    if measured != family:
        raise WrongFamilyRun(f"run {run_id} measured a {measured} sensor, not a {family} one: its results have the "
                             f"{measured} view")
    return run


def finite_or_none(value) -> float | None:
    """A number for JSON: None for a missing or non-finite one."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def calibration_record(catalogue, run_id: int, method: str | None) -> dict:
    """The stored calibration `method` of the run (its chosen one when None), the latest if fitted again; raises
    :class:`NoCalibration` when it has none."""
    matches = [c for c in catalogue.calibrations(run_id) if (c["method"] == method if method else c["chosen"])]
    if not matches:
        raise NoCalibration(f"run {run_id} has no {method or 'chosen'} calibration")
    return matches[-1]


def readings_by_point(readings) -> dict[int, list]:
    """Readings of the catalogue (:class:`bench.descriptor.ReadingRecord`) grouped by their point's id."""
    by_point = defaultdict(list)
    for reading in readings:
        by_point[reading.point_id].append(reading)
    return by_point


def split_left_out(rows, reason) -> tuple[list, list[dict], str | None]:
    """``(used, left_out, excluded)`` of a point's readings `rows`: those no fit uses are those `reason(row)`
    names a reason for (None: used), each as ``{"reading_id", "reason"}``; `excluded` joins their reasons when
    every row was left out (None when some was used, or there are none)."""
    left_out = [{"reading_id": r.id, "reason": why} for r in rows if (why := reason(r)) is not None]
    out = {entry["reading_id"] for entry in left_out}
    used = [r for r in rows if r.id not in out]
    excluded = "; ".join(dict.fromkeys(entry["reason"] for entry in left_out)) if rows and not used else None
    return used, left_out, excluded


def _mean_spots(catalogue, run_id: int, rejected: dict[int, str], readings=None) -> list[dict]:
    """The run's points in recording order, each with the mean spot of the frames a fit uses, and what was
    left out: frames clipped at the detector's edge, and those in `rejected` (reading id → reason). `readings`:
    the run's, when the caller has read them already."""
    catalogue.run(run_id)  # "no run N" rather than an empty list
    if readings is None:
        readings = catalogue.readings(run_id)
    spots_of = readings_by_point(r for r in readings if has_spot(r))
    points = []
    for point in catalogue.points(run_id):
        spots = spots_of.get(point["id"], [])
        used, left_out, excluded = split_left_out(
            spots, lambda r: EDGE_REASON if clipped(r) else rejected.get(r.id))
        # a point left out whole is drawn where its spots were, marked as left out
        mean_of = used or spots
        mean = ([sum(r.value(c) for r in mean_of) / len(mean_of) for c in ("x_px", "y_px")] if mean_of
                else [None, None])
        points.append({**point, "n_ok": len(spots), "x_px": mean[0], "y_px": mean[1], "excluded": excluded,
                       "frames_left_out": left_out})
    return points


def point_means(catalogue, run_id: int) -> list[dict]:
    """The run's points in recording order, each with `n_ok` (frames with a spot) and the mean spot (`x_px`,
    `y_px`) of those the fits use (None when it has no spot at all). A point whose every spot was clipped at
    the detector's edge is left out of every fit: its mean is of those spots, and `excluded` says why
    (None for the others); `frames_left_out` lists each clipped frame (`reading_id`, `reason`)."""
    return _mean_spots(catalogue, run_id, {})


def run_points(catalogue, run_id: int) -> list[dict]:
    """:func:`point_means`, each point with its `summary`: what the run's family shows of the point's readings
    live (:attr:`bench.families.Family.summary`, as the engine's ``point`` event carries it: spots, currents …;
    None for a point without readings). No family-specific code here; the readings are read once."""
    from .families import family

    run = catalogue.run(run_id)
    summary = family(run.get("family") or "cmos").summary
    readings = catalogue.readings(run_id)
    by_point = readings_by_point(readings)
    return [{**p, "summary": summary(by_point[p["id"]]) if p["id"] in by_point else None}
            for p in _mean_spots(catalogue, run_id, {}, readings)]


def rejected_readings(document: dict) -> dict[int, str]:
    """The readings (a CMOS run's frames) a calibration rejected as outliers, by reading id (the document's
    ``rejected`` rows), with the reason of each; those without a row (older or CSV-fitted documents) cannot be
    placed and are left."""
    out = {}
    for entry in document.get("rejected") or []:
        if isinstance(entry, dict) and isinstance(entry.get("row"), int):
            out.setdefault(entry["row"], str(entry.get("reason") or "rejected as an outlier"))
    return out


def _finite(values) -> list:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float)]


def fit_residuals(catalogue, run_id: int, method: str | None = None) -> dict:
    """Each point with a spot, seen through one calibration (default: the chosen one): its radius and its
    measured azimuth about the calibration's centre (seed 003 eqs. 7, 10), the direction the calibration gives
    and the residuals (eq. 13). The mean spot is of the frames the fit used; a point the fit left out whole
    (every spot clipped at the detector's edge, or every frame rejected by this calibration) keeps the mean of
    its spots and says why in `excluded`; `frames_left_out` names each frame left out of the point.

    Raises :class:`NoCalibration` when the run has no such calibration; the calibration's own format errors
    (:class:`calibration.errors.CalibrationFormatError`) pass through.
    """
    catalogue.run(run_id)
    record = calibration_record(catalogue, run_id, method)
    points = [p for p in _mean_spots(catalogue, run_id, rejected_readings(record["document"]))
              if p["x_px"] is not None]
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
    data = [{"id": p["id"], "key": p["key"], "stage": p["stage"], "zenith_deg": p["zenith_deg"],
             "azimuth_deg": p["azimuth_body_deg"], "x_px": p["x_px"], "y_px": p["y_px"], "radius_px": float(r),
             "azimuth_spot_deg": float(a), "zenith_fit_deg": zf, "azimuth_fit_deg": af, "zenith_residual_deg": dz,
             "azimuth_residual_deg": da, "error_deg": e, "excluded": p["excluded"],
             "frames_left_out": p["frames_left_out"]}
            for p, r, a, zf, af, dz, da, e in columns]
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]), "x0_px": x0,
            "y0_px": y0, "data": data, "count": len(data)}
