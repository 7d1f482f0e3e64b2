"""What a horizon run's results look like (seed 004's scanning Earth-horizon sensor on an Earth-simulator bench): the
sensor's own errors ± 1σ against the nominal design, the fit's quality and warnings in words, the roll and pitch the
calibrated sensor reports against the table's (held out, and over the grid), every edge's phase residual, and the
pulse of a reading — plain data for the dashboard's horizon results view.

Computed here, with the calibration core, so ``web/`` holds no science (as :mod:`bench.css_results` does for the CSS
family). Everything is read from the catalogue: the run's lineage (a resumed run's parent included) and the calibration
document stored at the run's end (:func:`calibration.horizon.bench_document.horizon_document`, method ``crossings``).

The scans are those the family's fit takes (:func:`bench.families.horizon.bench_data`: two rows, one per cone, per ok
reading; the roll and pitch the table set recovered from the recorded body direction; check rows from the check stage),
so that:

* each fitted edge's residual (reported phase − the document's model, :func:`calibration.horizon.bench_fit.
  predicted_phases`) has the document's ``fit.rms_deg`` over the edges it used (:func:`horizon_edges`);
* each scan's roll and pitch error (the crossings solved through the document's parameters, turned into the table's
  frame through its mount: :func:`calibration.horizon.bench_fit.solve_roll_pitch`, :func:`~calibration.horizon.
  bench_fit.table_roll_pitch`) scores the fitted and the check scans as the document's ``heldout.at_nodes`` and
  ``heldout.check`` do, for the calibrated and the nominal sensor (:func:`horizon_attitude`). The leave-one-radius-out
  figures need a refit each and are the document's.

The pulse (:func:`horizon_pulse`): the run does not record the module's sampled pulse (its readings keep the edges and
the pulse's two levels), so the pulse of a reading is drawn from the calibration — the IFOV's covered fraction of the
disc along each cone's scan (:func:`calibration.horizon.ifov.covered_fraction_along_scan`, a top-hat of the
calibration's IFOV half-angle, the design's 2°) with the calibrated γ_k, o_k, ρ + Δρ and mount, scaled between the
levels the module reported — beside the module's detected edges, the locator's threshold and the edges the calibrated
and the nominal model predict.
"""

from __future__ import annotations

import numpy as np

from calibration.errors import InsufficientDataError
from calibration.horizon.bench_document import sensor_parameters_from_document
from calibration.horizon.bench_fit import (
    ALL_PARAMETERS,
    EDGES,
    NOMINAL,
    body_nadir,
    model_disc_radius_deg,
    predicted_phases,
    solve_roll_pitch,
    table_roll_pitch,
    wrap_deg,
)
from calibration.horizon.ifov import covered_fraction_along_scan, locator_radius_bias_deg
from calibration.horizon.scan import THESIS_IFOV_HALF_ANGLE_DEG

from .families.horizon import CHECK, bench_data, roll_pitch_of_direction
from .results import NoCalibration, calibration_record, family_run, finite_or_none

#: The family whose runs these views read
FAMILY = "horizon"

#: What each parameter is, in words and as a symbol (:data:`calibration.horizon.bench_fit.ALL_PARAMETERS`)
PARAMETER_WORDS = {
    "gamma1_deg": ("γ1", "cone 1's half-angle"),
    "gamma2_deg": ("γ2", "cone 2's half-angle"),
    "phase_offset1_deg": ("o1", "cone 1's phase offset (index mark, mirror azimuth, detector lag; the mount's pitch "
                                "folded in)"),
    "phase_offset2_deg": ("o2", "cone 2's phase offset (the mount's pitch folded in)"),
    "radius_bias_deg": ("Δρ", "threshold bias: the disc the locator sees is ρ + Δρ"),
    "mount_roll_deg": ("φm", "mount roll on the table"),
    "mount_yaw_deg": ("ψm", "mount yaw: the spin axis turned about the boresight"),
    "mount_pitch_deg": ("θm", "mount pitch: a turn about the spin axis, a phase offset of both cones (never fitted)"),
}

