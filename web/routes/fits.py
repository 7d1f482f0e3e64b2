"""What the result plots need and the stored API lacks: each point seen through one fitted calibration.

Read-only, and no science here: :func:`bench.results.fit_residuals` computes it with the calibration core.
"""

from __future__ import annotations

from fastapi import APIRouter, HTTPException
from pydantic import Field

from bench.results import NoCalibration, fit_residuals
from calibration.errors import CalibrationFormatError

from ..deps import READ, CatalogueDep, RunId
from ..schemas import LeftOutFramePublic, _Out

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration of it"}})

#: Where the results of another family's run are (web/routes/qd.py, web/routes/camera.py, web/routes/css.py)
RESULTS_ROUTES = {"qd": "qd/metrics", "camera": "camera/fit", "css": "css/metrics"}


class FitPointPublic(_Out):
    id: int
    key: str
    stage: str
    zenith_deg: float = Field(description="True zenith of the point [°]")
    azimuth_deg: float = Field(description="True body azimuth of the point [°]")
    x_px: float
    y_px: float
    radius_px: float = Field(description="Distance of the mean spot from the calibration's centre [px]")
    azimuth_spot_deg: float = Field(description="Azimuth of the mean spot about the calibration's centre, "
                                                "seed 003 eq. 10, before calibration [°]")
    zenith_fit_deg: float | None = Field(description="Zenith the calibration gives for the mean spot [°]")
    azimuth_fit_deg: float | None
    zenith_residual_deg: float | None = Field(description="Fitted minus true zenith [°]")
    azimuth_residual_deg: float | None = Field(description="Fitted minus true azimuth, wrapped to ±180° [°]")
    error_deg: float | None = Field(description="Angle between the fitted and the true direction [°]")
    excluded: str | None = Field(None, description="Why this calibration's fit left the point out (Table 4.1 "
                                                   "counts it nowhere): \"spot clipped at the detector's edge\", or "
                                                   "the reason it rejected the point's frames; null when fitted")
    frames_left_out: list[LeftOutFramePublic] = Field([], description="The point's frames the fit did not use, "
                                                                      "and why (its mean spot is of the others)")


class FitPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    x0_px: float = Field(description="The calibration's normal-incidence centre [px]")
    y0_px: float
    data: list[FitPointPublic]
    count: int


@router.get("/{run_id}/fit", response_model=FitPublic, summary="Points of a run through one calibration")
def read_fit(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """The run's points (mean spot of each) with their radius from the calibration's centre, the direction
    the calibration gives, and its residuals: what the zenith-vs-radius and residual plots draw.
    `method` defaults to the chosen calibration. A spot-sensor (cmos) view: a run of another family is 409 (a QD
    run's figures are under ``/api/runs/{id}/qd/…``, a camera run's at ``/api/runs/{id}/camera/fit``)."""
    family = catalogue.run(run_id)["family"]
    if family != "cmos":
        raise HTTPException(409, f"run {run_id} measured a {family} sensor: its results are not spot fits "
                                 f"(see /api/runs/{run_id}/{RESULTS_ROUTES.get(family, f'{family}/metrics')})")
    try:
        return FitPublic(**fit_residuals(catalogue, run_id, method))
    except NoCalibration as exc:
        raise HTTPException(404, str(exc)) from None
    except CalibrationFormatError as exc:
        raise HTTPException(409, str(exc)) from None
