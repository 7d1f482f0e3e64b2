"""Campaigns end to end: preflight, one run per sensor of the queue, fits when each run ends, resume.

This is what ``sunbench run`` and ``sunbench resume`` call; the web dashboard will enqueue the same calls.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata

import numpy as np

from calibration.data import BenchData
from calibration.design import DEFAULT_SENSOR
from calibration.evaluation import StageFrames, calibrate
from calibration.stage_geometry import GeometryPrior

from .campaign import Campaign
from .catalogue import LIVE_RUN_STATUSES
from .datafile import calibration_document
from .descriptor import ReadingRecord
from .engine import RunEngine
from .families import family_of_sensor, journal_fit, table_mount
from .families.cmos import EDGE_FLAGS
from .interlocks import SIMULATED_TIMING
from .plans import alignment_violations
from .preflight import PreflightReport, TimingModel, disc_radius_check, preflight_campaign, timing_from_table


class ResumeRefused(Exception):
    """A run that cannot be resumed (complete, still live, or already resumed)."""


#: How a run of a campaign may end without completing and still be resumed (its points are kept)
RESUMABLE_STATUSES = ("aborted", "failed", "crashed")


class PreflightRefused(Exception):
    """The campaign would break a limit or an alignment tolerance; `violations` lists every one."""

    def __init__(self, violations: list[str]):
        self.violations = violations
        super().__init__("preflight refused the campaign:\n  " + "\n  ".join(violations))


def software_version() -> str:
    try:
        return metadata.version("sunbench")
    except metadata.PackageNotFoundError:
        return "unknown"


@dataclass
class Session:
    """An open bench: its file, connected devices, catalogue and engine."""

    bench_file: object
    devices: object
    catalogue: object
    engine: RunEngine

    def close(self) -> None:
        self.devices.close()


def open_session(bench_file, catalogue, *, time_scale: float | None = None, ask=None) -> Session:
    """Connect the bench's devices and build the engine around them."""
    from .hardware import connect_bench

    devices = connect_bench(bench_file, time_scale=time_scale, **({"ask": ask} if ask else {}))
    sim = devices.sim
    interlocks = (bench_file.interlocks.interlocks(enclosure_open=sim.enclosure_open, **SIMULATED_TIMING)
                  if sim is not None else bench_file.interlocks.interlocks())
    clock = sim.clock.now if sim is not None else None
    engine = RunEngine(devices, catalogue, geometry=bench_file.bench_geometry(), interlocks=interlocks,
                       family=family_of_sensor(bench_file.devices.sensor.kind),
                       axis_order=sim.axis_order if sim is not None else table_axis_order(bench_file),
                       **({"clock": clock} if clock else {}))
    return Session(bench_file, devices, catalogue, engine)


def table_axis_order(bench_file) -> str:
    """The kinematics of a real table: an LX200 is an alt-az fork, the two-stage tables are seed 003's."""
    return "zenith-on-azimuth" if bench_file.devices.table.kind == "lx200" else "azimuth-on-zenith"


def session_mount(session: Session):
    """The table's kinematics, for plans set in the sensor's own angles (:func:`bench.families.table_mount`)."""
    return table_mount(session.engine.axis_order, session.engine.geometry)


def timing_model(session: Session) -> TimingModel:
    sim = session.devices.sim
    if sim is None:
        return timing_from_table(session.devices.table)  # the axes' speeds as the table reports them
    axis = sim.config.zenith_axis  # a simulated bench estimates what the same bench would take in real time
    return timing_from_table(session.devices.table, TimingModel(
        rate_deg_s=axis.max_rate_deg_s, accel_deg_s2=axis.accel_deg_s2, settle_s=axis.settle_s,
        warmup_s=sim.lamp_warm_time_s))


def check_campaign(campaign: Campaign, session: Session) -> PreflightReport:
    """Expand the campaign's plan, check every move, every disc radius (the Earth simulator's soft limits) and the
    alignment, count the points, estimate the time."""
    geometry = session.bench_file.bench_geometry()
    timing = timing_model(session)
    family = session.engine.family
    wrong = [] if campaign.plan in family.plans else [
        f"the {campaign.plan} plan is not one of the {family.name} sensor's on this bench "
        f"(its plans: {', '.join(family.plans)})"]
    report = preflight_campaign(campaign, check=session.devices.table.check, timing=timing,
                                mount=session_mount(session),
                                check_radius=disc_radius_check(session.devices.source),
                                extra_violations=wrong + alignment_violations(campaign.alignment, geometry))
    return dataclasses.replace(report, duration_s=report.duration_s * len(campaign.sensors))


