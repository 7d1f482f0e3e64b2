"""The horizon family's results view (seed 004's scanning Earth-horizon sensor): what its plots and tables need.

Read-only, and no science here: :mod:`bench.horizon_results` computes it with the calibration core. A run of another
family is refused (409: its results have another view; GET /api/runs/{id} says which, `results_view`).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query
from pydantic import Field

from bench.horizon_results import NoReading, horizon_attitude, horizon_calibration, horizon_edges, horizon_pulse
from bench.results import NoCalibration, WrongFamilyRun
from calibration.errors import CalibrationFormatError

from ..deps import MAX_ID, READ, CatalogueDep, RunId
from ..schemas import _Out

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration or reading of it"},
                              409: {"description": "Not a horizon run, or a calibration this version cannot read"}})

#: A reading's id in a query, bounded as every id is
ReadingId = Annotated[int | None, Query(ge=1, le=MAX_ID, description="A reading of the run's lineage (default: its "
                                                                     "latest usable scan)")]
#: The calibration drawn
Method = Annotated[str | None, Query(max_length=64, description="A calibration of the run (default: the chosen one)")]


def _answer(compute, *args):
    try:
        return compute(*args)
    except (NoCalibration, NoReading) as exc:
        raise HTTPException(404, str(exc)) from None
    except (WrongFamilyRun, CalibrationFormatError) as exc:
        raise HTTPException(409, str(exc)) from None


# -- the calibration ------------------------------------------------------------------------------------------------
class HorizonParameterPublic(_Out):
    name: str = Field(description="gamma1_deg, gamma2_deg, phase_offset1_deg, phase_offset2_deg, radius_bias_deg, "
                                  "mount_roll_deg, mount_yaw_deg, mount_pitch_deg")
    symbol: str
    words: str = Field(description="What the parameter is")
    unit: str
    value: float
    sd: float | None = Field(description="1σ from the fit's covariance (× its uncertainty scale); null when not fitted")
    fitted: bool
    nominal: float = Field(description="The design's value (γ = 70°, no offset, a perfect mount)")
    difference: float = Field(description="value − nominal [°]")
    difference_sigma: float | None = Field(description="(value − nominal) / sd")


class HorizonNoisePublic(_Out):
    cone: int
    edge: str = Field(description="out (Earth → space) or in (space → Earth)")
    sigma_deg: float | None = Field(description="1σ of one reported phase, from the repeat scatter [°]")
    dof: int | None


class HorizonRejectedPublic(_Out):
    reading_id: int | None
    key: str | None
    stage: str | None
    cone: int | None
    edge: str | None
    roll_deg: float | None
    pitch_deg: float | None
    disc_radius_deg: float | None
    residual_deg: float | None
    reason: str


class HorizonHeldoutPublic(_Out):
    check: dict | None = Field(description="The check scans (never fitted): phase RMS, and roll/pitch errors of the "
                                           "calibrated and the nominal sensor")
    at_nodes: dict | None = Field(description="The fitted scans, likewise")
    radius_out: list[dict] = Field(description="Each disc radius left out of a refit and scored on it")


class HorizonCalibrationPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    created_utc: str | None
    sensor_id: str | None
    parameters: list[HorizonParameterPublic]
    fit: dict = Field(description="chi2_dof, dof, uncertainty_scale, rms_deg, n_scans, n_edges, n_missing, "
                                  "noise_source")
    noise: list[HorizonNoisePublic]
    condition_number: float | None = Field(description="Of the scaled Jacobian")
    trades: list[str] = Field(description="Pairs of parameters the plan does not separate, in words")
    correlation: dict = Field(description="names, matrix: of the fitted parameters")
    warnings: list[str] = Field(description="What an engineer should know before trusting the calibration")
    rejected: list[HorizonRejectedPublic] = Field(description="Edges the fit left out as outliers, and why")
    heldout: HorizonHeldoutPublic
    plan: dict = Field(description="disc_radii_deg, roll_span_deg, pitch_span_deg")
    model: dict = Field(description="The crossing model in words")
    design: dict = Field(description="ifov_half_angle_deg, locator_level: the design's, known, not fitted")


@router.get("/{run_id}/horizon/metrics", response_model=HorizonCalibrationPublic,
            summary="The sensor's own errors of a horizon run")
def read_horizon_calibration(run_id: RunId, catalogue: CatalogueDep, method: Method = None):
    """The calibration `method` (default the chosen one): each parameter ± 1σ beside the nominal design, χ²/dof and
    the noise of each edge, the trades and warnings in words, the rejected edges named, the roll and pitch held out
    (each disc radius left out, the check scans) against the nominal sensor's."""
    return _answer(horizon_calibration, catalogue, run_id, method)


