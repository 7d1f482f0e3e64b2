"""The QD bench data CSV (README, "QD bench data CSV") and QD calibration files.

A quadrant-photodiode sensor's bench data (seed 002): one row per reading, the true sun direction in the body
frame, the four raw quadrant currents in amperes (quadrant k as numbered by seed 002 eq. 2.1: Q1 (−x, −y),
Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y)), the die's temperature, and whether the shutter was closed (`dark`) or
the row is an off-node check point (`check`).

The file is read with the CMOS reader's table (:func:`bench.datafile.read_csv_table`: header row, ``#``
comments, blank lines, a byte-order mark, duplicate columns, ragged rows), so every problem is the same
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
from calibration.qd.angles import angle_between_projections_deg, projection_angles
from calibration.qd.data import QdBenchData
from calibration.qd.design import DEFAULT_QD, QdDesign
from calibration.qd.document import FAMILY as QD_FAMILY
from calibration.qd.document import validate_document

from .datafile import (
    TRUE_COLUMNS,
    CsvTable,
    DataFileError,
    flag_column,
    header_numbers,
    load_calibration_json,
    read_bench_table,
    refuse_rows,
    require_columns,
    row_place,
    sensor_rows,
    temperature_column,
)

#: Quadrant currents, column k−1 = quadrant k of seed 002 eq. 2.1 [A].
CURRENT_COLUMNS = ("i1_a", "i2_a", "i3_a", "i4_a")
#: Columns every QD bench data CSV has.
REQUIRED_COLUMNS = TRUE_COLUMNS + CURRENT_COLUMNS + ("temperature_c",)
#: 0/1 columns: shutter closed; off-node check point (never fitted, only scored).
FLAG_COLUMNS = ("dark", "check")
#: Largest current a quadrant may carry [A]: a photodiode's are µA to mA, so more is a file in other units.
MAX_CURRENT_A = 0.01
#: Largest file read [bytes]: a full ±40° grid at 1° with 3 repeats is about 5 MB.
MAX_FILE_BYTES = 64 * 2**20
#: ``# key: value`` header comments: the sensor's nominal design (:class:`calibration.qd.design.QdDesign`),
#: where a QD fit starts (the angles do not depend on its scale).
DESIGN_KEYS = ("diaphragm_diameter_m", "pinhole_height_m", "gap_m", "length_m", "fov_half_deg")


@dataclass(frozen=True)
class QdFrames:
    """A QD bench data CSV as read.

    Attributes
    ----------
    data : QdBenchData
        One row per reading; `row_id` is the file's data row (1-based, the header not counted).
    design : QdDesign
        The nominal design, from the header comments over the default.
    given : dict
        The header comments' numbers (:data:`DESIGN_KEYS`).
    path : str
    lines : dict of int to int
        The file line of each data row.
    """

    data: QdBenchData
    design: QdDesign = DEFAULT_QD
    given: dict = field(default_factory=dict)
    path: str = ""
    lines: dict = field(default_factory=dict)

    def where(self, row: int) -> str:
        """``row N (line L)`` of a data row, as error messages say it."""
        return row_place(self.lines, row)


def _design(table: CsvTable) -> tuple[QdDesign, dict]:
    given = header_numbers(table, DESIGN_KEYS)
    try:
        return QdDesign(**given), given
    except ValueError as exc:
        raise DataFileError(table.path, f"header comments: {exc}") from None


def _currents(table: CsvTable) -> np.ndarray:
    columns = []
    for name in CURRENT_COLUMNS:
        values = table.numbers(name)
        refuse_rows(table, name, values, np.abs(values) > MAX_CURRENT_A,
                             lambda v: f"{v:g} A is out of range for a photodiode (|current| ≤ {MAX_CURRENT_A:g} A); "
                                       "the currents are in amperes (µA × 1e-6)")
        columns.append(values)
    return np.stack(columns, axis=1)


def _directions(table: CsvTable, dark: np.ndarray, *, optional: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Zenith and azimuth; empty on dark rows (or anywhere when `optional`): NaN. A light row's zenith lies in
    [0, 90)."""
    empty_ok = np.ones(len(table.rows), bool) if optional else dark
    zenith = table.numbers("zenith_deg", allow_empty=empty_ok)
    azimuth = table.numbers("azimuth_deg", allow_empty=empty_ok)
    light = ~dark & np.isfinite(zenith)
    refuse_rows(table, "zenith_deg", zenith, light & ((zenith < 0) | (zenith >= 90)),
                         lambda v: f"zenith {v:g}° on a light row must lie in [0, 90) (the sun in front of the "
                                   "sensor; mark shutter-closed rows dark = 1)")
    half = ~dark & (np.isfinite(zenith) != np.isfinite(azimuth))
    if half.any():  # only where empty cells are allowed
        i = int(np.flatnonzero(half)[0])
        raise DataFileError(table.path, "empty cell: a direction needs both zenith_deg and azimuth_deg", row=i + 1,
                            line=table.lines[i], column="azimuth_deg" if np.isfinite(zenith[i]) else "zenith_deg")
    return zenith, azimuth


