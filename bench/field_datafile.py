"""The field data CSV: a sensor's readings against the real Sun, one row per reading, stamped in UTC.

Format (README, "Field data CSV"):
- columns: ``time_utc`` (ISO 8601; no zone means UTC), then the sensor's own readings — its spot ``x_px, y_px``
  (a CMOS or camera sensor, turned into directions with a calibration) or its calibrated ``zenith_deg,
  azimuth_deg`` in the sensor frame — and optionally ``status`` (``ok`` or why the reading failed), ``peak_dn``,
  ``exposure_ms``, ``temperature_c`` and ``pressure_hpa`` (the air, per row), ``cloud`` (1 where the operator saw
  cloud), ``spot_cloud`` (1 where the sensor's own spot showed a cloud: the camera's shape flag), ``sensor_id``;
- header comments ``# key: value`` above the column names for the site and the mount: ``latitude_deg``,
  ``longitude_deg``, ``altitude_m``, ``heading_deg`` (azimuth of the sensor's +x axis, east of north),
  ``roll_deg``, ``pitch_deg`` (the mount's level, from an inclinometer), ``pressure_hpa``, ``temperature_c``,
  ``delta_t_s``, ``fov_half_deg``. Command-line options override them.

Every problem is a :class:`~bench.datafile.DataFileError` naming the file, row and column.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.errors import FieldDataError
from calibration.field.sky import utc_seconds

from .datafile import CsvTable, DataFileError, header_numbers, read_csv_table

#: Header comments a field CSV may carry (README, "Field data CSV").
FIELD_KEYS = ("latitude_deg", "longitude_deg", "altitude_m", "heading_deg", "roll_deg", "pitch_deg", "pressure_hpa",
              "temperature_c", "delta_t_s", "fov_half_deg")
SPOT_COLUMNS = ("x_px", "y_px")
DIRECTION_COLUMNS = ("zenith_deg", "azimuth_deg")
OPTIONAL_NUMBERS = ("peak_dn", "exposure_ms", "temperature_c", "pressure_hpa")
#: Row limit: a day at 1 Hz is 86 400 rows; a file ten times that is a mistake, not a field run.
MAX_ROWS = 1_000_000


@dataclass(frozen=True)
class FieldData:
    """A field CSV read and checked.

    Attributes
    ----------
    path : str
    time_utc : list of str
        The rows' stamps as written.
    t_s : ndarray
        The same as Unix seconds (UTC).
    ok : ndarray of bool
        Rows whose reading worked (``status`` absent, empty or ``ok``, and finite readings).
    x_px, y_px : ndarray or None
        The spot, when the file gives it.
    zenith_deg, azimuth_deg : ndarray or None
        Calibrated directions in the sensor frame, when the file gives them.
    numbers : dict of str to ndarray
        Optional numeric columns present (:data:`OPTIONAL_NUMBERS`); NaN where a cell is empty.
    cloud : ndarray of bool or None
        The operator's cloud marks.
    spot_cloud : ndarray of bool or None
        The sensor's own cloud flag of each reading (the camera's, from its spot's shape); empty cells are False.
    metadata : dict of str to float
        The header comments (:data:`FIELD_KEYS`).
    sensor_id : str or None
    """

    path: str
    time_utc: list[str]
    t_s: np.ndarray
    ok: np.ndarray
    x_px: np.ndarray | None = None
    y_px: np.ndarray | None = None
    zenith_deg: np.ndarray | None = None
    azimuth_deg: np.ndarray | None = None
    numbers: dict = field(default_factory=dict)
    cloud: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    sensor_id: str | None = None
    spot_cloud: np.ndarray | None = None

    @property
    def has_spots(self) -> bool:
        return self.x_px is not None

    def __len__(self) -> int:
        return len(self.t_s)


def read_field_csv(path, *, text: str | None = None) -> FieldData:
    """Read a field CSV (README, "Field data CSV"); see the module docstring for its columns. With `text`, that is
    the file's content (an upload) and `path` only names it."""
    table = read_csv_table(path, text=text)
    if not table.has("time_utc"):
        raise DataFileError(table.path, f"missing column time_utc; the header has {', '.join(table.header)}")
    has_spots = all(table.has(c) for c in SPOT_COLUMNS)
    has_directions = all(table.has(c) for c in DIRECTION_COLUMNS)
    if not (has_spots or has_directions):
        raise DataFileError(table.path, "needs the sensor's spot (x_px, y_px) or its calibrated direction "
                                        f"(zenith_deg, azimuth_deg); the header has {', '.join(table.header)}")
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    if len(table.rows) > MAX_ROWS:
        raise DataFileError(table.path, f"{len(table.rows)} rows: more than the {MAX_ROWS} a field file may hold")
    metadata = header_numbers(table, FIELD_KEYS)
    times = table.texts("time_utc")
    t_s = _times(table, times)
    status_ok = np.array([s.lower() in ("", "ok") for s in table.texts("status")]) if table.has("status") \
        else np.ones(len(times), bool)
    spots = {c: table.numbers(c, allow_empty=~status_ok) for c in SPOT_COLUMNS} if has_spots else {}
    directions = {c: table.numbers(c, allow_empty=~status_ok) for c in DIRECTION_COLUMNS} if has_directions else {}
    ok = status_ok.copy()
    for values in (*spots.values(), *directions.values()):
        ok &= np.isfinite(values)
    if has_directions:
        _check_range(table, "zenith_deg", directions["zenith_deg"], 0.0, 180.0)
    numbers = {c: table.numbers(c, allow_empty=np.ones(len(times), bool)) for c in OPTIONAL_NUMBERS if table.has(c)}
    if "pressure_hpa" in numbers:
        _check_range(table, "pressure_hpa", numbers["pressure_hpa"], 0.0, 1100.0)
    cloud, spot_cloud = (_flags(table, name) if table.has(name) else None for name in ("cloud", "spot_cloud"))
    sensor_id = None
    if table.has("sensor_id"):
        ids = sorted({i for i in table.texts("sensor_id") if i})  # an empty cell names no other sensor
        if len(ids) > 1:
            raise DataFileError(table.path, f"holds readings of {len(ids)} sensors ({', '.join(ids[:5])}); a field "
                                            "file is one sensor's", column="sensor_id")
        sensor_id = ids[0] if ids else None
    return FieldData(path=table.path, time_utc=times, t_s=t_s, ok=ok, x_px=spots.get("x_px"), y_px=spots.get("y_px"),
                     zenith_deg=directions.get("zenith_deg"), azimuth_deg=directions.get("azimuth_deg"),
                     numbers=numbers, cloud=cloud, metadata=metadata, sensor_id=sensor_id, spot_cloud=spot_cloud)


