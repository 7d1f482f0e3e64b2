"""The Horizon bench data CSV (README, "Horizon bench data CSV") and horizon calibration files.

A scanning horizon sensor's bench data (seed 004): one row per cone of one scan (revolution). Columns:

* ``roll_deg, pitch_deg``: what the table set, in its own frame — the Earth simulator's disc centre at
  n = (−sin θ, sin φ cos θ, cos φ cos θ) (calibration/horizon conventions), |roll|, |pitch| < 90°;
* ``cone``: 1 or 2;
* ``t_out_s, t_in_s, period_s``: the falling (Earth → space) and rising (space → Earth) edges' times after the index
  mark and the revolution's period [s] — or instead ``phase_out_deg, phase_in_deg`` = 360° · t / T, in [0, 360); an
  empty cell is an edge the module did not find;
* ``disc_radius_deg``: the disc radius the Earth simulator reported, in (0, 90)°;
* optional: ``repeat`` (whole number), ``scan`` (the rows of both cones of one revolution share it; without the column
  the k-th row of cone 1 and the k-th of cone 2 at one pose, radius and repeat are paired), ``check`` (0/1: never
  fitted, only scored), ``sensor_id``, ``temperature_c``.

The file is read with the CMOS reader's table (:func:`bench.datafile.read_csv_table`: header row, ``#`` comments,
blank lines, a byte-order mark, duplicate columns, ragged rows), so every problem is the same
:class:`~bench.datafile.DataFileError` naming the file, the row (and its line) and the column.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.errors import BenchDataError, CalibrationFormatError
from calibration.horizon.bench_fit import HorizonBenchData

from .datafile import (
    CsvTable,
    DataFileError,
    flag_column,
    header_numbers,
    load_calibration_json,
    read_bench_table,
    read_csv_table,
    refuse_rows,
    require_columns,
    row_place,
    sensor_rows,
    temperature_column,
)

POSE_COLUMNS = ("roll_deg", "pitch_deg")
TIME_COLUMNS = ("t_out_s", "t_in_s", "period_s")
PHASE_COLUMNS = ("phase_out_deg", "phase_in_deg")
#: ``# key: value`` header comments: the sensor's design (the IFOV half-angle α whose limb-curvature bias the fit's
#: crossing model carries, :func:`calibration.horizon.bench_fit.model_disc_radius_deg`; without it the design's 2°)
DESIGN_KEYS = ("ifov_half_angle_deg",)
#: A revolution's period a file may hold [s]: seed 004's sensor turns once a second; more is a file in ms.
MAX_PERIOD_S = 60.0
#: Largest file read [bytes].
MAX_FILE_BYTES = 64 * 2**20


@dataclass(frozen=True)
class HorizonFrames:
    """A Horizon bench data CSV as read.

    Attributes
    ----------
    data : HorizonBenchData
        One row per cone of a scan; `row_id` is the file's data row (1-based, the header not counted).
    path : str
    lines : dict of int to int
        The file line of each data row.
    temperature_c : ndarray or None
    """

    data: HorizonBenchData
    path: str = ""
    lines: dict = field(default_factory=dict)
    temperature_c: np.ndarray | None = None

    def where(self, row: int) -> str:
        """``row N (line L)`` of a data row, as error messages say it."""
        return row_place(self.lines, row)


def _hint_other_family(table: CsvTable) -> None:
    if table.has("cone") or any(table.has(c) for c in TIME_COLUMNS + PHASE_COLUMNS):
        return
    if table.has("x_px") and table.has("y_px"):
        raise DataFileError(table.path, "has spot columns x_px, y_px and no cone, t_out_s …: a CMOS or camera sensor's "
                                        "CSV (`sunbench fit cmos` or `fit camera` reads it), not a horizon one")
    if table.has("i1_a"):
        raise DataFileError(table.path, "has quadrant currents i1_a … i4_a: a QD sensor's CSV (`sunbench fit qd` reads "
                                        "it), not a horizon one")
    if any(c.endswith(("_uv_a", "_vis_a", "_ir_v")) for c in table.header):
        raise DataFileError(table.path, "has CSS detector columns: a CSS head's CSV (`sunbench fit css` reads it), not "
                                        "a horizon one")


def _phases(table: CsvTable) -> tuple[np.ndarray, np.ndarray]:
    """The edges' phases [°] from times and periods or from phase columns (empty cell: no edge, NaN)."""
    times = any(table.has(c) for c in TIME_COLUMNS)
    phases = any(table.has(c) for c in PHASE_COLUMNS)
    if times and phases:
        raise DataFileError(table.path, "has both edge times (t_out_s, t_in_s, period_s) and phases (phase_out_deg, "
                                        "phase_in_deg): give one or the other")
    anywhere = np.ones(len(table.rows), bool)
    if times:
        require_columns(table, TIME_COLUMNS)
        period = table.numbers("period_s")
        refuse_rows(table, "period_s", period, (period <= 0) | (period > MAX_PERIOD_S),
                    lambda v: f"a revolution's period of {v:g} s is out of range (0 < T ≤ {MAX_PERIOD_S:g} s); times "
                              "are in seconds")
        out = []
        for name in TIME_COLUMNS[:2]:
            t = table.numbers(name, allow_empty=anywhere)
            bad = np.isfinite(t) & ((t < 0) | (t >= period))
            refuse_rows(table, name, t, bad, lambda v: f"{v:g} s is not within the revolution (0 ≤ t < period_s); "
                                                       "times are in seconds after the index mark")
            out.append(360.0 * t / period)
        return out[0], out[1]
    if not phases:
        raise DataFileError(table.path, "no edge columns: a horizon file has t_out_s, t_in_s, period_s (or "
                                        f"phase_out_deg, phase_in_deg); the header has {', '.join(table.header)}")
    require_columns(table, PHASE_COLUMNS)
    out = []
    for name in PHASE_COLUMNS:
        p = table.numbers(name, allow_empty=anywhere)
        refuse_rows(table, name, p, np.isfinite(p) & ((p < 0) | (p >= 360)),
                    lambda v: f"phase {v:g}° is not in [0, 360)")
        out.append(p)
    return out[0], out[1]


