"""The CSS bench data CSV (README, "CSS bench data CSV") and CSS calibration files.

A coarse-sun-sensor head's bench data (seed 000): one row per reading, the true sun direction in the head's body
frame (zenith from +z up to 180°: a cube is lit from every side), one column per detector — ``<face>_<type>_a`` for
the photodiodes' currents in amperes (types uv and vis), ``<face>_ir_v`` for the thermopiles' voltages in volts,
faces px, py, mx, my, pz, mz (:data:`calibration.css.head.COLUMNS`) —, the head's temperature, and whether the
shutter was closed (`dark`) or the row is a check direction (`check`). A file may carry any subset of the
detectors (at least one); a cell may be empty where that detector has no reading (a clipped channel), but every
row needs one.

The file is read with the CMOS reader's table (:func:`bench.datafile.read_csv_table`: header row, ``#``
comments, blank lines, a byte-order mark, duplicate columns, ragged rows), so every problem is the same
:class:`~bench.datafile.DataFileError` naming the file, the row (and its line) and the column.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.css.data import CssBenchData
from calibration.css.head import CHANNELS, COLUMNS, DETECTORS, FACES, UNITS, column
from calibration.errors import BenchDataError, CalibrationFormatError

from .datafile import (
    TRUE_COLUMNS,
    CsvTable,
    DataFileError,
    flag_column,
    load_calibration_json,
    read_bench_table,
    refuse_rows,
    require_columns,
    row_place,
    sensor_rows,
    temperature_column,
)

#: 0/1 columns: shutter closed; check direction (never fitted, only scored).
FLAG_COLUMNS = ("dark", "check")
#: Largest photocurrent a photodiode column may hold [A]: a photodiode's are nA to mA, so more is a file in other
#: units (µA or nA).
MAX_CURRENT_A = 0.1
#: Largest thermopile voltage [V]: a thermopile's are µV to mV behind its amplifier, so more is a file in mV.
MAX_VOLTAGE_V = 1.0
#: Largest file read [bytes].
MAX_FILE_BYTES = 64 * 2**20
#: A column that looks like a channel's: ``<face>_<type>`` with or without a unit suffix.
_CHANNEL_LIKE = re.compile(r"^(?P<face>px|py|mx|my|pz|mz)_(?P<kind>uv|vis|ir)(?:_(?P<unit>[a-z]+))?$")


@dataclass(frozen=True)
class CssFrames:
    """A CSS bench data CSV as read.

    Attributes
    ----------
    data : CssBenchData
        One row per reading; `row_id` is the file's data row (1-based, the header not counted).
    path : str
    lines : dict of int to int
        The file line of each data row.
    """

    data: CssBenchData
    path: str = ""
    lines: dict = field(default_factory=dict)

    def where(self, row: int) -> str:
        """``row N (line L)`` of a data row, as error messages say it."""
        return row_place(self.lines, row)


def channel_columns(table: CsvTable) -> list[str]:
    """The detector columns the file has, in the head's order; a column named like a channel but with the wrong
    unit (``px_ir_a``: a thermopile reads volts) or none (``px_uv``) is refused, naming the right name."""
    for name in table.header:
        m = _CHANNEL_LIKE.match(name)
        if not m or name in COLUMNS:
            continue
        right = column(f"{m['face']}_{m['kind']}")
        what = "a thermopile's voltage in volts" if m["kind"] == "ir" else "a photodiode's current in amperes"
        raise DataFileError(table.path, f"the detector column is {right} ({what})", column=name)
    return [c for c in COLUMNS if table.has(c)]


def _hint_other_family(table: CsvTable) -> None:
    if channel_columns(table):
        return
    if table.has("x_px") and table.has("y_px"):
        raise DataFileError(table.path, "has spot columns x_px, y_px and no detector columns px_uv_a … mz_ir_v: a "
                                        "CMOS or camera sensor's CSV (`sunbench fit cmos` or `fit camera` reads it), "
                                        "not a CSS one")
    if table.has("i1_a"):
        raise DataFileError(table.path, "has quadrant currents i1_a … i4_a and no detector columns px_uv_a … "
                                        "mz_ir_v: a QD sensor's CSV (`sunbench fit qd` reads it), not a CSS one")
    raise DataFileError(table.path, "no detector column: a CSS file has at least one of "
                                    f"{', '.join(COLUMNS[:3])} … {COLUMNS[-1]} (<face>_<type>_a for the photodiodes "
                                    f"[A], <face>_ir_v for the thermopiles [V]; faces {', '.join(FACES)}, types "
                                    f"{', '.join(DETECTORS)}); the header has {', '.join(table.header)}")


def _signals(table: CsvTable, columns: list[str]) -> np.ndarray:
    """The detector columns (N, K); an empty cell is a missing reading (NaN), every row needs one."""
    out = []
    anywhere = np.ones(len(table.rows), bool)
    for name in columns:
        values = table.numbers(name, allow_empty=anywhere)
        if name.endswith("_v"):
            refuse_rows(table, name, values, np.abs(values) > MAX_VOLTAGE_V,
                    lambda v: f"{v:g} V is out of range for a thermopile (|voltage| ≤ {MAX_VOLTAGE_V:g} V); the "
                              "thermopiles' columns are in volts (mV × 1e-3)")
        else:
            refuse_rows(table, name, values, np.abs(values) > MAX_CURRENT_A,
                    lambda v: f"{v:g} A is out of range for a photodiode (|current| ≤ {MAX_CURRENT_A:g} A); the "
                              "photodiodes' columns are in amperes (µA × 1e-6)")
        out.append(values)
    signals = np.stack(out, axis=1)
    empty = np.all(np.isnan(signals), axis=1)
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise DataFileError(table.path, "empty cells: a row needs the reading of at least one detector", row=i + 1,
                            line=table.lines[i], column=columns[0])
    return signals


def _directions(table: CsvTable, dark: np.ndarray, *, optional: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Zenith and azimuth; empty on dark rows (or anywhere when `optional`): NaN. A lit row's zenith lies in
    [0, 180] (a cube is lit from every side)."""
    empty_ok = np.ones(len(table.rows), bool) if optional else dark
    zenith = table.numbers("zenith_deg", allow_empty=empty_ok)
    azimuth = table.numbers("azimuth_deg", allow_empty=empty_ok)
    lit = ~dark & np.isfinite(zenith)
    refuse_rows(table, "zenith_deg", zenith, lit & ((zenith < 0) | (zenith > 180)),
            lambda v: f"zenith {v:g}° must lie in [0, 180] (from the head's +z axis)")
    refuse_rows(table, "azimuth_deg", azimuth, ~dark & np.isfinite(azimuth) & (np.abs(azimuth) > 720),
            lambda v: f"azimuth {v:g}° is out of range (|azimuth| ≤ 720°)")
    half = ~dark & (np.isfinite(zenith) != np.isfinite(azimuth))
    if half.any():  # only where empty cells are allowed
        i = int(np.flatnonzero(half)[0])
        raise DataFileError(table.path, "empty cell: a direction needs both zenith_deg and azimuth_deg", row=i + 1,
                            line=table.lines[i], column="azimuth_deg" if np.isfinite(zenith[i]) else "zenith_deg")
    return zenith, azimuth


