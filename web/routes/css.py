"""The CSS family's results view (seed 000's coarse-sun-sensor head): what its plots and tables need.

Read-only, and no science here: :mod:`bench.css_results` computes it with the calibration core. A run of another
family is refused (409: its results have another view; GET /api/runs/{id} says which, `results_view`).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query
from pydantic import Field

from bench.css_results import NoReading, css_codes, css_detectors, css_directions, css_methods
from bench.results import NoCalibration, WrongFamilyRun
from calibration.errors import CalibrationFormatError

from ..deps import MAX_ID, READ, CatalogueDep, RunId
from ..schemas import _Out

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration or reading of it"},
                              409: {"description": "Not a CSS run, or a calibration this version cannot read"}})

#: A reading's id in a query, bounded as every id is
ReadingId = Annotated[int | None, Query(ge=1, le=MAX_ID, description="A reading of the run's lineage (default: its "
                                                                     "latest lit reading)")]


def _answer(compute, *args):
    try:
        return compute(*args)
    except (NoCalibration, NoReading) as exc:
        raise HTTPException(404, str(exc)) from None
    except (WrongFamilyRun, CalibrationFormatError) as exc:
        raise HTTPException(409, str(exc)) from None


# -- every response law's figures --------------------------------------------------------------------------------
class CssSunFiguresPublic(_Out):
    n_points: int | None = Field(None, description="Readings scored (two or more non-coplanar faces lit)")
    n_degenerate: int | None = Field(None, description="Readings lighting fewer than two non-coplanar faces: their "
                                                       "direction is not determined (not scored)")
    n_failed: int | None = Field(None, description="Readings without an estimate (no detector lit)")
    rms_deg: float | None = None
    p95_deg: float | None = None
    max_deg: float | None = None
    normalised_rms: float | None = Field(None, description="RMS of the error over the estimator's stated 1σ (≈ 1 "
                                                           "when the stated uncertainty is honest)")


class CssMethodPublic(_Out):
    id: int
    method: str = Field(description="The response law fitted: kelly or power")
    chosen: bool
    created_utc: str
    error: str | None = None
    held_out: CssSunFiguresPublic | None = Field(None, description="The Sun's direction from readings of directions "
                                                                   "left out of the fit (folds refitted): what the "
                                                                   "law is judged by")
    check: CssSunFiguresPublic | None = Field(None, description="At the check directions (never fitted)")
    at_nodes: CssSunFiguresPublic | None = Field(None, description="At the fitted directions")
    heldout_scheme: str | None = None
    n_channels: int = Field(description="Detectors calibrated")
    faulty: dict[str, str] = Field({}, description="Detectors left out, and their fault")
    n_rejected: int | None = None


class CssFaultyPublic(_Out):
    channel: str
    fault: str | None = Field(description="stuck, dead, saturated, inverted or unlit")
    words: str = Field(description="What the fit found, in words")


class CssRejectedPublic(_Out):
    row: int | None = Field(None, description="The reading's id")
    channel: str | None = Field(None, description="The detector whose reading was rejected (the others stand)")
    key: str | None = Field(None, description="Its point")
    stage: str | None = None
    zenith_deg: float | None = None
    azimuth_deg: float | None = None
    reason: str


class CssMetricsPublic(_Out):
    run_id: int
    chosen: str | None
    data: list[CssMethodPublic]
    count: int
    warnings: list[str] = Field(description="What an engineer should know before trusting the calibration")
    faulty: list[CssFaultyPublic] = Field(description="Detectors the chosen calibration left out, in words")
    missing: list[str] = Field(description="Detectors the chosen calibration has no entry for")
    rejected: list[CssRejectedPublic] = Field(description="Single readings of a detector the fit left out, and why")
    uncertainty_scale: float | None = Field(description="The factor the stated 1σ of a direction is multiplied by "
                                                        "(the held-out error over the stated 1σ, when above 1)")


@router.get("/{run_id}/css/metrics", response_model=CssMetricsPublic, summary="Figures of every CSS calibration")
def read_css_metrics(run_id: RunId, catalogue: CatalogueDep):
    """Every response law fitted to the run with the Sun's direction error held out, at the check directions and at
    the fitted ones (the chosen law marked); of the chosen calibration its warnings, its faulty detectors in words and
    the readings it rejected."""
    return _answer(css_methods, catalogue, run_id)


# -- every detector ---------------------------------------------------------------------------------------------
class CssPointsPublic(_Out):
    """A detector's readings with the Sun in front of it, as columns (one entry per reading)."""
    reading_id: list[int]
    incidence_deg: list[float | None] = Field(description="Angle between the Sun and the detector's calibrated normal "
                                                          "(the face's nominal one when not calibrated) [°]")
    signal: list[float | None] = Field(description="Raw reading, offset included [A or V]")
    residual: list[float | None] = Field(description="Reading − the calibration's model [A or V]; null without one")
    temperature_c: list[float | None]
    group: list[int] = Field(description="Its plate temperature: an index of `temperatures_c`")
    check: list[bool] = Field(description="A check reading (never fitted)")
    left_out: list[str | None] = Field(description="Why the fit left the reading out; null when it used it")