def _flags(table: CsvTable, column: str) -> np.ndarray:
    """A 0/1 column (empty cells 0) as booleans: nonzero is set."""
    values = table.numbers(column, integer=True, allow_empty=np.ones(len(table.rows), bool))
    return np.nan_to_num(values, nan=0.0) != 0


def _times(table: CsvTable, times: list[str]) -> np.ndarray:
    try:
        t_s = utc_seconds(times)
    except FieldDataError as exc:
        row = None if exc.row is None else exc.row + 1
        raise DataFileError(table.path, str(exc).split(": ", 1)[-1], row=row,
                            line=None if row is None else table.lines[row - 1], column="time_utc") from None
    back = np.flatnonzero(np.diff(t_s) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise DataFileError(table.path, f"time goes backwards ({times[i]} after {times[i - 1]}); sort the rows",
                            row=i + 1, line=table.lines[i], column="time_utc")
    return t_s


def _check_range(table: CsvTable, column: str, values: np.ndarray, low: float, high: float) -> None:
    bad = np.flatnonzero(np.isfinite(values) & ((values < low) | (values > high)))
    if bad.size:
        i = int(bad[0])
        raise DataFileError(table.path, f"{values[i]:g} is outside {low:g}…{high:g}", row=i + 1,
                            line=table.lines[i], column=column)


def iso_utc(t_s: float) -> str:
    """Unix seconds as ISO 8601 UTC with milliseconds (``2019-09-29T04:58:17.000Z``)."""
    stamp = dt.datetime.fromtimestamp(t_s, dt.UTC)
    return stamp.isoformat(timespec="milliseconds").replace("+00:00", "Z")


class FieldCsvAppender:
    """A field CSV written row by row, as a field run reads: the header comments and the column names at once, then
    each row flushed to the operating system as it is appended (a run killed keeps every row read) and synced to
    the disk every `sync_s` seconds (a power cut loses at most that much). A context manager.

    Parameters
    ----------
    path : path-like
    names : sequence of str
        The columns, ``time_utc`` first.
    metadata : dict, optional
        The ``# key: value`` header comments (:data:`FIELD_KEYS`; None values are left out).
    """

    def __init__(self, path, names, *, metadata: dict | None = None, flush: bool = True, sync_s: float = 30.0):
        self.names = list(names)
        if not self.names or self.names[0] != "time_utc":
            raise ValueError("a field CSV starts with its time_utc column")
        unknown = [key for key in (metadata or {}) if key not in FIELD_KEYS]
        if unknown:
            raise ValueError(f"unknown field header key(s) {', '.join(unknown)}")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = self.path.open("w", newline="")
        self._flush, self._sync_s, self._synced = flush, sync_s, time.monotonic()
        for key, value in (metadata or {}).items():
            if value is not None:
                self._fh.write(f"# {key}: {value:.10g}\n")
        self._csv = csv.writer(self._fh)
        self._csv.writerow(self.names)
        self._push()

    def append(self, row: dict) -> None:
        """One row: column → value (``time_utc`` an ISO string or Unix seconds; a missing column is left empty)."""
        stamp = row["time_utc"]
        self._csv.writerow([stamp if isinstance(stamp, str) else iso_utc(float(stamp))]
                           + [_cell(row.get(c)) for c in self.names[1:]])
        self._push()

    def _push(self) -> None:
        if not self._flush:
            return
        self._fh.flush()
        if time.monotonic() - self._synced >= self._sync_s:
            os.fsync(self._fh.fileno())
            self._synced = time.monotonic()

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()

    def __enter__(self) -> FieldCsvAppender:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_field_csv(path, columns: dict, *, metadata: dict | None = None) -> None:
    """Write a field CSV: `columns` maps column name → values (``time_utc`` first: ISO strings or Unix seconds),
    `metadata` the ``# key: value`` header comments (:data:`FIELD_KEYS`; None values are left out)."""
    names = list(columns)
    with FieldCsvAppender(path, names, metadata=metadata, flush=False) as out:
        for i in range(len(columns[names[0]]) if names else 0):
            out.append({c: columns[c][i] for c in names})


def _cell(value) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{float(value):.6f}"