def read_css_frames(path, *, sensor_id: str | None = None) -> CssFrames:
    """Read a CSS bench data CSV (README, "CSS bench data CSV").

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
    columns = channel_columns(table)
    require_columns(table, TRUE_COLUMNS + ("temperature_c",))
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    keep, sensor_id = sensor_rows(table, sensor_id)
    dark, check = flag_column(table, "dark"), flag_column(table, "check")
    refuse_rows(table, "check", check, dark & check, lambda v: "a row cannot be both dark and a check direction (a "
                                                           "check direction is lit)")
    signals = _signals(table, columns)
    temperature = temperature_column(table)
    zenith, azimuth = _directions(table, dark)
    repeat = table.numbers("repeat", integer=True) if table.has("repeat") else None
    row_id = np.arange(1, len(table.rows) + 1)
    channels = tuple(CHANNELS[COLUMNS.index(c)] for c in columns)
    try:
        data = CssBenchData(zenith, azimuth, signals, temperature, channels=channels, repeat=repeat,
                            sensor_id=sensor_id, dark=dark, check=check, row_id=row_id)
    except BenchDataError as exc:  # what the checks above did not catch
        row = None if exc.row is None else exc.row + 1
        raise DataFileError(table.path, str(exc), row=row, line=None if row is None else table.lines[row - 1],
                            column=exc.column if exc.column in table.header else None) from None
    if not keep.all():
        data = data.subset(keep)
    return CssFrames(data, table.path, {i + 1: line for i, line in enumerate(table.lines)})


def read_css_csv(path, *, sensor_id: str | None = None) -> CssBenchData:
    """:func:`read_css_frames`, the data only."""
    return read_css_frames(path, sensor_id=sensor_id).data


def _number(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ""


def write_css_csv(path, data: CssBenchData) -> None:
    """Write CSS bench data in the format :func:`read_css_csv` reads.

    Floats are written as Python's shortest round-trip repr, so they read back bit for bit; a missing reading (NaN)
    is an empty cell. Dark rows are written without a direction (the shutter was closed: there was none).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*TRUE_COLUMNS, *data.columns, "temperature_c", "repeat", *FLAG_COLUMNS]
                   + (["sensor_id"] if data.sensor_id else []))
        for i in range(len(data)):
            dark = bool(data.dark[i])
            row = ["" if dark else _number(data.zenith_deg[i]), "" if dark else _number(data.azimuth_deg[i])]
            row += [_number(v) for v in data.signals[i]]
            row += [repr(float(data.temperature_c[i])), int(data.repeat[i]), int(dark), int(data.check[i])]
            if data.sensor_id:
                row.append(data.sensor_id)
            w.writerow(row)


