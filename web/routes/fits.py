"""What the result plots need and the stored API lacks: each point seen through one fitted calibration.

Read-only, and no science here: the radius and the predicted directions come from :mod:`calibration`.
"""

from __future__ import annotations

import numpy as np
from fastapi import APIRouter, HTTPException
from pydantic import Field

from calibration.errors import CalibrationFormatError
from calibration.geometry import angular_error_deg, spot_radius_px, wrap_deg
from calibration.models import calibration_from_dict

from ..deps import READ, CatalogueDep
from ..schemas import _Out
from .runs import read_points

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration of it"}})


class FitPointPublic(_Out):
    id: int
    stage: str
    zenith_deg: float = Field(description="True zenith of the point [°]")
    azimuth_deg: float = Field(description="True body azimuth of the point [°]")
    x_px: float
    y_px: float
    radius_px: float = Field(description="Distance of the mean spot from the calibration's centre [px]")
    zenith_fit_deg: float | None = Field(description="Zenith the calibration gives for the mean spot [°]")
    azimuth_fit_deg: float | None
    zenith_residual_deg: float | None = Field(description="Fitted minus true zenith [°]")
    azimuth_residual_deg: float | None = Field(description="Fitted minus true azimuth, wrapped to ±180° [°]")
    error_deg: float | None = Field(description="Angle between the fitted and the true direction [°]")


class FitPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    x0_px: float = Field(description="The calibration's normal-incidence centre [px]")
    y0_px: float
    data: list[FitPointPublic]
    count: int


def _finite(values) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float)]


@router.get("/{run_id}/fit", response_model=FitPublic, summary="Points of a run through one calibration")
def read_fit(run_id: int, catalogue: CatalogueDep, method: str | None = None):
    """The run's points (mean spot of each) with their radius from the calibration's centre, the direction
    the calibration gives, and its residuals: what the zenith-vs-radius and residual plots draw.
    `method` defaults to the chosen calibration."""
    points = [p for p in read_points(run_id, catalogue).data if p.x_px is not None]
    calibrations = catalogue.calibrations(run_id)
    matches = [c for c in calibrations if (c["method"] == method if method else c["chosen"])]
    if not matches:
        raise HTTPException(404, f"run {run_id} has no {method or 'chosen'} calibration")
    record = matches[-1]
    try:
        calibration = calibration_from_dict(record["document"])
    except CalibrationFormatError as exc:
        raise HTTPException(409, str(exc)) from None
    x0, y0 = float(calibration.x0_px), float(calibration.y0_px)
    x = np.array([p.x_px for p in points], dtype=float)
    y = np.array([p.y_px for p in points], dtype=float)
    zenith = np.array([p.zenith_deg for p in points], dtype=float)
    azimuth = np.array([p.azimuth_body_deg for p in points], dtype=float)
    radius = spot_radius_px(x, y, x0, y0) if points else np.empty(0)
    if points:
        with np.errstate(invalid="ignore"):
            zenith_fit, azimuth_fit = (np.asarray(a, dtype=float) for a in calibration.apply(x, y))
            error = angular_error_deg(zenith_fit, azimuth_fit, zenith, azimuth)
    else:
        zenith_fit = azimuth_fit = error = np.empty(0)
    columns = zip(points, radius, _finite(zenith_fit), _finite(azimuth_fit), _finite(zenith_fit - zenith),
                  _finite(wrap_deg(azimuth_fit - azimuth)), _finite(error), strict=True)
    data = [FitPointPublic(id=p.id, stage=p.stage, zenith_deg=p.zenith_deg, azimuth_deg=p.azimuth_body_deg,
                           x_px=p.x_px, y_px=p.y_px, radius_px=float(r), zenith_fit_deg=zf, azimuth_fit_deg=af,
                           zenith_residual_deg=dz, azimuth_residual_deg=da, error_deg=e)
            for p, r, zf, af, dz, da, e in columns]
    return FitPublic(run_id=run_id, method=record["method"], chosen=bool(record["chosen"]), x0_px=x0, y0_px=y0,
                     data=data, count=len(data))