#: Why such a frame is left out of the fit, in words (the result plots say it)
EDGE_REASON = "spot clipped at the detector's edge"


def has_spot(reading: ReadingRecord) -> bool:
    """A reading of the catalogue whose centroid was found."""
    return reading.ok and reading.value("x_px") is not None


def clipped(reading: ReadingRecord) -> bool:
    """A reading whose spot touches the frame's edge (:data:`EDGE_FLAGS`): recorded, never fitted."""
    return bool(int(reading.value("flags", 0)) & EDGE_FLAGS)


def bench_data(catalogue, run_ids, *, sensor_id: str | None = None) -> BenchData:
    """The bench data of runs: one point per good frame, true angles from the bench geometry (seed 003 eq. 8).

    Frames whose centroid failed, or whose spot touches the frame's edge (a clipped spot's centre is
    biased), stay in the catalogue but are left out.
    """
    return _bench_data(catalogue.readings(run_ids), run_ids, sensor_id)


def _bench_data(readings: list[ReadingRecord], run_ids, sensor_id: str | None) -> BenchData:
    """:func:`bench_data` of the runs' `readings`, as the catalogue gave them."""
    rows = [r for r in readings if has_spot(r) and not clipped(r)]
    if not rows:
        from calibration.errors import InsufficientDataError
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable frame")
    pose = lambda name: np.array([getattr(r, name) for r in rows], dtype=float)  # noqa: E731
    spot = lambda name: np.array([r.value(name) for r in rows], dtype=float)  # noqa: E731
    return BenchData(pose("zenith_deg"), pose("azimuth_body_deg"), spot("x_px"), spot("y_px"),
                     repeat=np.array([r.repeat for r in rows]), sensor_id=sensor_id,
                     exposure_ms=pose("exposure_ms"), frame_id=np.array([r.id for r in rows]))


def fit_run(catalogue, run_id: int, methods, design=None, geometry: GeometryPrior | None = None, *,
            journal=None) -> list:
    """Fit every method to the run's lineage; keep each calibration, the best held-out one as chosen.

    Repeats are combined robustly and the rejected frames named (by reading id) in every calibration document,
    with the quality (χ²/dof against the repeat scatter) and its warnings, which also go to the run's journal.
    With `geometry` (what the bench file says of the lever arm and the source distance, with their 1σ) the
    bench geometry is fitted jointly from the recorded stage angles instead of taken as the bench believes it.
    """
    design = design or DEFAULT_SENSOR
    journal = journal or (lambda kind, message: catalogue.log_event(run_id, kind, message))
    run = catalogue.run(run_id)
    lineage = catalogue.lineage(run_id)
    readings = catalogue.readings(lineage)
    data = _bench_data(readings, lineage, run["sensor_id"])
    stage = None
    if geometry is not None:
        rows = {r.id: r for r in readings}
        stage = StageFrames(np.array([rows[i].azimuth_deg for i in data.frame_id], dtype=float),
                            np.array([rows[i].zenith_stage_deg for i in data.frame_id], dtype=float), geometry)
    outcome = calibrate(data, methods=list(methods), design=design, stage=stage)
    chosen = outcome.chosen
    for report in outcome.reports:
        if report.calibration is None:
            continue
        document = calibration_document(report.calibration, sensor_id=run["sensor_id"], source=f"run {run_id}",
                                        software=software_version(), outcome=outcome, design=design)
        document.pop("created_utc", None)  # the catalogue stamps its own time
        catalogue.add_calibration(run_id, report.method, document, report.to_dict(), report is chosen)
    journal_fit(journal, f"fitted {len(data)} frames; chosen {chosen.method}"
                + (f", held-out vector RMS {chosen.heldout.rms_vector_deg:.4f}°" if chosen.heldout else ""),
                outcome.rejected, outcome.warnings, "frame")
    return outcome.reports