def signal_unit(channel: str) -> str:
    """"A" or "V": the unit of a channel's signal."""
    return {"a": "A", "v": "V"}[UNITS[channel.split("_", 1)[1]]]


# --- fitting: the one place the bench calls calibration.css.calibrate -------------------------------------------

#: The response laws `fit css` and a run's end fit when none is named: the Kelly law and the spline, the better
#: held out kept (:func:`rank_css_fits`)
DEFAULT_CSS_LAWS = ("kelly", "spline")
#: A fit with more parameters is preferred only when its held-out Sun direction RMS is below this share of the
#: simpler fit's (the held-out figure of a few hundred readings is not exact; a tie goes to the simpler law)
RANK_MARGIN = 0.95


def fit_css(data: CssBenchData, *, response: str | None = "kelly", start=None):
    """Calibrate a head from its bench data with the response law `response` (None: ``kelly``):
    :func:`calibration.css.calibrate.calibrate_css`, every channel present fitted, the Sun's direction held out.
    `start`: a calibration of the same data with another law to start each detector's fit from (its normal and
    temperature coefficient)."""
    from calibration.css.calibrate import calibrate_css

    return calibrate_css(data, response=response or "kelly", start=start)


def fit_css_laws(data: CssBenchData, laws=DEFAULT_CSS_LAWS) -> list:
    """:func:`fit_css` with each of `laws` in turn, the spline law started from a parametric law's fit when one
    was fitted before it (its linear start then needs no search for the normals: work shared between the laws)."""
    outcomes: list = []
    for law in dict.fromkeys(laws):
        start = next((o for o in outcomes if o.response != "spline"), None) if law == "spline" else None
        outcomes.append(fit_css(data, response=law, start=start))
    return outcomes


def _sun(metrics) -> dict | None:
    return None if metrics is None else metrics.to_dict()


def _n_parameters(outcome) -> int:
    return sum(len(f.free) for f in outcome.fits.values() if f.valid)


def rank_css_fits(outcomes) -> list:
    """The outcomes of :func:`fit_css`, best first: the smallest RMS of the Sun's direction on directions the fit
    never saw — held out, else at the check directions — with a margin for the number of fitted parameters: a
    fit with more parameters (the spline law) comes first only when its figure is below :data:`RANK_MARGIN` × a
    simpler one's. Fits without either figure come last, fewest parameters first (the figure at the fitted
    directions would favour the most flexible law)."""
    def figure(outcome):
        for metrics in (outcome.sun_heldout, outcome.sun_check):
            if metrics is not None and metrics.n_points and math.isfinite(metrics.rms_deg):
                return metrics.rms_deg
        return None

    scored = sorted((o for o in outcomes if figure(o) is not None), key=lambda o: (figure(o), _n_parameters(o)))
    ranked = []
    while scored:
        best = scored[0]
        simpler = [o for o in scored if _n_parameters(o) < _n_parameters(best)
                   and figure(best) >= RANK_MARGIN * figure(o)]
        if simpler:
            best = min(simpler, key=lambda o: (figure(o), _n_parameters(o)))
        ranked.append(best)
        scored.remove(best)
    return ranked + sorted((o for o in outcomes if figure(o) is None), key=_n_parameters)


