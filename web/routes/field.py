"""Field data (issue 13): a field CSV posted whole, set against the real Sun, and the site located from it.

Read-only, and no science here: :func:`bench.field_analysis.analyse_field_csv` compares the readings with SPA and
locates the site. It takes up to a few seconds of CPU, so the route is a plain ``def`` (FastAPI runs it in its
thread pool, never on the event loop), and at most :data:`CONCURRENT_ANALYSES` run at once, so a few uploads
cannot starve the bench's own threads. A field file is larger than any other request: the guard takes up to
:attr:`~web.settings.WebSettings.field_max_body_bytes` under ``/api/field/`` (:mod:`web.guard`).

A file or a calibration it cannot use is 422 with the analysis' own message, which names the file, the row and
the column.
"""

from __future__ import annotations

import math
import threading
from typing import Any, Literal

import numpy as np
from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, ConfigDict, Field

from bench.datafile import DataFileError
from calibration.errors import CalibrationError

from ..deps import READ

router = APIRouter(prefix="/api/field", tags=["field"], dependencies=READ,
                   responses={413: {"description": "A body over WebSettings.field_max_body_bytes (4 MiB)"},
                              422: {"description": "A file or a calibration the analysis cannot use: the "
                                                   "message names the row and the column"}})

#: Analyses running at once; further requests wait for one to end
CONCURRENT_ANALYSES = 2
_slots = threading.BoundedSemaphore(CONCURRENT_ANALYSES)


class FieldAnalyseRequest(BaseModel):
    """A field CSV and how to read it (README, "Field data CSV")."""

    # strict, as the commands: a number is a JSON number, a switch true or false, no field the API does not know
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    csv: str = Field(min_length=1, description="The field CSV's text, header comments included")
    calibration: dict[str, Any] | None = Field(None, description="A calibration document (the calibration JSON "
                                                                 "download) turning the file's spots into "
                                                                 "directions; null when the file gives directions")
    heading: Literal["file", "fit"] = Field("file", description="\"file\": the heading in the file's header; "
                                                                "\"fit\": unknown, fitted to the track (the azimuth "
                                                                "error then is relative)")
    level: Literal["file", "fit"] = Field("file", description="\"file\": the mount's roll and pitch in the header; "
                                                              "\"fit\": fitted to the track")
    locate: bool = Field(True, description="Also locate the site (latitude, longitude, heading) from the track")
    fov_half_deg: float | None = Field(None, gt=0, le=90, description="Half field of view [°]: samples beyond it "
                                                                      "are out of the field; null: the file's")
    level_sd_deg: float | None = Field(None, gt=0, le=10, description="1σ of the file's roll and pitch [°] (the "
                                                                      "inclinometer's accuracy): the located site's "
                                                                      "uncertainty then includes the level's; null: "
                                                                      "the level is taken as exact")
    name: str = Field("upload.csv", min_length=1, max_length=255, description="The file's name, for the messages")


# -- the answer: documented for the schema; any key the analysis adds passes through -------------------------
class _Open(BaseModel):
    model_config = ConfigDict(extra="allow")


Numbers = list[float | None]


class FieldSitePublic(_Open):
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    altitude_m: float | None = None


class FieldStatsPublic(_Open):
    n: int = 0
    rms_zenith_deg: float | None = None
    rms_azimuth_deg: float | None = None
    rms_vector_deg: float | None = None
    std_vector_deg: float | None = None
    max_vector_deg: float | None = None


class FieldHeadingPublic(_Open):
    deg: float | None = Field(None, description="The heading used [°, east of north]")
    sd_deg: float | None = Field(None, description="Its 1σ when fitted [°]")
    fitted: bool = False


class FieldLevelPublic(_Open):
    roll_deg: float | None = None
    pitch_deg: float | None = None
    fitted: bool = False


class FieldComparisonPublic(_Open):
    time_utc: list[str] = []
    sun_zenith_deg: Numbers = Field([], description="SPA's apparent zenith [°]")
    sun_azimuth_deg: Numbers = Field([], description="SPA's azimuth, east of north [°]")
    measured_zenith_deg: Numbers = []
    measured_azimuth_deg: Numbers = []
    zenith_error_deg: Numbers = Field([], description="Measured − SPA [°]; null where the sensor gave none")
    azimuth_error_deg: Numbers = Field([], description="Measured − SPA, wrapped to ±180° [°] (relative when the "
                                                       "heading is fitted)")
    vector_error_deg: Numbers = Field([], description="Angle between the measured and SPA's direction [°]")
    clear: list[bool] = Field([], description="Valid readings not flagged as cloud (the stats of `clear` count "
                                              "those with the Sun in the field of view)")
    in_fov: list[bool] = []
    cloud: list[bool] = []
    heading: FieldHeadingPublic | None = None
    level: FieldLevelPublic | None = Field(None, description="The mount's roll and pitch used [°]")
    stats: dict[str, FieldStatsPublic] = Field({}, description="`clear`: clear sky, the Sun in the field of view; "
                                                               "`all`: every valid reading with the Sun in the field "
                                                               "of view, cloudy ones too")
    notes: list[str] = []
    warnings: list[str] = []


class FieldEllipsePublic(_Open):
    latitude_deg: Numbers = []
    longitude_deg: Numbers = []


class FieldLocationPublic(_Open):
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    heading_deg: float | None = None
    sd_latitude_km: float | None = None
    sd_longitude_km: float | None = None
    sd_heading_deg: float | None = None
    ellipse: FieldEllipsePublic | None = Field(None, description="The uncertainty ellipse, a closed polygon")
    ellipse_level: str | None = Field(None, description="Its level in words (\"1σ\", \"95 %\")")
    semi_axes_km: list[float | None] | None = Field(None, description="The 1σ ellipse's semi-axes [km]")
    error_km: float | None = Field(None, description="Distance to the site the file states, when it states one")
    n: int | None = None
    residual_rms_deg: float | None = None
    warnings: list[str] = []


class FieldAnalysisPublic(_Open):
    name: str
    n: int = Field(description="Rows of the file")
    notes: list[str] = Field([], description="How the file was read (refraction, cloud flags …), in words")
    site: FieldSitePublic | None = Field(None, description="The site the file's header states")
    comparison: FieldComparisonPublic | None = Field(None, description="The readings against SPA")
    location: FieldLocationPublic | None = Field(None, description="The site located from the track")


def plain(value):
    """`value` as plain JSON data: numpy arrays and scalars as lists and numbers, NaN and ±inf as null."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@router.post("/analyse", response_model=FieldAnalysisPublic, summary="Field data against the real Sun")
def analyse_field(request: FieldAnalyseRequest):
    """The field CSV's readings against SPA's Sun (zenith, azimuth and vector errors over time, their statistics
    in clear sky and over all samples) and, with `locate`, the site and heading found from the Sun's track with
    their uncertainty ellipse, and how far that is from the site the file states. Arrays hold null where a value
    is not a number."""
    from bench.field_analysis import analyse_field_csv  # imported here: it loads the solar-position code

    with _slots:
        try:
            result = analyse_field_csv(request.csv, calibration=request.calibration, heading=request.heading,
                                       level=request.level, locate=request.locate,
                                       fov_half_deg=request.fov_half_deg, level_sd_deg=request.level_sd_deg,
                                       name=request.name)
        except (DataFileError, CalibrationError) as exc:
            raise HTTPException(422, str(exc)) from None
    return plain(result)
