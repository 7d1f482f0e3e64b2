"""The camera sun sensor of seed 001: one reading is the Sun's spot found in a camera frame.

The bench takes a frame from the camera (:class:`drivers.interfaces.ImageSensor`: a webcam through OpenCV,
:mod:`drivers.usb_camera`, or the simulated camera, :mod:`drivers.sim.camera`), finds the spot with seed 001's
pipeline (:func:`calibration.camera.detect_spot`: threshold, largest object, intensity-weighted centroid, the
thesis's validity test) and records its centre, peak, flux, area, roundness, the validity test and whether its shape
shows a cloud (:func:`calibration.camera.cloud_flag`); the frame itself is kept as a file beside the catalogue.

Its plan, ``camera-grid``, is the bench calibration seed 001 lacks (digest §7 item 4): zenith rings × azimuths over
the whole frame out to its corners (:func:`calibration.camera.camera_grid` on the design camera), each direction
set through the table's kinematics (:mod:`calibration.mount`, as the QD family's grid) so that the body direction
the engine records is the direction planned, after an auto-exposure at the boresight that puts the Sun's peak at
60–70 % of full scale. The fit at a run's end is :func:`calibration.camera.calibrate_camera` (OpenCV's camera model
and its rotation against the body frame, held out by whole zenith rings and whole azimuths).
"""

from __future__ import annotations

import math

import numpy as np

from calibration.camera import (
    CameraBenchData,
    calibrate_camera,
    camera_grid,
    cloud_flag,
    design_camera,
    detect_spot,
)
from calibration.camera.fit import SUN_DIAMETER_DEG
from calibration.centroid import CentroidError, SaturatedSpotError
from calibration.geometry import direction_vector
from calibration.mount import ForkMount, fork_for_vectors, table_for_vectors
from calibration.stage_geometry import StageGeometry

from ..campaign import CAMERA_DESIGN_FOV_DEG, CameraGridProcedure
from ..descriptor import FieldSpec, ReadingDescriptor
from ..messages import CloseShutter, LampOn, Log, Measure, Move, OpenShutter, Point, Reading, WaitWarm
from . import Family, journal_fit, register

#: An 8-bit webcam's full scale [DN] (a sensor that says otherwise, `full_scale_dn`, wins)
FULL_SCALE_DN = 255
#: The design camera (the simulated webcam's: f = 2.4 mm on 3 µm pixels, 640×480) and the Sun's disc on it [px],
#: the size the cloud flag expects of a clear disc (the bench's 0.5° source is 6 % smaller, within its bounds)
DESIGN = design_camera(640, 480, horizontal_fov_deg=CAMERA_DESIGN_FOV_DEG)
EXPECTED_RADIUS_PX = DESIGN.fx_px * math.tan(math.radians(SUN_DIAMETER_DEG / 2))
#: A spot whose centre lies closer than this to the frame's border is recorded but never fitted: its disc is cut
#: (1.5 disc radii) [px]
EDGE_MARGIN_PX = 1.5 * EXPECTED_RADIUS_PX
#: Stage of the grid's points
GRID = "grid"

DESCRIPTOR = ReadingDescriptor("camera", (
    FieldSpec("x_px", "number", "px", doc="spot centre, column: the intensity-weighted centroid (seed 001 A5)"),
    FieldSpec("y_px", "number", "px", doc="spot centre, row"),
    FieldSpec("peak_dn", "number", "DN", required=False, doc="brightest luminance in the spot"),
    FieldSpec("flux_dn", "number", "DN", required=False, doc="background-subtracted luminance of the spot"),
    FieldSpec("area_px", "integer", "px^2", required=False, doc="pixels of the spot above the threshold (eq. 1)"),
    FieldSpec("roundness", "number", "", required=False, doc="minor over major axis of the spot's second moments"),
    FieldSpec("valid", "boolean", "", required=False, doc="seed 001's validity test, eqs. 2-3 (ε = 0.95)"),
    FieldSpec("cloud", "boolean", "", required=False,
              doc="the spot's shape shows a cloud (calibration.camera.cloud_flag)"),
))


def camera_reading(repeat: int, x_px: float = math.nan, y_px: float = math.nan, status: str = "ok", t_s: float = 0.0,
                   frame=None, **values) -> Reading:
    """A camera reading from its spot's numbers (the family's, preflight's and the tests' way to make one)."""
    return Reading(repeat, status, t_s, {"x_px": float(x_px), "y_px": float(y_px), **values}, frame)


