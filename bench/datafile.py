"""Files a lab engineer hands to sunbench: the bench data CSV, spot CSVs and calibration JSON.

Every problem is a :class:`DataFileError` that names the file, and where it can the row and the column,
so the CLI can say exactly what to fix. The CSV format is documented in the README ("Bench data CSV").
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.data import BenchData
from calibration.design import BenchGeometry
from calibration.errors import BenchDataError, CalibrationFormatError
from calibration.models import Calibration, calibration_from_dict
from calibration.stage_geometry import body_direction_deg
from calibration.uncertainty import uncertainty_document

_METADATA = re.compile(r"^\s*#\s*(?P<key>[A-Za-z_][A-Za-z0-9_]*)\s*[:=]\s*(?P<value>.+)$")

TRUE_COLUMNS = ("zenith_deg", "azimuth_deg")
STAGE_COLUMNS = ("stage_zenith_deg", "stage_azimuth_deg")
SPOT_COLUMNS = ("x_px", "y_px")
OPTIONAL_NUMERIC = ("repeat", "exposure_ms")


class DataFileError(Exception):
    """A file sunbench cannot use, with where the problem is.

    Attributes
    ----------
    path : str
    row : int or None
        Data row, 1-based (the header is not counted).
    line : int or None
        Line in the file, 1-based.
    column : str or None
    """

    def __init__(self, path, message: str, *, row: int | None = None, line: int | None = None,
                 column: str | None = None):
        self.path, self.row, self.line, self.column = str(path), row, line, column
        where = [self.path]
        if row is not None:
            where.append(f"row {row}" + (f" (line {line})" if line is not None else ""))
        elif line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        super().__init__(", ".join(where) + ": " + message)


@dataclass(frozen=True)
class CsvTable:
    """Cells of a CSV file by column, with the file line of every data row, and the ``# key: value`` (or
    ``# key = value``) comments above the header."""

    path: str
    header: list[str]
    rows: list[list[str]]
    lines: list[int]
    metadata: dict = field(default_factory=dict)

    def has(self, column: str) -> bool:
        return column in self.header

    def numbers(self, column: str, *, integer: bool = False, allow_empty=None) -> np.ndarray:
        """The column as finite numbers; the first bad cell raises :class:`DataFileError`.

        `allow_empty`, a boolean per row, lets those rows leave the cell empty (NaN then).
        """
        j = self.header.index(column)
        out = np.empty(len(self.rows), dtype=float)
        for i, row in enumerate(self.rows):
            cell = row[j].strip()
            if not cell and allow_empty is not None and allow_empty[i]:
                out[i] = np.nan
                continue
            try:
                value = float(cell)
            except ValueError:
                raise DataFileError(self.path, f"{cell!r} is not a number" if cell else "empty cell",
                                    row=i + 1, line=self.lines[i], column=column) from None
            if not math.isfinite(value):
                raise DataFileError(self.path, f"{cell!r} is not a finite number", row=i + 1,
                                    line=self.lines[i], column=column)
            if integer and value != int(value):
                raise DataFileError(self.path, f"{cell!r} is not a whole number", row=i + 1,
                                    line=self.lines[i], column=column)
            out[i] = value
        return out

    def texts(self, column: str) -> list[str]:
        j = self.header.index(column)
        return [row[j].strip() for row in self.rows]


def read_bench_table(path, max_bytes: int) -> CsvTable:
    """:func:`read_csv_table` of a bench data file, refusing one larger than `max_bytes` before reading it."""
    path = Path(path)
    try:
        size = path.stat().st_size if path.is_file() else 0
    except OSError:
        size = 0  # read_csv_table says what is wrong with it
    if size > max_bytes:
        raise DataFileError(path, f"{size / 2**20:.0f} MiB is too large for bench data (at most "
                                  f"{max_bytes // 2**20} MiB); split it by sensor or by run")
    return read_csv_table(path)