def _pair_scans(roll, pitch, radius, repeat, check, cone, sensor=None) -> np.ndarray:
    """A scan id per row: the k-th row of cone 1 and the k-th of cone 2 of one sensor at one pose, radius, repeat and
    kind (`sensor`: each row's sensor id, None: one sensor)."""
    seen: dict = {}
    scan = np.empty(cone.size, int)
    next_id = 0
    for i in range(cone.size):
        key = (None if sensor is None else sensor[i], round(roll[i], 6), round(pitch[i], 6), round(radius[i], 6),
               int(repeat[i]), bool(check[i]))
        counts = seen.setdefault(key, {1: [], 2: []})
        k = len(counts[int(cone[i])])
        other = counts[3 - int(cone[i])]
        if k < len(other):
            scan[i] = other[k][1]
        else:
            scan[i] = next_id
            next_id += 1
        counts[int(cone[i])].append((i, scan[i]))
    return scan


def read_horizon_frames(path, *, sensor_id: str | None = None) -> HorizonFrames:
    """Read a Horizon bench data CSV (README, "Horizon bench data CSV").

    Parameters
    ----------
    path : path-like
    sensor_id : str, optional
        Keep only this sensor's rows (a file may hold a batch; one holding several needs it).

    Raises
    ------
    DataFileError
        Naming the file, and where it can the row, its line and the column.
    """
    table = read_bench_table(path, MAX_FILE_BYTES)
    _hint_other_family(table)
    require_columns(table, POSE_COLUMNS + ("cone", "disc_radius_deg"))
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    keep, sensor_id = sensor_rows(table, sensor_id)
    roll, pitch = table.numbers("roll_deg"), table.numbers("pitch_deg")
    refuse_rows(table, "roll_deg", roll, np.abs(roll) >= 90, lambda v: f"roll {v:g}° is out of range (|roll| < 90°)")
    refuse_rows(table, "pitch_deg", pitch, np.abs(pitch) >= 90,
                lambda v: f"pitch {v:g}° is out of range (|pitch| < 90°)")
    cone = table.numbers("cone", integer=True)
    refuse_rows(table, "cone", cone, (cone != 1) & (cone != 2), lambda v: f"cone {v:g}: a cone is 1 or 2")
    radius = table.numbers("disc_radius_deg")
    refuse_rows(table, "disc_radius_deg", radius, (radius <= 0) | (radius >= 90),
                lambda v: f"a disc radius of {v:g}° is out of range (0 < ρ < 90°)")
    phase_out, phase_in = _phases(table)
    repeat = table.numbers("repeat", integer=True).astype(int) if table.has("repeat") else np.zeros(len(table.rows),
                                                                                                     int)
    check = flag_column(table, "check")
    temperature = temperature_column(table) if table.has("temperature_c") else None
    scan = table.numbers("scan", integer=True).astype(int) if table.has("scan") else None
    design = header_numbers(table, DESIGN_KEYS)
    # the chosen sensor's rows only, before the scans are paired and checked: each sensor of a batch numbers its
    # own scans (scan 0 of sensor A is not scan 0 of sensor B)
    index = np.flatnonzero(keep)
    roll, pitch, cone, phase_out, phase_in, radius, repeat, check = (a[index] for a in (
        roll, pitch, cone, phase_out, phase_in, radius, repeat, check))
    temperature = None if temperature is None else temperature[index]
    if scan is None:
        ids = table.texts("sensor_id") if table.has("sensor_id") else None
        scan = _pair_scans(roll, pitch, radius, repeat, check, cone, None if ids is None else [ids[i] for i in index])
    else:
        scan = scan[index]
    row_id = index + 1  # the file's data row, whatever rows of other sensors lie between
    try:
        data = HorizonBenchData(roll, pitch, cone.astype(int), phase_out, phase_in, radius, scan=scan, repeat=repeat,
                                check=check, sensor_id=sensor_id, row_id=row_id,
                                ifov_half_angle_deg=design.get("ifov_half_angle_deg"))
    except BenchDataError as exc:  # what the checks above did not catch (a scan with two rows of one cone)
        row = None if exc.row is None else int(row_id[exc.row])
        raise DataFileError(table.path, str(exc), row=row, line=None if row is None else table.lines[row - 1],
                            column=exc.column if exc.column in table.header else None) from None
    return HorizonFrames(data, table.path, {i + 1: line for i, line in enumerate(table.lines)}, temperature)