def _provenance(session: Session, campaign: Campaign, sensor_id: str, identity=None) -> dict:
    from .hardware import _identity_text
    devices = dict(session.devices.identities)
    if identity is not None:  # what the module said when this sensor was checked, not at connection
        devices["sensor"] = _identity_text(identity)
    return {"bench_config_hash": session.bench_file.config_hash(), "software_version": software_version(),
            "devices": devices, "simulated": session.devices.sim is not None,
            "operator": campaign.operator, "sensor_serial": sensor_id, "frames": campaign.frames}


@dataclass(frozen=True)
class MountRequest:
    """A sensor the operator must put on the bench, and confirm, before its run.

    Attributes
    ----------
    sensor_id : str
        Its serial, as the campaign lists it.
    campaign_id : int or None
    position, count : int
        Its place in the campaign's queue (from 0) and the queue's length.
    resumes_run : int or None
        The run of this sensor that the coming run resumes.
    """

    sensor_id: str
    campaign_id: int | None
    position: int
    count: int
    resumes_run: int | None = None

    def prompt(self) -> str:
        where = (f" (sensor {self.position + 1} of {self.count} of campaign {self.campaign_id})"
                 if self.campaign_id is not None else "")
        return f"mount sensor {self.sensor_id} on the bench{where}"


#: ``confirm_mount(request) -> bool``: True once the operator says the sensor is mounted, False to stop
ConfirmMount = Callable[[MountRequest], bool]


def reads_serial(session: Session) -> bool:
    """Whether the sensor module tells its serial (the CMOS module does; a camera's "serial" is its port)."""
    return bool(getattr(session.devices.sensor, "reports_serial", False))


def _mount(session: Session, request: MountRequest, confirm_mount: ConfirmMount | None) -> bool:
    """Get `request`'s sensor onto the bench; False when the operator did not confirm it.

    Every sensor but the first of its campaign waits for the operator (it has to be swapped in), and so does
    the first when the module cannot tell its serial; on a simulated bench the simulator mounts it first,
    as the operator's hands would.
    """
    sim = session.devices.sim
    if sim is not None:
        sim.mount_sensor(request.sensor_id)
    if request.position == 0 and reads_serial(session):
        return True  # the operator who started the campaign mounted it; its serial is checked next
    return confirm_mount is not None and bool(confirm_mount(request))


def _queue_place(catalogue, campaign_id: int | None, sensor_id: str) -> tuple[int, int]:
    if campaign_id is None:
        return 0, 1
    queue = catalogue.fleet(campaign_id)
    return next(e["position"] for e in queue if e["sensor_id"] == sensor_id), len(queue)


def _run_sensor(session: Session, campaign: Campaign, campaign_id: int | None, sensor_id: str, *,
                parent: int | None = None, n_points: int | None = None, confirm_mount: ConfirmMount | None = None,
                on_run=None) -> tuple[int | None, str]:
    """Mount one sensor, check its serial, then measure it (resuming `parent`'s lineage) and fit it.

    Returns (run id, its status), or (None, "not mounted") when the operator did not confirm the mount.
    A module reporting another serial than `sensor_id` fails the run before anything moves.
    """
    catalogue = session.catalogue
    session.engine.check_unlatched()  # nothing starts behind a latched emergency stop (its sensor stays queued)
    position, count = _queue_place(catalogue, campaign_id, sensor_id)
    request = MountRequest(sensor_id, campaign_id, position, count, parent)
    if not _mount(session, request, confirm_mount):
        catalogue.log_event(parent, "mount", f"{request.prompt()}: not confirmed; nothing was measured")
        return None, "not mounted"
    identity = session.devices.sensor.identify() if reads_serial(session) else None
    if n_points is None:
        n_points = len(check_campaign(campaign.model_copy(update={"sensors": (sensor_id,)}), session).points)
    session.engine.check_unlatched()  # an emergency stop while the operator mounted the sensor
    run_id = catalogue.create_run(campaign_id=campaign_id, sensor_id=sensor_id, plan_name=campaign.plan,
                                  plan_args=campaign.model_dump(mode="json"), parent_run_id=parent,
                                  provenance=_provenance(session, campaign, sensor_id, identity),
                                  descriptor=session.engine.family.descriptor,
                                  n_points_planned=n_points)
    if campaign_id is not None:
        catalogue.set_queue_status(campaign_id, sensor_id, "running", run_id)
    if identity is not None and identity.serial != sensor_id:
        # a run labelled with one serial must never hold another sensor's data
        status = "failed"
        catalogue.set_run_status(run_id, status, f"the sensor on the bench reports serial {identity.serial}, not "
                                                 f"{sensor_id}: mount {sensor_id} and resume (nothing was measured)")
    else:
        if on_run:
            on_run(run_id, sensor_id)
        status = _execute(session, campaign, run_id, n_points, lineage=catalogue.lineage(run_id))
    if campaign_id is not None:
        # an aborted sensor stays queued (linked to its run), so resuming the campaign resumes it
        queue_status = {"completed": "done", "aborted": "queued"}.get(status, "failed")
        catalogue.set_queue_status(campaign_id, sensor_id, queue_status, run_id)
    return run_id, status