def row_place(lines: dict, row: int) -> str:
    """``row N (line L)`` of a data row, as error messages say it (`lines`: data row → the file's line)."""
    line = lines.get(int(row))
    return f"row {row}" + (f" (line {line})" if line is not None else "")


def read_csv_table(path, *, text: str | None = None) -> CsvTable:
    """Read a CSV with a header row; blank lines and lines starting with ``#`` are skipped. With `text`, that is
    the file's content (an upload) and `path` only names it in errors."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig") if text is None else text.removeprefix("\ufeff")
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except UnicodeDecodeError:
        raise DataFileError(path, "not a text (UTF-8) file") from None
    except OSError as exc:
        raise DataFileError(path, f"cannot read ({exc.strerror})") from None
    header, rows, lines, metadata = None, [], [], {}
    reader = csv.reader(text.splitlines())
    try:
        for cells in reader:
            if cells and cells[0].lstrip().startswith("#") and header is None:
                match = _METADATA.match(",".join(cells))
                if match:
                    metadata[match["key"]] = (match["value"].strip(), reader.line_num)
                continue
            if not cells or not "".join(cells).strip() or cells[0].lstrip().startswith("#"):
                continue
            if header is None:
                header = [c.strip() for c in cells]
                dup = sorted({c for c in header if header.count(c) > 1})
                if dup:
                    raise DataFileError(path, f"duplicate column(s) {', '.join(dup)} in the header",
                                        line=reader.line_num)
                continue
            if len(cells) != len(header):
                raise DataFileError(path, f"{len(cells)} cells, the header has {len(header)}",
                                    row=len(rows) + 1, line=reader.line_num)
            rows.append(cells)
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise DataFileError(path, f"malformed CSV ({exc})", line=reader.line_num) from None
    if header is None:
        raise DataFileError(path, "empty file: no header row")
    return CsvTable(str(path), header, rows, lines, metadata)


def require_columns(table: CsvTable, columns) -> None:
    """Raise :class:`DataFileError` naming every column of `columns` the table lacks (and the header it has)."""
    missing = [c for c in columns if not table.has(c)]
    if missing:
        raise DataFileError(table.path, f"missing column(s) {', '.join(missing)}; the header has "
                                        f"{', '.join(table.header)}")


def sensor_rows(table: CsvTable, sensor_id: str | None) -> tuple[np.ndarray, str | None]:
    """The rows of one sensor, and its id: a file without `sensor_id` is one unnamed sensor; a file holding
    several needs `sensor_id` to choose one (:class:`DataFileError` otherwise, naming the column)."""
    keep = np.ones(len(table.rows), dtype=bool)
    if table.has("sensor_id"):
        ids = table.texts("sensor_id")
        distinct = sorted(set(ids))
        if sensor_id is not None:
            keep = np.array([i == sensor_id for i in ids])
            if not keep.any():
                raise DataFileError(table.path, f"no rows of sensor {sensor_id!r} (it has {', '.join(distinct)})",
                                    column="sensor_id")
        elif len(distinct) > 1:
            raise DataFileError(table.path, f"holds {len(distinct)} sensors ({', '.join(distinct[:5])}"
                                            f"{', …' if len(distinct) > 5 else ''}); choose one with --sensor",
                                column="sensor_id")
        else:
            sensor_id = distinct[0]
    elif sensor_id is not None:
        raise DataFileError(table.path, f"has no sensor_id column, so it cannot select sensor {sensor_id!r}")
    return keep, sensor_id


#: Temperatures a sensor may report [°C]; outside, the column is likely in kelvin or in ADC counts
TEMPERATURE_RANGE_C = (-100.0, 150.0)


def refuse_rows(table: CsvTable, column: str, values: np.ndarray, bad: np.ndarray, message) -> None:
    """:class:`DataFileError` at the first row where `bad`, naming the row, its line and `column`; its text is
    `message(value)` of that row's value."""
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataFileError(table.path, message(values[i]), row=i + 1, line=table.lines[i], column=column)


