"""Files to take away: a run's bench data CSV, and calibrations as JSON or as a C header."""

from __future__ import annotations

import tempfile
from pathlib import Path

from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse, PlainTextResponse

from bench.families import family
from calibration.errors import CalibrationError, InsufficientDataError

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
    """The run's lineage as bench data, in the format ``sunbench fit`` reads (as ``sunbench export`` writes it): of a
    cmos run true angles and spot centres (``fit cmos``), of a qd run the four currents and the temperature of
    every reading, dark ones included (``fit qd``, README "QD bench data CSV")."""
    run = catalogue.run(run_id)
    with tempfile.TemporaryDirectory() as folder:  # the writer wants a path; one writer per format
        path = Path(folder) / "data.csv"
        try:
            family(run["family"]).export_csv(catalogue, catalogue.lineage(run_id), path, run["sensor_id"])
        except InsufficientDataError as exc:
            raise HTTPException(404, str(exc)) from None
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
    """A C header defining ``sunbench_sun_direction(x_px, y_px, &zenith, &azimuth)`` for the flight code (of a QD
    calibration ``sunbench_qd_sun_direction(currents_a, temperature_c, &zenith, &azimuth)``)."""
    document = _calibration_document(catalogue, run_id, method)
    try:
        text = family(document.get("family") or "cmos").c_header(document)
    except TypeError as exc:  # a method without a C export
        raise HTTPException(404, str(exc)) from None
    except CalibrationError as exc:  # a document it cannot export (a non-finite value …)
        raise HTTPException(409, str(exc)) from None
    return PlainTextResponse(text, media_type="text/x-c", headers=_attachment(f"run-{run_id}-{method}.h"))