#: The pulse's sample step [°]
PULSE_STEP_DEG = 0.25
#: The locator's threshold the pulse is drawn with: the design's C1 (seed 004 eq. 2.1; the run does not record it)
DESIGN_THRESHOLD = 0.5
#: Poses within this of each other [°] are one node of the error maps
POSE_ROUND_DEG = 1e-3


class NoReading(LookupError):
    """The run's lineage has no such reading (or no usable scan at all)."""


def _document(catalogue, run_id: int, method: str | None, *, required: bool):
    """(record, document) of the run's calibration `method` (default the chosen one); (None, None) when the run has
    none and it is not `required`."""
    try:
        record = calibration_record(catalogue, run_id, method)
    except NoCalibration:
        if required or method is not None:
            raise
        return None, None
    return record, record["document"]


def _data(catalogue, run_id: int):
    """The lineage's scans as the fit takes them, and each reading's point key and stage."""
    lineage = catalogue.lineage(run_id)
    try:
        data, _ = bench_data(catalogue, lineage)
    except InsufficientDataError as exc:
        raise NoReading(str(exc)) from None
    points = {r.id: (r.key, r.stage) for r in catalogue.readings(lineage)}
    return data, points


def _plain(values) -> list:
    return [finite_or_none(v) for v in np.asarray(values, float).ravel()]


# --- the calibration: parameters, quality, held-out figures ---------------------------------------------------------
def horizon_calibration(catalogue, run_id: int, method: str | None = None) -> dict:
    """The run's calibration (default the chosen one) as the view shows it: each parameter ± 1σ beside the nominal
    design (and the difference in σ), χ²/dof, the noise of each cone's edges, the condition number and the pairs that
    trade, the warnings in words, the rejected edges named (reading, point, cone, edge, pose, residual, why), the
    roll and pitch held out (each disc radius left out, the check scans; calibrated and nominal) and at the fitted
    scans, the correlation matrix and the plan's extent.

    Raises :class:`~bench.results.NoCalibration` when the run has none,
    :class:`~calibration.errors.CalibrationFormatError` for a document this version cannot read."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=True)
    sensor_parameters_from_document(document)  # checked: a document this version cannot read is refused
    parameters = []
    for name in ALL_PARAMETERS:
        entry = document["parameters"][name]
        value, nominal, sd = entry["value"], entry.get("nominal", 0.0), entry.get("sd")
        symbol, words = PARAMETER_WORDS[name]
        difference = value - nominal
        parameters.append({"name": name, "symbol": symbol, "words": words, "unit": "deg", "value": value,
                           "sd": finite_or_none(sd), "fitted": bool(entry.get("fitted")), "nominal": nominal,
                           "difference": difference,
                           "difference_sigma": finite_or_none(difference / sd) if sd else None})
    points = {}
    rejected_entries = document.get("rejected") or []
    if rejected_entries:
        points = {r.id: (r.key, r.stage) for r in catalogue.readings(catalogue.lineage(run_id))}
    rejected = []
    for entry in rejected_entries:
        key, stage = points.get(entry.get("row_id"), (None, None))
        rejected.append({"reading_id": entry.get("row_id"), "key": key, "stage": stage, "cone": entry.get("cone"),
                         "edge": entry.get("edge"), "roll_deg": finite_or_none(entry.get("roll_deg")),
                         "pitch_deg": finite_or_none(entry.get("pitch_deg")),
                         "disc_radius_deg": finite_or_none(entry.get("disc_radius_deg")),
                         "residual_deg": finite_or_none(entry.get("residual_deg")),
                         "reason": str(entry.get("reason") or "")})
    fit = document.get("fit") or {}
    noise = [{"cone": int(name[4]), "edge": name.split("_")[1], "sigma_deg": finite_or_none(value.get("sigma_deg")),
              "dof": value.get("dof")} for name, value in sorted((fit.get("noise") or {}).items())]
    identifiability = document.get("identifiability") or {}
    heldout = document.get("heldout") or {}
    radius_out = [{k: v for k, v in entry.items() if k != "parameters"} for entry in heldout.get("radius_out") or []]
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]),
            "created_utc": record.get("created_utc"), "sensor_id": document.get("sensor_id"),
            "parameters": parameters,
            "fit": {k: fit.get(k) for k in ("chi2_dof", "dof", "uncertainty_scale", "rms_deg", "n_scans", "n_edges",
                                            "n_missing", "noise_source")},
            "noise": noise, "condition_number": finite_or_none(identifiability.get("condition_number")),
            "trades": [str(t) for t in identifiability.get("trades") or []],
            "correlation": document.get("correlation") or {"names": [], "matrix": []},
            "warnings": [str(w) for w in document.get("warnings") or []], "rejected": rejected,
            "heldout": {"check": heldout.get("check"), "at_nodes": heldout.get("at_nodes"), "radius_out": radius_out},
            "plan": document.get("plan") or {}, "model": document.get("model") or {},
            "design": document.get("design") or {}}


# --- every edge's phase residual -------------------------------------------------------------------------------------
def _residuals(data, parameters) -> np.ndarray:
    """(N, 2) reported − predicted phase of each row's out and in edge [°], wrapped; NaN where there is no edge."""
    out, in_ = predicted_phases(data.roll_deg, data.pitch_deg, data.disc_radius_deg, data.cone, parameters)
    return wrap_deg(data.phases() - np.column_stack([out, in_]))


