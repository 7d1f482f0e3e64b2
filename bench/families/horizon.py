"""The scanning Earth-horizon sensor of seed 004: one reading is one revolution — both cones' crossing times — and the
disc radius the Earth simulator reported.

The sensor (:class:`drivers.interfaces.HorizonSensor`) reports per revolution each cone's falling (Earth → space) and
rising (space → Earth) edge as times after its index mark, the revolution's period, the pulse's levels and the head's
temperature. The bench's source is an IR Earth simulator (:class:`drivers.interfaces.EarthSimulator`): a warm disc
behind an iris whose radius stands for an altitude (seed 004 eq. 2.3). The engine hands the family the source with each
reading (:attr:`bench.families.Family.reads_source`), so every reading records the radius the source reported.

Its plan, ``horizon-grid`` (:class:`bench.campaign.HorizonGridProcedure`): the disc heated and settled, the cover open,
then per disc radius a :class:`~bench.messages.SetDiscRadius` and a grid of roll × pitch over the sensor's range (seed
004 Table 1-1), each (roll, pitch) the disc centre's body direction n = (−sin θ, sin φ cos θ, cos φ cos θ) set through
the table's kinematics (:func:`bench.families.css.table_poses`), and check points never fitted; the cover closed at
the end. The fit at a run's end is :func:`calibration.horizon.bench_fit.fit_horizon_bench` (γ_k, o_k, Δρ, the mount).
"""

from __future__ import annotations

import numpy as np

from calibration.geometry import direction_vector
from calibration.horizon.scan import nadir_in_body, roll_pitch_of_nadir
from calibration.sequences import halton_points
from calibration.stage_geometry import StageGeometry

from ..campaign import HorizonGridProcedure
from ..descriptor import FieldSpec, ReadingDescriptor
from ..messages import CloseShutter, LampOn, Log, Measure, OpenShutter, Point, Reading, SetDiscRadius, WaitWarm
from . import Family, journal_fit, register

#: Stages of a horizon plan: fitted grid points, never-fitted check points
GRID, CHECK = "grid", "check"
#: The fit a run's end makes (:data:`bench.campaign.HORIZON_METHODS`)
METHOD = "crossings"

DESCRIPTOR = ReadingDescriptor("horizon", (
    FieldSpec("t_out_s", "number", "s", (2,), required=False,
              doc="per cone (1, 2): the falling edge's (Earth → space) time after the index mark; null: not found"),
    FieldSpec("t_in_s", "number", "s", (2,), required=False,
              doc="per cone: the rising edge's (space → Earth) time after the index mark; null: not found"),
    FieldSpec("period_s", "number", "s", doc="the revolution's period, index mark to index mark"),
    FieldSpec("disc_radius_deg", "number", "deg", doc="the Earth simulator's disc radius as its iris reported it"),
    FieldSpec("temperature_c", "number", "degC", doc="the head's temperature"),
    FieldSpec("level_space", "number", "", (2,), required=False, doc="per cone: the pulse's space level [counts]"),
    FieldSpec("level_earth", "number", "", (2,), required=False, doc="per cone: the pulse's Earth level [counts]"),
    FieldSpec("saturated", "integer", "", required=False,
              doc="bit k set: cone k + 1's pulse reached the ADC's full scale (its edges are not fitted)"),
    FieldSpec("revolution", "integer", "", required=False, doc="the module's revolution counter"),
))


def _finite(values) -> list:
    return [float(v) if np.isfinite(v) else None for v in values]


def read(sensor, repeat: int, clock, source=None) -> Reading:
    """One revolution of the sensor and the disc radius the source reports (NaN without an Earth simulator). A
    revolution in which neither cone found both edges is recorded with the status ``no_edges`` (the cover closed, the
    disc cold, the sensor facing away)."""
    (scan,) = sensor.read_scans(1)
    t = clock()
    radius = float("nan")
    if source is not None and hasattr(source, "disc_radius_deg"):
        radius = float(source.disc_radius_deg())
    values = {"t_out_s": _finite(scan.t_out_s), "t_in_s": _finite(scan.t_in_s), "period_s": float(scan.period_s),
              "disc_radius_deg": radius if np.isfinite(radius) else None,
              "temperature_c": float(scan.temperature_c), "level_space": _finite(scan.level_space),
              "level_earth": _finite(scan.level_earth),
              "saturated": sum(1 << k for k, s in enumerate(getattr(scan, "saturated", (False, False))) if s),
              "revolution": int(scan.revolution)}
    edges = any(np.isfinite(o) and np.isfinite(i) for o, i in zip(scan.t_out_s, scan.t_in_s))
    ok = edges and np.isfinite(radius)
    return Reading(repeat, "ok" if ok else "no_edges" if not edges else "no_disc_radius", t, values)