def read(sensor, repeat: int, clock) -> Reading:
    """Capture a frame and find its spot (seed 001 §2.1 A1–A6); a frame without a usable spot (none, or saturated)
    is a reading whose status names the detection's error."""
    frame = sensor.capture()
    t = clock()
    full = float(getattr(sensor, "full_scale_dn", FULL_SCALE_DN))
    try:
        spot = detect_spot(frame, saturation_dn=full, reject_saturated=True, expected_radius_px=EXPECTED_RADIUS_PX)
    except CentroidError as exc:
        peak = full if isinstance(exc, SaturatedSpotError) else getattr(exc, "peak_dn", None)
        return camera_reading(repeat, status=type(exc).__name__, t_s=t, frame=frame,
                              peak_dn=math.nan if peak is None else float(peak))
    cloudy, _ = cloud_flag(spot, expected_radius_px=EXPECTED_RADIUS_PX)
    return camera_reading(repeat, spot.x_px, spot.y_px, "ok", t, frame, peak_dn=float(spot.peak_dn),
                          flux_dn=float(spot.flux_dn), area_px=int(spot.area_px), roundness=float(spot.roundness),
                          valid=bool(spot.valid), cloud=bool(cloudy))


def dry_reading(repeat: int, campaign) -> Reading:
    """Preflight's answer: a spot at the auto-exposure's target peak, nowhere in particular."""
    target = campaign.camera_grid.auto_exposure.target_peak_fraction
    return camera_reading(repeat, peak_dn=target * FULL_SCALE_DN)


def spot_clipped(reading, width_px: int = DESIGN.width_px, height_px: int = DESIGN.height_px) -> bool:
    x, y = reading.value("x_px"), reading.value("y_px")
    return not (EDGE_MARGIN_PX <= x <= width_px - 1 - EDGE_MARGIN_PX and EDGE_MARGIN_PX <= y <= height_px - 1
                - EDGE_MARGIN_PX)


def summary(readings) -> dict:
    """The spots of a point, for a live spot map (a spot at the frame's border is recorded but never fitted), and
    how many of them the cloud flag marked."""
    good = [r for r in readings if r.ok]
    return {"spots": [(r.value("x_px"), r.value("y_px")) for r in good],
            "spots_clipped": [spot_clipped(r) for r in good],
            "clouds": sum(bool(r.value("cloud", False)) for r in good)}


def status(sensor) -> dict:
    temperature = sensor.temperature_c()
    return {"temperature_c": float(temperature) if np.isfinite(temperature) else None,
            "exposure_ms": sensor.exposure_ms()}


# --- the plan ------------------------------------------------------------------------------------------------
def table_poses(zenith_deg, azimuth_deg, mount) -> tuple[np.ndarray, np.ndarray]:
    """The table's readings that put the Sun at body directions (zenith, azimuth) [°], through its kinematics:
    (φ_s, Ω) of seed 003's azimuth-on-zenith table with its lever arm, (A, E) of an alt-az fork
    (:mod:`calibration.mount`). A direction no reading reaches raises :class:`~bench.plans.PlanError`."""
    s = direction_vector(np.asarray(zenith_deg, float), np.asarray(azimuth_deg, float))
    if isinstance(mount, ForkMount):
        first, second = fork_for_vectors(s, mount)
    else:
        first, second = table_for_vectors(s, mount)
    missed = ~(np.isfinite(first) & np.isfinite(second))
    if missed.any():
        from ..plans import PlanError

        i = int(np.flatnonzero(missed)[0])
        raise PlanError(f"{int(missed.sum())} direction(s) of the camera grid cannot be set on the table, the first "
                        f"zenith {np.ravel(zenith_deg)[i]:g}°, azimuth {np.ravel(azimuth_deg)[i]:g}°")
    return first, second


def grid_directions(procedure: CameraGridProcedure) -> tuple[np.ndarray, np.ndarray]:
    """The grid's body directions [°]: :func:`calibration.camera.camera_grid` on the design camera of the
    procedure's field of view and frame size (the boresight first, then ring by ring)."""
    design = design_camera(procedure.width_px, procedure.height_px, horizontal_fov_deg=procedure.horizontal_fov_deg)
    return camera_grid(design, rings=procedure.rings, azimuths=procedure.azimuths,
                       source_diameter_deg=SUN_DIAMETER_DEG, margin_radii=procedure.margin_radii)


def grid_points(procedure: CameraGridProcedure, mount) -> list[Point]:
    """The grid's poses, ring by ring from the boresight, every other ring's azimuths backwards (the azimuth stage
    sweeps to and fro instead of unwinding a full turn between rings)."""
    zenith, azimuth = grid_directions(procedure)
    first, second = table_poses(zenith, azimuth, mount)
    points = []
    for k, ring in enumerate(np.unique(np.round(zenith, 9))):
        members = np.flatnonzero(np.round(zenith, 9) == ring)
        members = members[np.argsort(azimuth[members])]
        if k % 2 == 0:
            members = members[::-1]
        for i in members:
            key = f"{GRID}_z{zenith[i]:07.3f}_a{azimuth[i]:07.3f}"
            points.append(Point(key, GRID, float(first[i]), float(second[i]), procedure.repeats))
    return points


def camera_grid_plan(procedure: CameraGridProcedure, *, mount):
    """The camera's bench calibration (module docstring): light up, auto-expose at the boresight, then the grid."""
    from ..plans import auto_exposure

    points = grid_points(procedure, mount)
    yield Log(f"camera grid: {len(points)} directions ({procedure.rings} zenith rings × {procedure.azimuths} azimuths "
              f"and the frame's corners, over a {procedure.horizontal_fov_deg:g}° design field of view), "
              f"{procedure.repeats} frame(s) each")
    yield LampOn()
    yield WaitWarm()
    yield OpenShutter()
    yield Move(0.0, 0.0)
    yield from auto_exposure(procedure.auto_exposure, FULL_SCALE_DN)
    for point in points:
        yield Measure(point)
    yield CloseShutter()


