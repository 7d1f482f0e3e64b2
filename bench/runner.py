"""Campaigns end to end: preflight, one run per sensor of the queue, fits when each run ends, resume.

This is what ``sunbench run`` and ``sunbench resume`` call; the web dashboard will enqueue the same calls.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass
from importlib import metadata

import numpy as np

from calibration.centroid import SpotFlag
from calibration.data import BenchData
from calibration.design import DEFAULT_SENSOR
from calibration.evaluation import StageFrames, calibrate
from calibration.stage_geometry import GeometryPrior
from .campaign import Campaign
from .datafile import calibration_document
from .engine import Interlocks, RunEngine
from .plans import alignment_violations, make_plan, procedure_auto_exposure
from .preflight import PreflightReport, TimingModel, preflight, timing_from_table


class ResumeRefused(Exception):
    """A run that cannot be resumed (complete, still live, or already resumed)."""


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
    interlocks = bench_file.interlocks
    sim = devices.sim
    enclosure = (lambda: sim.world.enclosure_open) if sim is not None else None
    clock = sim.world.clock.now if sim is not None else None
    engine = RunEngine(devices, catalogue, geometry=bench_file.bench_geometry(),
                       interlocks=Interlocks(sensor_max_temperature_c=interlocks.sensor_max_temperature_c,
                                             lamp_fault=interlocks.lamp_fault, enclosure_open=enclosure,
                                             poll_s=0.05 if sim is not None else 0.5,
                                             hold_off_s=0.0 if sim is not None else 1.0),
                       **({"clock": clock} if clock else {}))
    return Session(bench_file, devices, catalogue, engine)


def timing_model(session: Session) -> TimingModel:
    sim = session.devices.sim
    if sim is None:
        return timing_from_table(session.devices.table)  # the axes' speeds as the table reports them
    axis = sim.config.zenith_axis  # a simulated bench estimates what the same bench would take in real time
    return timing_from_table(session.devices.table, TimingModel(
        rate_deg_s=axis.max_rate_deg_s, accel_deg_s2=axis.accel_deg_s2, settle_s=axis.settle_s,
        warmup_s=sim.world.lamp.spec.warm_time_s))


def check_campaign(campaign: Campaign, session: Session) -> PreflightReport:
    """Expand the campaign's plan, check every move and the alignment, count the points, estimate the time."""
    geometry = session.bench_file.bench_geometry()
    timing = timing_model(session)
    report = preflight(make_plan(campaign, timing=timing), check=session.devices.table.check, timing=timing,
                       dry_peak_dn=procedure_auto_exposure(campaign).target_peak_fraction * 1023.0,
                       extra_violations=alignment_violations(campaign.alignment, geometry))
    return dataclasses.replace(report, duration_s=report.duration_s * len(campaign.sensors))


def bench_data(catalogue, run_ids, *, sensor_id: str | None = None) -> BenchData:
    """The bench data of runs: one point per good frame, true angles from the bench geometry (seed 003 eq. 8).

    Frames whose centroid failed, or whose spot touches the frame's edge (a clipped spot's centre is
    biased), stay in the catalogue but are left out.
    """
    # a spot cut by the frame's edge has a biased centre: recorded, but not fitted
    unusable = int(SpotFlag.NEAR_EDGE | SpotFlag.ROI_CLIPPED)
    rows = [r for r in catalogue.readings(run_ids)
            if r["status"] == "ok" and r["x_px"] is not None and not (r["flags"] or 0) & unusable]
    if not rows:
        from calibration.errors import InsufficientDataError
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable frame")
    column = lambda name: np.array([r[name] for r in rows], dtype=float)  # noqa: E731
    return BenchData(column("zenith_deg"), column("azimuth_body_deg"), column("x_px"), column("y_px"),
                     repeat=np.array([r["repeat"] for r in rows]), sensor_id=sensor_id,
                     exposure_ms=column("exposure_ms"), frame_id=np.array([r["id"] for r in rows]))