#: One reading on the bench [s]: a revolution at the design's 1 rev/s (seed 004 §3-5) after waiting, on average, half a
#: revolution for the index mark (each reading asks for the next complete revolution)
READING_S = 1.5

#: Preflight's answer: the design sensor (γ = 70°, 1 rev/s) at zero roll and pitch before a 68° disc
_DRY_T_OUT, _DRY_T_IN = 0.18451, 0.81549


def dry_reading(repeat: int, campaign) -> Reading:
    """Preflight's answer: both cones of the design sensor at zero attitude (seed 004 Table 4-2's 0.1845 s)."""
    return Reading(repeat, "ok", 0.0, {"t_out_s": [_DRY_T_OUT] * 2, "t_in_s": [_DRY_T_IN] * 2, "period_s": 1.0,
                                       "disc_radius_deg": campaign.horizon_grid.radii_deg()[0],
                                       "temperature_c": 25.0, "level_space": [0.0, 0.0],
                                       "level_earth": [1000.0, 1000.0], "saturated": 0, "revolution": repeat})


def summary(readings) -> dict:
    """A point's mean phases per cone (falling, rising edge) [°], the disc radius and the head's temperature, for the
    live view; a cone whose edge no reading found is None."""
    ok = [r for r in readings if r.ok]
    if not ok:
        return {"phase_out_deg": None, "phase_in_deg": None, "disc_radius_deg": None, "temperature_c": None}

    def phases(name):
        values = np.array([[np.nan if t is None else 360.0 * t / r.values["period_s"] for t in r.values[name]]
                           for r in ok], float)
        found = np.isfinite(values)
        mean = np.where(found.any(axis=0), np.nansum(values, axis=0) / np.maximum(found.sum(axis=0), 1), np.nan)
        return [float(v) if np.isfinite(v) else None for v in mean]

    return {"phase_out_deg": phases("t_out_s"), "phase_in_deg": phases("t_in_s"),
            "disc_radius_deg": float(np.mean([r.values["disc_radius_deg"] for r in ok])),
            "temperature_c": float(np.mean([r.values["temperature_c"] for r in ok]))}


def status(sensor) -> dict:
    return {"temperature_c": float(sensor.temperature_c())}


# --- the plan ---------------------------------------------------------------------------------------------------------
def body_direction_of(roll_deg, pitch_deg) -> tuple[np.ndarray, np.ndarray]:
    """The disc centre's body direction (zenith, azimuth) [°] for a roll φ and pitch θ: n = (−sin θ, sin φ cos θ,
    cos φ cos θ) (seed 004 eq. 2.6, :func:`calibration.horizon.scan.nadir_in_body`), zenith = acos n_z, azimuth =
    atan2(n_y, n_x) in [0, 360)."""
    n = nadir_in_body(roll_deg, pitch_deg)
    zenith = np.degrees(np.arccos(np.clip(n[..., 2], -1.0, 1.0)))
    azimuth = np.mod(np.degrees(np.arctan2(n[..., 1], n[..., 0])), 360.0)
    return zenith, azimuth


def roll_pitch_of_direction(zenith_deg, azimuth_deg) -> tuple[np.ndarray, np.ndarray]:
    """:func:`body_direction_of` inverted: the roll and pitch [°] whose disc centre lies at the body direction."""
    return roll_pitch_of_nadir(direction_vector(zenith_deg, azimuth_deg))