def make_plan(campaign, *, timing=None, mount=None):
    return camera_grid_plan(campaign.camera_grid, mount=mount if mount is not None else StageGeometry(0.0))


# --- fits when a run ends -------------------------------------------------------------------------------------
def _procedure(catalogue, run_ids) -> CameraGridProcedure:
    """The camera grid of the runs' campaign (its frame size), from the last run's plan arguments."""
    spec = (catalogue.run(list(run_ids)[-1]).get("plan_args") or {}).get("camera_grid") or {}
    return CameraGridProcedure.model_validate(spec)


def bench_data(catalogue, run_ids, *, sensor_id: str | None = None,
               procedure: CameraGridProcedure | None = None) -> tuple[CameraBenchData, np.ndarray, int]:
    """The camera bench data of runs: every reading with a spot, at the body direction the engine recorded, less the
    spots at the frame's border (recorded, never fitted). Returns the data, each point's exposure [ms] and how many
    spots the border left out."""
    procedure = procedure or _procedure(catalogue, run_ids)
    rows = [r for r in catalogue.readings(run_ids) if r.ok and r.value("x_px") is not None
            and r.value("y_px") is not None and r.zenith_deg is not None and 0.0 <= r.zenith_deg < 90.0]
    kept = [r for r in rows if not spot_clipped(r, procedure.width_px, procedure.height_px)]
    if not kept:
        from calibration.errors import InsufficientDataError
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable spot")
    data = CameraBenchData([r.zenith_deg for r in kept], [r.azimuth_body_deg for r in kept],
                           [r.value("x_px") for r in kept], [r.value("y_px") for r in kept],
                           np.array([r.repeat for r in kept]), sensor_id=sensor_id or "",
                           width_px=procedure.width_px, height_px=procedure.height_px)
    exposure = np.array([np.nan if r.exposure_ms is None else r.exposure_ms for r in kept], dtype=float)
    return data, exposure, len(rows) - len(kept)


def fit_inputs(session):
    """Nothing of the bench: the camera model starts from the spots themselves (calibration.camera.initial_camera)."""
    return None


def fit_run(catalogue, run_id: int, campaign, inputs=None, journal=None) -> list:
    """Fit the camera model to the run's lineage, keep the calibration document (the chosen one: the family has one
    method), and journal the held-out figures and the warnings."""
    from ..camera_datafile import METHOD, camera_calibration_document, camera_metrics
    from ..runner import software_version

    journal = journal or (lambda kind, message: catalogue.log_event(run_id, kind, message))
    run = catalogue.run(run_id)
    data, _, edge = bench_data(catalogue, catalogue.lineage(run_id), sensor_id=run["sensor_id"],
                               procedure=campaign.camera_grid)
    calibration = calibrate_camera(data)
    document = camera_calibration_document(calibration, source=f"run {run_id}", software=software_version(),
                                           created=False)
    catalogue.add_calibration(run_id, METHOD, document, camera_metrics(calibration), True)
    held = calibration.held_out
    figures = "" if held is None else (
        f"; held out by rings RMS {held.rings.rms_deg:.4f}°, max {held.rings.max_deg:.4f}°; by azimuths RMS "
        f"{held.azimuths.rms_deg:.4f}°, max {held.azimuths.max_deg:.4f}°")
    journal_fit(journal, f"fitted the camera model to {len(data)} spots (fit RMS {calibration.fit_rms_px:.4f} px, "
                f"{calibration.fit_rms_deg:.4f}°; χ²/dof {calibration.fit.reduced_chi2:.2f})" + figures
                + (f"; {edge} spot(s) at the frame's border left out" if edge else ""),
                (), calibration.warnings, "spot")
    return [calibration]


def export_csv(catalogue, run_ids, target, sensor_id: str | None) -> None:
    from ..camera_datafile import write_camera_csv
    data, exposure, _ = bench_data(catalogue, run_ids, sensor_id=sensor_id)
    write_camera_csv(target, data, exposure)


def c_header(document: dict) -> str:
    from ..camera_datafile import camera_header_from_document
    return camera_header_from_document(document)


FAMILY = register(Family(
    name="camera", title="Camera sun sensor (seed 001)", descriptor=DESCRIPTOR, plans=("camera-grid",), read=read,
    dry_reading=dry_reading, summary=summary, status=status, make_plan=make_plan, fit_run=fit_run,
    fit_inputs=fit_inputs, results_view="camera", export_csv=export_csv, c_header=c_header, sensor_kinds=("camera",),
    has_exposure=True))

__all__ = ["FAMILY", "DESCRIPTOR", "FULL_SCALE_DN", "bench_data", "camera_grid_plan", "grid_points", "read"]
