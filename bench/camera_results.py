"""What a camera run's results look like through its calibration: the camera model with its 1σ, the fit's and the
held-out figures, the warnings, and every point's spot with the calibration's residual — plain data for the
dashboard's camera results view (seed 001's camera sun sensor).

Computed here, with the calibration core (:mod:`calibration.camera`), so ``web/`` holds no science (as
:mod:`bench.results` does for the CMOS family and :mod:`bench.qd_results` for the QD one). Everything is read from
the catalogue: the run's lineage (the readings its fit used, a resumed run's parent included) and the calibration
document stored at the run's end (:func:`bench.families.camera.fit_run`).

The fit used every frame with a spot, less the spots at the frame's border (recorded, never fitted:
:data:`bench.families.camera.EDGE_MARGIN_PX`). Applying the stored model to those frames gives back the document's
fit figures (its RMS and largest angular residual); the view draws one mean spot per point (a direction the table
set), its residual the angle between the direction the model gives for that spot and the direction set, and the
vector from the spot to where the model puts the direction set [px]. The held-out figures (whole zenith rings, and
whole azimuths, left out and refitted) are the document's: they need a refit per group and are not recomputed.
"""

from __future__ import annotations

import numpy as np

from calibration.camera import PARAMETERS, camera_from_document, project, zenith_azimuth
from calibration.geometry import angular_error_deg, direction_vector

from .families.camera import spot_clipped
from .results import calibration_record, family_run, finite_or_none, readings_by_point, split_left_out

__all__ = ["FAMILY", "camera_fit"]

#: The family whose runs this view reads
FAMILY = "camera"

#: Why a frame's spot is never fitted (bench.families.camera.bench_data leaves it out)
EDGE_REASON = "spot at the frame's border (its disc is cut): recorded, never fitted"

#: The held-out schemes of :func:`calibration.camera.held_out`, and what each leaves out
SCHEMES = {"rings": "whole zenith rings (not the boresight, not the outermost)", "azimuths": "whole azimuths"}

#: What the 1σ of the parameters cannot say alone (calibration.camera.fit_camera's notes)
PARAMETERS_NOTE = ("± 1σ from the fit's covariance. The principal point (cx, cy) and the camera's tilts (rotation "
                   "x, y) are nearly degenerate: their 1σ are large together, while the directions the model gives "
                   "stay as well determined as the held-out figures say.")








def _has_spot(reading) -> bool:
    return reading.ok and reading.value("x_px") is not None and reading.value("y_px") is not None


def _unit(name: str) -> str:
    return "px" if name.endswith("_px") else "°" if name.endswith("_deg") else ""


def _parameters(model, document: dict) -> list[dict]:
    """The model's parameters in :data:`calibration.camera.PARAMETERS` order: value, its unit, its 1σ (None for a
    parameter the fit held fixed: absent from the document's ``sigma``)."""
    sigma = document.get("sigma") or {}
    values = {name: getattr(model, name) for name in PARAMETERS[:9]}
    values.update(zip(PARAMETERS[9:], model.rotation_deg, strict=True))
    return [{"name": name, "unit": _unit(name), "value": float(values[name]), "sd": finite_or_none(sigma.get(name)),
             "fitted": name in sigma} for name in PARAMETERS]


def _figures(metrics: dict) -> dict:
    """The document's figures: the fit's over every frame it used, and each held-out scheme's, the worse marked."""
    held = metrics.get("held_out") or {}
    worse = held.get("worst_scheme")
    schemes = []
    for name, left_out in SCHEMES.items():
        scheme = held.get(name)
        if not isinstance(scheme, dict):
            continue
        groups = [float(g) for g in scheme.get("groups") or []]
        schemes.append({"scheme": name, "left_out": left_out, "groups_deg": groups, "n_groups": len(groups),
                        "n_points": scheme.get("n_points"), "rms_deg": finite_or_none(scheme.get("rms_deg")),
                        "max_deg": finite_or_none(scheme.get("max_deg")), "worse": name == worse})
    return {"fit": {"n_points": metrics.get("n_points"), "rms_deg": finite_or_none(metrics.get("fit_rms_deg")),
                    "max_deg": finite_or_none(metrics.get("fit_max_deg")),
                    "rms_px": finite_or_none(metrics.get("fit_rms_px")),
                    "reduced_chi2": finite_or_none(metrics.get("reduced_chi2")),
                    "noise_px": finite_or_none(metrics.get("noise_px"))},
            "held_out": schemes, "worse_scheme": worse,
            "heldout_rms_deg": finite_or_none(held.get("worst_rms_deg")),
            "heldout_max_deg": finite_or_none(held.get("max_deg"))}


def _summary(errors) -> dict:
    values = np.asarray([e for e in errors if e is not None], dtype=float)
    if not values.size:
        return {"n_points": 0, "rms_deg": None, "max_deg": None}
    return {"n_points": int(values.size), "rms_deg": float(np.sqrt(np.mean(values**2))),
            "max_deg": float(values.max())}


