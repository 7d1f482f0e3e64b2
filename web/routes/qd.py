"""The QD family's results view (seed 002's quadrant-photodiode sensor): what its plots and tables need.

Read-only, and no science here: :mod:`bench.qd_results` computes it with the calibration core. A run of another
family is refused (409: its results have another view; GET /api/runs/{id} says which, `results_view`).
"""

from __future__ import annotations

from fastapi import APIRouter, HTTPException
from pydantic import Field

from bench.qd_results import qd_currents, qd_dark, qd_error_map, qd_metrics
from bench.results import NoCalibration, WrongFamilyRun
from calibration.errors import CalibrationFormatError

from ..deps import READ, CatalogueDep, RunId
from ..schemas import RejectedReadingPublic, _Out

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run, or no such calibration of it"},
                              409: {"description": "Not a QD run, or a calibration this version cannot read"}})


def _answer(compute, *args):
    try:
        return compute(*args)
    except NoCalibration as exc:
        raise HTTPException(404, str(exc)) from None
    except (WrongFamilyRun, CalibrationFormatError) as exc:
        raise HTTPException(409, str(exc)) from None


# -- currents ---------------------------------------------------------------------------------------------------
class QdPointPublic(_Out):
    id: int
    run_id: int = Field(description="The run that measured it (a resumed run's parent for points it kept)")
    index: int = Field(description="Its place in the lineage's recording order, from 1")
    key: str
    stage: str = Field(description="dark (shutter closed), grid (a fitted node) or check (between the nodes)")
    zenith_deg: float | None = Field(description="True zenith in the body frame [°]; null at a dark point")
    azimuth_deg: float | None = Field(description="True body azimuth [°]; null at a dark point")
    alpha_deg: float | None = Field(description="True projection angle α (seed 002 eq. 2.2) [°]; null at a dark point")
    beta_deg: float | None = Field(description="True projection angle β [°]; null at a dark point")
    currents_a: list[float] | None = Field(description="Mean raw current of quadrants 1…4, dark current included, "
                                                       "over the readings without a clipped channel [A]")
    sum_a: float | None = Field(description="Their sum [A]")
    temperature_c: float | None = Field(description="Mean die temperature [°C]")
    n_readings: int
    n_ok: int = Field(description="Readings without a clipped channel")
    n_saturated: int = Field(description="Readings with a channel at full scale (never fitted)")


class QdCurrentsPublic(_Out):
    run_id: int
    data: list[QdPointPublic]
    count: int


@router.get("/{run_id}/qd/currents", response_model=QdCurrentsPublic, summary="Quadrant currents of a QD run")
def read_qd_currents(run_id: RunId, catalogue: CatalogueDep):
    """Every point of the run's lineage, dark sweep first, with its true direction (α, β) and the mean current of
    each quadrant and their sum: what the currents plots draw."""
    return _answer(qd_currents, catalogue, run_id)


# -- dark current ---------------------------------------------------------------------------------------------
class QdDarkReadingPublic(_Out):
    reading_id: int
    key: str
    temperature_c: float | None
    currents_a: list[float] | None = Field(description="Raw current of quadrants 1…4, shutter closed [A]")
    left_out: str | None = Field(description="Why the dark fit left the reading out; null when it used it")


class QdDarkCurvePublic(_Out):
    temperature_c: list[float]
    currents_a: list[list[float]] = Field(description="The model's dark current of quadrants 1…4 at each "
                                                      "temperature [A]")


class QdDarkPublic(_Out):
    run_id: int
    method: str | None = Field(description="The calibration whose dark model this is; null when the run has none")
    chosen: bool | None
    source: str | None = Field(description="\"calibration\": the document's model; \"readings\": fitted here to "
                                           "the dark readings (a dark sweep alone has no calibration); null: none")
    model: str | None = Field(description="none, constant, linear (seed 002 §2.1) or exponential")
    t_ref_c: float | None = None
    quadrants: list[dict] = Field([], description="Each quadrant's parameters, {name: {value, sd}}: id0_a, kd_a_per_c "
                                                  "(linear), a_a, c_a, b_per_c (exponential)")
    residual_sd_a: list[float | None] = Field([], description="Residual standard deviation per quadrant [A]")
    note: str | None = Field(None, description="How the model was chosen, in words")
    temperature_range_c: list[float | None] | None = None
    curve: QdDarkCurvePublic | None = Field(description="The model sampled over the run's temperatures")
    readings: list[QdDarkReadingPublic]
    count: int
    dark_range_c: list[float] | None = Field(description="Temperatures of the dark readings used [°C]")
    light_range_c: list[float] | None = Field(description="Temperatures of the lit readings [°C]: outside "
                                                          "`dark_range_c` the dark current is extrapolated")