def horizon_edges(catalogue, run_id: int, method: str | None = None) -> dict:
    """Every edge of the run's scans as columns (one entry per edge found: reading, point, stage, cone, ``out``/``in``,
    the table's roll and pitch, the disc radius, the reported phase) with its residual against the calibration
    `method` (default the chosen one; null without one) and against the nominal sensor, and why the fit rejected it
    (null when it used it). ``summary``: per kind (fitted, check), per cone and edge the RMS of the calibrated and the
    nominal residuals; ``fitted_rms_deg`` over the fitted edges the calibration used (its document's ``fit.rms_deg``).
    """
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=False)
    data, points = _data(catalogue, run_id)
    calibrated = None if document is None else _residuals(data, sensor_parameters_from_document(document))
    nominal = _residuals(data, NOMINAL)
    rejected = {(e.get("row_id"), e.get("cone"), e.get("edge")): str(e.get("reason") or "rejected")
                for e in (document or {}).get("rejected") or []}
    columns = {k: [] for k in ("reading_id", "key", "stage", "check", "cone", "edge", "roll_deg", "pitch_deg",
                               "disc_radius_deg", "phase_deg", "residual_deg", "residual_nominal_deg", "rejected")}
    phases = data.phases()
    for i in range(len(data)):
        reading = int(data.row_id[i])
        key, stage = points.get(reading, (None, None))
        for k, edge in enumerate(EDGES):
            if not np.isfinite(phases[i, k]):
                continue
            cone = int(data.cone[i])
            for name, value in (("reading_id", reading), ("key", key), ("stage", stage),
                                ("check", bool(data.check[i])), ("cone", cone), ("edge", edge),
                                ("roll_deg", float(data.roll_deg[i])), ("pitch_deg", float(data.pitch_deg[i])),
                                ("disc_radius_deg", float(data.disc_radius_deg[i])), ("phase_deg", float(phases[i, k])),
                                ("residual_deg", None if calibrated is None else finite_or_none(calibrated[i, k])),
                                ("residual_nominal_deg", finite_or_none(nominal[i, k])),
                                ("rejected", rejected.get((reading, cone, edge)))):
                columns[name].append(value)
    summary = []
    check = np.array(columns["check"], bool)
    cone = np.array(columns["cone"], int)
    edge = np.array(columns["edge"], object)
    res = np.array([np.nan if v is None else v for v in columns["residual_deg"]], float)
    res_nominal = np.array([np.nan if v is None else v for v in columns["residual_nominal_deg"]], float)
    left = np.array([r is not None for r in columns["rejected"]], bool)

    def rms(values, mask):
        v = values[mask & np.isfinite(values)]
        return float(np.sqrt(np.mean(v ** 2))) if v.size else None

    for kind, mask in (("fitted", ~check), ("check", check)):
        for c in (1, 2):
            for e in EDGES:
                m = mask & (cone == c) & (edge == e)
                if m.any():
                    summary.append({"kind": kind, "cone": c, "edge": e, "n": int(m.sum()),
                                    "rms_deg": rms(res, m & ~left), "rms_nominal_deg": rms(res_nominal, m)})
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None, **columns, "count": len(columns["reading_id"]),
            "summary": summary, "fitted_rms_deg": rms(res, ~check & ~left)}