def fit_run(catalogue, run_id: int, methods, design=None, geometry: GeometryPrior | None = None) -> list:
    """Fit every method to the run's lineage; keep each calibration, the best held-out one as chosen.

    Repeats are combined robustly and the rejected frames named (by reading id) in every calibration document,
    with the quality (χ²/dof against the repeat scatter) and its warnings, which also go to the run's journal.
    With `geometry` (what the bench file says of the lever arm and the source distance, with their 1σ) the
    bench geometry is fitted jointly from the recorded stage angles instead of taken as the bench believes it.
    """
    design = design or DEFAULT_SENSOR
    run = catalogue.run(run_id)
    lineage = catalogue.lineage(run_id)
    data = bench_data(catalogue, lineage, sensor_id=run["sensor_id"])
    stage = None
    if geometry is not None:
        rows = {r["id"]: r for r in catalogue.readings(lineage)}
        stage = StageFrames(np.array([rows[i]["azimuth_deg"] for i in data.frame_id], dtype=float),
                            np.array([rows[i]["zenith_stage_deg"] for i in data.frame_id], dtype=float), geometry)
    outcome = calibrate(data, methods=list(methods), design=design, stage=stage)
    chosen = outcome.chosen
    for report in outcome.reports:
        if report.calibration is None:
            continue
        document = calibration_document(report.calibration, sensor_id=run["sensor_id"], source=f"run {run_id}",
                                        software=software_version(), outcome=outcome, design=design)
        document.pop("created_utc", None)  # the catalogue stamps its own time
        catalogue.add_calibration(run_id, report.method, document, report.to_dict(), report is chosen)
    catalogue.log_event(run_id, "fit", f"fitted {len(data)} frames; chosen {chosen.method}, held-out vector RMS "
                                       f"{chosen.heldout.rms_vector_deg:.4f}°" if chosen.heldout else
                        f"fitted {len(data)} frames; chosen {chosen.method}")
    if outcome.rejected:
        catalogue.log_event(run_id, "fit", f"{len(outcome.rejected)} frame(s) rejected: "
                            + "; ".join(r.describe() for r in outcome.rejected[:10])
                            + (" …" if len(outcome.rejected) > 10 else ""))
    for warning in outcome.warnings:
        catalogue.log_event(run_id, "fit", f"warning: {warning}")
    return outcome.reports


def _provenance(session: Session, campaign: Campaign, sensor_id: str) -> dict:
    return {"bench_config_hash": session.bench_file.config_hash(), "software_version": software_version(),
            "devices": dict(session.devices.identities), "simulated": session.devices.sim is not None,
            "operator": campaign.operator, "sensor_serial": sensor_id, "frames": campaign.frames}


def _mount_sensor(session: Session, sensor_id: str, ask_operator) -> None:
    """Put the next sensor of a fleet on the bench: the simulated world swaps its truth; a real bench asks."""
    sim = session.devices.sim
    if sim is not None:
        sim.world.sensor = fleet_sensor_truth(sim.world.sensor, sensor_id, first=sim.config.sensor.serial)
    elif ask_operator is not None:
        ask_operator(f"mount sensor {sensor_id} on the bench and confirm")


def fleet_sensor_truth(base, serial: str, *, first: str):
    """A simulated flight sensor: the bench's sensor for its own serial, others with their own build errors
    drawn (reproducibly, from the serial) around it."""
    if serial == first:
        return dataclasses.replace(base, serial=serial)
    rng = np.random.default_rng(zlib.crc32(serial.encode()))
    b = base.build
    build = dataclasses.replace(b, x0_px=b.x0_px + rng.normal(0, 6), y0_px=b.y0_px + rng.normal(0, 6),
                                gap_mm=b.gap_mm + rng.normal(0, 0.03), glass_mm=max(b.glass_mm + rng.normal(0, 0.03), 0),
                                tilt_x_deg=rng.normal(0, 0.2), tilt_y_deg=rng.normal(0, 0.2),
                                rotation_deg=rng.normal(0, 1.5))
    return dataclasses.replace(base, build=build, serial=serial,
                               aperture_ellipticity=abs(base.aperture_ellipticity * (1 + rng.normal(0, 0.3))))


def run_campaign(campaign: Campaign, session: Session, *, ask_operator=None, on_run=None) -> list[int]:
    """Preflight, then one run per sensor of the campaign (a persisted queue), each fitted when it ends.

    Returns the run ids. Raises :class:`PreflightRefused` before anything moves when the plan breaks a limit.
    """
    report = check_campaign(campaign, session)
    if not report.ok:
        raise PreflightRefused(report.violations)
    catalogue = session.catalogue
    campaign_id = catalogue.create_campaign(campaign.name, campaign.plan, campaign.model_dump(mode="json"))
    catalogue.enqueue_sensors(campaign_id, list(campaign.sensors))
    return continue_campaign(campaign_id, session, ask_operator=ask_operator, on_run=on_run)


