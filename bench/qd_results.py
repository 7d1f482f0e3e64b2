"""What a QD run's results look like: its quadrant currents, its dark-current fit, the angular error of a
calibration over the field, and every method's figures — plain data for the dashboard's QD results view.

Computed here, with the calibration core, so ``web/`` holds no science (as :mod:`bench.results` does for the
CMOS family). Everything is read from the catalogue: the run's lineage (the readings its fit used, a resumed
run's parent included) and the calibration documents stored at the run's end.

The error map applies a stored document to the run's readings as the fit scored them
(:func:`calibration.qd.evaluation.calibrate_qd`): the readings the document rejected (its ``rejected`` rows,
``row`` = reading id) and those with a clipped channel left out, the document's dark model subtracted from
each reading (seed 002 §2.1), the photocurrents of a direction averaged, then eq. 2.1 and the method
(:func:`calibration.qd.document.angles_from_photocurrents`). So its largest and RMS error over the grid nodes
are the document's ``at_nodes`` figures, and over the check points (never fitted) its held-out ``check``
figures. The held-out figures of leaving grid lines out need a refit per fold and are not in the map.
"""

from __future__ import annotations

import numpy as np

from calibration.errors import InsufficientDataError
from calibration.qd.angles import angle_between_projections_deg, projection_angles, zenith_azimuth_from_projection
from calibration.qd.dark import DarkModel, fit_dark, subtract_dark
from calibration.qd.document import angles_from_photocurrents, validate_document

from .families.qd import CHECK, DARK, SATURATED
from .families.qd import summary as point_summary
from .results import (
    NoCalibration,
    calibration_record,
    family_run,
    finite_or_none,
    readings_by_point,
    rejected_readings,
    split_left_out,
)

#: The family whose runs these views read
FAMILY = "qd"

#: Why a reading is left out of every QD fit (bench.families.qd.bench_data keeps ok readings only)
SATURATED_REASON = "a quadrant reached full scale (its current is only a lower bound)"

#: Temperatures the dark model's curve is drawn at
CURVE_SAMPLES = 61








def _chosen_or_none(catalogue, run_id: int, method: str | None) -> dict | None:
    try:
        return calibration_record(catalogue, run_id, method)
    except NoCalibration:
        if method:
            raise
        return None


def _left_out_reason(reading, rejected: dict[int, str]) -> str | None:
    """Why every QD fit, or the calibration that `rejected` its readings (reading id → reason), left the reading
    out; None when it was fitted."""
    if reading.status == SATURATED:
        return SATURATED_REASON
    return reading.status if not reading.ok else rejected.get(reading.id)


def _true_angles(points) -> list[tuple[float, float]]:
    """The true (α, β) of each lit point (seed 002 eq. 2.2), computed at once for all of them."""
    if not points:
        return []
    alpha, beta = projection_angles(np.array([float(p["zenith_deg"]) for p in points]),
                                    np.array([float(p["azimuth_body_deg"]) for p in points]))
    return [(float(a), float(b)) for a, b in zip(np.atleast_1d(alpha), np.atleast_1d(beta))]


# --- the quadrant currents of every point -------------------------------------------------------------------
def qd_currents(catalogue, run_id: int) -> dict:
    """Every point of the run's lineage in recording order: its stage, its true direction (zenith, azimuth and
    the projection angles α, β of seed 002 eq. 2.2; None at a dark point), and the mean raw current of each
    quadrant (dark current included) over its readings without a clipped channel, their sum and the mean
    temperature; `n_saturated` counts the readings with a clipped channel."""
    family_run(catalogue, run_id, FAMILY)
    lineage = catalogue.lineage(run_id)
    readings = readings_by_point(catalogue.readings(lineage))
    points = catalogue.points(lineage)
    lit = iter(_true_angles([p for p in points if p["stage"] != DARK]))
    data = []
    for index, point in enumerate(points, start=1):
        rows = readings.get(point["id"], [])
        ok = [r for r in rows if r.ok]
        mean = point_summary(ok)  # the family's: the mean currents and temperature of the ok readings
        currents = mean["currents_a"]
        dark = point["stage"] == DARK
        alpha, beta = (None, None) if dark else next(lit)
        data.append({"id": point["id"], "run_id": point["run_id"], "index": index, "key": point["key"],
                     "stage": point["stage"], "zenith_deg": None if dark else point["zenith_deg"],
                     "azimuth_deg": None if dark else point["azimuth_body_deg"], "alpha_deg": alpha, "beta_deg": beta,
                     "currents_a": currents, "sum_a": None if currents is None else float(np.sum(currents)),
                     "temperature_c": mean["temperature_c"], "n_readings": len(rows), "n_ok": len(ok),
                     "n_saturated": sum(1 for r in rows if r.status == SATURATED)})
    return {"run_id": run_id, "data": data, "count": len(data)}