@router.get("/{run_id}/qd/dark", response_model=QdDarkPublic, summary="Dark-current fit of a QD run")
def read_qd_dark(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """The dark readings (each quadrant's current against the die's temperature) and the dark model through them:
    that of the calibration `method` (default the chosen one), else the model fitted here to the readings."""
    return _answer(qd_dark, catalogue, run_id, method)


# -- error map ----------------------------------------------------------------------------------------------
class LeftOutReadingPublic(_Out):
    reading_id: int
    reason: str


class QdDirectionPublic(_Out):
    id: int
    key: str
    stage: str
    kind: str = Field(description="\"node\": fitted, its error is at the nodes; \"check\": between the nodes, "
                                  "never fitted, its error is held out")
    alpha_deg: float = Field(description="True α [°]")
    beta_deg: float = Field(description="True β [°]")
    zenith_deg: float
    azimuth_deg: float
    n_readings: int = Field(description="Readings averaged (those the fit used)")
    alpha_fit_deg: float | None = Field(None, description="α the calibration gives [°]; null where it gives none")
    beta_fit_deg: float | None = None
    zenith_fit_deg: float | None = None
    azimuth_fit_deg: float | None = None
    error_deg: float | None = Field(None, description="Angle between the calibrated and the true direction [°]")
    excluded: str | None = Field(None, description="Why the fit left the whole direction out; null when fitted")
    readings_left_out: list[LeftOutReadingPublic] = []


class QdErrorSummaryPublic(_Out):
    n_points: int
    n_failed: int = Field(description="Directions the calibration gave no direction for")
    max_deg: float | None
    rms_deg: float | None


class QdErrorMapPublic(_Out):
    run_id: int
    method: str
    chosen: bool
    field_deg: float | None = Field(description="Largest |α| or |β| of the directions [°]")
    summary: dict[str, QdErrorSummaryPublic] = Field(description="`node` (the document's at-node figures) and "
                                                                 "`check` (its held-out check-point figures)")
    data: list[QdDirectionPublic]
    count: int


@router.get("/{run_id}/qd/error-map", response_model=QdErrorMapPublic, summary="Angular error of a QD calibration "
                                                                                "over the field")
def read_qd_error_map(run_id: RunId, catalogue: CatalogueDep, method: str | None = None):
    """The stored calibration `method` (default the chosen one) applied to the readings of every lit direction,
    as its fit scored them: the angle between the direction it gives and the true one, at the fitted grid
    nodes and at the check points between them (held out)."""
    return _answer(qd_error_map, catalogue, run_id, method)


# -- metrics ------------------------------------------------------------------------------------------------
class QdAngularPublic(_Out):
    n_points: int | None = None
    n_failed: int | None = None
    max_deg: float | None = None
    rms_deg: float | None = None
    p99_deg: float | None = None
    rms_alpha_deg: float | None = None
    rms_beta_deg: float | None = None


class QdMethodPublic(_Out):
    id: int
    method: str
    chosen: bool
    created_utc: str
    error: str | None = None
    heldout: QdAngularPublic | None = Field(None, description="The worst held-out scheme, by its largest error: "
                                                              "what the method is judged by")
    heldout_scheme: str | None = Field(None, description="check (points between the nodes), columns or rows "
                                                         "(grid lines left out), checkerboard")
    heldout_by_scheme: dict[str, QdAngularPublic] = {}
    at_nodes: QdAngularPublic | None = None
    chi2_dof: float | None = Field(None, description="χ² per degree of freedom against the repeat scatter")


class QdRejectedPublic(RejectedReadingPublic):
    """A reading the fit rejected (:class:`~web.schemas.RejectedReadingPublic`), with its point."""
    key: str | None = Field(None, description="Its point")
    stage: str | None = None


class QdMetricsPublic(_Out):
    run_id: int
    chosen: str | None
    data: list[QdMethodPublic]
    count: int
    rejected: list[QdRejectedPublic] = Field(description="Readings the fit left out, and why")
    warnings: list[str] = Field(description="What an engineer should know before trusting the calibration")
    dark_model: str | None = None
    dark_note: str | None = None


@router.get("/{run_id}/qd/metrics", response_model=QdMetricsPublic, summary="Figures of every QD method")
def read_qd_metrics(run_id: RunId, catalogue: CatalogueDep):
    """Every method fitted to the run (held out between the nodes, at the nodes, χ²/dof; the chosen one marked),
    the readings the fit rejected and its warnings."""
    return _answer(qd_metrics, catalogue, run_id)