def _settle_campaign(catalogue, campaign_id: int, last: str | None, *, more: bool = False) -> str:
    """Set the campaign's status once its worker stops: `last` is how its last sensor ended; `more` when the
    caller goes on with the rest of the queue (it stays running then)."""
    queue = catalogue.fleet(campaign_id)
    if all(e["status"] == "done" for e in queue):
        status = "completed"
    elif last in ("aborted", "not mounted"):
        status = "aborted"
    elif last == "completed" and more:
        return catalogue.campaign(campaign_id)["status"]
    else:
        status = "failed"  # this run failed, or an earlier sensor's did
    catalogue.set_campaign_status(campaign_id, status)
    return status


def run_campaign(campaign: Campaign, session: Session, *, confirm_mount: ConfirmMount | None = None,
                 on_run=None) -> list[int]:
    """Preflight, then one run per sensor of the campaign (a persisted queue), each fitted when it ends.

    Returns the run ids. Raises :class:`PreflightRefused` before anything moves when the plan breaks a limit.
    `confirm_mount` is asked before each sensor that must be mounted by hand (see :class:`MountRequest`);
    without it, such a sensor stops the campaign.
    """
    report = check_campaign(campaign, session)
    if not report.ok:
        raise PreflightRefused(report.violations)
    catalogue = session.catalogue
    campaign_id = catalogue.create_campaign(campaign.name, campaign.plan, campaign.model_dump(mode="json"))
    catalogue.enqueue_sensors(campaign_id, list(campaign.sensors))
    return continue_campaign(campaign_id, session, confirm_mount=confirm_mount, on_run=on_run)


def continue_campaign(campaign_id: int, session: Session, *, confirm_mount: ConfirmMount | None = None,
                      on_run=None) -> list[int]:
    """Work through the campaign's queue of sensors (also after a restart), keeping its status.

    A queued sensor whose last run crashed, was aborted or failed is resumed from that run (its points kept).
    The campaign ends completed, aborted (a run aborted, a mount not confirmed) or failed.
    """
    catalogue = session.catalogue
    campaign = Campaign.model_validate(catalogue.campaign(campaign_id)["spec"])
    catalogue.set_campaign_status(campaign_id, "running")
    runs, last = [], None
    try:
        while (sensor_id := catalogue.next_queued_sensor(campaign_id)) is not None:
            earlier = catalogue.queued_run(campaign_id, sensor_id)
            parent = earlier if earlier is not None and \
                catalogue.run(earlier)["status"] in RESUMABLE_STATUSES else None
            run_id, last = _run_sensor(session, campaign, campaign_id, sensor_id, parent=parent,
                                       confirm_mount=confirm_mount, on_run=on_run)
            if run_id is not None:
                runs.append(run_id)
            if last != "completed":
                break
    except BaseException as exc:
        _settle_campaign(catalogue, campaign_id, "failed" if isinstance(exc, Exception) else "aborted")
        raise
    _settle_campaign(catalogue, campaign_id, last)
    return runs


def _execute(session: Session, campaign: Campaign, run_id: int, n_points: int, *, lineage=()) -> str:
    catalogue = session.catalogue
    lineage = list(lineage) or [run_id]
    done = catalogue.completed_keys(lineage)
    session.engine.frames = campaign.frames
    family = session.engine.family
    inputs = family.fit_inputs(session)
    plan = family.make_plan(campaign, timing=timing_model(session), mount=session_mount(session))
    return session.engine.execute(plan, run_id=run_id,
                                  done_keys=done, lineage=lineage, n_points=n_points,
                                  on_completed=lambda: family.fit_run(catalogue, run_id, campaign, inputs,
                                                                      session.engine.journal))


