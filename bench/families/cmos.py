"""The CMOS pinhole sun sensor of seed 003: one reading is the spot centre found in a frame.

The bench takes a frame from the module (:class:`drivers.interfaces.ImageSensor`), finds the spot with the
seed 003 centroid (:func:`calibration.centroid.find_spot`) and records its centre, peak, size and flags; the
frame itself is kept as a file beside the catalogue. Its plans are seed 003's procedure, a plain grid and the
physical model's D-optimal plan; the fits at a run's end are every CMOS method, scored held out.
"""

from __future__ import annotations

import numpy as np

from calibration.centroid import CentroidError, SpotFlag, find_spot
from calibration.design import FULL_SCALE_DN  # the detector's full scale [DN], one definition
from calibration.models import METHODS

from ..descriptor import FieldSpec, ReadingDescriptor
from ..messages import Reading
from . import Family, register

#: Spot flags of a spot cut by the frame's edge: its centre is biased, so it is recorded but never fitted
EDGE_FLAGS = int(SpotFlag.NEAR_EDGE | SpotFlag.ROI_CLIPPED)

DESCRIPTOR = ReadingDescriptor("cmos", (
    FieldSpec("x_px", "number", "px", doc="spot centre, column"),
    FieldSpec("y_px", "number", "px", doc="spot centre, row"),
    FieldSpec("peak_dn", "number", "DN", required=False, doc="brightest pixel"),
    FieldSpec("n_pixels", "integer", "", required=False, doc="pixels in the spot"),
    FieldSpec("flags", "integer", "", required=False, doc="calibration.centroid.SpotFlag bits"),
))


def spot_reading(repeat: int, x_px: float, y_px: float, peak_dn: float = float("nan"), n_pixels: int = 0,
                 flags: int = 0, status: str = "ok", t_s: float = 0.0, frame=None, *,
                 zenith_deg: float = float("nan"), azimuth_body_deg: float = float("nan")) -> Reading:
    """A CMOS reading from its spot's numbers (the engine's, preflight's and the tests' way to make one)."""
    values = {"x_px": float(x_px), "y_px": float(y_px), "peak_dn": float(peak_dn), "n_pixels": int(n_pixels),
              "flags": int(flags)}
    return Reading(repeat, status, t_s, values, frame, zenith_deg, azimuth_body_deg)


def read(sensor, repeat: int, clock) -> Reading:
    """Capture a frame and find its spot (seed 003 §3.3); a frame without a usable spot is a reading whose
    status names the centroid error."""
    frame = sensor.capture()
    t = clock()
    try:
        spot = find_spot(frame, saturation_dn=FULL_SCALE_DN)
    except CentroidError as exc:
        peak = getattr(exc, "peak_dn", None)
        return spot_reading(repeat, np.nan, np.nan, np.nan if peak is None else float(peak), 0, 0,
                            type(exc).__name__, t, frame)
    return spot_reading(repeat, spot.x_px, spot.y_px, spot.peak_dn, spot.n_pixels, int(spot.flags), "ok", t, frame)


def dry_reading(repeat: int, campaign) -> Reading:
    """Preflight's answer: a spot at the auto-exposure's target peak, nowhere in particular."""
    from ..plans import procedure_auto_exposure
    return spot_reading(repeat, np.nan, np.nan, procedure_auto_exposure(campaign).target_peak_fraction * FULL_SCALE_DN,
                        0, 0, "ok")


def summary(readings) -> dict:
    """The spots of a point, for a live spot map; a spot cut by the frame's edge is recorded but never fitted."""
    good = [r for r in readings if r.ok]
    return {"spots": [(r.value("x_px"), r.value("y_px")) for r in good],
            "spots_clipped": [bool(int(r.value("flags", 0)) & EDGE_FLAGS) for r in good]}


def status(sensor) -> dict:
    return {"temperature_c": sensor.temperature_c(), "exposure_ms": sensor.exposure_ms()}


def make_plan(campaign, *, timing=None, mount=None):
    from ..plans import make_plan as cmos_plan
    return cmos_plan(campaign, timing=timing)


def fit_inputs(session):
    from ..runner import fit_inputs as cmos_inputs
    return cmos_inputs(session)


def fit_run(catalogue, run_id: int, campaign, inputs, journal=None) -> list:
    from ..runner import fit_run as cmos_fit
    design, geometry = inputs
    return cmos_fit(catalogue, run_id, campaign.methods or METHODS, design, geometry, journal=journal)


def export_csv(catalogue, run_ids, target, sensor_id: str | None) -> None:
    from ..datafile import write_bench_csv
    from ..runner import bench_data
    write_bench_csv(target, bench_data(catalogue, run_ids, sensor_id=sensor_id))


def c_header(document: dict) -> str:
    from ..datafile import header_from_document
    return header_from_document(document)


FAMILY = register(Family(
    name="cmos", title="CMOS pinhole sun sensor (seed 003)", descriptor=DESCRIPTOR,
    plans=("seed003", "grid", "physical"), read=read, dry_reading=dry_reading, summary=summary, status=status,
    make_plan=make_plan, fit_run=fit_run, fit_inputs=fit_inputs, results_view="cmos",
    export_csv=export_csv, c_header=c_header, sensor_kinds=("cmos",),
    has_exposure=True))
