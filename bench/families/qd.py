"""The quadrant-photodiode sun sensor of seed 002: one reading is four photocurrents and a temperature.

The bench reads the module (:class:`drivers.interfaces.QuadrantSensor`, :mod:`drivers.qd_sensor`), averaging
:data:`AVERAGE` samples per reading. Its plans sweep the dark current over temperature with the shutter
closed (seed 002 §2.1), then set a square grid of the sensor's projection angles α, β over ±40° through the
table's kinematics (:mod:`calibration.mount`: the table's angles are *not* α and β, digest §7 item 9) with
check points between the nodes. The fits at a run's end are :func:`calibration.qd.evaluation.calibrate_qd`:
the dark model, the geometric model of eq. 2.2, the 2-D polynomial of eq. 2.3 and the physical model, each
scored held out between the grid's nodes.
"""

from __future__ import annotations

import numpy as np

from calibration.mount import mount_for_projection, projection_grid
from calibration.qd.data import QdBenchData
from calibration.qd.design import DEFAULT_QD
from calibration.qd.evaluation import calibrate_qd
from calibration.sequences import halton_points
from calibration.stage_geometry import StageGeometry

from ..descriptor import FieldSpec, ReadingDescriptor
from ..messages import (
    CloseShutter,
    LampOn,
    Log,
    MayStopEarly,
    Measure,
    OpenShutter,
    Point,
    Reading,
    Record,
    SetTemperature,
    WaitWarm,
)
from . import Family, journal_fit, register

#: Samples the module averages into one reading (1 ms each on the simulated module)
AVERAGE = 16

#: Status of a reading with a clipped channel: recorded, never fitted (its current is only a lower bound)
SATURATED = "SaturatedChannel"

DESCRIPTOR = ReadingDescriptor("qd", (
    FieldSpec("currents_a", "number", "A", (4,),
              doc="quadrant currents Q1…Q4 as numbered by seed 002 eq. 2.1, dark current included"),
    FieldSpec("temperature_c", "number", "degC", doc="die temperature from the module's thermometer"),
    FieldSpec("saturated", "integer", "", required=False, doc="bit k−1 set: quadrant k reached full scale"),
    FieldSpec("n_samples", "integer", "", required=False, doc="samples averaged"),
))

#: Stages of a QD plan: shutter-closed dark readings, fitted grid nodes, never-fitted check points
DARK, GRID, CHECK = "dark", "grid", "check"


def read(sensor, repeat: int, clock) -> Reading:
    """One averaged READ of the module; a clipped channel makes the reading :data:`SATURATED`."""
    r = sensor.read(average=AVERAGE)
    t = clock()
    mask = sum(1 << k for k, clipped in enumerate(r.saturated) if clipped)
    return Reading(repeat, SATURATED if mask else "ok", t,
                   {"currents_a": [float(c) for c in r.currents_a], "temperature_c": float(r.temperature_c),
                    "saturated": int(mask), "n_samples": int(r.n_samples)})


def dry_reading(repeat: int, campaign) -> Reading:
    """Preflight's answer: a lit module at room temperature."""
    return Reading(repeat, "ok", 0.0, {"currents_a": [6e-7] * 4, "temperature_c": 25.0, "saturated": 0,
                                       "n_samples": AVERAGE})


def summary(readings) -> dict:
    """A point's mean currents and temperature, for the live view."""
    ok = [r for r in readings if r.ok]
    if not ok:
        return {"currents_a": None, "temperature_c": None}
    currents = np.mean([r.values["currents_a"] for r in ok], axis=0)
    return {"currents_a": [float(c) for c in currents],
            "temperature_c": float(np.mean([r.values["temperature_c"] for r in ok]))}


def status(sensor) -> dict:
    reading = sensor.read(average=AVERAGE)
    return {"temperature_c": float(reading.temperature_c), "currents_a": [float(c) for c in reading.currents_a]}


# --- plans ---------------------------------------------------------------------------------------------------
def dark_sweep(sweep):
    """Dark readings over temperature, shutter closed (seed 002 §2.1): the module's thermal control is set to
    each temperature and `sweep.repeats` readings are taken at the table's home. Returns the readings."""
    yield CloseShutter()
    readings = []
    for t in sweep.temperatures_c:
        point = Point(f"{DARK}_t{float(t):+07.2f}", DARK, 0.0, 0.0, sweep.repeats)
        reached = yield SetTemperature(float(t), sweep.tolerance_c, for_points=(point.key,))
        yield Log(f"dark sweep: the die is at {reached:.2f} °C" if reached is not None else
                  f"dark sweep: {t:g} °C, already recorded")
        readings += (yield Measure(point)) or []
    return readings


def _points(alpha, beta, check, repeats: int, mount, step_deg: float) -> list[Point]:
    """Directions (α, β) as table poses through the table's kinematics, in serpentine order (fewer long moves)."""
    alpha, beta, check = np.asarray(alpha, float), np.asarray(beta, float), np.asarray(check, bool)
    first, second = mount_for_projection(alpha, beta, mount)
    order = np.lexsort((np.where(np.round(alpha / step_deg * 2) % 2 == 0, beta, -beta), alpha))
    points = []
    for i in order:
        stage = CHECK if check[i] else GRID
        key = f"{stage}_a{alpha[i]:+07.2f}_b{beta[i]:+07.2f}"
        points.append(Point(key, stage, round(float(first[i]), 4), round(float(second[i]), 4), repeats))
    return points