def _hint_cmos(table: CsvTable) -> None:
    if not any(table.has(c) for c in CURRENT_COLUMNS) and table.has("x_px") and table.has("y_px"):
        raise DataFileError(table.path, "has spot columns x_px, y_px and no quadrant currents i1_a … i4_a: a CMOS "
                                        "sensor's CSV (`sunbench fit cmos` reads it), not a QD one")


def read_qd_frames(path, *, sensor_id: str | None = None) -> QdFrames:
    """Read a QD bench data CSV (README, "QD bench data CSV").

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
    design, given = _design(table)
    _hint_cmos(table)
    require_columns(table, REQUIRED_COLUMNS)
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    keep, sensor_id = sensor_rows(table, sensor_id)
    dark, check = flag_column(table, "dark"), flag_column(table, "check")
    both = dark & check
    refuse_rows(table, "check", check, both, lambda v: "a row cannot be both dark and a check point "
                                                                "(a check point is lit)")
    currents = _currents(table)
    temperature = temperature_column(table)
    zenith, azimuth = _directions(table, dark)
    repeat = table.numbers("repeat", integer=True) if table.has("repeat") else None
    row_id = np.arange(1, len(table.rows) + 1)
    try:
        data = QdBenchData(zenith, azimuth, currents, temperature, repeat=repeat, sensor_id=sensor_id, dark=dark,
                           check=check, row_id=row_id)
    except BenchDataError as exc:  # what the checks above did not catch
        row = None if exc.row is None else exc.row + 1
        raise DataFileError(table.path, str(exc), row=row, line=None if row is None else table.lines[row - 1],
                            column=exc.column if exc.column in table.header else None) from None
    if not keep.all():
        data = data.subset(keep)
    return QdFrames(data, design, given, table.path, {i + 1: line for i, line in enumerate(table.lines)})


def read_qd_csv(path, *, sensor_id: str | None = None) -> QdBenchData:
    """:func:`read_qd_frames`, the data only."""
    return read_qd_frames(path, sensor_id=sensor_id).data


def _number(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ""


def write_qd_csv(path, data: QdBenchData) -> None:
    """Write QD bench data in the format :func:`read_qd_csv` reads.

    Floats are written as Python's shortest round-trip repr, so they read back bit for bit. Dark rows are
    written without a direction (the shutter was closed: there was none).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*REQUIRED_COLUMNS, "repeat", *FLAG_COLUMNS] + (["sensor_id"] if data.sensor_id else []))
        for i in range(len(data)):
            dark = bool(data.dark[i])
            row = ["" if dark else _number(data.zenith_deg[i]), "" if dark else _number(data.azimuth_deg[i])]
            row += [repr(float(c)) for c in data.currents_a[i]]
            row += [repr(float(data.temperature_c[i])), int(data.repeat[i]), int(dark), int(data.check[i])]
            if data.sensor_id:
                row.append(data.sensor_id)
            w.writerow(row)


# --- applying a calibration -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class QdReadings:
    """A CSV of raw readings to turn into directions (:func:`read_qd_readings`).

    Attributes
    ----------
    table : CsvTable
        Its cells, to repeat them in the output.
    currents_a : ndarray, shape (N, 4)
    temperature_c : ndarray, shape (N,)
    dark : ndarray of bool
        Shutter-closed rows (no direction is computed for them).
    zenith_deg, azimuth_deg : ndarray or None
        The true direction, when the file has it (NaN on rows without).
    sensor_ids : list of str
        The distinct `sensor_id` values, if the file has the column.
    """

    table: CsvTable
    currents_a: np.ndarray
    temperature_c: np.ndarray
    dark: np.ndarray
    zenith_deg: np.ndarray | None
    azimuth_deg: np.ndarray | None
    sensor_ids: list

    @property
    def has_truth(self) -> bool:
        return self.zenith_deg is not None