def halton_poses(n: int, roll_range_deg: float, pitch_range_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """`n` check poses spread over ±roll × ±pitch (Halton bases 2 and 3, from the second element: off the grid's
    centre)."""
    u, v = halton_points(n).T
    return (2 * u - 1) * roll_range_deg, (2 * v - 1) * pitch_range_deg


def _key(stage: str, radius: float, roll: float, pitch: float) -> str:
    return f"{stage}_r{radius:07.4f}_roll{roll:+08.3f}_pitch{pitch:+08.3f}"


def grid_points(procedure: HorizonGridProcedure, radius_deg: float, mount, *, offset: int = 0) -> list[Point]:
    """The points at one disc radius: the roll × pitch grid in serpentine order (pitch rows, roll to and fro), then
    the check poses (the `offset`-th on in the Halton sequence, so each radius gets its own)."""
    from .css import table_poses

    rolls, pitches = procedure.rolls_deg(), procedure.pitches_deg()
    grid = [(r, p) for j, p in enumerate(pitches) for r in (rolls if j % 2 == 0 else rolls[::-1])]
    check_roll, check_pitch = halton_poses(offset + procedure.check_points, procedure.roll_range_deg,
                                           procedure.pitch_range_deg)
    poses = [(GRID, r, p) for r, p in grid]
    poses += [(CHECK, round(float(r), 3), round(float(p), 3)) for r, p in zip(check_roll[offset:],
                                                                               check_pitch[offset:])]
    roll = np.array([p[1] for p in poses], float)
    pitch = np.array([p[2] for p in poses], float)
    zenith, azimuth = body_direction_of(roll, pitch)
    first, second = table_poses(zenith, azimuth, mount)
    return [Point(_key(stage, radius_deg, r, p), stage, round(float(a), 4), round(float(z), 4), procedure.repeats)
            for (stage, r, p), a, z in zip(poses, first, second)]


def horizon_grid_plan(procedure: HorizonGridProcedure, *, mount):
    """The sensor's bench calibration (module docstring)."""
    radii = procedure.radii_deg()
    stages = [(radius, grid_points(procedure, radius, mount, offset=k * procedure.check_points))
              for k, radius in enumerate(radii)]
    n = sum(len(points) for _, points in stages)
    yield Log(f"horizon grid: disc radii {', '.join(f'{r:.4f}°' for r in radii)}; roll ±{procedure.roll_range_deg:g}° "
              f"every {procedure.roll_step_deg:g}°, pitch ±{procedure.pitch_range_deg:g}° every "
              f"{procedure.pitch_step_deg:g}°, {procedure.check_points} check point(s) per radius; {n} points × "
              f"{procedure.repeats} scans")
    yield LampOn()
    yield WaitWarm()
    for radius, points in stages:
        reached = yield SetDiscRadius(float(radius), procedure.tolerance_deg, for_points=tuple(p.key for p in points))
        yield Log(f"the disc radius is {reached:.4f}°" if reached is not None else f"disc radius {radius:.4f}°: "
                  "already recorded")
        yield OpenShutter()
        for point in points:
            yield Measure(point)
    yield CloseShutter()


def make_plan(campaign, *, timing=None, mount=None):
    return horizon_grid_plan(campaign.horizon_grid, mount=mount if mount is not None else StageGeometry(0.0))


# --- fits when a run ends ---------------------------------------------------------------------------------------------
def bench_data(catalogue, run_ids, *, sensor_id: str | None = None, ifov_half_angle_deg: float | None = None):
    """The horizon bench data of runs (:class:`calibration.horizon.bench_fit.HorizonBenchData`): two rows (cones) per
    ok reading, the roll and pitch from the body direction the engine recorded, the phases 360° · t / T (a missing
    edge, or a cone whose pulse saturated, NaN), the disc radius the reading recorded, check rows from the check stage,
    the scan and the rows named by the reading's id; `ifov_half_angle_deg` the sensor's IFOV half-angle α as its
    IDENTIFY reported it (:func:`recorded_ifov_half_angle_deg`; None: not recorded, the fit takes the design's)."""
    from calibration.errors import InsufficientDataError
    from calibration.horizon.bench_fit import HorizonBenchData

    rows = {k: [] for k in ("roll", "pitch", "cone", "out", "in", "radius", "scan", "repeat", "check", "id", "t")}
    for r in catalogue.readings(run_ids):
        if not r.ok or r.zenith_deg is None:
            continue
        roll, pitch = roll_pitch_of_direction(r.zenith_deg, r.azimuth_body_deg)
        period = r.values["period_s"]
        saturated = int(r.values.get("saturated") or 0)
        for k, cone in enumerate((1, 2)):
            out, in_ = r.values["t_out_s"][k], r.values["t_in_s"][k]
            spoilt = bool(saturated >> k & 1)
            for key, value in (("roll", float(roll)), ("pitch", float(pitch)), ("cone", cone),
                               ("out", np.nan if out is None or spoilt else 360.0 * out / period),
                               ("in", np.nan if in_ is None or spoilt else 360.0 * in_ / period),
                               ("radius", r.values["disc_radius_deg"]), ("scan", r.id), ("repeat", r.repeat),
                               ("check", r.stage == CHECK), ("id", r.id), ("t", r.values["temperature_c"])):
                rows[key].append(value)
    if not rows["id"]:
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable scan")
    data = HorizonBenchData(rows["roll"], rows["pitch"], rows["cone"], rows["out"], rows["in"], rows["radius"],
                            scan=rows["scan"], repeat=rows["repeat"], check=rows["check"], sensor_id=sensor_id,
                            row_id=rows["id"], ifov_half_angle_deg=ifov_half_angle_deg)
    return data, np.array(rows["t"], float)


#: The run value (:meth:`bench.catalogue.Catalogue.set_run_value`) under which a run keeps the IFOV half-angle α [°]
#: its sensor's IDENTIFY reported: the crossing model's curvature bias b(ρ, α) (calibration.horizon.bench_fit)
IFOV_KEY = "ifov_half_angle_deg"


def fit_inputs(session) -> dict | None:
    """What the fit needs of the bench: the IFOV half-angle α [°] the sensor's IDENTIFY reports
    (:class:`drivers.horizon_sensor.HorizonIdentity`), ``{"ifov_half_angle_deg": α}``; None when the sensor does not
    tell it (the fit then takes the design's 2°). The module's identity as the runner last asked it (it checks the
    serial before each run); the wire's float32 rounded to 6 decimals (1.7, not 1.70000005)."""
    sensor = session.devices.sensor
    identity = getattr(sensor, "identity", None)
    if identity is None:
        identity = sensor.identify()
    alpha = getattr(identity, "ifov_half_angle_deg", None)
    if alpha is None or not np.isfinite(alpha):
        return None
    return {IFOV_KEY: round(float(alpha), 6)}


def recorded_ifov_half_angle_deg(catalogue, run_ids) -> float | None:
    """The IFOV half-angle α [°] the runs kept (:data:`IFOV_KEY`, each run's fit at its end keeps it), None when none
    did (a run that never reached its end).

    Raises
    ------
    BenchDataError
        The runs kept different values: their scans are not of one sensor design.
    """
    from calibration.errors import BenchDataError

    values = {run_id: catalogue.run_value(run_id, IFOV_KEY) for run_id in run_ids}
    distinct = sorted({float(v) for v in values.values() if v is not None})
    if len(distinct) > 1:
        listed = ", ".join(f"{v:g}°" for v in distinct)
        raise BenchDataError(f"runs {list(values)} recorded different IFOV half-angles ({listed}): their scans are not "
                             "of one sensor design; take them one at a time", column=IFOV_KEY)
    return distinct[0] if distinct else None


def fit_run(catalogue, run_id: int, campaign, inputs=None, journal=None) -> list:
    """Fit the sensor's own errors to the run's lineage (:func:`bench.horizon_datafile.fit_horizon`), keep the
    document in the catalogue and journal what it found: the parameters ± 1σ, the roll and pitch at the check points
    and held out by radius, the rejected edges and the warnings. The IFOV half-angle of `inputs`
    (:func:`fit_inputs`) is kept as the run's value :data:`IFOV_KEY` first, so the fit, an export and a later re-fit
    model the sensor's own IFOV."""
    from ..horizon_datafile import fit_horizon, horizon_calibration_file, horizon_fit_summary, horizon_metrics
    from ..runner import software_version

    journal = journal or (lambda kind, message: catalogue.log_event(run_id, kind, message))
    run = catalogue.run(run_id)
    if isinstance(inputs, dict) and inputs.get(IFOV_KEY) is not None:  # kept, so an export and a re-fit find it
        catalogue.set_run_value(run_id, IFOV_KEY, float(inputs[IFOV_KEY]))
    lineage = catalogue.lineage(run_id)
    data, _ = bench_data(catalogue, lineage, sensor_id=run["sensor_id"],
                         ifov_half_angle_deg=recorded_ifov_half_angle_deg(catalogue, lineage))
    fit = fit_horizon(data)
    document = horizon_calibration_file(fit, source=f"run {run_id}", software=software_version(), created=False)
    catalogue.add_calibration(run_id, METHOD, document, horizon_metrics(fit), True)
    journal_fit(journal, horizon_fit_summary(fit, len(data)), fit.rejected, fit.warnings, "edge")
    return [fit]


def export_csv(catalogue, run_ids, target, sensor_id: str | None) -> None:
    from ..horizon_datafile import write_horizon_csv

    data, temperature = bench_data(catalogue, run_ids, sensor_id=sensor_id,
                                   ifov_half_angle_deg=recorded_ifov_half_angle_deg(catalogue, run_ids))
    write_horizon_csv(target, data, temperature_c=temperature)  # α, when kept, as its `# ifov_half_angle_deg` line


def c_header(document: dict) -> str:
    from ..horizon_datafile import horizon_header_from_document

    return horizon_header_from_document(document)


FAMILY = register(Family(
    name="horizon", title="Scanning Earth-horizon sensor (seed 004)", descriptor=DESCRIPTOR, plans=("horizon-grid",),
    read=read, dry_reading=dry_reading, summary=summary, status=status, make_plan=make_plan, fit_run=fit_run,
    fit_inputs=fit_inputs, results_view="horizon", export_csv=export_csv, c_header=c_header,
    sensor_kinds=("horizon",), reads_source=True, reading_s=READING_S))

__all__ = ["FAMILY", "DESCRIPTOR", "GRID", "CHECK", "IFOV_KEY", "METHOD", "bench_data", "body_direction_of",
           "grid_points", "horizon_grid_plan", "read", "recorded_ifov_half_angle_deg", "roll_pitch_of_direction"]
