"""The camera family's results view (seed 001's camera sun sensor): what its tables and plots need.

Read-only, and no science here: :mod:`bench.camera_results` computes it with the calibration core. A run of another
family is refused (409: its results have another view; GET /api/runs/{id} says which, `results_view`).
"""

from __future__ import annotations

from fastapi import APIRouter, HTTPException
from pydantic import Field

from bench.camera_results import camera_fit
from bench.results import NoCalibration, WrongFamilyRun
from calibration.errors import CalibrationFormatError

from ..deps import READ, CatalogueDep, RunId
from ..schemas import _Out

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration of it"},
                              409: {"description": "Not a camera run, or a calibration this version cannot read"}})


class CameraParameterPublic(_Out):
    name: str = Field(description="fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2, k3, rot_x_deg, rot_y_deg, rot_z_deg "
                                  "(the rotation body → camera as a Rodrigues vector)")
    unit: str = Field(description="px, ° or empty (a ratio)")
    value: float
    sd: float | None = Field(description="1σ from the fit's covariance; null for a parameter held fixed")
    fitted: bool


class CameraFitFiguresPublic(_Out):
    n_points: int | None = Field(description="Frames the fit used")
    rms_deg: float | None = Field(description="RMS angular residual of the fit [°]")
    max_deg: float | None = Field(description="Largest angular residual of the fit [°]")
    rms_px: float | None = Field(description="RMS residual distance [px]")
    reduced_chi2: float | None = Field(description="χ² per degree of freedom against the centroid noise")
    noise_px: float | None = Field(description="Centroid noise the χ² is against (the repeat scatter) [px]")


class CameraSchemePublic(_Out):
    scheme: str = Field(description="rings or azimuths")
    left_out: str = Field(description="What each refit left out, in words")
    groups_deg: list[float] = Field(description="The zenith (rings) or azimuth (azimuths) of each group left out [°]")
    n_groups: int
    n_points: int | None = Field(description="Frames predicted by a fit that never saw them")
    rms_deg: float | None
    max_deg: float | None
    worse: bool = Field(description="The scheme with the larger RMS: what the calibration is judged by")


class CameraFiguresPublic(_Out):
    fit: CameraFitFiguresPublic
    held_out: list[CameraSchemePublic] = Field(description="Empty when the fit was not held out")
    worse_scheme: str | None
    heldout_rms_deg: float | None = Field(description="RMS of the worse scheme [°]")
    heldout_max_deg: float | None = Field(description="Largest held-out error of either scheme [°]")


class CameraSummaryPublic(_Out):
    n_points: int
    rms_deg: float | None
    max_deg: float | None
    rms_px: float | None = None


class CameraFrameLeftOutPublic(_Out):
    reading_id: int
    reason: str = Field(description="No spot found in the frame, or its spot at the frame's border (never fitted)")


class CameraPointPublic(_Out):
    id: int
    run_id: int = Field(description="The run that measured it (a resumed run's parent for points it kept)")
    key: str
    stage: str
    zenith_deg: float = Field(description="Zenith the table set, in the body frame: the field angle [°]")
    azimuth_deg: float = Field(description="Body azimuth the table set [°]")
    n_frames: int = Field(description="Frames the fit used")
    x_px: float = Field(description="Mean spot of those frames (of all its spots when `excluded`) [px]")
    y_px: float
    zenith_fit_deg: float | None = Field(description="Zenith the calibration gives for the mean spot [°]")
    azimuth_fit_deg: float | None
    error_deg: float | None = Field(description="Angle between that direction and the one set [°]")
    residual_x_px: float | None = Field(description="Where the calibration puts the direction set, minus the mean "
                                                    "spot (the fit's residual) [px]")
    residual_y_px: float | None
    excluded: str | None = Field(description="Why the fit left the whole point out; null when fitted")
    frames_left_out: list[CameraFrameLeftOutPublic]


class CameraFitPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    created_utc: str | None
    sensor_id: str | None
    width_px: int = Field(description="The frame's size [px]")
    height_px: int
    fov_half_deg: float | None = Field(description="Largest angle from the boresight the frame sees, at its "
                                                   "corners [°]")
    parameters: list[CameraParameterPublic]
    parameters_note: str
    figures: CameraFiguresPublic
    warnings: list[str] = Field(description="What an engineer should know before trusting the calibration")
    frames: CameraSummaryPublic = Field(description="The stored model applied to every frame the fit used again: "
                                                    "the fit's own figures")
    points: CameraSummaryPublic = Field(description="Over the points' mean spots (the excluded ones apart)")
    data: list[CameraPointPublic]
    count: int


@router.get("/{run_id}/camera/fit", response_model=CameraFitPublic, summary="Camera model of a camera run and its "
                                                                             "residuals")
def read_camera_fit(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """The calibration `method` (default the chosen one) of a camera run: OpenCV's camera model and its rotation
    against the body frame with the 1σ of each parameter, the fit's and the held-out figures (whole zenith rings,
    and whole azimuths, left out: the worse scheme marked), the warnings, and every point's mean spot with the
    direction the table set and the calibration's residual (the angle, and the vector in px)."""
    try:
        return camera_fit(catalogue, run_id, method)
    except NoCalibration as exc:
        raise HTTPException(404, str(exc)) from None
    except (WrongFamilyRun, CalibrationFormatError) as exc:
        raise HTTPException(409, str(exc)) from None