def fit_inputs(session: Session):
    """The sensor's design and what the bench file says of its geometry, for the fits at a run's end.

    The stage-angle model (:mod:`calibration.stage_geometry`) is seed 003's azimuth-on-zenith bench; on an
    alt-az mount the directions the engine recorded are used as they are (geometry None).
    """
    sim = session.devices.sim
    given = getattr(session.bench_file.devices.sensor, "design", None)  # the bench file's word wins
    design = given.sensor_design() if given is not None else (sim.sensor_design if sim is not None
                                                               else DEFAULT_SENSOR)
    if session.engine.axis_order != "azimuth-on-zenith":  # a simulated or a real alt-az mount alike
        return design, None
    return design, GeometryPrior.from_bench(session.bench_file.bench_geometry())


def check_resumable(catalogue, run_id: int) -> dict:
    """The run, if it may be resumed; else :class:`ResumeRefused` saying why."""
    old = catalogue.run(run_id)
    if old["status"] == "completed":
        raise ResumeRefused(f"run {run_id} is complete; nothing to resume")
    if old["status"] in LIVE_RUN_STATUSES:
        raise ResumeRefused(f"run {run_id} is {old['status']}; only an ended run can be resumed")
    children = [r["id"] for r in catalogue.runs() if r["parent_run_id"] == run_id]
    if children:
        raise ResumeRefused(f"run {run_id} was already resumed by run {children[-1]}; resume that one")
    return old


def resume_run(run_id: int, session: Session, *, confirm_mount: ConfirmMount | None = None, on_run=None) -> int:
    """Start a new run linked to `run_id` that measures only the points its lineage is missing.

    The sensor is mounted and its serial checked as for any run (:func:`continue_campaign`). Once it completes,
    the rest of its campaign waits for :func:`continue_campaign` (:func:`resume_and_continue` does both).
    """
    catalogue = session.catalogue
    old = check_resumable(catalogue, run_id)
    campaign = Campaign.model_validate(old["plan_args"])
    campaign_id = old["campaign_id"]
    if campaign_id is not None:
        catalogue.set_campaign_status(campaign_id, "running")
    try:
        new_id, status = _run_sensor(session, campaign, campaign_id, old["sensor_id"], parent=run_id,
                                     n_points=old["n_points_planned"], confirm_mount=confirm_mount, on_run=on_run)
    except BaseException as exc:
        if campaign_id is not None:
            _settle_campaign(catalogue, campaign_id, "failed" if isinstance(exc, Exception) else "aborted")
        raise
    if campaign_id is not None:
        _settle_campaign(catalogue, campaign_id, status, more=True)
    if new_id is None:
        raise ResumeRefused(f"sensor {old['sensor_id']} was not confirmed mounted; run {run_id} was not resumed")
    return new_id


def resume_and_continue(run_id: int, session: Session, *, confirm_mount: ConfirmMount | None = None,
                        on_run=None) -> list[int]:
    """:func:`resume_run`, then the rest of its campaign's queue once it completed; every run started.

    A completed run whose campaign still has sensors queued (a mount that was not confirmed) goes on with them.
    """
    catalogue = session.catalogue
    done = catalogue.run(run_id)
    if done["status"] == "completed" and done["campaign_id"] is not None \
            and catalogue.next_queued_sensor(done["campaign_id"]) is not None:
        return continue_campaign(done["campaign_id"], session, confirm_mount=confirm_mount, on_run=on_run)
    new_id = resume_run(run_id, session, confirm_mount=confirm_mount, on_run=on_run)
    run = session.catalogue.run(new_id)
    if run["status"] != "completed" or run["campaign_id"] is None:
        return [new_id]
    return [new_id, *continue_campaign(run["campaign_id"], session, confirm_mount=confirm_mount, on_run=on_run)]


__all__ = ["Session", "open_session", "check_campaign", "run_campaign", "continue_campaign", "resume_run",
           "resume_and_continue", "check_resumable", "fit_run", "bench_data", "MountRequest", "PreflightRefused",
           "ResumeRefused", "RESUMABLE_STATUSES"]
