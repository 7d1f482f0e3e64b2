"""The camera bench data CSV (README, "Camera bench data CSV") and camera calibration files.

A camera sun sensor's bench data (seed 001, calibrated on the bench as its digest §7 item 4 asks): one row per
frame, the true sun direction in the sensor's body frame, the spot's centre in the frame, and optionally the frame's
index at its direction, the sensor's serial and the exposure; ``# width_px: 640`` and ``# height_px: 480`` header
comments give the frame's size. The file is read with the CMOS reader's table (:func:`bench.datafile.read_csv_table`:
a header row, ``#`` comments, blank lines, a byte-order mark, duplicate columns, ragged rows), so every problem is
the same :class:`~bench.datafile.DataFileError` naming the file, the row (and its line) and the column.

The calibration document (``sunbench fit camera``, a camera run's fit) is ``{"format": "sunbench.calibration",
"version": 1, "family": "camera", "kind": "camera", "method": "opencv", "model": CameraModel.to_dict(), ...}`` with
its provenance, the parameters' 1σ, the design (frame size, half field of view), the metrics (the fit's and the
held-out figures by scheme) and the warnings; :func:`calibration.camera.camera_from_document` reads its model.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.camera import CameraBenchData, CameraCalibration, CameraModel, camera_from_document, ray_directions
from calibration.camera.model import DOCUMENT_FORMAT, DOCUMENT_VERSION, FAMILY
from calibration.errors import BenchDataError, CalibrationFormatError

from .datafile import (
    TRUE_COLUMNS,
    CsvTable,
    DataFileError,
    header_numbers,
    load_calibration_json,
    read_csv_table,
    require_columns,
    sensor_rows,
)

#: Columns every camera bench data CSV has.
REQUIRED_COLUMNS = TRUE_COLUMNS + ("x_px", "y_px")
#: The columns the writer writes, in this order (README).
COLUMNS = REQUIRED_COLUMNS + ("repeat", "sensor_id", "exposure_ms")
#: ``# key: value`` header comments: the frame's size [px].
HEADER_KEYS = ("width_px", "height_px")
DEFAULT_FRAME = (640, 480)
#: The one method of the camera family (OpenCV's camera model).
METHOD = "opencv"


@dataclass(frozen=True)
class CameraFrames:
    """A camera bench data CSV as read.

    Attributes
    ----------
    data : CameraBenchData
        One point per frame (the rows of the chosen sensor).
    exposure_ms : ndarray or None
        The exposure of each frame [ms], when the file gives it.
    path : str
    lines : ndarray of int
        The file line of each point of `data`.
    rows : ndarray of int
        The data row (1-based, the header not counted) of each point of `data`.
    metadata : dict
        The header comments' numbers (:data:`HEADER_KEYS`).
    """

    data: CameraBenchData
    exposure_ms: np.ndarray | None
    path: str
    lines: np.ndarray
    rows: np.ndarray
    metadata: dict = field(default_factory=dict)


def _refuse(table: CsvTable, column: str, bad: np.ndarray, message) -> None:
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataFileError(table.path, message(i), row=i + 1, line=table.lines[i], column=column)


def _hint_other_family(table: CsvTable) -> None:
    if table.has("i1_a") and not table.has("x_px"):
        raise DataFileError(table.path, "has quadrant currents i1_a … i4_a and no spot columns x_px, y_px: a QD "
                                        "sensor's CSV (`sunbench fit qd` reads it), not a camera one")
    if table.has("stage_zenith_deg") and not table.has("zenith_deg"):
        raise DataFileError(table.path, "has stage angles (stage_zenith_deg, stage_azimuth_deg): a camera bench CSV "
                                        "gives the true body direction, zenith_deg and azimuth_deg (`sunbench export` "
                                        "of a camera run writes it)")


def _frame_size(table: CsvTable, metadata: dict, width_px: int | None, height_px: int | None) -> tuple[int, int]:
    size = []
    for key, option, default in (("width_px", width_px, DEFAULT_FRAME[0]), ("height_px", height_px,
                                                                          DEFAULT_FRAME[1])):
        value = option if option is not None else metadata.get(key, default)
        if not (float(value).is_integer() and 16 <= value <= 100_000):
            raise DataFileError(table.path, f"{key} {value:g} is not a frame size (a whole number of pixels, "
                                            "16…100000)")
        size.append(int(value))
    return size[0], size[1]


def read_camera_frames(path, *, sensor_id: str | None = None, width_px: int | None = None,
                       height_px: int | None = None) -> CameraFrames:
    """Read a camera bench data CSV (README, "Camera bench data CSV").

    Parameters
    ----------
    path : path-like
    sensor_id : str, optional
        Keep only this sensor's rows (a file holding several needs it).
    width_px, height_px : int, optional
        The frame's size [px]; by default the ``# width_px:``/``# height_px:`` header comments, else 640×480.

    Raises
    ------
    DataFileError
        Naming the file, and where it can the row, its line and the column.
    """
    table = read_csv_table(path)
    metadata = header_numbers(table, HEADER_KEYS)
    _hint_other_family(table)
    require_columns(table, REQUIRED_COLUMNS)
    if not table.rows:
        raise DataFileError(table.path, "no data rows")
    width, height = _frame_size(table, metadata, width_px, height_px)
    keep, sensor_id = sensor_rows(table, sensor_id)
    zenith, azimuth = table.numbers("zenith_deg"), table.numbers("azimuth_deg")
    _refuse(table, "zenith_deg", (zenith < 0) | (zenith >= 90),
            lambda i: f"zenith {zenith[i]:g}° must lie in [0, 90) (the sun in front of the sensor)")
    x, y = table.numbers("x_px"), table.numbers("y_px")
    _refuse(table, "x_px", (x < -0.5) | (x > width - 0.5),
            lambda i: f"{x[i]:g} px is outside the frame's {width} columns (-0.5 … {width - 0.5:g}); a frame of "
                      "another size needs --width-px or '# width_px: …'")
    _refuse(table, "y_px", (y < -0.5) | (y > height - 0.5),
            lambda i: f"{y[i]:g} px is outside the frame's {height} rows (-0.5 … {height - 0.5:g}); a frame of another "
                      "size needs --height-px or '# height_px: …'")
    repeat = table.numbers("repeat", integer=True) if table.has("repeat") else None
    if repeat is not None:
        _refuse(table, "repeat", repeat < 0, lambda i: f"{repeat[i]:g} is not a frame index (0, 1, …)")
    exposure = None
    if table.has("exposure_ms"):
        exposure = table.numbers("exposure_ms", allow_empty=np.ones(len(table.rows), bool))
        _refuse(table, "exposure_ms", exposure <= 0, lambda i: f"exposure {exposure[i]:g} ms must be positive")
    try:
        data = CameraBenchData(zenith, azimuth, x, y, repeat, sensor_id=sensor_id or "", width_px=width,
                               height_px=height)
    except BenchDataError as exc:  # what the checks above did not catch
        row = None if exc.row is None else exc.row + 1
        raise DataFileError(table.path, str(exc), row=row, line=None if row is None else table.lines[row - 1],
                            column=exc.column if exc.column in table.header else None) from None
    index = np.flatnonzero(keep)
    if not keep.all():
        data = data.subset(index)
    return CameraFrames(data, None if exposure is None else exposure[index], table.path,
                        np.asarray(table.lines)[index], index + 1, metadata)


def _number(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ""


def write_camera_csv(path, data: CameraBenchData, exposure_ms=None) -> None:
    """Write camera bench data in the format :func:`read_camera_frames` reads: the frame's size as header comments,
    then :data:`COLUMNS` (floats as Python's shortest round-trip repr, so they read back bit for bit)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    repeat = data.repeat if data.repeat is not None else np.zeros(len(data), int)
    exposure = np.full(len(data), np.nan) if exposure_ms is None else np.asarray(exposure_ms, float)
    with path.open("w", newline="") as fh:
        fh.write(f"# width_px: {int(data.width_px)}\n# height_px: {int(data.height_px)}\n")
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for i in range(len(data)):
            w.writerow([_number(data.zenith_deg[i]), _number(data.azimuth_deg[i]), _number(data.x_px[i]),
                        _number(data.y_px[i]), int(repeat[i]), data.sensor_id, _number(exposure[i])])


# --- calibration documents -------------------------------------------------------------------------------------

def fov_half_deg(model: CameraModel) -> float:
    """The largest angle from the boresight the frame sees, at its corners [°] (a field file's field of view)."""
    w, h = model.width_px, model.height_px
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
    rays = ray_directions(model, corners)
    return float(np.degrees(np.max(np.arctan2(np.hypot(rays[:, 0], rays[:, 1]), rays[:, 2]))))


def camera_metrics(calibration: CameraCalibration) -> dict:
    """The figures of a camera calibration: the fit's at the nodes, the held-out ones by scheme (whole zenith rings
    and whole azimuths left out) and, as ``heldout``, the worse scheme's RMS and the largest error of either, in the
    keys the fleet table reads (``rms_vector_deg``)."""
    fit, held = calibration.fit, calibration.held_out
    out = {"n_points": int(len(fit.residual_deg)), "fit_rms_px": fit.rms_px, "fit_rms_deg": fit.rms_deg,
           "fit_max_deg": fit.max_deg, "reduced_chi2": fit.reduced_chi2, "noise_px": fit.noise_px,
           "held_out": None, "heldout": None}
    if held is not None:
        out["held_out"] = held.to_dict()
        out["heldout"] = {"rms_vector_deg": held.rms_deg, "max_vector_deg": held.max_deg, "scheme": held.worst.name}
    return _finite(out)


def _finite(value):
    """JSON-ready: non-finite numbers as None (a scheme with no group has no RMS)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def camera_calibration_document(calibration: CameraCalibration, *, source: str | None, software: str | None,
                                created: bool = True) -> dict:
    """The calibration document of a camera calibration (module docstring), with its provenance; `created`
    stamps the time (the catalogue stamps its own)."""
    model = calibration.model
    document = {"format": DOCUMENT_FORMAT, "version": DOCUMENT_VERSION, "family": FAMILY, "kind": "camera",
                "method": METHOD, "sensor_id": calibration.sensor_id or None, "source": source, "software": software,
                "model": model.to_dict(), "sigma": _finite(calibration.fit.sigma),
                "design": {"width_px": model.width_px, "height_px": model.height_px,
                           "fov_half_deg": fov_half_deg(model)},
                "metrics": camera_metrics(calibration), "warnings": list(calibration.warnings)}
    if created:
        document["created_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    return document


def is_camera_document(document) -> bool:
    """Whether a calibration document (parsed JSON) says it is of the camera family."""
    return isinstance(document, dict) and (document.get("family") == FAMILY or document.get("kind") == "camera")


def read_camera_calibration(path) -> tuple[CameraModel, dict]:
    """A camera calibration file's model and document; a bad one raises :class:`DataFileError` naming the problem."""
    document = load_calibration_json(path)
    try:
        return camera_from_document(document), document
    except CalibrationFormatError as exc:
        raise DataFileError(path, str(exc)) from None


def camera_header_from_document(document: dict) -> str:
    """The C header of a camera calibration document (:func:`calibration.camera.export.camera_c_header`), its
    opening comment naming the source, the date, the software and the held-out accuracy."""
    from calibration.camera.export import camera_c_header

    heldout = (document.get("metrics") or {}).get("heldout") or {}
    held = None
    if heldout.get("rms_vector_deg") is not None:
        held = (f"RMS {heldout['rms_vector_deg']:.4f} deg ({heldout.get('scheme')} left out), max "
                f"{heldout.get('max_vector_deg') or float('nan'):.4f} deg")
    provenance = {"source": document.get("source"), "created": document.get("created_utc"),
                  "software": document.get("software"), "held-out error": held}
    return camera_c_header(camera_from_document(document), sensor_id=document.get("sensor_id"),
                           provenance=provenance)