def flag_column(table: CsvTable, column: str) -> np.ndarray:
    """A 0/1 column as booleans (all False when the file has none); another value is refused."""
    if not table.has(column):
        return np.zeros(len(table.rows), bool)
    values = table.numbers(column, integer=True)
    refuse_rows(table, column, values, (values != 0) & (values != 1), lambda v: f"{v:g} is not 0 or 1")
    return values == 1


def temperature_column(table: CsvTable, column: str = "temperature_c") -> np.ndarray:
    """A sensor's temperature [°C], refused outside :data:`TEMPERATURE_RANGE_C` (kelvin or counts)."""
    values = table.numbers(column)
    lo, hi = TEMPERATURE_RANGE_C
    refuse_rows(table, column, values, (values < lo) | (values > hi),
                lambda v: f"{v:g} °C is out of range ({lo:g}…{hi:g} °C); the temperature is in Celsius, not kelvin")
    return values


def read_bench_csv(path, *, bench: BenchGeometry | None = None, sensor_id: str | None = None) -> BenchData:
    """Read a bench data CSV (README, "Bench data CSV") into :class:`BenchData`.

    Parameters
    ----------
    path : path-like
    bench : BenchGeometry, optional
        Converts `stage_zenith_deg` to the true zenith with seed 003 eq. 8 when the file has stage angles
        instead of `zenith_deg, azimuth_deg`. Required in that case.
    sensor_id : str, optional
        Keep only this sensor's rows (a file may hold a batch).
    """
    return _bench_data(read_csv_table(path), bench, sensor_id)


def _bench_data(table: CsvTable, bench: BenchGeometry | None, sensor_id: str | None) -> BenchData:
    """:func:`read_bench_csv` on a table already read."""
    stage = not all(table.has(c) for c in TRUE_COLUMNS)
    require_columns(table, SPOT_COLUMNS + (STAGE_COLUMNS if stage else TRUE_COLUMNS))
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    keep, sensor_id = sensor_rows(table, sensor_id)
    x, y = (_pixels(table, name) for name in SPOT_COLUMNS)
    if stage:
        if bench is None:
            raise DataFileError(table.path, "has stage angles; the bench geometry is needed to convert them")
        omega, stage_az = table.numbers("stage_zenith_deg"), table.numbers("stage_azimuth_deg")
        zenith, azimuth = body_direction_deg(stage_az, omega, bench)  # eq. 8; a negative tilt: the far side
    else:
        zenith, azimuth = table.numbers("zenith_deg"), table.numbers("azimuth_deg")
    optional = {name: table.numbers(name, integer=(name == "repeat")) if table.has(name) else None
                for name in OPTIONAL_NUMERIC}
    zen_column = "stage_zenith_deg" if stage else "zenith_deg"
    try:
        data = BenchData(zenith, azimuth, x, y, repeat=optional["repeat"], sensor_id=sensor_id,
                         exposure_ms=optional["exposure_ms"], frame_id=np.arange(1, len(table.rows) + 1))
    except BenchDataError as exc:
        row = None if exc.row is None else exc.row + 1
        column = zen_column if exc.column == "zenith_deg" else exc.column
        raise DataFileError(table.path, str(exc), row=row, line=None if row is None else table.lines[row - 1],
                            column=column) from None
    return data.subset(keep) if not keep.all() else data


def header_numbers(table: CsvTable, known) -> dict[str, float]:
    """The ``# key: value`` comments above the header as numbers; a key not in `known` or a value that is not a
    finite number raises :class:`DataFileError` naming its line."""
    numbers = {}
    for key, (value, line) in table.metadata.items():
        if key not in known:
            raise DataFileError(table.path, f"unknown header comment {key!r}; known: {', '.join(known)}", line=line)
        try:
            number = float(value)
        except ValueError:
            raise DataFileError(table.path, f"header comment {key}: {value!r} is not a number", line=line) from None
        if not math.isfinite(number):
            raise DataFileError(table.path, f"header comment {key}: {value!r} is not a finite number", line=line)
        numbers[key] = number
    return numbers