def _errors(model, pixels: np.ndarray, zenith: np.ndarray, azimuth: np.ndarray):
    """The direction the model gives for each spot, its angle to the direction set, and the vector from each spot to
    where the model puts the direction set [px] (the fit's residual, model − measured)."""
    with np.errstate(invalid="ignore"):
        zenith_fit, azimuth_fit = (np.atleast_1d(np.asarray(v, dtype=float)) for v in zenith_azimuth(model, pixels))
        error = np.atleast_1d(angular_error_deg(zenith, azimuth, zenith_fit, azimuth_fit))
        predicted = np.atleast_2d(project(model, direction_vector(zenith, azimuth)))
    return zenith_fit, azimuth_fit, error, predicted - pixels


def camera_fit(catalogue, run_id: int, method: str | None = None) -> dict:
    """The calibration `method` of a camera run (default: the chosen one) and the run's spots through it.

    Returns a dict: `method`, `chosen`, the frame's size and the half field of view at its corners; `parameters`
    (fx, fy, cx, cy [px], k1, k2, p1, p2, k3, the rotation body → camera as a Rodrigues vector [°], each with its
    1σ); `figures` (the document's: the fit's RMS and largest angular residual over the frames it used, χ²/dof, the
    centroid noise; each held-out scheme's, the worse marked); `warnings`; `frames` (the stored model applied to
    those frames again: it gives back the fit's figures) and `points` (over the points' mean spots) summaries; and
    `data`, one entry per point with a spot in recording order: the direction the table set (body zenith and
    azimuth), the mean spot of the frames the fit used, the direction the model gives for it, the angle between the
    two (`error_deg`) and the residual vector (`residual_x_px`, `residual_y_px`: where the model puts the direction
    set, minus the mean spot). A point whose every spot lay at the frame's border keeps the mean of its spots and
    says why in `excluded` (counted in no summary); `frames_left_out` names each frame of a point no fit used.

    Raises :class:`~bench.results.WrongFamilyRun` for a run of another family, :class:`~bench.results.NoCalibration`
    when the run has no such calibration; the document's own format errors
    (:class:`calibration.errors.CalibrationFormatError`) pass through."""
    family_run(catalogue, run_id, FAMILY)
    record = calibration_record(catalogue, run_id, method)
    document = record["document"]
    model = camera_from_document(document)
    metrics = document.get("metrics") or record.get("metrics") or {}
    lineage = catalogue.lineage(run_id)
    readings = readings_by_point(catalogue.readings(lineage))

    def clipped(reading) -> bool:
        return spot_clipped(reading, model.width_px, model.height_px)

    def reason(reading) -> str | None:
        if not _has_spot(reading):
            return f"no spot ({reading.status})"
        return EDGE_REASON if clipped(reading) else None

    points, means, used_frames = [], [], []
    for point in catalogue.points(lineage):
        rows = readings.get(point["id"], [])
        spots = [r for r in rows if _has_spot(r)]
        if not spots or point["zenith_deg"] is None:
            continue  # nothing to place on the frame
        used, left_out, excluded = split_left_out(rows, reason)
        mean_of = used or spots
        means.append([np.mean([r.value(c) for r in mean_of]) for c in ("x_px", "y_px")])
        used_frames += [(r.value("x_px"), r.value("y_px"), r.zenith_deg, r.azimuth_body_deg) for r in used]
        points.append({"id": point["id"], "run_id": point["run_id"], "key": point["key"], "stage": point["stage"],
                       "zenith_deg": float(point["zenith_deg"]), "azimuth_deg": float(point["azimuth_body_deg"]),
                       "n_frames": len(used), "excluded": excluded if not used else None,
                       "frames_left_out": left_out})
    if points:
        pixels = np.array(means, dtype=float)
        zenith = np.array([p["zenith_deg"] for p in points])
        azimuth = np.array([p["azimuth_deg"] for p in points])
        zenith_fit, azimuth_fit, error, residual = _errors(model, pixels, zenith, azimuth)
        for i, p in enumerate(points):
            p.update(x_px=float(pixels[i, 0]), y_px=float(pixels[i, 1]), zenith_fit_deg=finite_or_none(zenith_fit[i]),
                     azimuth_fit_deg=finite_or_none(azimuth_fit[i]), error_deg=finite_or_none(error[i]),
                     residual_x_px=finite_or_none(residual[i, 0]), residual_y_px=finite_or_none(residual[i, 1]))
    frames = {"n_points": 0, "rms_deg": None, "max_deg": None, "rms_px": None}
    if used_frames:
        f = np.array(used_frames, dtype=float)
        _, _, error, residual = _errors(model, f[:, :2], f[:, 2], f[:, 3])
        frames = {**_summary(error), "rms_px": finite_or_none(np.sqrt(np.mean(np.sum(residual**2, axis=1))))}
    design = document.get("design") or {}
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]),
            "created_utc": record.get("created_utc"), "sensor_id": document.get("sensor_id"),
            "width_px": model.width_px, "height_px": model.height_px,
            "fov_half_deg": finite_or_none(design.get("fov_half_deg")),
            "parameters": _parameters(model, document), "parameters_note": PARAMETERS_NOTE,
            "figures": _figures(metrics), "warnings": [str(w) for w in document.get("warnings") or []],
            "frames": frames, "points": _summary([p["error_deg"] for p in points if not p["excluded"]]),
            "data": points, "count": len(points)}