def grid_points(procedure, mount) -> list[Point]:
    """The grid plan's poses: a square (α, β) grid over ±field and the cells' centres."""
    grid = projection_grid(procedure.field_deg, procedure.step_deg, checkpoints=procedure.check_points)
    return _points(grid["alpha_deg"], grid["beta_deg"], grid["check"], procedure.repeats, mount, procedure.step_deg)


def check_directions(n: int, field_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """`n` check directions spread over the field and off every grid: the Halton sequence in bases 2 and 3,
    over 95 % of ±field [°] (the same every run, so a resumed run measures the same ones)."""
    u = halton_points(n)
    span = 0.95 * field_deg
    return np.round((2 * u[:, 0] - 1) * span, 2), np.round((2 * u[:, 1] - 1) * span, 2)


def _light_up(procedure):
    """After the dark sweep: the die at the procedure's temperature (unless None), the lamp lit and warm, the
    shutter open."""
    if procedure.temperature_c is not None:
        yield SetTemperature(float(procedure.temperature_c), procedure.dark.tolerance_c)
    yield LampOn()
    yield WaitWarm()
    yield OpenShutter()


def qd_grid_plan(procedure, *, mount):
    """Seed 002's calibration: the dark sweep with the source off (no light past a closed shutter, and an LED's
    "shutter" is its own output), then the lamp, then the grid."""
    yield from dark_sweep(procedure.dark)
    yield from _light_up(procedure)
    for point in grid_points(procedure, mount):
        yield Measure(point)
    yield CloseShutter()


def _bench_data(readings, stages) -> QdBenchData | None:
    """The readings a plan was answered, as bench data; None for preflight's dry readings (no direction)."""
    lit = [r for r, s in zip(readings, stages) if s != DARK]
    if any(not np.isfinite(r.zenith_deg) for r in lit):
        return None
    ok = [(r, s) for r, s in zip(readings, stages) if r.ok]
    return QdBenchData(zenith_deg=np.array([0.0 if s == DARK else r.zenith_deg for r, s in ok]),
                       azimuth_deg=np.array([0.0 if s == DARK else r.azimuth_body_deg for r, s in ok]),
                       currents_a=np.array([r.values["currents_a"] for r, _ in ok]),
                       temperature_c=np.array([r.values["temperature_c"] for r, _ in ok]),
                       repeat=np.array([r.repeat for r, _ in ok]), dark=np.array([s == DARK for _, s in ok]),
                       check=np.array([s == CHECK for _, s in ok]))


def qd_physical_plan(procedure, *, mount):
    """The physical model's short plan (the QD analogue of the CMOS ``physical`` plan).

    1. The dark sweep, with the source off.
    2. Batch 1: the coarsest grid of α, β (every `steps_deg[0]`) and `check_directions` fixed check directions off
       every grid (:func:`check_directions`); the physical model and the polynomial are fitted to the nodes
       measured so far (:func:`calibration.qd.evaluation.calibrate_qd`) and the one it would choose is scored on
       the check directions, which neither fits.
    3. Stop once the check maximum and RMS meet their targets; otherwise the next, finer grid's new nodes.

    In preflight nothing is fitted (the dry readings have no direction), so the plan expands to its finest grid:
    its counts are the upper bound (:class:`MayStopEarly`).
    """
    steps = procedure.steps_deg
    yield Log(f"QD physical procedure: grids every {', '.join(f'{s:g}' for s in steps)}° over "
              f"±{procedure.field_deg:g}°, {procedure.check_directions} check directions; it stops once the check "
              f"maximum is ≤ {procedure.check_max_target_deg}° and the RMS ≤ {procedure.check_rms_target_deg}°")
    yield MayStopEarly(f"the qd-physical plan stops after the first of its {len(steps)} grids whose fit meets the "
                       "targets")
    dark = yield from dark_sweep(procedure.dark)
    readings, stages = list(dark), [DARK] * len(dark)
    yield from _light_up(procedure)
    measured: set[str] = set()
    check_alpha, check_beta = check_directions(procedure.check_directions, procedure.field_deg)
    decision: dict = {}
    for number, step in enumerate(steps, start=1):
        grid = projection_grid(procedure.field_deg, step, checkpoints=False)
        points = [p for p in _points(grid["alpha_deg"], grid["beta_deg"], grid["check"], procedure.repeats, mount,
                                     step) if p.key not in measured]
        if number == 1:
            points += _points(check_alpha, check_beta, np.ones(check_alpha.size, bool), procedure.repeats, mount,
                              step)
        for point in points:
            answer = (yield Measure(point)) or []
            readings += answer
            stages += [point.stage] * len(answer)
            measured.add(point.key)
        data = _bench_data(readings, stages)
        if data is None:
            continue  # preflight: nothing to decide on
        # the method the run's end would choose, judged on the check directions it never fits
        report = calibrate_qd(data, methods=("physical", "polynomial")).chosen
        check = report.heldout_by_scheme.get("check")
        decision = {"grid_step_deg": step, "n_nodes": int(sum(1 for k in measured if k.startswith(GRID))),
                    "check_max_deg": None if check is None else check.max_deg,
                    "check_rms_deg": None if check is None else check.rms_deg, "error": report.error,
                    "method": report.method}
        decision["stop"] = bool(check is not None and check.max_deg <= procedure.check_max_target_deg
                                and check.rms_deg <= procedure.check_rms_target_deg)
        yield Record(f"qd_physical_batch_{number}", decision)
        yield Log(f"grid {number}/{len(steps)} ({step:g}°, {decision['n_nodes']} nodes): check max "
                  + (f"{check.max_deg:.4f}°, RMS {check.rms_deg:.4f}°" if check else "—")
                  + ("; targets met, stopping" if decision["stop"] else ""))
        if decision["stop"]:
            break
    yield Record("qd_physical_stop", decision)
    yield CloseShutter()


def qd_dark_plan(sweep):
    """Only the dark sweep: no light at all."""
    yield from dark_sweep(sweep)


def make_plan(campaign, *, timing=None, mount=None):
    if campaign.plan == "qd-dark":
        return qd_dark_plan(campaign.qd_dark)
    mount = mount if mount is not None else StageGeometry(0.0)
    if campaign.plan == "qd-physical":
        return qd_physical_plan(campaign.qd_physical, mount=mount)
    return qd_grid_plan(campaign.qd_grid, mount=mount)


# --- fits when a run ends -------------------------------------------------------------------------------------
def bench_data(catalogue, run_ids, *, sensor_id: str | None = None) -> QdBenchData:
    """The QD bench data of runs: every ok reading (a clipped channel's reading stays in the catalogue only),
    dark rows from the dark stage, check points from the check stage, rows named by reading id."""
    rows = [r for r in catalogue.readings(run_ids) if r.ok]
    if not rows:
        from calibration.errors import InsufficientDataError
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable reading")
    return QdBenchData(zenith_deg=[r.zenith_deg for r in rows], azimuth_deg=[r.azimuth_body_deg for r in rows],
                       currents_a=[r.values["currents_a"] for r in rows],
                       temperature_c=[r.values["temperature_c"] for r in rows],
                       repeat=[r.repeat for r in rows], sensor_id=sensor_id,
                       dark=[r.stage == DARK for r in rows], check=[r.stage == CHECK for r in rows],
                       row_id=[r.id for r in rows])


def fit_inputs(session):
    """The nominal design (the fit starts from it; every parameter that matters is fitted)."""
    return DEFAULT_QD


def fit_run(catalogue, run_id: int, campaign, design, journal=None) -> list:
    """Fit every QD method to the run's lineage; keep each calibration, the best held-out one as chosen; what it
    found goes to `journal(kind, message)` (the engine's journaled events, which the CLI and the stream see)."""
    journal = journal or (lambda kind, message: catalogue.log_event(run_id, kind, message))
    run = catalogue.run(run_id)
    data = bench_data(catalogue, catalogue.lineage(run_id), sensor_id=run["sensor_id"])
    if campaign.plan == "qd-dark":
        return []  # a dark sweep alone calibrates no direction (the results page fits its dark current)
    outcome = calibrate_qd(data, methods=campaign.methods, design=design)
    for report in outcome.reports:
        if report.document is None:
            continue
        document = {**report.document, "source": f"run {run_id}", "rejected": [r.to_dict() for r in outcome.rejected],
                    "warnings": list(outcome.warnings)}
        catalogue.add_calibration(run_id, report.method, document, report.to_dict(), report is outcome.chosen)
    chosen = outcome.chosen
    held = chosen.heldout
    journal_fit(journal, f"fitted {len(outcome.directions)} directions; chosen {chosen.method}"
                + (f", held-out max {held.max_deg:.4f}°, RMS {held.rms_deg:.4f}°" if held else ""),
                outcome.rejected, outcome.warnings, "reading")
    return outcome.reports


def export_csv(catalogue, run_ids, target, sensor_id: str | None) -> None:
    from ..qd_datafile import write_qd_csv
    write_qd_csv(target, bench_data(catalogue, run_ids, sensor_id=sensor_id))


def c_header(document: dict) -> str:
    from ..qd_datafile import qd_header_from_document
    return qd_header_from_document(document)


FAMILY = register(Family(
    name="qd", title="Quadrant-photodiode sun sensor (seed 002)", descriptor=DESCRIPTOR,
    plans=("qd-grid", "qd-physical", "qd-dark"), read=read, dry_reading=dry_reading, summary=summary, status=status,
    make_plan=make_plan, fit_run=fit_run, fit_inputs=fit_inputs, results_view="qd",
    export_csv=export_csv, c_header=c_header, sensor_kinds=("qd",)))

__all__ = ["FAMILY", "DESCRIPTOR", "AVERAGE", "bench_data", "grid_points", "qd_grid_plan", "qd_dark_plan"]