#: Header comments a bench data CSV may carry: the sensor's design and the bench's geometry (README).
DESIGN_KEYS = ("width_px", "height_px", "pixel_pitch_mm", "pinhole_height_mm", "hole_diameter_mm", "bit_depth",
               "fov_half_deg")
GEOMETRY_KEYS = ("lever_arm_mm", "lever_arm_sd_mm", "source_distance_mm", "source_distance_sd_mm",
                 "mount_tilt_x_deg", "mount_tilt_y_deg")
OTHER_KEYS = ("glass_index",)


@dataclass(frozen=True)
class BenchFrames:
    """A bench data CSV as frames, with what its header comments say.

    Attributes
    ----------
    data : BenchData
        One point per frame; `frame_id` is the data row (1-based). For stage angles the directions are
        placeholders that only group the repeats (|Ω| and the stage azimuth).
    stage : (azimuth_deg, zenith_deg) or None
        The stage angles, when the file gives them instead of true angles.
    metadata : dict
        Numbers from ``# key: value`` comments (:data:`DESIGN_KEYS`, :data:`GEOMETRY_KEYS`, :data:`OTHER_KEYS`).
    """

    data: BenchData
    stage: tuple | None
    metadata: dict


def read_bench_frames(path, *, sensor_id: str | None = None) -> BenchFrames:
    """Read a bench data CSV without converting stage angles: the bench geometry is fitted, never assumed.

    Header comments such as ``# pixel_pitch_mm: 0.0053`` or ``# source_distance_mm = 7100`` are read as numbers;
    an unknown key or a value that is not a number raises :class:`DataFileError` naming the line.
    """
    table = read_csv_table(path)
    metadata = header_numbers(table, DESIGN_KEYS + GEOMETRY_KEYS + OTHER_KEYS)
    stage = not all(table.has(c) for c in TRUE_COLUMNS)
    if not stage:
        return BenchFrames(_bench_data(table, None, sensor_id), None, metadata)
    # stage angles: group by the readings; |Ω| with the far side's azimuth keeps a direction's repeats together
    placeholder = BenchGeometry(lever_arm_mm=0.0, source_distance_mm=1.0)
    data = _bench_data(table, placeholder, sensor_id)
    table_rows = data.frame_id - 1
    omega, stage_az = table.numbers("stage_zenith_deg")[table_rows], table.numbers("stage_azimuth_deg")[table_rows]
    return BenchFrames(data, (stage_az, omega), metadata)