# --- roll and pitch of each scan -------------------------------------------------------------------------------------
def _scan_errors(data, parameters) -> dict:
    """Per scan (sorted by id): the sensor's own roll and pitch solved from its crossings and their error against the
    table's once turned into the table's frame through the mount (as :func:`calibration.horizon.bench_fit.
    attitude_errors` scores them) [°]; NaN where not solved."""
    scans, roll, pitch = solve_roll_pitch(data, parameters)
    first = np.unique(data.scan, return_index=True)[1]
    table_roll, table_pitch = table_roll_pitch(np.nan_to_num(roll), np.nan_to_num(pitch), parameters)
    ok = np.isfinite(roll) & np.isfinite(pitch)
    roll_error = np.where(ok, wrap_deg(table_roll - data.roll_deg[first]), np.nan)
    pitch_error = np.where(ok, table_pitch - data.pitch_deg[first], np.nan)
    return {"scan": scans, "first": first, "roll": roll, "pitch": pitch, "roll_error": roll_error,
            "pitch_error": pitch_error}


def _figures(roll_error, pitch_error) -> dict:
    """RMS, largest |error| and mean of the solved scans' roll and pitch errors [°] (NaN-free), as the document's."""
    ok = np.isfinite(roll_error) & np.isfinite(pitch_error)
    out = {"n_scans": int(ok.sum()), "n_failed": int((~ok).sum())}
    for name, e in (("roll", roll_error[ok]), ("pitch", pitch_error[ok])):
        out[f"{name}_rms_deg"] = float(np.sqrt(np.mean(e ** 2))) if e.size else None
        out[f"{name}_max_deg"] = float(np.max(np.abs(e))) if e.size else None
        out[f"{name}_mean_deg"] = float(np.mean(e)) if e.size else None
    return out


def _maps(rows: dict, radii) -> list:
    """The fitted scans' mean roll and pitch errors at each node of each radius's roll × pitch grid (rows: pitch,
    columns: roll; null where no scan was solved)."""
    out = []
    for radius in radii:
        at = np.flatnonzero(~rows["check"] & (np.abs(rows["radius"] - radius) < POSE_ROUND_DEG))
        rolls = np.unique(np.round(rows["roll"][at] / POSE_ROUND_DEG) * POSE_ROUND_DEG)
        pitches = np.unique(np.round(rows["pitch"][at] / POSE_ROUND_DEG) * POSE_ROUND_DEG)
        entry = {"disc_radius_deg": float(radius), "roll_deg": rolls.tolist(), "pitch_deg": pitches.tolist()}
        for name in ("roll_error", "pitch_error", "roll_error_nominal", "pitch_error_nominal"):
            total = np.zeros((pitches.size, rolls.size))
            count = np.zeros((pitches.size, rolls.size))
            for i in at:
                value = rows[name][i]
                if not np.isfinite(value):
                    continue
                r = int(np.argmin(np.abs(rolls - rows["roll"][i])))
                p = int(np.argmin(np.abs(pitches - rows["pitch"][i])))
                total[p, r] += value
                count[p, r] += 1
            mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
            entry[f"{name}_deg"] = [_plain(row) for row in mean]
        out.append(entry)
    return out