# -- every edge ---------------------------------------------------------------------------------------------------
class HorizonEdgeSummaryPublic(_Out):
    kind: str = Field(description="fitted or check")
    cone: int
    edge: str
    n: int
    rms_deg: float | None = Field(description="RMS residual against the calibration (rejected edges left out) [°]")
    rms_nominal_deg: float | None = Field(description="RMS residual against the nominal sensor [°]")


class HorizonEdgesPublic(_Out):
    """Every edge found, as columns (one entry per edge)."""
    run_id: int
    method: str | None
    chosen: bool | None
    reading_id: list[int]
    key: list[str | None]
    stage: list[str | None]
    check: list[bool]
    cone: list[int]
    edge: list[str] = Field(description="out (Earth → space) or in (space → Earth)")
    roll_deg: list[float] = Field(description="The table's roll [°]")
    pitch_deg: list[float] = Field(description="The table's pitch [°]")
    disc_radius_deg: list[float] = Field(description="The disc radius the Earth simulator reported [°]")
    phase_deg: list[float] = Field(description="The reported phase 360° · t / T [°]")
    residual_deg: list[float | None] = Field(description="Reported − the calibration's predicted phase [°]")
    residual_nominal_deg: list[float | None] = Field(description="Reported − the nominal sensor's predicted phase [°]")
    rejected: list[str | None] = Field(description="Why the fit rejected the edge; null when it used it")
    count: int
    summary: list[HorizonEdgeSummaryPublic]
    fitted_rms_deg: float | None = Field(description="RMS residual of the fitted edges the calibration used")


@router.get("/{run_id}/horizon/edges", response_model=HorizonEdgesPublic,
            summary="Every edge's phase residual of a horizon run")
def read_horizon_edges(run_id: RunId, catalogue: CatalogueDep, method: Method = None):
    """Each edge the module found, with the table's roll and pitch and the disc radius, and its phase residual against
    the calibration `method` (default the chosen one) and against the nominal sensor."""
    return _answer(horizon_edges, catalogue, run_id, method)


# -- roll and pitch of every scan -----------------------------------------------------------------------------------
class HorizonFiguresPublic(_Out):
    n_scans: int
    n_failed: int
    roll_rms_deg: float | None
    roll_max_deg: float | None
    roll_mean_deg: float | None
    pitch_rms_deg: float | None
    pitch_max_deg: float | None
    pitch_mean_deg: float | None


class HorizonSensorsPublic(_Out):
    calibrated: HorizonFiguresPublic | None
    nominal: HorizonFiguresPublic


class HorizonMapPublic(_Out):
    disc_radius_deg: float
    roll_deg: list[float] = Field(description="The grid's rolls (columns)")
    pitch_deg: list[float] = Field(description="The grid's pitches (rows)")
    roll_error_deg: list[list[float | None]] = Field(description="Mean roll error of the calibrated sensor at each "
                                                                 "node [pitch][roll] [°]")
    pitch_error_deg: list[list[float | None]]
    roll_error_nominal_deg: list[list[float | None]]
    pitch_error_nominal_deg: list[list[float | None]]