def read_horizon_csv(path, *, sensor_id: str | None = None) -> HorizonBenchData:
    """:func:`read_horizon_frames`, the data only."""
    return read_horizon_frames(path, sensor_id=sensor_id).data


def _number(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ""


def write_horizon_csv(path, data: HorizonBenchData, *, temperature_c=None) -> None:
    """Write horizon bench data in the format :func:`read_horizon_csv` reads, with the edges as phases.

    Floats are written as Python's shortest round-trip repr, so they read back bit for bit; an edge the module did not
    find (NaN) is an empty cell.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        if data.ifov_half_angle_deg is not None:
            fh.write(f"# ifov_half_angle_deg: {data.ifov_half_angle_deg!r}\n")
        w = csv.writer(fh)
        w.writerow([*POSE_COLUMNS, "cone", *PHASE_COLUMNS, "disc_radius_deg", "scan", "repeat", "check"]
                   + (["temperature_c"] if temperature_c is not None else [])
                   + (["sensor_id"] if data.sensor_id else []))
        for i in range(len(data)):
            row = [repr(float(data.roll_deg[i])), repr(float(data.pitch_deg[i])), int(data.cone[i]),
                   _number(data.phase_out_deg[i]), _number(data.phase_in_deg[i]), repr(float(data.disc_radius_deg[i])),
                   int(data.scan[i]), int(data.repeat[i]), int(data.check[i])]
            if temperature_c is not None:
                row.append(repr(float(temperature_c[i])))
            if data.sensor_id:
                row.append(data.sensor_id)
            w.writerow(row)


# --- fitting: the one place the bench calls calibration.horizon.bench_fit ---------------------------------------------

def fit_horizon(data: HorizonBenchData, *, heldout: bool = True):
    """The sensor's own errors from its bench data (:func:`calibration.horizon.bench_fit.fit_horizon_bench`)."""
    from calibration.horizon.bench_fit import fit_horizon_bench

    return fit_horizon_bench(data, heldout=heldout)


def horizon_calibration_file(fit, *, source: str | None, software: str | None, created: bool = True) -> dict:
    """The calibration document of a fit (:func:`calibration.horizon.bench_document.horizon_document`) with its
    provenance: the source (file or run), the time (`created`; the catalogue stamps a run's itself), the software."""
    from calibration.horizon.bench_document import horizon_document

    document = horizon_document(fit)
    document.update({"source": source, "software": software})
    if created:
        document["created_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    return document


def horizon_metrics(fit) -> dict:
    """A calibration's figures as the catalogue keeps them beside its document: the parameters ± 1σ, χ²/dof, the
    condition number, and the roll and pitch errors held out (check scans, each radius left out) and at the fitted
    scans, calibrated and nominal."""
    held = fit.heldout or {}
    return {"parameters": {n: {"value": getattr(fit.parameters, n), "sd": fit.sd.get(n)} for n in fit.free},
            "chi2_dof": fit.chi2_dof, "condition_number": fit.condition_number, "rms_deg": fit.rms_deg,
            "check": held.get("check"), "at_nodes": held.get("at_nodes"),
            "radius_out": [{k: v for k, v in e.items() if k != "parameters"} for e in held.get("radius_out", [])],
            "n_rejected": len(fit.rejected)}


def _attitude(entry: dict | None) -> str:
    if not entry or not entry.get("n_scans"):
        return "—"
    return (f"roll RMS {entry['roll_rms_deg']:.4f}° (max {entry['roll_max_deg']:.4f}°), pitch RMS "
            f"{entry['pitch_rms_deg']:.4f}° (max {entry['pitch_max_deg']:.4f}°) over {entry['n_scans']} scans")


def horizon_fit_summary(fit, n_rows: int) -> str:
    """One line of what a fit found, for a run's journal: the parameters ± 1σ, χ²/dof, and roll and pitch against
    the table at the check scans and with each disc radius left out."""
    params = ", ".join(f"{n} {getattr(fit.parameters, n):.4f} ± {fit.sd[n]:.4f}" for n in fit.free)
    line = (f"fitted the horizon sensor to {fit.n_edges} edges of {fit.n_scans} scans ({n_rows} rows): {params}; "
            f"χ²/dof {fit.chi2_dof:.2f} against the repeat scatter")
    held = fit.heldout or {}
    if held.get("check"):
        line += f"; at the check points: {_attitude(held['check']['calibrated'])} (nominal sensor: " \
                f"{_attitude(held['check']['nominal'])})"
    for entry in held.get("radius_out", []):
        line += f"; ρ {entry['disc_radius_deg']:.3f}° left out: {_attitude(entry.get('calibrated'))}"
    return line


def is_horizon_document(document) -> bool:
    """Whether a calibration document (parsed JSON) says it is of the horizon family."""
    return isinstance(document, dict) and document.get("family") == "horizon"


def read_horizon_calibration(path) -> dict:
    """A horizon calibration document, checked
    (:func:`calibration.horizon.bench_document.validate_horizon_document`)."""
    from calibration.horizon.bench_document import validate_horizon_document

    document = load_calibration_json(path)
    try:
        validate_horizon_document(document)
    except CalibrationFormatError as exc:
        raise DataFileError(path, str(exc)) from None
    return document


def horizon_header_from_document(document: dict) -> str:
    """The C header of a horizon calibration document (:func:`calibration.horizon.bench_document.c_header`), its
    opening comment naming the source, the date, the software and the roll/pitch error at the check points."""
    from calibration.horizon.bench_document import c_header

    check = ((document.get("heldout") or {}).get("check") or {}).get("calibrated")
    provenance = {"source": document.get("source"), "created": document.get("created_utc"),
                  "software": document.get("software"),
                  "check points": None if not check or not check.get("n_scans") else _attitude(check)}
    return c_header(document, provenance=provenance)


# --- applying a calibration -----------------------------------------------------------------------------------------

def apply_horizon(document: dict, frames: HorizonFrames) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Each row's scan's roll and pitch [°] in the sensor's own frame from its crossings with the document alone
    (:func:`calibration.horizon.bench_fit.solve_roll_pitch`), and, where the file gives the table's angles, the error
    of the same attitude turned into the table's frame through the calibrated mount, (N, 2) or None."""
    from calibration.horizon.bench_document import sensor_parameters_from_document
    from calibration.horizon.bench_fit import solve_roll_pitch, table_roll_pitch, wrap_deg

    parameters = sensor_parameters_from_document(document)
    data = frames.data
    scans, roll, pitch = solve_roll_pitch(data, parameters)
    index = np.searchsorted(scans, data.scan)
    roll, pitch = roll[index], pitch[index]
    table_roll, table_pitch = table_roll_pitch(np.nan_to_num(roll), np.nan_to_num(pitch), parameters)
    error = np.column_stack([wrap_deg(table_roll - data.roll_deg), table_pitch - data.pitch_deg])
    error[~np.isfinite(roll)] = np.nan
    return roll, pitch, error


def write_horizon_applied_csv(path, source, roll, pitch, error) -> None:
    """The input file's columns, then `sensor_roll_deg, sensor_pitch_deg` (the sensor's own attitude, empty where not
    solved) and `roll_error_deg, pitch_error_deg` (against the table, through the mount)."""
    table = read_csv_table(source)
    added = ["sensor_roll_deg", "sensor_pitch_deg", "roll_error_deg", "pitch_error_deg"]
    header = [f"input_{c}" if c in added else c for c in table.header] + added
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, row in enumerate(table.rows):
            cells = [roll[i], pitch[i], error[i, 0], error[i, 1]]
            w.writerow([*row, *("" if not np.isfinite(c) else f"{c:.6f}" for c in cells)])