# --- the dark current -----------------------------------------------------------------------------------------
def _model_parts(model: DarkModel, document: dict) -> dict:
    return {"model": model.kind, "t_ref_c": float(model.t_ref_c), "quadrants": document.get("quadrants") or [],
            "residual_sd_a": [finite_or_none(v) for v in model.residual_sd_a], "note": document.get("note"),
            "temperature_range_c": document.get("temperature_range_c")}


def qd_dark(catalogue, run_id: int, method: str | None = None) -> dict:
    """The run's dark readings (shutter closed: each quadrant's current against the die's temperature) and the
    dark model of seed 002 §2.1 drawn through them: the one of the calibration `method` (default the chosen
    one), else — a dark sweep alone has no calibration — the model :func:`calibration.qd.dark.fit_dark` fits
    to the readings here (`source` says which; None when there are too few). `curve` samples the model over
    the temperatures of every reading of the run, light ones included (a model outside its dark readings'
    range is extrapolated: `dark_range_c` against `light_range_c`)."""
    family_run(catalogue, run_id, FAMILY)
    lineage = catalogue.lineage(run_id)
    record = _chosen_or_none(catalogue, run_id, method)
    rejected = rejected_readings(record["document"]) if record else {}
    rows = catalogue.readings(lineage)
    dark_rows = [r for r in rows if r.stage == DARK]
    readings = [{"reading_id": r.id, "key": r.key, "temperature_c": r.values.get("temperature_c"),
                 "currents_a": r.values.get("currents_a"), "left_out": _left_out_reason(r, rejected)}
                for r in dark_rows]
    used = [r for r in dark_rows if _left_out_reason(r, rejected) is None]
    light_t = [r.values["temperature_c"] for r in rows if r.ok and r.stage != DARK]
    dark_t = [r.values["temperature_c"] for r in used]
    model = parts = None
    source = None
    if record is not None:
        document = record["document"]
        validate_document(document)
        model = DarkModel.from_dict(document["dark"])
        parts, source = _model_parts(model, document["dark"]), "calibration"
    elif used:
        try:
            fit = fit_dark(dark_t, [r.values["currents_a"] for r in used])
        except InsufficientDataError:
            fit = None
        if fit is not None:
            model, parts, source = fit.model, _model_parts(fit.model, fit.to_dict()), "readings"
    curve = None
    span = dark_t + light_t
    if model is not None and model.kind != "none" and span:
        low, high = min(span), max(span)
        pad = max(0.05 * (high - low), 1.0)
        t = np.linspace(low - pad, high + pad, CURVE_SAMPLES)
        curve = {"temperature_c": [float(v) for v in t],
                 "currents_a": [[float(c) for c in row] for row in model.current(t)]}
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None, "source": source, **(parts or {"model": None}),
            "curve": curve, "readings": readings, "count": len(readings),
            "dark_range_c": [min(dark_t), max(dark_t)] if dark_t else None,
            "light_range_c": [min(light_t), max(light_t)] if light_t else None}


# --- the angular error over the field ---------------------------------------------------------------------
def _summary(errors: list[float]) -> dict:
    values = np.asarray([e for e in errors if e is not None], dtype=float)
    if not values.size:
        return {"n_points": len(errors), "n_failed": len(errors), "max_deg": None, "rms_deg": None}
    return {"n_points": len(errors), "n_failed": len(errors) - int(values.size), "max_deg": float(values.max()),
            "rms_deg": float(np.sqrt(np.mean(values**2)))}