class HorizonAttitudePublic(_Out):
    """Every scan, as columns (one entry per scan)."""
    run_id: int
    method: str | None
    chosen: bool | None
    reading_id: list[int]
    key: list[str | None]
    stage: list[str | None]
    check: list[bool]
    roll_deg: list[float] = Field(description="The table's roll [°]")
    pitch_deg: list[float]
    disc_radius_deg: list[float]
    sensor_roll_deg: list[float | None] = Field(description="The sensor's own roll from its crossings [°]")
    sensor_pitch_deg: list[float | None]
    roll_error_deg: list[float | None] = Field(description="The calibrated sensor's roll, in the table's frame, − the "
                                                           "table's [°]")
    pitch_error_deg: list[float | None]
    roll_error_nominal_deg: list[float | None] = Field(description="The nominal sensor's, likewise [°]")
    pitch_error_nominal_deg: list[float | None]
    count: int
    summary: dict[str, HorizonSensorsPublic | None] = Field(description="fitted, check")
    maps: list[HorizonMapPublic] = Field(description="One per disc radius: the fitted scans' mean errors")


@router.get("/{run_id}/horizon/attitude", response_model=HorizonAttitudePublic,
            summary="Roll and pitch errors of every scan of a horizon run")
def read_horizon_attitude(run_id: RunId, catalogue: CatalogueDep, method: Method = None):
    """The roll and pitch each scan gives through the calibration `method` (default the chosen one) and through the
    nominal sensor, against the table's; their figures at the fitted and the check scans; maps over the grid."""
    return _answer(horizon_attitude, catalogue, run_id, method)


# -- the pulse of a reading -----------------------------------------------------------------------------------------
class HorizonConePulsePublic(_Out):
    cone: int
    level: list[float | None] = Field(description="The pulse at `phase_deg` [counts]; the covered fraction when the "
                                                  "reading has no levels")
    fraction: list[float | None] = Field(description="The IFOV's covered fraction of the disc (0–1)")
    level_space: float | None = Field(description="The space level the module reported [counts]")
    level_earth: float | None
    threshold: float | None = Field(description="The locator's threshold [counts]")
    levels_reported: bool
    saturated: bool
    detected_deg: dict[str, float | None] = Field(description="out, in: the edges the module reported [°]")
    calibrated_deg: dict[str, float | None] = Field(description="out, in: the calibration's predicted edges [°]")
    nominal_deg: dict[str, float | None] = Field(description="out, in: the nominal sensor's predicted edges [°]")


class HorizonPulsePublic(_Out):
    run_id: int
    method: str | None
    chosen: bool | None
    reading: dict = Field(description="id, key, stage, check, roll_deg, pitch_deg, disc_radius_deg, period_s, "
                                      "temperature_c, revolution")
    phase_deg: list[float] = Field(description="The reported phase of each sample [°]")
    cones: list[HorizonConePulsePublic]
    threshold_fraction: float = Field(description="C1 of the locator the pulse is drawn with (the design's)")
    ifov_half_angle_deg: float
    disc_radius_drawn_deg: float = Field(description="The disc drawn: the model's edge circle widened by the "
                                                             "50 % locator's bias on the curved limb (≈ ρ + Δρ) [°]")
    source: str = Field(description="model: drawn from the calibration (the run keeps no sampled pulse)")


@router.get("/{run_id}/horizon/pulse", response_model=HorizonPulsePublic,
            summary="The pulse of a horizon reading, as the calibration draws it")
def read_horizon_pulse(run_id: RunId, catalogue: CatalogueDep, method: Method = None,
                       reading_id: ReadingId = None):
    """Each cone's pulse over one revolution for a reading (default the latest usable scan), drawn from the
    calibration `method` (default the chosen one) between the levels the module reported, with the locator's threshold,
    the module's detected edges and the edges the calibrated and the nominal sensor predict."""
    return _answer(horizon_pulse, catalogue, run_id, method, reading_id)
