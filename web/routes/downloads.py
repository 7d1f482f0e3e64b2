"""Files to take away: a run's bench data CSV, and calibrations as JSON or as a C header."""

from __future__ import annotations

import tempfile
from pathlib import Path

from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse, PlainTextResponse

from bench.datafile import header_from_document, write_bench_csv
from bench.runner import bench_data
from calibration.errors import InsufficientDataError
from calibration.models import calibration_from_dict

from ..deps import READ, CatalogueDep, RunId

router = APIRouter(prefix="/api", tags=["downloads"], dependencies=READ,
                   responses={404: {"description": "No such run, calibration or data"}})


def _attachment(filename: str) -> dict:
    return {"Content-Disposition": f'attachment; filename="{filename}"'}


def _calibration_document(catalogue, run_id: int, method: str) -> dict:
    """The stored document with what `sunbench fit` writes beside it: the created time, every method's metrics
    and the run's provenance."""
    run = catalogue.run(run_id)
    records = catalogue.calibrations(run_id)
    matches = [c for c in records if c["method"] == method]
    if not matches:
        raise HTTPException(404, f"run {run_id} has no {method} calibration")
    record = matches[-1]  # the latest, should the run have been fitted again
    return {**record["document"], "created_utc": record["created_utc"],
            "metrics": {c["method"]: c["metrics"] for c in records}, "provenance": run["provenance"]}


@router.get("/runs/{run_id}/data.csv", response_class=PlainTextResponse, summary="Bench data CSV of a run",
            responses={200: {"content": {"text/csv": {}}}})
def download_run_data(run_id: RunId, catalogue: CatalogueDep):
    """The run's lineage as bench data (true angles, spot centres), in the format ``sunbench fit`` reads."""
    run = catalogue.run(run_id)
    try:
        data = bench_data(catalogue, catalogue.lineage(run_id), sensor_id=run["sensor_id"])
    except InsufficientDataError as exc:
        raise HTTPException(404, str(exc)) from None
    with tempfile.TemporaryDirectory() as folder:  # the writer wants a path; one writer, one format
        path = Path(folder) / "data.csv"
        write_bench_csv(path, data)
        text = path.read_text()
    return PlainTextResponse(text, media_type="text/csv", headers=_attachment(f"run-{run_id}-data.csv"))


@router.get("/calibrations/{run_id}/{method}.json", summary="Calibration document",
            responses={200: {"content": {"application/json": {}}}})
def download_calibration_json(run_id: RunId, method: str, catalogue: CatalogueDep):
    """The calibration as ``sunbench apply`` reads it."""
    document = _calibration_document(catalogue, run_id, method)
    return JSONResponse(document, headers=_attachment(f"run-{run_id}-{method}.json"))


@router.get("/calibrations/{run_id}/{method}.h", response_class=PlainTextResponse, summary="Calibration as C header",
            responses={200: {"content": {"text/x-c": {}}}})
def download_calibration_header(run_id: RunId, method: str, catalogue: CatalogueDep):
    """A C header defining ``sunbench_sun_direction(x_px, y_px, &zenith, &azimuth)`` for the flight code."""
    document = _calibration_document(catalogue, run_id, method)
    try:
        text = header_from_document(document)
    except TypeError as exc:  # a method without a C export
        raise HTTPException(404, str(exc)) from None
    return PlainTextResponse(text, media_type="text/x-c", headers=_attachment(f"run-{run_id}-{method}.h"))