def horizon_attitude(catalogue, run_id: int, method: str | None = None) -> dict:
    """Each scan's roll and pitch error against the table's, for the calibrated sensor (the calibration `method`,
    default the chosen one; null without one) and the nominal one: columns per scan (reading, point, stage, the
    table's roll and pitch, the disc radius, the sensor's own roll and pitch, the errors), ``summary`` per kind
    (fitted, check) and sensor (calibrated, nominal) as the document's held-out figures, and ``maps``: the fitted
    scans' mean errors over each radius's roll × pitch grid."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=False)
    data, points = _data(catalogue, run_id)
    parameters = None if document is None else sensor_parameters_from_document(document)
    columns = {k: [] for k in ("reading_id", "key", "stage", "check", "roll_deg", "pitch_deg", "disc_radius_deg",
                               "sensor_roll_deg", "sensor_pitch_deg", "roll_error_deg", "pitch_error_deg",
                               "roll_error_nominal_deg", "pitch_error_nominal_deg")}
    summary = {}
    arrays = {k: [] for k in ("check", "roll", "pitch", "radius", "roll_error", "pitch_error", "roll_error_nominal",
                              "pitch_error_nominal")}
    for kind, mask in (("fitted", ~data.check), ("check", data.check)):
        if not mask.any():
            summary[kind] = None
            continue
        part = data.subset(mask)
        nominal = _scan_errors(part, NOMINAL)
        calibrated = _scan_errors(part, parameters) if parameters is not None else None
        summary[kind] = {"nominal": _figures(nominal["roll_error"], nominal["pitch_error"]),
                         "calibrated": None if calibrated is None else _figures(calibrated["roll_error"],
                                                                                calibrated["pitch_error"])}
        shown = calibrated or nominal
        for j, i in enumerate(nominal["first"]):
            reading = int(part.row_id[i])
            key, stage = points.get(reading, (None, None))
            values = (("reading_id", reading), ("key", key), ("stage", stage), ("check", kind == "check"),
                      ("roll_deg", float(part.roll_deg[i])), ("pitch_deg", float(part.pitch_deg[i])),
                      ("disc_radius_deg", float(part.disc_radius_deg[i])),
                      ("sensor_roll_deg", finite_or_none(shown["roll"][j])),
                      ("sensor_pitch_deg", finite_or_none(shown["pitch"][j])),
                      ("roll_error_deg", None if calibrated is None else finite_or_none(calibrated["roll_error"][j])),
                      ("pitch_error_deg", None if calibrated is None else finite_or_none(calibrated["pitch_error"][j])),
                      ("roll_error_nominal_deg", finite_or_none(nominal["roll_error"][j])),
                      ("pitch_error_nominal_deg", finite_or_none(nominal["pitch_error"][j])))
            for name, value in values:
                columns[name].append(value)
            for name, value in (("check", kind == "check"), ("roll", part.roll_deg[i]), ("pitch", part.pitch_deg[i]),
                                ("radius", part.disc_radius_deg[i]),
                                ("roll_error", np.nan if calibrated is None else calibrated["roll_error"][j]),
                                ("pitch_error", np.nan if calibrated is None else calibrated["pitch_error"][j]),
                                ("roll_error_nominal", nominal["roll_error"][j]),
                                ("pitch_error_nominal", nominal["pitch_error"][j])):
                arrays[name].append(value)
    rows = {k: np.array(v, bool if k == "check" else float) for k, v in arrays.items()}
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None, **columns, "count": len(columns["reading_id"]),
            "summary": summary, "maps": _maps(rows, data.subset(~data.check).radii() if (~data.check).any() else [])}


# --- the pulse of a reading ----------------------------------------------------------------------------------------
def horizon_pulse(catalogue, run_id: int, method: str | None = None, reading_id: int | None = None) -> dict:
    """The pulse of each cone over one revolution for one reading of the run — `reading_id`, by default the latest ok
    one of its lineage — drawn from the calibration `method` (default the chosen one; the nominal sensor without one):
    the IFOV's covered fraction of the disc along the cone's scan at the reported phase (module docstring; the disc
    drawn is the model's edge circle, :func:`calibration.horizon.bench_fit.model_disc_radius_deg`, widened by the 50 %
    locator's bias on a curved limb, so the drawn pulse crosses the threshold where the calibration puts the edges),
    scaled between the space and Earth levels the module reported; the threshold at
    the design's C1 = 0.5; the module's detected edges; and the edges the calibrated and the nominal model predict
    (seed 004 eqs. 2.1, 2.5–2.7).

    Raises :class:`NoReading` when the lineage has no such (or no ok) reading."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=False)
    readings = [r for r in catalogue.readings(catalogue.lineage(run_id)) if r.ok and r.zenith_deg is not None]
    if reading_id is None:
        if not readings:
            raise NoReading(f"run {run_id} has no usable scan")
        reading = readings[-1]
    else:
        reading = next((r for r in readings if r.id == reading_id), None)
        if reading is None:
            raise NoReading(f"run {run_id} has no usable reading {reading_id}")
    parameters = NOMINAL if document is None else sensor_parameters_from_document(document)
    roll, pitch = (float(v) for v in roll_pitch_of_direction(reading.zenith_deg, reading.azimuth_body_deg))
    values = reading.values
    period = float(values["period_s"])
    radius = float(values["disc_radius_deg"])
    phase = np.arange(0.0, 360.0, PULSE_STEP_DEG)
    n_b = body_nadir(roll, pitch, parameters)
    # the disc whose 50 % crossings lie on the model's edge circle (ρ − b + Δρ): that circle widened by the IFOV's own
    # curvature bias (≈ ρ + Δρ when the calibration's IFOV is the one drawn)
    alpha = getattr(parameters, "ifov_half_angle_deg", 0.0) or THESIS_IFOV_HALF_ANGLE_DEG
    edge = float(model_disc_radius_deg(radius, parameters))
    drawn = edge + float(locator_radius_bias_deg(edge, alpha, DESIGN_THRESHOLD))
    saturated = int(values.get("saturated") or 0)
    cones = []
    for k, cone in enumerate((1, 2)):
        offset = float(parameters.phase_offset_deg(cone))
        fraction = covered_fraction_along_scan(phase - offset, n_b, drawn, alpha,
                                               float(parameters.gamma_deg(cone)), cone)
        space, earth = values["level_space"][k], values["level_earth"][k]
        scaled = space is not None and earth is not None
        level = space + fraction * (earth - space) if scaled else fraction
        threshold = space + DESIGN_THRESHOLD * (earth - space) if scaled else DESIGN_THRESHOLD
        calibrated = [float(v) for v in predicted_phases(roll, pitch, radius, cone, parameters)]
        nominal = [float(v) for v in predicted_phases(roll, pitch, radius, cone, NOMINAL)]
        detected = [None if values[name][k] is None else 360.0 * values[name][k] / period
                    for name in ("t_out_s", "t_in_s")]
        cones.append({"cone": cone, "level": _plain(level), "fraction": _plain(fraction),
                      "level_space": finite_or_none(space), "level_earth": finite_or_none(earth),
                      "threshold": finite_or_none(threshold), "levels_reported": bool(scaled),
                      "saturated": bool(saturated >> k & 1),
                      "detected_deg": {"out": detected[0], "in": detected[1]},
                      "calibrated_deg": {"out": finite_or_none(calibrated[0]), "in": finite_or_none(calibrated[1])},
                      "nominal_deg": {"out": finite_or_none(nominal[0]), "in": finite_or_none(nominal[1])}})
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None,
            "reading": {"id": reading.id, "key": reading.key, "stage": reading.stage, "check": reading.stage == CHECK,
                        "roll_deg": roll, "pitch_deg": pitch, "disc_radius_deg": radius, "period_s": period,
                        "temperature_c": finite_or_none(values.get("temperature_c")),
                        "revolution": values.get("revolution")},
            "phase_deg": phase.tolist(), "cones": cones, "threshold_fraction": DESIGN_THRESHOLD,
            "ifov_half_angle_deg": alpha, "disc_radius_drawn_deg": drawn,
            "source": "model" if document is not None else "nominal model"}


__all__ = ["NoReading", "PARAMETER_WORDS", "horizon_attitude", "horizon_calibration", "horizon_edges",
           "horizon_pulse"]