def write_bench_csv(path, data: BenchData) -> None:
    """Write bench data in the format :func:`read_bench_csv` reads (true angles)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        columns = ["zenith_deg", "azimuth_deg", "x_px", "y_px"]
        columns += [c for c in ("repeat", "exposure_ms") if getattr(data, c) is not None]
        columns += ["sensor_id"] if data.sensor_id else []
        w.writerow(columns)
        for i in range(len(data)):
            row = [repr(float(getattr(data, c)[i])) for c in columns[:4]]
            if data.repeat is not None:
                row.append(int(data.repeat[i]))
            if data.exposure_ms is not None:
                row.append(repr(float(data.exposure_ms[i])))
            if data.sensor_id:
                row.append(data.sensor_id)
            w.writerow(row)


#: Largest spot coordinate a file may hold [px]: any real detector is far smaller.
MAX_PIXEL = 1e6


def _pixels(table: CsvTable, name: str) -> np.ndarray:
    """A spot-coordinate column, every value within ±:data:`MAX_PIXEL`."""
    values = table.numbers(name)
    bad = np.flatnonzero(np.abs(values) > MAX_PIXEL)
    if bad.size:
        i = int(bad[0])
        raise DataFileError(table.path, f"{values[i]:g} px is out of range (|value| ≤ {MAX_PIXEL:g})", row=i + 1,
                            line=table.lines[i], column=name)
    return values


def read_spots_csv(path) -> tuple[CsvTable, np.ndarray, np.ndarray]:
    """A CSV with at least `x_px, y_px`; returns the table (to repeat its columns) and the two columns."""
    table = read_csv_table(path)
    require_columns(table, SPOT_COLUMNS)
    return table, _pixels(table, "x_px"), _pixels(table, "y_px")


def write_applied_csv(path, table: CsvTable, zenith_deg, azimuth_deg) -> None:
    """The spot CSV's columns, then `zenith_deg, azimuth_deg` from the calibration.

    Input columns of those two names (say, the bench's true angles) are kept as `input_zenith_deg` and
    `input_azimuth_deg`.
    """
    header = [f"input_{c}" if c in TRUE_COLUMNS else c for c in table.header] + list(TRUE_COLUMNS)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row, z, a in zip(table.rows, zenith_deg, azimuth_deg):
            w.writerow([*row, f"{z:.6f}", f"{a:.6f}"])


def calibration_document(calibration: Calibration, *, sensor_id: str | None, source: str | None,
                         reports=None, software: str | None = None, outcome=None, design=None) -> dict:
    """The calibration JSON: the versioned model document plus provenance and the metrics table.

    With the :class:`~calibration.evaluation.CalibrationOutcome` it also holds the sensor's design, the quality
    (χ²/dof against the repeat scatter, warnings in words), every rejected frame, the bench geometry of
    stage-angle data and the 1σ pointing-uncertainty map of a physical calibration.
    """
    document = calibration.to_dict()
    document.update({
        "sensor_id": sensor_id,
        "created_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "software": software,
        "source": source,
    })
    if reports:
        document["metrics"] = {r.method: r.to_dict() for r in reports}
    if design is not None:
        document["design"] = design.to_dict()
    if outcome is not None:
        quality = outcome.quality()
        if outcome.chosen.calibration is not calibration:  # a method asked for by name: its own figures
            mine = next((r for r in outcome.reports if r.calibration is calibration), None)
            quality["chi2_dof"] = mine.chi2_dof if mine else None
        document["quality"] = quality
        document["rejected"] = [r.to_dict() for r in outcome.rejected]
        if outcome.geometry is not None:
            document["bench_geometry"] = outcome.geometry
    uncertainty = uncertainty_document(calibration)
    if uncertainty is not None:
        document["uncertainty_map"] = uncertainty
    return document


def header_from_document(document: dict, calibration: Calibration | None = None) -> str:
    """The C header of a calibration document, its opening comment naming the source (run or file), the
    date, the software and the held-out accuracy, and its `#define`s the detector's design."""
    from calibration.design import SensorDesign
    from calibration.export import c_header

    calibration = calibration or calibration_from_dict(document)
    metrics = (document.get("metrics") or {}).get(calibration.method) or {}
    heldout = (metrics.get("heldout") or {}).get("rms_vector_deg")
    design = None
    if isinstance(document.get("design"), dict):
        try:
            design = SensorDesign(**document["design"])
        except (TypeError, ValueError):
            design = None  # an old or foreign design block: the header goes without it
    provenance = {"source": document.get("source"), "created": document.get("created_utc"),
                  "software": document.get("software"),
                  "held-out vector RMS": None if heldout is None else f"{heldout:.4f} deg "
                  f"({metrics.get('heldout_scheme') or 'azimuth'} out)"}
    return c_header(calibration, sensor_id=document.get("sensor_id"), design=design, provenance=provenance)


def write_calibration(path, document: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2) + "\n")


def load_calibration_json(path):
    """The JSON of a calibration file, not yet checked (any family); unreadable files raise :class:`DataFileError`."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"not a JSON calibration file ({exc})") from None
    except RecursionError:
        raise DataFileError(path, "not a calibration file (JSON nested too deeply)") from None


def read_calibration(path) -> tuple[Calibration, dict]:
    """Load a calibration JSON; other formats or versions raise :class:`DataFileError`."""
    path = Path(path)
    document = load_calibration_json(path)
    try:
        return calibration_from_dict(document), document
    except CalibrationFormatError as exc:
        raise DataFileError(path, str(exc)) from None