class CssCountPublic(_Out):
    n: int
    rms_residual: float | None = Field(description="RMS residual of those the fit used [A or V]")


class CssCurvePublic(_Out):
    signals: list[list[float | None]] = Field(description="The model against `incidence_deg`, one list per "
                                                          "temperature of `temperatures_c` [A or V]")
    noise_sd: list[float | None] = Field(description="1σ noise of one reading on the curve at the reference "
                                                     "temperature [A or V]")
    snr_db: list[float | None] = Field(description="20 log10((signal − offset)/noise) at the reference temperature")


class CssParameterPublic(_Out):
    name: str = Field(description="scale, bias, tilt_u_deg, tilt_v_deg, kappa or power, fov_half_deg (null: no "
                                  "cut-off), temp_coeff_per_c, bias_temp_coeff_per_c")
    unit: str
    value: float | None
    sd: float | None = Field(description="1σ from the fit's covariance; null when held or not determined")
    fitted: bool


class CssNormalPublic(_Out):
    zenith_deg: float | None
    azimuth_deg: float | None
    sd_deg: float | None = Field(description="1σ of the normal's direction [°]")


class CssScorePublic(_Out):
    n_points: int | None = None
    rms: float | None = Field(None, description="RMS residual [A or V]")
    rms_normalised: float | None = Field(None, description="RMS residual over the noise [σ]")


class CssDiodePublic(_Out):
    channel: str
    face: str
    thesis_face: int = Field(description="The thesis' face number 1 … 6")
    detector: str = Field(description="uv (EPD-365), vis (BPW 21) or ir (TPS 230)")
    unit: str = Field(description="A (photodiodes) or V (thermopile)")
    valid: bool = Field(description="Calibrated (false: faulty, or no calibration)")
    fault: str | None
    warnings: list[str]
    statements: list[str] = Field(description="What the fit fitted and held, and why")
    points: CssPointsPublic
    count: int
    behind: CssCountPublic = Field(description="Readings with the Sun behind the detector")
    dark: CssCountPublic = Field(description="Shutter-closed readings")
    rms_residual: float | None = Field(description="RMS residual of the readings the fit used, computed here")
    n_fitted: int
    curve: CssCurvePublic | None
    parameters: list[CssParameterPublic]
    normal: CssNormalPublic | None
    fit: dict | None = Field(description="The document's chi2_dof, rms, rms_normalised, n_points, temperature_fitted, "
                                         "fov_fitted")
    noise: dict | None = Field(description="The noise model σ² = sigma0² + shot·|m| + (relative·m)², and the "
                                           "model's own error `model`")
    at_nodes: CssScorePublic | None
    heldout: CssScorePublic | None = Field(description="Residuals at directions left out of the fit")


class CssDetectorsPublic(_Out):
    run_id: int
    method: str | None = Field(description="The calibration drawn; null when the run has none")
    chosen: bool | None
    response: str | None
    reference_temperature_c: float
    temperatures_c: list[float] = Field(description="The plate temperatures the curves are drawn at")
    main_temperature: int = Field(description="The index of `temperatures_c` with the most lit readings (the full "
                                              "sweep's)")
    incidence_deg: list[float | None] = Field(description="The curves' incidence angles [°]")
    incidence_limit_deg: float
    n_readings: int
    data: list[CssDiodePublic]
    count: int


