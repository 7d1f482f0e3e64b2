"""Runs and their results, read from the catalogue."""

from __future__ import annotations

from fastapi import APIRouter

from bench.results import point_means

from ..deps import READ, CatalogueDep
from ..schemas import CalibrationsPublic, PointsPublic, RunLogPublic, RunPublic, RunsPublic

router = APIRouter(prefix="/api/runs", tags=["runs"], dependencies=READ,
                   responses={404: {"description": "No such run"}})


#: What the results page shows of a calibration document besides its metrics (none in older documents)
DOCUMENT_FIELDS = ("quality", "rejected", "uncertainty_map")


def _with_document_fields(record: dict) -> dict:
    document = record.get("document") or {}
    return {**record, **{name: document.get(name) for name in DOCUMENT_FIELDS}}


@router.get("", response_model=RunsPublic, summary="List runs")
def read_runs(catalogue: CatalogueDep, campaign_id: int | None = None):
    """Every run (or those of one campaign), oldest first."""
    runs = catalogue.runs(campaign_id)
    return RunsPublic(data=runs, count=len(runs))


@router.get("/{run_id}", response_model=RunPublic, summary="One run")
def read_run(run_id: int, catalogue: CatalogueDep):
    """A run with its plan arguments, provenance and progress."""
    return catalogue.run(run_id)


@router.get("/{run_id}/points", response_model=PointsPublic, summary="Points of a run")
def read_points(run_id: int, catalogue: CatalogueDep):
    """The run's points in recording order, each with the mean spot of its good readings."""
    points = point_means(catalogue, run_id)
    return PointsPublic(run_id=run_id, data=points, count=len(points))


@router.get("/{run_id}/calibrations", response_model=CalibrationsPublic, summary="Calibrations of a run")
def read_calibrations(run_id: int, catalogue: CatalogueDep):
    """Every method fitted to the run with its metrics; `chosen` marks the best held-out one. From each
    calibration document: its quality and warnings, the frames it rejected, and (physical model) its 1σ
    pointing uncertainty over the field; null where the document does not say."""
    catalogue.run(run_id)
    calibrations = [_with_document_fields(c) for c in catalogue.calibrations(run_id)]
    return CalibrationsPublic(run_id=run_id, data=calibrations, count=len(calibrations))


@router.get("/{run_id}/log", response_model=RunLogPublic, summary="Log of a run")
def read_log(run_id: int, catalogue: CatalogueDep, after_id: int = 0):
    """What the engine logged during the run (state changes, warnings, errors, its end), oldest first;
    `after_id` returns only the events after the one a client saw last."""
    catalogue.run(run_id)
    events = catalogue.events(run_id, after_id)
    return RunLogPublic(run_id=run_id, data=events, count=len(events))