def css_metrics(outcome) -> dict:
    """A calibration's figures as the catalogue keeps them beside its document: the Sun's direction held out, at the
    fitted directions and at the check directions (each n_points, n_degenerate, n_failed, rms/p95/max [°] and the RMS
    over the stated 1σ), the held-out scheme, the channels calibrated and those left out with their fault."""
    return {"response": outcome.response, "held_out": _sun(outcome.sun_heldout), "at_nodes": _sun(outcome.sun_at_nodes),
            "check": _sun(outcome.sun_check), "heldout_scheme": (outcome.heldout or {}).get("scheme"),
            "channels": list(outcome.valid_channels), "faulty": dict(outcome.faulty),
            "n_rejected": len(outcome.rejected)}


def css_calibration_file(outcome, *, source: str | None, software: str | None, created: bool = True) -> dict:
    """The calibration document of an outcome of :func:`fit_css` (:func:`calibration.css.calibrate.css_document`:
    every detector's parameters ± 1σ, the held-out figures, the rejected readings and the warnings) with its
    provenance: the source (file or run), the time (`created`; the catalogue stamps a run's itself) and the software."""
    document = dict(outcome.document)
    document.update({"source": source, "software": software})
    if created:
        document["created_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    return document


def _figures(metrics) -> str:
    if metrics is None or not metrics.n_points:
        return "—"
    return (f"RMS {metrics.rms_deg:.3f}°, p95 {metrics.p95_deg:.3f}°, max {metrics.max_deg:.3f}° over "
            f"{metrics.n_points} readings" + (f" ({metrics.n_degenerate} degenerate)" if metrics.n_degenerate else ""))


def css_fit_summary(outcome, n_readings: int, *, others=()) -> str:
    """One line of what a fit found, for a run's journal: the detectors calibrated, the Sun's direction held out,
    at the check directions and at the fitted ones, and the other laws' held-out RMS."""
    faulty = outcome.faulty
    line = (f"fitted {len(outcome.valid_channels)} detector(s) ({outcome.response} law) to {n_readings} readings"
            + (f", {len(faulty)} left out ({', '.join(f'{c}: {f}' for c, f in faulty.items())})" if faulty else "")
            + f"; the Sun's direction held out: {_figures(outcome.sun_heldout)}; at the check directions: "
            + f"{_figures(outcome.sun_check)}; at the fitted directions: {_figures(outcome.sun_at_nodes)}")
    for other in others:
        held = other.sun_heldout
        line += f"; {other.response} law held out RMS " + ("—" if held is None else f"{held.rms_deg:.3f}°")
    return line


# --- calibration documents -------------------------------------------------------------------------------------

def is_css_document(document) -> bool:
    """Whether a calibration document (parsed JSON) says it is of the CSS family."""
    return isinstance(document, dict) and document.get("family") == "css"


def read_css_calibration(path) -> dict:
    """A CSS calibration document, checked (:func:`calibration.css.calibrate.validate_css_document`)."""
    from calibration.css.calibrate import validate_css_document

    document = load_calibration_json(path)
    try:
        validate_css_document(document)
    except CalibrationFormatError as exc:
        raise DataFileError(path, str(exc)) from None
    return document


def css_diodes(document: dict) -> list:
    """The calibrated detectors of a (checked) document, :class:`calibration.css.diode.DiodeParameters` in head
    order."""
    from calibration.css.calibrate import diode_parameters_from_document

    return diode_parameters_from_document(document)


# --- applying a calibration -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class CssReadings:
    """A CSV of raw head readings to turn into directions (:func:`read_css_readings`).

    Attributes
    ----------
    table : CsvTable
        Its cells, to repeat them in the output.
    signals : ndarray, shape (N, K)
        The detector columns present (NaN: no reading).
    channels : tuple of str
        The channels of `signals`' columns, in head order.
    temperature_c : ndarray, shape (N,)
    dark : ndarray of bool
        Shutter-closed rows (no direction is computed for them).
    zenith_deg, azimuth_deg : ndarray or None
        The true direction, when the file has it (NaN on rows without).
    sensor_ids : list of str
        The distinct `sensor_id` values, if the file has the column.
    """

    table: CsvTable
    signals: np.ndarray
    channels: tuple
    temperature_c: np.ndarray
    dark: np.ndarray
    zenith_deg: np.ndarray | None
    azimuth_deg: np.ndarray | None
    sensor_ids: list

    @property
    def has_truth(self) -> bool:
        return self.zenith_deg is not None


def read_css_readings(path) -> CssReadings:
    """A CSV with at least one detector column and `temperature_c`; `zenith_deg, azimuth_deg` (the truth, cells may
    be empty) and `dark` are used when present. Bad cells raise :class:`DataFileError` as in
    :func:`read_css_frames`."""
    table = read_bench_table(path, MAX_FILE_BYTES)
    _hint_other_family(table)
    columns = channel_columns(table)
    require_columns(table, ("temperature_c",))
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    dark = flag_column(table, "dark")
    zenith = azimuth = None
    if all(table.has(c) for c in TRUE_COLUMNS):
        zenith, azimuth = _directions(table, dark, optional=True)
    ids = sorted(set(table.texts("sensor_id"))) if table.has("sensor_id") else []
    channels = tuple(CHANNELS[COLUMNS.index(c)] for c in columns)
    return CssReadings(table, _signals(table, columns), channels, temperature_column(table), dark, zenith, azimuth, ids)


#: Columns `apply` adds to a CSS readings CSV: the direction, its 1σ cone radius and the faces lit.
APPLIED_COLUMNS = ("zenith_deg", "azimuth_deg", "sigma_deg", "faces_lit")


@dataclass(frozen=True)
class CssApplied:
    """The Sun's direction per row of a readings CSV (:func:`apply_css`).

    Attributes
    ----------
    zenith_deg, azimuth_deg, sigma_deg : ndarray (N,)
        The direction [°] and its stated 1σ cone radius [°]; NaN on dark rows and where it is not determined.
    faces_lit : ndarray of int (N,)
    determined : ndarray of bool (N,)
        A direction was found and it is not degenerate (at least two non-coplanar faces lit).
    error_deg : ndarray (N,) or None
        The angle to the file's true direction [°], with the truth (NaN where either is missing).
    """

    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    sigma_deg: np.ndarray
    faces_lit: np.ndarray
    determined: np.ndarray
    error_deg: np.ndarray | None


def apply_css(document: dict, readings: CssReadings) -> CssApplied:
    """Each row's Sun direction from its readings and temperature with the document alone
    (:func:`calibration.css.calibrate.apply_css_document`: weighted least squares over the calibrated detectors); a
    dark row, and a row lighting fewer than two non-coplanar faces, gets none."""
    from calibration.css.calibrate import apply_css_document
    from calibration.css.head import sun_vectors

    estimate = apply_css_document(document, readings.signals, readings.channels, readings.temperature_c)
    vector = np.asarray(estimate.vector, float).reshape(-1, 3)
    determined = (np.all(np.isfinite(vector), axis=1) & ~np.asarray(estimate.degenerate, bool)
                  & ~readings.dark)
    keep = lambda v: np.where(determined, np.asarray(v, float), np.nan)  # noqa: E731
    error = None
    if readings.has_truth:
        truth = np.isfinite(readings.zenith_deg) & np.isfinite(readings.azimuth_deg)
        t = sun_vectors(np.where(truth, readings.zenith_deg, 0.0), np.where(truth, readings.azimuth_deg, 0.0))
        cos = np.clip(np.sum(t * np.where(determined[:, None], vector, 0.0), axis=1), -1.0, 1.0)
        error = np.where(truth & determined, np.degrees(np.arccos(cos)), np.nan)
    return CssApplied(keep(estimate.zenith_deg), keep(estimate.azimuth_deg), keep(estimate.sigma_deg),
                      np.where(readings.dark, 0, np.asarray(estimate.n_faces_lit, int)), determined, error)


def write_css_applied_csv(path, readings: CssReadings, applied: CssApplied) -> None:
    """The readings' columns, then `zenith_deg, azimuth_deg, sigma_deg, faces_lit` (the direction empty where the
    calibration gives none) and, with the truth, `error_deg`. Input columns of those names are kept as
    ``input_<name>``."""
    added = list(APPLIED_COLUMNS) + (["error_deg"] if applied.error_deg is not None else [])
    header = [f"input_{c}" if c in added else c for c in readings.table.header] + added
    columns = [applied.zenith_deg, applied.azimuth_deg, applied.sigma_deg]
    if applied.error_deg is not None:
        columns.append(applied.error_deg)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, row in enumerate(readings.table.rows):
            cells = ["" if not np.isfinite(c[i]) else f"{c[i]:.6f}" for c in columns]
            cells.insert(3, str(int(applied.faces_lit[i])))
            w.writerow([*row, *cells])


# --- the C header -----------------------------------------------------------------------------------------------

#: The thesis' quantiser tables (listing D.6) a bench calibration rebuilds: the Sun's, per photodiode type
QUANTISER_TABLES = {"uv": "epd_sun", "vis": "bpw_sun"}


def quantiser_tables(diodes) -> dict:
    """Seed 000's Sun quantiser tables rebuilt from a calibration (its future work (e), ch. 7): for each photodiode
    type, the thresholds t0 … t18 of :func:`calibration.css.quantiser.thresholds_from_response` on the mean over the
    faces of the calibrated signal against incidence on each detector's own normal (25 °C, the bench's irradiance),
    raised to a dark floor of the mean offset + 3σ of the noise floor. A type without a calibrated detector keeps the
    listing's table."""
    from calibration.css.quantiser import thresholds_from_response

    angles = np.arange(0.0, 90.5, 0.5)
    tables = {}
    for kind, name in QUANTISER_TABLES.items():
        chosen = [d for d in diodes if d.detector == kind]
        if not chosen:
            continue
        curves = [d.scale * d.relative_response(np.cos(np.radians(angles))) + d.bias for d in chosen]
        floor = float(np.mean([d.bias for d in chosen]) + 3 * np.mean([d.sigma0 for d in chosen]))
        tables[name] = thresholds_from_response(angles, np.mean(curves, axis=0), floor=floor)
    return tables


def css_header_from_document(document: dict) -> str:
    """The C header of a CSS calibration document: every detector's fitted model with ``sunbench_css_signal()`` and
    ``sunbench_css_relative()`` (:func:`calibration.css.export.c_header`), then seed 000's look-up tables and
    quantiser (:func:`calibration.css.lut.c_header`) with its Sun tables rebuilt from this calibration
    (:func:`quantiser_tables`); its opening comments name the source, the date, the software and the held-out
    accuracy."""
    from calibration.css import lut
    from calibration.css.export import c_header
    from calibration.css.quantiser import TABLES

    diodes = css_diodes(document)
    sun = ((document.get("heldout") or {}).get("sun") or {}).get("heldout") or {}
    held = None
    if sun.get("rms_deg") is not None:
        held = (f"the Sun's direction RMS {sun['rms_deg']:.4f} deg, p95 {sun['p95_deg']:.4f} deg, max "
                f"{sun['max_deg']:.4f} deg over {sun['n_points']} readings")
    provenance = {"source": document.get("source"), "created": document.get("created_utc"),
                  "software": document.get("software"), "response law": document.get("response"),
                  "held-out error": held}
    tables = quantiser_tables(diodes)
    rebuilt = ", ".join(sorted(tables)) or "none"
    kept = ", ".join(sorted(set(TABLES) - set(tables)))
    lut_provenance = {**{k: v for k, v in provenance.items() if k in ("source", "created")},
                      "quantiser tables": f"{rebuilt} rebuilt from this calibration (the faces' mean response at "
                                          f"25 degC and the bench's irradiance); {kept}: listing D.6's (the bench has "
                                          "no Earth for the albedo tables and no blackbody for the TPS' seen "
                                          "temperature)"}
    return (c_header(diodes, sensor_id=document.get("sensor_id"), provenance=provenance) + "\n"
            + lut.c_header(tables=tables, provenance=lut_provenance))