def qd_error_map(catalogue, run_id: int, method: str | None = None) -> dict:
    """The angular error of one calibration (default: the chosen one) at every lit direction of the run: its
    stored document applied to the direction's readings as the fit scored them (module docstring). A grid
    node was fitted (`kind` "node": the error at the nodes); a check point between the nodes never was
    (`kind` "check": held out). Each direction has its true (α, β, zenith, azimuth), the calibration's, and
    the angle between them; a direction whose every reading the fit left out keeps the figures of all its
    readings and says why in `excluded` (counted in no summary); `readings_left_out` names each reading left out.

    Raises :class:`~bench.results.NoCalibration` when the run has no such calibration; the document's own
    format errors (:class:`calibration.errors.CalibrationFormatError`) pass through."""
    family_run(catalogue, run_id, FAMILY)
    record = calibration_record(catalogue, run_id, method)
    document = record["document"]
    validate_document(document)
    dark = DarkModel.from_dict(document["dark"])
    rejected = rejected_readings(document)
    lineage = catalogue.lineage(run_id)
    readings = readings_by_point(catalogue.readings(lineage))
    lit = [p for p in catalogue.points(lineage) if p["stage"] != DARK]
    directions, measured = [], []
    for point, (alpha, beta) in zip(lit, _true_angles(lit), strict=True):
        rows = readings.get(point["id"], [])
        used, left_out, excluded = split_left_out(rows, lambda r: _left_out_reason(r, rejected))
        applied = used or [r for r in rows if r.values.get("currents_a") is not None]
        if not applied:  # nothing was read there: nothing to apply the calibration to
            continue
        measured.append(applied)
        directions.append({"id": point["id"], "key": point["key"], "stage": point["stage"],
                           "kind": "check" if point["stage"] == CHECK else "node",
                           "alpha_deg": alpha, "beta_deg": beta, "zenith_deg": point["zenith_deg"],
                           "azimuth_deg": point["azimuth_body_deg"], "n_readings": len(used),
                           "excluded": excluded, "readings_left_out": left_out})
    if directions:
        # the dark model subtracted from every reading at once (seed 002 §2.1), then averaged per direction
        rows = [r for applied in measured for r in applied]
        photo = subtract_dark([r.values["currents_a"] for r in rows], [r.values["temperature_c"] for r in rows], dark)
        ends = np.cumsum([len(applied) for applied in measured])
        photocurrents = [np.mean(photo[end - len(applied):end], axis=0) for end, applied in zip(ends, measured)]
        with np.errstate(invalid="ignore", divide="ignore"):
            fit_a, fit_b = (np.asarray(v, dtype=float)
                            for v in angles_from_photocurrents(document, np.array(photocurrents)))
            true_a = np.array([d["alpha_deg"] for d in directions])
            true_b = np.array([d["beta_deg"] for d in directions])
            ok = np.isfinite(fit_a) & np.isfinite(fit_b)
            error = np.where(ok, angle_between_projections_deg(true_a, true_b, np.where(ok, fit_a, 0.0),
                                                               np.where(ok, fit_b, 0.0)), np.nan)
            fit_zen, fit_az = zenith_azimuth_from_projection(np.where(ok, fit_a, 0.0), np.where(ok, fit_b, 0.0))
        for i, d in enumerate(directions):
            good = bool(ok[i])
            d.update(alpha_fit_deg=finite_or_none(fit_a[i]) if good else None,
                     beta_fit_deg=finite_or_none(fit_b[i]) if good else None,
                     zenith_fit_deg=finite_or_none(fit_zen[i]) if good else None,
                     azimuth_fit_deg=finite_or_none(fit_az[i]) if good else None,
                     error_deg=finite_or_none(error[i]) if good else None)
    summary = {kind: _summary([d["error_deg"] for d in directions if d["kind"] == kind and not d["excluded"]])
               for kind in ("node", "check")}
    field = max((max(abs(d["alpha_deg"]), abs(d["beta_deg"])) for d in directions), default=None)
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]), "field_deg": field,
            "summary": summary, "data": directions, "count": len(directions)}


# --- every method's figures -------------------------------------------------------------------------------------
def qd_metrics(catalogue, run_id: int) -> dict:
    """Every calibration of the run with its figures (held out between the nodes: max, RMS, p99 and the scheme
    that gave the worst; at the nodes; χ²/dof against the repeat scatter), the chosen one marked; of the chosen
    (else the latest) document, the readings the fit rejected (with their point) and its warnings."""
    family_run(catalogue, run_id, FAMILY)
    records = catalogue.calibrations(run_id)
    methods = []
    for c in records:
        m = c.get("metrics") or {}
        methods.append({"id": c["id"], "method": c["method"], "chosen": bool(c["chosen"]),
                        "created_utc": c["created_utc"],
                        "error": m.get("error"), "heldout": m.get("heldout"), "heldout_scheme": m.get("heldout_scheme"),
                        "heldout_by_scheme": m.get("heldout_by_scheme") or {}, "at_nodes": m.get("at_nodes"),
                        "chi2_dof": m.get("chi2_dof")})
    chosen = next((c for c in reversed(records) if c["chosen"]), records[-1] if records else None)
    document = chosen["document"] if chosen else {}
    entries = document.get("rejected") or []
    # the point of each rejected reading (the lineage's readings are read only when there are some)
    keys = {r.id: (r.key, r.stage) for r in catalogue.readings(catalogue.lineage(run_id))} if entries else {}
    rejected = []
    for entry in entries:
        if not isinstance(entry, dict):
            continue
        key, stage = keys.get(entry.get("row"), (None, None))
        rejected.append({"row": entry.get("row"), "key": key, "stage": stage, "alpha_deg": entry.get("alpha_deg"),
                         "beta_deg": entry.get("beta_deg"), "reason": str(entry.get("reason") or "")})
    dark = document.get("dark") or {}
    return {"run_id": run_id, "chosen": chosen["method"] if chosen else None, "data": methods, "count": len(methods),
            "rejected": rejected, "warnings": [str(w) for w in document.get("warnings") or []],
            "dark_model": dark.get("model"), "dark_note": dark.get("note")}


__all__ = ["qd_currents", "qd_dark", "qd_error_map", "qd_metrics"]