def continue_campaign(campaign_id: int, session: Session, *, ask_operator=None, on_run=None) -> list[int]:
    """Work through the campaign's queue of sensors (also after a restart)."""
    catalogue = session.catalogue
    campaign = Campaign.model_validate(catalogue.campaign(campaign_id)["spec"])
    runs = []
    while (sensor_id := catalogue.next_queued_sensor(campaign_id)) is not None:
        _mount_sensor(session, sensor_id, ask_operator)
        n_points = len(check_campaign(campaign.model_copy(update={"sensors": (sensor_id,)}), session).points)
        run_id = catalogue.create_run(campaign_id=campaign_id, sensor_id=sensor_id, plan_name=campaign.plan,
                                      plan_args=campaign.model_dump(mode="json"),
                                      provenance=_provenance(session, campaign, sensor_id), n_points_planned=n_points)
        catalogue.set_queue_status(campaign_id, sensor_id, "running", run_id)
        if on_run:
            on_run(run_id, sensor_id)
        status = _execute(session, campaign, run_id, n_points)
        catalogue.set_queue_status(campaign_id, sensor_id, "done" if status == "completed" else "failed", run_id)
        runs.append(run_id)
        if status != "completed":
            break
    return runs


def _execute(session: Session, campaign: Campaign, run_id: int, n_points: int, *, lineage=()) -> str:
    catalogue = session.catalogue
    lineage = list(lineage) or [run_id]
    done = catalogue.completed_keys(lineage)
    session.engine.frames = campaign.frames
    design, geometry = fit_inputs(session)
    return session.engine.execute(make_plan(campaign, timing=timing_model(session)), run_id=run_id, done_keys=done, lineage=lineage,
                                  n_points=n_points,
                                  on_completed=lambda: fit_run(catalogue, run_id, campaign.methods, design, geometry))


def fit_inputs(session: Session):
    """The sensor's design and what the bench file says of its geometry, for the fits at a run's end.

    The stage-angle model (:mod:`calibration.stage_geometry`) is seed 003's azimuth-on-zenith bench; on an
    alt-az mount the directions the engine recorded are used as they are (geometry None).
    """
    sim = session.devices.sim
    design = sim.world.sensor.design if sim is not None else DEFAULT_SENSOR
    if sim is not None and sim.world.axis_order != "azimuth-on-zenith":
        return design, None
    g = session.bench_file.geometry
    return design, GeometryPrior(lever_arm_mm=g.lever_arm_mm or None, lever_arm_sd_mm=getattr(g, "lever_arm_sd_mm", None),
                                 source_distance_mm=g.source_distance_mm,
                                 source_distance_sd_mm=getattr(g, "source_distance_sd_mm", None))


def resume_run(run_id: int, session: Session, *, on_run=None) -> int:
    """Start a new run linked to `run_id` that measures only the points its lineage is missing."""
    catalogue = session.catalogue
    old = catalogue.run(run_id)
    if old["status"] == "completed":
        raise ResumeRefused(f"run {run_id} is complete; nothing to resume")
    if old["status"] in ("running", "paused", "suspended"):
        raise ResumeRefused(f"run {run_id} is {old['status']}; only an ended run can be resumed")
    children = [r["id"] for r in catalogue.runs() if r["parent_run_id"] == run_id]
    if children:
        raise ResumeRefused(f"run {run_id} was already resumed by run {children[-1]}; resume that one")
    campaign = Campaign.model_validate(old["plan_args"])
    _mount_sensor(session, old["sensor_id"], None)
    new_id = catalogue.create_run(campaign_id=old["campaign_id"], sensor_id=old["sensor_id"], plan_name=old["plan_name"],
                                  plan_args=old["plan_args"], provenance=_provenance(session, campaign, old["sensor_id"]),
                                  parent_run_id=run_id, n_points_planned=old["n_points_planned"])
    if old["campaign_id"] is not None:
        catalogue.set_queue_status(old["campaign_id"], old["sensor_id"], "running", new_id)
    if on_run:
        on_run(new_id, old["sensor_id"])
    status = _execute(session, campaign, new_id, old["n_points_planned"] or 0, lineage=catalogue.lineage(new_id))
    if old["campaign_id"] is not None:
        catalogue.set_queue_status(old["campaign_id"], old["sensor_id"], "done" if status == "completed" else "failed",
                                   new_id)
    return new_id


__all__ = ["Session", "open_session", "check_campaign", "run_campaign", "continue_campaign", "resume_run",
           "fit_run", "bench_data", "PreflightRefused", "ResumeRefused"]