@router.get("/{run_id}/css/detectors", response_model=CssDetectorsPublic, summary="Every detector of a CSS run")
def read_css_detectors(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """Each of the head's 18 detectors through the calibration `method` (default the chosen one): its readings against
    the incidence on its calibrated normal with their residuals, the fitted curve (its noise and SNR), its parameters
    ± 1σ, its held-out residuals and warnings, or the fault that left it out."""
    return _answer(css_detectors, catalogue, run_id, method)


# -- the Sun's direction from each reading ------------------------------------------------------------------------
class CssDirectionPublic(_Out):
    reading_id: int
    key: str
    stage: str
    kind: str = Field(description="\"fitted\" (a sweep reading) or \"check\" (never fitted)")
    temperature_c: float | None
    zenith_deg: float | None = Field(description="True body zenith [°]")
    azimuth_deg: float | None
    az_deg: float | None = Field(description="True thesis azimuth [°]")
    el_deg: float | None = Field(description="True thesis elevation [°]")
    zenith_fit_deg: float | None
    azimuth_fit_deg: float | None
    az_fit_deg: float | None
    el_fit_deg: float | None
    sigma_deg: float | None = Field(description="The estimator's stated 1σ cone [°]; null when undetermined")
    sigma_scaled_deg: float | None = Field(description="× the calibration's uncertainty scale [°]")
    sigma_major_deg: float | None
    sigma_minor_deg: float | None
    error_deg: float | None = Field(description="Angle to the true direction [°]")
    n_faces_lit: int
    degenerate: bool
    ambiguous: bool
    failed: bool


class CssDirectionsSummaryPublic(_Out):
    fitted: CssSunFiguresPublic | None = Field(description="Over the fitted readings: the document's at_nodes")
    check: CssSunFiguresPublic | None = Field(description="Over the check readings: the document's check")
    heldout: CssSunFiguresPublic | None = Field(description="The document's held-out figures (folds refitted)")


class CssDirectionsPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    uncertainty_scale: float
    summary: CssDirectionsSummaryPublic
    data: list[CssDirectionPublic]
    count: int


@router.get("/{run_id}/css/directions", response_model=CssDirectionsPublic,
            summary="The Sun's direction from every reading of a CSS run")
def read_css_directions(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """The calibration `method` (default the chosen one) applied to every lit reading (the readings it rejected left
    out): the estimated direction ± its stated 1σ and its angle to the true one, at the fitted and the check
    directions."""
    return _answer(css_directions, catalogue, run_id, method)


# -- the thesis' quantiser codes -----------------------------------------------------------------------------------
class CssSunPublic(_Out):
    az_deg: float | None
    el_deg: float | None
    zenith_deg: float | None
    azimuth_deg: float | None
    error_deg: float | None = Field(description="Angle to the true direction [°]")


class CssCodesPublic(_Out):
    inputs: dict[str, list[float | None]] = Field(description="epd_a, bpw_a: the currents quantised, faces 1 … 6 [A]")
    matrices: dict[str, list[str]] = Field(description="EPDsun, BPWsun: five rows (bits MSB → LSB), a column per "
                                                       "face 1 … 6, x where not processed")
    codes: dict[str, list[int]] = Field(description="The same as ints, −1 where not processed")
    sun: dict[str, CssSunPublic] = Field(description="epd, bpw: the Sun from each detector type")
    sun_faces_epd: list[int]
    sun_faces_bpw: list[int]
    offsets_subtracted: bool
    tables: list[str] = []


class CssFaceCodesPublic(_Out):
    face: str
    thesis_face: int
    epd_incidence_deg: float | None = Field(description="True incidence on the face's EPD normal [°]")
    epd_true_code: int = Field(description="The code a noise-free detector would read there")
    epd_true_bits: str
    epd_clipped: bool
    bpw_incidence_deg: float | None
    bpw_true_code: int
    bpw_true_bits: str
    bpw_clipped: bool


class CssReadingPublic(_Out):
    id: int
    key: str
    stage: str
    temperature_c: float
    zenith_deg: float | None
    azimuth_deg: float | None
    az_deg: float | None = Field(description="True thesis azimuth [°]")
    el_deg: float | None = Field(description="True thesis elevation [°]")
    clipped: list[str]


class CssEstimatePublic(_Out):
    zenith_deg: float | None
    azimuth_deg: float | None
    az_deg: float | None
    el_deg: float | None
    sigma_deg: float | None
    sigma_major_deg: float | None
    sigma_minor_deg: float | None
    degenerate: bool
    n_faces_lit: int
    error_deg: float | None
    words: str


class CssQuantiserPublic(_Out):
    run_id: int
    method: str | None
    chosen: bool | None
    reading: CssReadingPublic
    faces: list[CssFaceCodesPublic]
    variants: dict[str, CssCodesPublic] = Field(description="listing: listing D.6's tables on the photocurrents; "
                                                            "calibrated: the tables rebuilt from the calibration")
    estimate: CssEstimatePublic | None = Field(description="The calibration's least-squares direction ± 1σ")
    quantisation_deg: float = Field(description="Half a code's bin [°]")
    tps_shown: bool
    tps_note: str


@router.get("/{run_id}/css/quantiser", response_model=CssQuantiserPublic,
            summary="The thesis' quantiser codes of a CSS reading")
def read_css_quantiser(run_id: RunId, catalogue: CatalogueDep, method: str | None = None,
                       reading_id: ReadingId = None):
    """Seed 000's 5×6 code matrices (listings D.5/D.6) of one reading (default the latest lit one) with listing D.6's
    tables and with tables rebuilt from the calibration `method` (default the chosen one), the Sun's azimuth and
    elevation they give, beside the truth and the calibration's least-squares estimate ± 1σ. The thermopiles' codes
    are not computed (`tps_note` says why)."""
    return _answer(css_codes, catalogue, run_id, method, reading_id)