def read_qd_readings(path) -> QdReadings:
    """A CSV with at least `i1_a … i4_a, temperature_c`; `zenith_deg, azimuth_deg` (the truth, cells may be
    empty) and `dark` are used when present. Bad cells raise :class:`DataFileError` as in :func:`read_qd_frames`."""
    table = read_bench_table(path, MAX_FILE_BYTES)
    _hint_cmos(table)
    require_columns(table, CURRENT_COLUMNS + ("temperature_c",))
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    dark = flag_column(table, "dark")
    truth = all(table.has(c) for c in TRUE_COLUMNS)
    zenith = azimuth = None
    if truth:
        zenith, azimuth = _directions(table, dark, optional=True)
    ids = sorted(set(table.texts("sensor_id"))) if table.has("sensor_id") else []
    return QdReadings(table, _currents(table), temperature_column(table), dark, zenith, azimuth, ids)


#: Columns `apply` adds to a QD readings CSV.
APPLIED_COLUMNS = ("alpha_deg", "beta_deg", "zenith_deg", "azimuth_deg")


def angular_errors_deg(readings: QdReadings, alpha_deg, beta_deg) -> np.ndarray:
    """Angle between each row's true and computed direction [°] (NaN without either)."""
    zen = np.where(np.isfinite(readings.zenith_deg), readings.zenith_deg, 0.0)
    az = np.where(np.isfinite(readings.azimuth_deg), readings.azimuth_deg, 0.0)
    at, bt = projection_angles(zen, az)
    ok = np.isfinite(readings.zenith_deg) & np.isfinite(alpha_deg) & np.isfinite(beta_deg) & ~readings.dark
    err = np.full(len(ok), np.nan)
    if ok.any():
        err[ok] = angle_between_projections_deg(at[ok], bt[ok], np.asarray(alpha_deg)[ok], np.asarray(beta_deg)[ok])
    return err


def write_qd_applied_csv(path, readings: QdReadings, alpha_deg, beta_deg, zenith_deg, azimuth_deg,
                         error_deg=None) -> None:
    """The readings' columns, then `alpha_deg, beta_deg, zenith_deg, azimuth_deg` (empty where the calibration
    gives no direction) and, with the truth, `error_deg`. Input columns of those names are kept as
    ``input_<name>``."""
    added = list(APPLIED_COLUMNS) + (["error_deg"] if error_deg is not None else [])
    header = [f"input_{c}" if c in added else c for c in readings.table.header] + added
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = [alpha_deg, beta_deg, zenith_deg, azimuth_deg] + ([error_deg] if error_deg is not None else [])
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, row in enumerate(readings.table.rows):
            w.writerow([*row, *("" if not np.isfinite(c[i]) else f"{c[i]:.6f}" for c in columns)])


# --- calibration documents -------------------------------------------------------------------------------------

def is_qd_document(document) -> bool:
    """Whether a calibration document (parsed JSON) says it is of the QD family."""
    return isinstance(document, dict) and document.get("family") == QD_FAMILY


def read_qd_calibration(path) -> dict:
    """A QD calibration document, checked (:func:`calibration.qd.document.validate_document`)."""
    document = load_calibration_json(path)
    try:
        validate_document(document)
    except CalibrationFormatError as exc:
        raise DataFileError(path, str(exc)) from None
    return document


def qd_calibration_file(document: dict, *, source: str | None, software: str | None, rejected=(),
                        warnings=()) -> dict:
    """A method's document from :func:`calibration.qd.evaluation.calibrate_qd` with its provenance (source file,
    time, software), the rejected rows and the warnings, as `sunbench fit qd` writes it."""
    return {**document, "source": source,
            "created_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "software": software, "rejected": [r.to_dict() for r in rejected], "warnings": list(warnings)}


def qd_header_from_document(document: dict) -> str:
    """The C header of a QD calibration document, its opening comment naming the source, the date, the software
    and the held-out accuracy (:func:`calibration.qd.export.c_header`)."""
    from calibration.qd.export import c_header

    metrics = document.get("metrics") or {}
    if isinstance(metrics, dict) and isinstance(metrics.get(document.get("method")), dict):
        metrics = metrics[document["method"]]  # the dashboard's download: every method's metrics, by method
    heldout = (metrics.get("heldout") or {}) if isinstance(metrics, dict) else {}
    held = None
    if heldout.get("max_deg") is not None:
        rms = heldout.get("rms_deg")
        held = (f"max {heldout['max_deg']:.4f} deg" + (f", RMS {rms:.4f} deg" if rms is not None else "")
                + f" ({metrics.get('heldout_scheme') or 'held out'})")
    provenance = {"source": document.get("source"), "created": document.get("created_utc"),
                  "software": document.get("software"), "held-out error": held}
    return c_header(document, provenance=provenance)
