"""Runs and their results, read from the catalogue."""

from __future__ import annotations

from fastapi import APIRouter, Depends, status

from bench.results import run_points

from ..deps import READ, AfterId, CampaignFilter, CatalogueDep, RunId, ServiceDep
from ..schemas import CalibrationsPublic, Message, PointsPublic, RunLogPublic, RunPublic, RunsPublic, RunValuesPublic
from ..security import require_token

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,  # resuming needs the token too
                   responses={404: {"description": "No such run"}})


#: What the results page shows of a calibration document besides its metrics (none in older documents)
DOCUMENT_FIELDS = ("quality", "rejected", "uncertainty_map", "parameters")


#: The physical plan's records (bench/plans.py physical_plan): one per measured batch, then the final one
BATCH_PREFIX, STOP_KEY, DESIGN_KEY = "physical_batch_", "physical_stop", "physical_design"


def _physical_records(values: dict) -> dict | None:
    """The physical plan's batch decisions in batch order (``physical_batch_10`` after ``_9``), its stop and
    the size of its design; None when the run recorded none of them."""
    batches = sorted((int(key.removeprefix(BATCH_PREFIX)), value) for key, value in values.items()
                     if key.startswith(BATCH_PREFIX) and key.removeprefix(BATCH_PREFIX).isdigit())
    design, stop = values.get(DESIGN_KEY), values.get(STOP_KEY)
    if not batches and design is None and stop is None:
        return None
    design = design or {}
    return {"check_rms_target_deg": design.get("check_rms_target_deg"),
            "n_batches": len(design["batches"]) if "batches" in design else None,
            "n_fit_directions": len(design["fit_directions_deg"]) if "fit_directions_deg" in design else None,
            "n_check_directions": (len(design["check_directions_deg"]) if "check_directions_deg" in design
                                   else None),
            "batches": [{**value, "batch": number} for number, value in batches], "stop": stop}


def _with_document_fields(record: dict) -> dict:
    document = record.get("document") or {}
    return {**record, **{name: document.get(name) for name in DOCUMENT_FIELDS}}


@router.get("", response_model=RunsPublic, summary="List runs")
def read_runs(catalogue: CatalogueDep, campaign_id: CampaignFilter = None):
    """Every run (or those of one campaign), oldest first."""
    runs = catalogue.runs(campaign_id)
    return RunsPublic(data=runs, count=len(runs))


@router.get("/{run_id}", response_model=RunPublic, summary="One run")
def read_run(run_id: RunId, catalogue: CatalogueDep):
    """A run with its plan arguments, provenance and progress."""
    return catalogue.run(run_id)


@router.get("/{run_id}/points", response_model=PointsPublic, summary="Points of a run")
def read_points(run_id: RunId, catalogue: CatalogueDep):
    """The run's points in recording order, each with the mean spot of its good readings (a cmos run's) and what
    its family shows of its readings live (`summary`: its spots, or its currents …)."""
    points = run_points(catalogue, run_id)
    return PointsPublic(run_id=run_id, data=points, count=len(points))


@router.get("/{run_id}/calibrations", response_model=CalibrationsPublic, summary="Calibrations of a run")
def read_calibrations(run_id: RunId, catalogue: CatalogueDep):
    """Every method fitted to the run with its metrics; `chosen` marks the best held-out one. From each
    calibration document: its quality and warnings, the frames it rejected, and (physical model) its 1σ
    pointing uncertainty over the field; null where the document does not say."""
    catalogue.run(run_id)
    calibrations = [_with_document_fields(c) for c in catalogue.calibrations(run_id)]
    return CalibrationsPublic(run_id=run_id, data=calibrations, count=len(calibrations))


@router.get("/{run_id}/values", response_model=RunValuesPublic, summary="Values a run's plan recorded")
def read_values(run_id: RunId, catalogue: CatalogueDep):
    """What the plan decided on the way, as `sunbench show` reads them: the exposure, the centre and the tilt
    stage of seed 003; the physical plan's design, its stopping rule's decision after each batch
    (`physical_batch_<k>`) and its final one (`physical_stop`), the latter also typed under `physical`."""
    catalogue.run(run_id)
    values = catalogue.run_values(run_id)
    return RunValuesPublic(run_id=run_id, values=values, physical=_physical_records(values))


@router.get("/{run_id}/log", response_model=RunLogPublic, summary="Log of a run")
def read_log(run_id: RunId, catalogue: CatalogueDep, after_id: AfterId = 0):
    """What the engine logged during the run (state changes, warnings, errors, its end), oldest first;
    `after_id` returns only the events after the one a client saw last."""
    catalogue.run(run_id)
    events = catalogue.events(run_id, after_id)
    return RunLogPublic(run_id=run_id, data=events, count=len(events))


@router.post("/{run_id}/resume", response_model=Message, status_code=status.HTTP_202_ACCEPTED,
             summary="Resume a run that ended without completing", dependencies=[Depends(require_token)],
             responses={409: {"description": "Complete, still live, already resumed, or its campaign is busy"}})
def resume_run(run_id: RunId, service: ServiceDep):
    """Queue a new run, linked to this crashed, aborted or failed one, that measures only the points its
    lineage is missing (as `sunbench resume`), then the rest of its campaign; follow it on /api/events."""
    service.resume_run(run_id)
    return Message(message=f"run {run_id} queued to resume")
