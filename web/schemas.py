"""What enters and leaves the API. Input, storage and output never share a class; the catalogue's dicts
are validated into these on the way out, so the OpenAPI schema says what a client gets."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, computed_field

from bench.campaign import Campaign

from .family import results_view

CampaignCreate = Campaign  # the campaign file's own model: the API accepts exactly what a YAML file may say


class _Out(BaseModel):
    model_config = ConfigDict(extra="ignore")


class Message(_Out):
    message: str


# -- status -----------------------------------------------------------------------------------------------
class TablePublic(_Out):
    azimuth_deg: float
    zenith_deg: float
    moving: bool = False


class EnginePublic(_Out):
    model_config = ConfigDict(extra="allow")
    state: str = Field(description="idle, running, pausing, paused, suspended, aborting, faulted, or estop: an "
                                   "emergency stop, latched until acknowledged (POST /api/stop/acknowledge)")
    run_id: int | None = None
    sensor_id: str | None = None
    index: int | None = None
    total: int | None = None
    eta_s: float | None = None
    ended_unsafe: str | None = Field(None, description="Set when the run ended without the bench made safe "
                                                      "(the shutter did not close …): what was not, in words")


class SensorStatusPublic(_Out):
    temperature_c: float | None = None
    exposure_ms: float | None = None
    width_px: int | None = Field(None, description="Width of the sensor's frames [px]")
    height_px: int | None = Field(None, description="Height of the sensor's frames [px]")
    family: str | None = Field(None, description="The sensor's family (cmos, qd …)")
    currents_a: list[float] | None = Field(None, description="Of a photodiode sensor (qd): its latest current per "
                                                             "quadrant, dark current included [A]")


class MountPublic(_Out):
    """A sensor the bench waits for the operator to mount and confirm (between the sensors of a fleet)."""
    campaign_id: int | None = None
    sensor_id: str = Field(description="Serial of the sensor to mount")
    position: int = Field(description="Its place in the campaign's queue, from 0")
    count: int = Field(description="Sensors in the campaign's queue")
    resumes_run: int | None = Field(None, description="The run of this sensor its run will resume")
    prompt: str = Field(description="What to do, in words")


class BenchPublic(_Out):
    simulated: bool = Field(description="The devices are simulated: nothing real moves, lights or measures")
    time_scale: float | None = Field(None, description="Of a simulated bench: bench seconds per wall-clock second "
                                                       "(100: a bench hour takes 36 s; 0: every wait is skipped)")
    family: str | None = Field(None, description="The sensor family on the bench (cmos, qd …): what its runs measure")
    family_title: str | None = Field(None, description="The family in words")
    plans: list[str] | None = Field(None, description="The campaign plans this bench runs (its family's)")
    has_frames: bool | None = Field(None, description="Its sensor takes image frames (GET /api/frame.png)")


class StatusPublic(_Out):
    engine: EnginePublic
    bench: BenchPublic | None = None
    mount: MountPublic | None = Field(None, description="The sensor mount awaited (POST /api/run/mount), if any")
    table: TablePublic | None = None
    source: dict[str, Any] | None = None
    sensor: SensorStatusPublic | None = None
    error: str | None = None
    updated_utc: str | None = None


class SpotPublic(_Out):
    x_px: float | None = None
    y_px: float | None = None
    peak_dn: float | None = None
    error: str | None = Field(None, description="The centroid's failure, when the frame has no usable spot")


# -- commands ---------------------------------------------------------------------------------------------
class _Command(BaseModel):
    # strict: a number is a JSON number (never true, "10" or NaN), a switch is true or false (never 1 or "yes")
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class JogCommand(_Command):
    azimuth_deg: float = Field(description="Azimuth of the table to go to [°]")
    zenith_deg: float = Field(description="Zenith stage angle to go to [°]")


class LampCommand(_Command):
    on: bool = Field(description="true: lamp on; false: standby (the shutter closes)")


class ShutterCommand(_Command):
    open: bool


class MountConfirm(_Command):
    sensor_id: str = Field(min_length=1, max_length=200,
                           description="The sensor the operator mounted: the one the bench awaits")


# -- campaigns --------------------------------------------------------------------------------------------
class DryRunPublic(_Out):
    points: int = Field(description="Points per sensor (at most this many when `upper_bound`)")
    frames: int = Field(description="Frames per sensor, the probes included (at most, when `upper_bound`)")
    moves: int = Field(description="Table moves per sensor (at most, when `upper_bound`)")
    sensors: int = Field(description="Sensors of the campaign")
    duration_s: float = Field(description="Estimated duration of the whole campaign, every sensor, in bench time "
                                          "[s] (at most, when `upper_bound`)")
    duration_per_sensor_s: float = Field(description="Of `duration_s`, each sensor's share [s]")
    warmup_s: float = Field(description="Of `duration_s`, the lamp's warm-up [s]")
    wall_duration_s: float | None = Field(
        None, description="`duration_s` on the wall clock [s]: the same on a real bench, bench time / time scale "
                          "on a simulated one; null when the simulation skips every wait (time scale 0)")
    simulated: bool = Field(False, description="The bench is simulated")
    time_scale: float | None = Field(None, description="The simulated bench's time scale (bench s per wall s)")
    upper_bound: bool = Field(description="The plan may stop early (a stopping rule): the counts and the "
                                          "duration are its cap, every point counted")
    upper_bound_reason: str | None = Field(None, description="Why they are upper bounds, in words")
    violations: list[str]


class CampaignQueued(_Out):
    campaign_id: int
    replayed: bool = Field(False, description="True when an earlier request with the same Idempotency-Key queued "
                                              "this campaign, and this one queued nothing")


class CampaignPublic(_Out):
    id: int
    name: str
    plan: str
    status: str
    created_utc: str
    n_runs: int
    spec: dict[str, Any]


class CampaignsPublic(_Out):
    data: list[CampaignPublic]
    count: int


class FleetEntryPublic(_Out):
    position: int
    sensor_id: str
    status: str
    updated_utc: str | None = None
    run_id: int | None = None
    run_status: str | None = None
    exit_reason: str | None = None
    n_points_planned: int | None = None
    n_points_recorded: int | None = None
    calibration_id: int | None = None
    method: str | None = None
    metrics: dict[str, Any] | None = None


class FleetPublic(_Out):
    campaign_id: int
    data: list[FleetEntryPublic]
    count: int


# -- runs -------------------------------------------------------------------------------------------------
class RunPublic(_Out):
    id: int
    campaign_id: int | None
    parent_run_id: int | None
    sensor_id: str
    plan_name: str
    status: str
    exit_reason: str | None
    created_utc: str
    started_utc: str | None
    ended_utc: str | None
    n_points_planned: int | None
    n_points_recorded: int
    plan_args: dict[str, Any]
    provenance: dict[str, Any]
    family: str = Field("cmos", description="The sensor family the run measured (cmos, qd …)")

    @computed_field(description="The dashboard's results view of the run, chosen by its family")
    @property
    def results_view(self) -> str:
        return results_view(self.family)


class RunsPublic(_Out):
    data: list[RunPublic]
    count: int


class LeftOutFramePublic(_Out):
    reading_id: int
    reason: str = Field(description="Why the fit left the frame out: \"spot clipped at the detector's edge\", or "
                                    "the calibration's reason for rejecting it as an outlier")


class PointPublic(_Out):
    id: int
    key: str
    stage: str
    azimuth_deg: float
    zenith_stage_deg: float
    zenith_deg: float
    azimuth_body_deg: float
    exposure_ms: float | None
    completed_utc: str
    n_readings: int
    n_ok: int = Field(description="Readings with a centroid")
    x_px: float | None = Field(description="Mean spot centre of the point's readings the fits use (of all its "
                                           "spots when it is `excluded`) [px]")
    y_px: float | None = Field(description="Mean spot centre, as `x_px` [px]")
    excluded: str | None = Field(None, description="Why every fit leaves the point out (each of its spots clipped "
                                                   "at the detector's edge); null when it is fitted")
    frames_left_out: list[LeftOutFramePublic] = Field([], description="The point's frames no fit uses, and why")
    summary: dict[str, Any] | None = Field(None, description="What the run's family shows of the point's readings "
                                                             "live, as its `point` event carries it: `spots` (cmos), "
                                                             "`currents_a` and `temperature_c` (qd) …")


class PointsPublic(_Out):
    run_id: int
    data: list[PointPublic]
    count: int


class QualityPublic(_Out):
    chi2_dof: float | None = Field(None, description="χ² per degree of freedom of the fit's residuals against "
                                                     "the repeat scatter (1 when the model explains the data)")
    repeat_scatter_px: float | None = Field(None, description="Scatter of the frames repeated at one direction [px]")
    residual_rms_px: float | None = Field(None, description="RMS of the fit's residuals per axis [px]")
    frames: int | None = Field(None, description="Frames the fit used, after rejection")
    directions: int | None = Field(None, description="Bench directions those frames were averaged into")
    warnings: list[str] = Field([], description="What an engineer should know before trusting the calibration")


class RejectedFramePublic(_Out):
    row: int | None = Field(None, description="Row of the frame in the bench data, when it has one")
    zenith_deg: float
    azimuth_deg: float
    x_px: float
    y_px: float
    offset_px: float = Field(description="How far the frame lay from the others at its direction [px]")
    reason: str


class RejectedReadingPublic(_Out):
    """A reading a photodiode family's fit (qd) rejected: its direction in the sensor's projection angles."""
    row: int | None = Field(None, description="The reading's id")
    alpha_deg: float | None = Field(None, description="Its direction's α (null for a dark reading) [°]")
    beta_deg: float | None = Field(None, description="Its direction's β [°]")
    reason: str


class UncertaintyMapPublic(_Out):
    zenith_deg: list[float] = Field(description="Zenith of each row of the grid [°]")
    azimuth_deg: list[float] = Field(description="Azimuth of each column of the grid [°]")
    sigma_deg: list[list[float | None]] = Field(
        description="1σ pointing uncertainty (RMS vector error) from the calibration's parameter covariance, "
                    "rows by zenith [°]")
    max_deg: float | None = None
    rms_deg: float | None = Field(None, description="RMS of σ over the field, per unit solid angle [°]")
    semi_major_deg: list[list[float | None]] | None = None
    semi_minor_deg: list[list[float | None]] | None = None
    noise_px: float | None = Field(None, description="Centroid noise of one frame assumed for noise_sigma_deg [px]")
    noise_sigma_deg: list[list[float | None]] | None = Field(
        None, description="What that centroid noise adds to one frame read in flight, apart [°]")
    kind: str | None = None


class CalibrationPublic(_Out):
    id: int
    method: str
    chosen: bool
    created_utc: str
    metrics: dict[str, Any]
    quality: QualityPublic | None = Field(None, description="The fit's quality in words and figures, from the "
                                                            "calibration document (absent from older ones)")
    rejected: list[RejectedFramePublic | RejectedReadingPublic] | None = Field(
        None, description="Frames (cmos) or readings (qd) left out of the fit, and why (absent from older documents)")
    uncertainty_map: UncertaintyMapPublic | None = Field(None, description="Methods with a parameter covariance "
                                                                           "(physical) only")
    parameters: dict[str, Any] | None = Field(None, description="The fitted parameters as the document holds them "
                                                                "(names with their unit); `uncertainties` gives the "
                                                                "1σ of each fitted one (physical models), `fitted` "
                                                                "their names")


class CalibrationsPublic(_Out):
    run_id: int
    data: list[CalibrationPublic]
    count: int


class LogEventPublic(_Out):
    id: int
    t_utc: str
    kind: str = Field(description="run-started, state, log, warning, error, finished, …")
    message: str
    data: dict[str, Any] | None = None


class _DecisionPublic(_Out):
    """The physical plan's stopping rule after a batch (bench/plans.py physical_plan,
    calibration.design_of_experiments.StopDecision)."""
    stop: bool = Field(description="Every parameter's 1σ is below its target and the check RMS is at most its own")
    reasons: list[str] = Field(description="What was not met yet (empty when `stop`), or why no fit was made")
    n_fit_directions: int = Field(description="Directions fitted so far")
    n_check_directions: int = Field(description="Check directions scored (never fitted)")
    check_rms_deg: float | None = Field(None, description="Vector RMS of the check directions (seed 003 eq. 13) [°]")
    check_max_deg: float | None = Field(None, description="Largest check error [°]")
    sigmas: dict[str, float | None] = Field({}, description="1σ of every fitted parameter [its unit]")
    targets: dict[str, float | None] = Field({}, description="The largest 1σ each parameter may keep [its unit]")


class StopDecisionPublic(_DecisionPublic):
    batch: int = Field(description="Batch number, from 1 (record `physical_batch_<batch>`)")


class PhysicalStopPublic(_DecisionPublic):
    reason: str = Field(description="\"targets met\" or \"cap reached\"")
    batches_measured: int


class PhysicalPlanPublic(_Out):
    check_rms_target_deg: float | None = Field(None, description="Largest check RMS that stops the run [°]")
    n_batches: int | None = Field(None, description="Batches of the design: the cap")
    n_fit_directions: int | None = Field(None, description="Fit directions of every batch: the cap")
    n_check_directions: int | None = None
    batches: list[StopDecisionPublic] = Field(description="The decision after each measured batch, in order")
    stop: PhysicalStopPublic | None = Field(None, description="The final decision (absent until the plan ends)")


class RunValuesPublic(_Out):
    run_id: int
    values: dict[str, Any] = Field(description="Every value the run's plan recorded, by key (exposure_ms, "
                                               "centre_px, tilt_stage, physical_design, physical_batch_<k>, "
                                               "physical_stop, …), as `sunbench show` reads them")
    physical: PhysicalPlanPublic | None = Field(None, description="The physical plan's batches and stop, "
                                                                  "typed; null for other plans")


class RunLogPublic(_Out):
    run_id: int
    data: list[LogEventPublic]
    count: int
