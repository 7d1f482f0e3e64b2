"""What a CSS run's results look like (seed 000's coarse-sun-sensor head): every detector's signal against the
incidence on its calibrated normal with the fitted curve, its residuals and its parameters ± 1σ; the Sun's direction
each reading gives through the calibration; every response law's figures; and the thesis' quantiser codes of one
reading — plain data for the dashboard's CSS results view.

Computed here, with the calibration core, so ``web/`` holds no science (as :mod:`bench.qd_results` does for the QD
family). Everything is read from the catalogue: the run's lineage (a resumed run's parent included) and the calibration
documents stored at the run's end (:func:`calibration.css.calibrate.css_document`).

The readings are those the family's fit takes (:func:`bench.families.css.bench_data`): every ok reading at the body
direction the engine recorded, a channel clipped at either end of its range left out (its signal is only a bound), dark
rows from the dark stage, check rows (never fitted) from the check stage. A document's ``rejected`` rows (``row`` =
reading id, ``channel``) say which single readings of a detector its fit rejected. So:

* a detector's residual (reading − the document's model) over its fitted readings has the RMS and the count of the
  document's ``fit.rms`` and ``fit.n_points`` (:func:`css_detectors`);
* the Sun's direction from the document's head model (:func:`calibration.css.estimate.estimate_sun`, rejected readings
  left out) scores the fitted readings and the check readings as the document's ``heldout.sun.at_nodes`` and
  ``heldout.sun.check`` do (:func:`css_directions`). The held-out folds need a refit each and are the document's.

The thesis' algorithm (:func:`css_codes`, listing D.5/D.6) needs the thermopiles' *seen temperatures* [°C]. Nothing
converts a thermopile's bench voltage into one (the TPS 230's Table 4 covers objects at −20…120 °C; the algorithm's
thresholds reach −205.7 °C, and the thesis itself decided not to extrapolate, seed 000 §5.2), so the codes are the
photodiodes' (EPD and BPW), every face taken as not seeing the Earth (on the bench there is none), and the view says so.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from calibration.css.calibrate import (
    apply_css_document,
    head_model_from_document,
    sun_error_metrics,
    validate_css_document,
)
from calibration.css.diode import REFERENCE_TEMPERATURE_C, SHAPE_NAME, noise_sd
from calibration.css.head import CHANNELS, FACES, NORMALS, THESIS_NUMBER, split_channel, sun_vectors, thesis_az_el
from calibration.css.karel import karel_attitude
from calibration.css.quantiser import DARK_CODE, STEP_DEG, code_bits, incidence_code

from .families.css import CHECK, DARK, clipped_mask
from .results import NoCalibration, calibration_record, family_run, finite_or_none

#: The family whose runs these views read
FAMILY = "css"

#: Readings with the Sun farther than this from a detector's normal are drawn nowhere on its curve [°] (the Sun is
#: behind it: its reading is its offset); their residuals are summarised (``behind``)
CURVE_MAX_INCIDENCE_DEG = 95.0
#: The fitted curve's step in incidence [°]
CURVE_STEP_DEG = 1.0
#: Readings whose temperatures differ by less than this are one plate temperature (a curve each) [°C]
TEMPERATURE_GAP_C = 2.0

#: Why a reading of a channel is left out of every fit (:func:`bench.families.css.bench_data`)
CLIPPED_REASON = "clipped at an end of the ADC's range (its signal is only a bound)"

#: The seen temperature given to the thesis' algorithm for every face: below its Earth threshold (−202.4 °C), so no
#: face is taken as seeing the Earth, as on the bench
NO_EARTH_C = -273.15
#: Half a quantiser bin: the thesis' codes say an incidence to within this [°]
QUANTISATION_DEG = STEP_DEG / 2.0
TPS_NOTE = ("The thermopiles' (TPS) codes are not shown: the algorithm wants each thermopile's seen temperature "
            "[°C], and nothing converts the bench's thermopile voltage into one (the TPS 230's Table 4 covers objects "
            "at −20…120 °C, the algorithm's thresholds reach −205.7 °C; the thesis decided not to extrapolate, §5.2). "
            "Every face is therefore taken as not seeing the Earth (on the bench there is none): the Earth's matrices "
            "(EPDalbedo, BPWalbedo, TPSalbedo) stay empty, and the Sun is searched for on all six faces.")

#: The quantiser's detector types: the EPD-365 (UV) and the BPW 21 (visible) photodiodes
CODE_DETECTORS = {"epd": "uv", "bpw": "vis"}

_UNITS = {"a": "A", "v": "V"}


class NoReading(LookupError):
    """The run's lineage has no such reading (or no lit reading at all)."""


# --- the run's readings ---------------------------------------------------------------------------------------
class _Rows:
    """The run's readings the family's fit takes (module docstring), as arrays in recording order."""

    def __init__(self, catalogue, run_id: int):
        rows, signals, clipped = [], [], []
        for r in catalogue.readings(catalogue.lineage(run_id)):
            if not r.ok:
                continue
            mask = clipped_mask(r.values)
            if mask.all():
                continue
            rows.append(r)
            signals.append(np.asarray(r.values["signals"], float))
            clipped.append(mask)
        n = len(rows)
        self.id = np.array([r.id for r in rows], int)
        self.key = [r.key for r in rows]
        self.stage = [r.stage for r in rows]
        self.dark = np.array([r.stage == DARK for r in rows], bool)
        self.check = np.array([r.stage == CHECK for r in rows], bool)
        self.zenith = np.array([np.nan if d else r.zenith_deg for r, d in zip(rows, self.dark)], float)
        self.azimuth = np.array([np.nan if d else r.azimuth_body_deg for r, d in zip(rows, self.dark)], float)
        self.temperature = np.array([r.values["temperature_c"] for r in rows], float)
        self.signals = np.array(signals, float).reshape(n, len(CHANNELS))
        self.clipped = np.array(clipped, bool).reshape(n, len(CHANNELS))
        self.sun = np.where(self.dark[:, None], np.nan,
                            sun_vectors(np.nan_to_num(self.zenith), np.nan_to_num(self.azimuth)).reshape(n, 3))

    def __len__(self) -> int:
        return self.id.size

    def left_out(self, rejected: dict) -> list[list[str | None]]:
        """Why each reading of each channel (rows × channels) is left out of the document's fit, None when used."""
        out = [[CLIPPED_REASON if c else None for c in row] for row in self.clipped]
        index = {int(i): k for k, i in enumerate(self.id)}
        for (row, channel), reason in rejected.items():
            k = index.get(row)
            if k is not None and channel in CHANNELS and out[k][CHANNELS.index(channel)] is None:
                out[k][CHANNELS.index(channel)] = reason
        return out


def _rejected(document: dict | None) -> dict[tuple[int, str], str]:
    """(reading id, channel) → reason of each reading the document's fit rejected."""
    out = {}
    for entry in (document or {}).get("rejected") or []:
        if isinstance(entry, dict) and entry.get("row") is not None and entry.get("channel"):
            out[(int(entry["row"]), str(entry["channel"]))] = str(entry.get("reason") or "")
    return out


def _document(catalogue, run_id: int, method: str | None, *, required: bool) -> tuple[dict | None, dict | None]:
    """(record, checked document) of the calibration `method` (the chosen one when None); (None, None) when the run
    has none and none was asked for (unless `required`)."""
    try:
        record = calibration_record(catalogue, run_id, method)
    except NoCalibration:
        if method or required:
            raise
        return None, None
    validate_css_document(record["document"])
    return record, record["document"]


def _plain(values) -> list:
    return [finite_or_none(v) for v in np.ravel(values)]


def _short(values, digits: int) -> list:
    """Numbers for JSON to `digits` significant digits (None for a missing or non-finite one): a run's readings are
    thousands per detector, and their 17th digit is noise."""
    return [float(f"{v:.{digits}g}") if np.isfinite(v) else None for v in np.ravel(np.asarray(values, float))]


def _temperature_groups(temperatures) -> list[float]:
    """The plate temperatures of some readings: their temperatures split where they jump by more than
    :data:`TEMPERATURE_GAP_C`, the mean of each."""
    t = np.sort(np.asarray(temperatures, float)[np.isfinite(temperatures)])
    if not t.size:
        return [REFERENCE_TEMPERATURE_C]
    cuts = np.flatnonzero(np.diff(t) > TEMPERATURE_GAP_C) + 1
    return [round(float(np.mean(part)), 1) for part in np.split(t, cuts)]


# --- every detector: its readings against incidence, its curve, its parameters ----------------------------------------
def _rms(residual, mask, used) -> dict:
    """How many readings `mask` selects, and the RMS residual of those the fit used (None without one)."""
    r = residual[mask & used & np.isfinite(residual)]
    return {"n": int(mask.sum()), "rms_residual": finite_or_none(np.sqrt(np.mean(r**2))) if r.size else None}


def _parameter_rows(entry: dict, response: str, unit: str) -> list[dict]:
    """The document's parameters of one valid detector as table rows, each with its unit."""
    params = entry["parameters"]
    shape = {SHAPE_NAME[response]: ""} if response in SHAPE_NAME else {  # a spline: its coefficients
        name: "" for name in params if name.startswith("spline_")}
    units = {"scale": unit, "bias": unit, "tilt_u_deg": "°", "tilt_v_deg": "°", **shape,
             "fov_half_deg": "°", "temp_coeff_per_c": "1/°C", "bias_temp_coeff_per_c": f"{unit}/°C"}
    rows = []
    for name, u in units.items():
        p = params.get(name) or {}
        rows.append({"name": name, "unit": u, "value": finite_or_none(p.get("value")),
                     "sd": finite_or_none(p.get("sd")), "fitted": bool(p.get("fitted"))})
    return rows


def _score(scores: dict | None) -> dict | None:
    if not scores:
        return None
    return {"n_points": scores.get("n_points"), "rms": finite_or_none(scores.get("rms")),
            "rms_normalised": finite_or_none(scores.get("rms_normalised"))}


def css_detectors(catalogue, run_id: int, method: str | None = None) -> dict:
    """Every detector of the run's head (18, in head order), through the calibration `method` (default the chosen
    one; none when the run has no calibration):

    * its lit readings (the Sun within :data:`CURVE_MAX_INCIDENCE_DEG` of its normal) as columns: the reading's id,
      the incidence on the calibrated normal (the face's nominal one for a detector the calibration left out or
      without a calibration) [°], the signal [A or V], the residual (signal − the document's model at the reading's
      direction and temperature), the temperature and its plate temperature (`group`, an index of `temperatures_c`;
      `main_temperature` is the one with the most readings: the full sweep's), whether it is a check reading (never
      fitted), and why the fit left it out (clipped, or rejected by the document; None when used);
    * the readings with the Sun behind it and the dark readings: how many, their residuals' RMS;
    * the fitted curve: the model against incidence at each plate temperature of the run's lit readings, its noise
      (1σ of one reading) and its SNR [dB] at the reference temperature, 20 log10((m − offset)/σ);
    * the document's parameters ± 1σ, the normal's zenith and azimuth ± its 1σ cone, the fit's figures, the held-out
      residuals, its warnings and statements, or the fault that left it out;
    * `rms_residual` and `n_fitted`: the RMS of the residuals of the readings its fit used and their number, computed
      here (the document's ``fit.rms`` and ``fit.n_points``, module docstring).

    Raises :class:`~bench.results.NoCalibration` for a `method` the run has not; a document this version cannot read
    raises :class:`calibration.errors.CalibrationFormatError`."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=False)
    rows = _Rows(catalogue, run_id)
    left_out = rows.left_out(_rejected(document))
    diodes_doc = (document or {}).get("diodes") or {}
    response = (document or {}).get("response")
    head = head_model_from_document(document) if document else None
    heldout = ((document or {}).get("heldout") or {}).get("channels") or {}
    lit_t = rows.temperature[~rows.dark] if len(rows) else np.zeros(0)
    temperatures = _temperature_groups(lit_t)
    # each reading's plate temperature (the nearest group), and the one with the most lit readings: the full sweep's
    group = np.abs(rows.temperature[:, None] - np.array(temperatures)[None, :]).argmin(axis=1) if len(rows) \
        else np.zeros(0, int)
    main = int(np.bincount(group[~rows.dark], minlength=len(temperatures)).argmax()) if lit_t.size else 0
    incidence_grid = np.arange(0.0, CURVE_MAX_INCIDENCE_DEG + CURVE_STEP_DEG / 2, CURVE_STEP_DEG)
    cos_grid = np.cos(np.radians(incidence_grid))
    if head is not None:
        relative_all = head.relative_responses(np.nan_to_num(rows.sun))  # (readings, valid channels); 0 on dark rows
        shape_all = head.responses_at(cos_grid[:, None] * np.ones(len(head)))  # (grid, valid channels)
    diodes = []
    for k, channel in enumerate(CHANNELS):
        face, detector = split_channel(channel)
        entry = diodes_doc.get(channel)
        valid = bool(head is not None and channel in head.channels)
        unit = _UNITS[entry["unit"]] if entry and entry.get("unit") in _UNITS else ("V" if detector == "ir" else "A")
        signal = rows.signals[:, k]
        if valid:
            j = head.channels.index(channel)
            normal = head.normals[j]
            dt = rows.temperature - REFERENCE_TEMPERATURE_C
            gain = head.scale[j] * (1.0 + head.temp_coeff_per_c[j] * dt)
            offset = head.bias[j] + head.bias_temp_coeff_per_c[j] * dt
            model = np.where(rows.dark, offset, gain * relative_all[:, j] + offset)
            residual = signal - model
        else:
            normal = np.asarray(NORMALS[face], float)
            residual = np.full(len(rows), np.nan)
        with np.errstate(invalid="ignore"):
            incidence = np.degrees(np.arccos(np.clip(rows.sun @ normal, -1.0, 1.0)))
        why = [left_out[i][k] for i in range(len(rows))]
        used = np.array([w is None for w in why], bool)
        shown = ~rows.dark & (incidence <= CURVE_MAX_INCIDENCE_DEG)
        behind = ~rows.dark & ~shown
        idx = np.flatnonzero(shown)
        points = {"reading_id": [int(v) for v in rows.id[idx]], "incidence_deg": _short(incidence[idx], 7),
                  "signal": _short(signal[idx], 8), "residual": _short(residual[idx], 5),
                  "temperature_c": _short(rows.temperature[idx], 5), "group": [int(v) for v in group[idx]],
                  "check": [bool(v) for v in rows.check[idx]],
                  "left_out": [why[i] for i in idx]}

        fitted = used & ~rows.check & np.isfinite(residual)
        item = {"channel": channel, "face": face, "thesis_face": THESIS_NUMBER[face], "detector": detector,
                "unit": unit, "valid": valid, "fault": (entry or {}).get("fault"),
                "warnings": [str(w) for w in (entry or {}).get("warnings") or []],
                "statements": [str(s) for s in (entry or {}).get("statements") or []],
                "points": points, "count": int(idx.size), "behind": _rms(residual, behind, used),
                "dark": _rms(residual, rows.dark, used),
                "rms_residual": finite_or_none(np.sqrt(np.mean(residual[fitted] ** 2))) if fitted.any() else None,
                "n_fitted": int(fitted.sum()), "curve": None, "parameters": [], "normal": None, "fit": None,
                "noise": None, "heldout": None, "at_nodes": None}
        if valid:
            shape = shape_all[:, j]
            signals = []
            for t in temperatures:
                dt = t - REFERENCE_TEMPERATURE_C
                signals.append(_short(head.scale[j] * (1 + head.temp_coeff_per_c[j] * dt) * shape
                                      + head.bias[j] + head.bias_temp_coeff_per_c[j] * dt, 6))
            m_ref = head.scale[j] * shape + head.bias[j]
            sigma = noise_sd(m_ref, head.sigma0[j], head.shot[j], head.noise_rel[j])
            photo = head.scale[j] * shape
            with np.errstate(divide="ignore", invalid="ignore"):
                snr = np.where(photo > 0, 20.0 * np.log10(photo / sigma), np.nan)
            item["curve"] = {"signals": signals, "noise_sd": _short(sigma, 4), "snr_db": _short(snr, 4)}
            item["parameters"] = _parameter_rows(entry, response, unit)
            item["normal"] = {name: finite_or_none(entry["normal"].get(name))
                              for name in ("zenith_deg", "azimuth_deg", "sd_deg")}
            item["fit"] = {name: (entry.get("fit") or {}).get(name) for name in
                           ("chi2_dof", "rms", "rms_normalised", "n_points", "temperature_fitted", "fov_fitted")}
            item["noise"] = entry.get("noise")
            scores = heldout.get(channel) or {}
            item["at_nodes"], item["heldout"] = _score(scores.get("at_nodes")), _score(scores.get("heldout"))
        diodes.append(item)
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None, "response": response,
            "reference_temperature_c": REFERENCE_TEMPERATURE_C, "temperatures_c": temperatures,
            "main_temperature": main, "incidence_deg": _plain(incidence_grid),
            "incidence_limit_deg": CURVE_MAX_INCIDENCE_DEG, "n_readings": len(rows), "data": diodes,
            "count": len(diodes)}


# --- the Sun's direction from each reading ---------------------------------------------------------------------------
def _fit_signals(rows: _Rows, left_out) -> np.ndarray:
    """The readings as the fit scored them: a channel clipped or rejected is no reading (NaN)."""
    signals = rows.signals.copy()
    signals[np.array([[w is not None for w in row] for row in left_out], bool).reshape(signals.shape)] = np.nan
    return signals


def _error_deg(true_vectors, vectors) -> np.ndarray:
    dot = np.sum(np.asarray(true_vectors) * np.asarray(vectors), axis=-1)
    with np.errstate(invalid="ignore"):
        return np.degrees(np.arccos(np.clip(dot, -1.0, 1.0)))


def css_directions(catalogue, run_id: int, method: str | None = None) -> dict:
    """The Sun's direction from every lit reading of the run through the calibration `method` (default the chosen
    one): the document's head model, the readings the fit rejected or that were clipped left out, the weighted
    least-squares estimator (:func:`calibration.css.estimate.estimate_sun`). Each reading has its true direction
    (body zenith, azimuth and the thesis' azimuth/elevation), the estimate's, its stated 1σ (the estimator's, and
    multiplied by the document's ``uncertainty_scale`` as :func:`calibration.css.calibrate.apply_css_document` reports
    it), its error ellipse, and the angle to the truth; `kind` "fitted" (a sweep reading the fit used) or "check"
    (never fitted). `summary` scores them as the document does (module docstring): ``fitted`` is its
    ``heldout.sun.at_nodes``, ``check`` its ``heldout.sun.check``; ``heldout`` is the document's own (folds refitted).

    Raises :class:`~bench.results.NoCalibration` when the run has no such calibration."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=True)
    rows = _Rows(catalogue, run_id)
    lit = np.flatnonzero(~rows.dark)
    scale = float(document.get("uncertainty_scale") or 1.0)
    data, summary = [], {"fitted": None, "check": None}
    if lit.size:
        estimate = _estimates(catalogue, run_id, record, rows, lit)
        truth = rows.sun[lit]
        error = _error_deg(truth, estimate.vector)
        true_az, true_el = thesis_az_el(rows.zenith[lit], rows.azimuth[lit])
        est_az, est_el = thesis_az_el(estimate.zenith_deg, estimate.azimuth_deg)
        check = rows.check[lit]
        for kind, mask in (("fitted", ~check), ("check", check)):
            if mask.any():
                sub = np.flatnonzero(mask)
                metrics = sun_error_metrics(truth[sub], _subset(estimate, sub))
                summary[kind] = metrics.to_dict()
        for i, k in enumerate(lit):
            failed = not np.all(np.isfinite(estimate.vector[i]))
            data.append({
                "reading_id": int(rows.id[k]), "key": rows.key[k], "stage": rows.stage[k],
                "kind": "check" if rows.check[k] else "fitted", "temperature_c": finite_or_none(rows.temperature[k]),
                "zenith_deg": finite_or_none(rows.zenith[k]), "azimuth_deg": finite_or_none(rows.azimuth[k]),
                "az_deg": finite_or_none(true_az[i]), "el_deg": finite_or_none(true_el[i]),
                "zenith_fit_deg": None if failed else finite_or_none(estimate.zenith_deg[i]),
                "azimuth_fit_deg": None if failed else finite_or_none(estimate.azimuth_deg[i]),
                "az_fit_deg": None if failed else finite_or_none(est_az[i]),
                "el_fit_deg": None if failed else finite_or_none(est_el[i]),
                "sigma_deg": finite_or_none(estimate.sigma_deg[i]),
                "sigma_scaled_deg": finite_or_none(estimate.sigma_deg[i] * scale),
                "sigma_major_deg": finite_or_none(estimate.sigma_major_deg[i]),
                "sigma_minor_deg": finite_or_none(estimate.sigma_minor_deg[i]),
                "error_deg": None if failed else finite_or_none(error[i]),
                "n_faces_lit": int(estimate.n_faces_lit[i]), "degenerate": bool(estimate.degenerate[i]),
                "ambiguous": bool(estimate.ambiguous[i]), "failed": failed})
    heldout = (((document.get("heldout") or {}).get("sun") or {}).get("heldout"))
    return {"run_id": run_id, "method": record["method"], "chosen": bool(record["chosen"]),
            "uncertainty_scale": scale, "summary": {**summary, "heldout": heldout}, "data": data, "count": len(data)}


#: The estimates of the latest few (run, calibration, readings): the estimator restarts from a grid of directions where
#: a reading fits badly, seconds for a full sweep, and the view asks again whenever another calibration is shown
_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 8
_CACHE_LOCK = threading.Lock()


def _estimates(catalogue, run_id: int, record: dict, rows: _Rows, lit: np.ndarray):
    """The Sun's direction from the readings `lit` of `rows` through the calibration `record` (module docstring), the
    same answer for the same readings and calibration (calibrations are stored once; a refit is a new record)."""
    from calibration.css.estimate import estimate_sun

    key = (str(getattr(catalogue, "path", id(catalogue))), run_id, record["id"], tuple(rows.id[lit].tolist()))
    with _CACHE_LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    document = record["document"]
    signals = _fit_signals(rows, rows.left_out(_rejected(document)))[lit]
    estimate = estimate_sun(head_model_from_document(document), signals, rows.temperature[lit], channels=CHANNELS)
    with _CACHE_LOCK:
        _CACHE[key] = estimate
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    return estimate


def _subset(estimate, index):
    """The estimates `index` of a :class:`~calibration.css.estimate.SunEstimate` (its arrays over readings)."""
    from dataclasses import fields, replace

    return replace(estimate, **{f.name: getattr(estimate, f.name)[index] for f in fields(estimate)
                                if f.name != "channels"})


# --- every response law's figures ------------------------------------------------------------------------------------
def _fault_words(channel: str, entry: dict) -> str:
    """Why the fit left a channel out, in words (its own warning, else its fault's name)."""
    for warning in entry.get("warnings") or []:
        if str(warning).startswith(f"{channel}:"):
            return str(warning).split(":", 1)[1].strip()
    return str(entry.get("fault") or "not calibrated")


def css_methods(catalogue, run_id: int) -> dict:
    """Every calibration of the run (one per response law fitted) with its figures — the Sun's direction held out,
    at the check directions and at the fitted ones (readings, degenerate ones, RMS, p95, max [°], RMS over the stated
    1σ), the detectors calibrated and those left out —, the chosen one marked; of the chosen (else the latest)
    document: its warnings, its faulty channels in words, the readings it rejected (with their point and channel) and
    its uncertainty scale."""
    family_run(catalogue, run_id, FAMILY)
    records = catalogue.calibrations(run_id)
    methods = []
    for c in records:
        m = c.get("metrics") or {}
        methods.append({"id": c["id"], "method": c["method"], "chosen": bool(c["chosen"]),
                        "created_utc": c["created_utc"], "error": m.get("error"), "held_out": m.get("held_out"),
                        "check": m.get("check"), "at_nodes": m.get("at_nodes"),
                        "heldout_scheme": m.get("heldout_scheme"), "n_channels": len(m.get("channels") or []),
                        "faulty": dict(m.get("faulty") or {}), "n_rejected": m.get("n_rejected")})
    chosen = next((c for c in reversed(records) if c["chosen"]), records[-1] if records else None)
    document = chosen["document"] if chosen else {}
    entries = [e for e in document.get("rejected") or [] if isinstance(e, dict)]
    points = {}
    if entries:  # the point of each rejected reading (the lineage's readings are read only when there are some)
        points = {r.id: (r.key, r.stage) for r in catalogue.readings(catalogue.lineage(run_id))}
    rejected = []
    for entry in entries:
        key, stage = points.get(entry.get("row"), (None, None))
        rejected.append({"row": entry.get("row"), "channel": entry.get("channel"), "key": key, "stage": stage,
                         "zenith_deg": finite_or_none(entry.get("zenith_deg")),
                         "azimuth_deg": finite_or_none(entry.get("azimuth_deg")),
                         "reason": str(entry.get("reason") or "")})
    diodes = document.get("diodes") or {}
    faulty = [{"channel": c, "fault": e.get("fault"), "words": _fault_words(c, e)}
              for c in CHANNELS if isinstance(e := diodes.get(c), dict) and not e.get("valid", True)]
    missing = [c for c in CHANNELS if diodes and c not in diodes]
    return {"run_id": run_id, "chosen": chosen["method"] if chosen else None, "data": methods, "count": len(methods),
            "warnings": [str(w) for w in document.get("warnings") or []], "faulty": faulty, "missing": missing,
            "rejected": rejected, "uncertainty_scale": finite_or_none(document.get("uncertainty_scale"))}


# --- the thesis' quantiser codes of one reading ----------------------------------------------------------------------
def _faces(values: np.ndarray, detector: str) -> np.ndarray:
    """The readings of one detector type on the six faces, thesis face order 1 … 6 (= head.FACES)."""
    return np.array([values[CHANNELS.index(f"{face}_{detector}")] for face in FACES], float)


def _karel(epd, bpw, tables, truth) -> dict:
    """The thesis' algorithm on the photodiodes (module docstring), its Sun matrices and directions."""
    result = karel_attitude(np.full(6, NO_EARTH_C), epd, bpw, tables=tables)
    sun = {}
    for name in ("epd", "bpw"):
        az, el = result.sun_az_el(name)
        vector = result.sun_vector(name)
        zenith, azimuth = result.sun_zenith_azimuth(name)
        sun[name] = {"az_deg": finite_or_none(az), "el_deg": finite_or_none(el), "zenith_deg": finite_or_none(zenith),
                     "azimuth_deg": finite_or_none(azimuth),
                     "error_deg": None if truth is None else finite_or_none(_error_deg(truth, vector))}
    return {"inputs": {"epd_a": _plain(epd), "bpw_a": _plain(bpw)},
            "matrices": {"EPDsun": list(result.EPDsun), "BPWsun": list(result.BPWsun)},
            "codes": {"EPDsun": [int(v) for v in result.codes("EPDsun")],
                      "BPWsun": [int(v) for v in result.codes("BPWsun")]},
            "sun": sun, "sun_faces_epd": list(result.sun_faces_epd), "sun_faces_bpw": list(result.sun_faces_bpw)}


def css_codes(catalogue, run_id: int, method: str | None = None, reading_id: int | None = None) -> dict:
    """The thesis' quantiser codes (seed 000 ch. 5.3.4, listings D.5/D.6) of one reading of the run — `reading_id`, by
    default the latest lit one of its lineage — and the Sun's direction they give, beside the truth and the
    calibration's estimate:

    * ``listing``: the photodiodes' photocurrents (the calibration's offset b + b_T (T − 25 °C) subtracted; the raw
      readings when the run has no calibration) through listing D.6's Sun tables;
    * ``calibrated``: the raw readings through the Sun tables rebuilt from the calibration (its future work (e),
      :func:`bench.css_datafile.quantiser_tables`: they hold the offset); absent without a calibration.

    Each has the 5×6 matrices ``EPDsun`` and ``BPWsun`` as :func:`calibration.css.karel.karel_attitude` returns them
    (rows = bits MSB → LSB, a column per face 1 … 6, ``x`` where a face was not processed), their codes, the faces
    used and the Sun's thesis azimuth/elevation from each detector type with its angle to the truth. Every face is
    taken as not seeing the Earth: the thermopiles' codes are not computed (module docstring, ``tps_note``).
    ``faces`` gives per face the true incidence on its photodiodes' normals and the code a noise-free detector with a
    falling response would read there (:func:`calibration.css.quantiser.incidence_code`). ``estimate`` is the
    calibration's least-squares direction (:func:`calibration.css.calibrate.apply_css_document`) ± its stated 1σ.

    Raises :class:`NoReading` when the lineage has no such (or no lit) reading, and
    :class:`~bench.results.NoCalibration` for a `method` the run has not."""
    family_run(catalogue, run_id, FAMILY)
    record, document = _document(catalogue, run_id, method, required=False)
    rows = _Rows(catalogue, run_id)
    if reading_id is None:
        lit = np.flatnonzero(~rows.dark)
        if not lit.size:
            raise NoReading(f"run {run_id} has no lit reading")
        k = int(lit[-1])
    else:
        found = np.flatnonzero(rows.id == reading_id)
        if not found.size:
            raise NoReading(f"run {run_id} has no usable reading {reading_id}")
        k = int(found[0])
    signals, temperature = rows.signals[k], float(rows.temperature[k])
    dark = bool(rows.dark[k])
    truth = None if dark else rows.sun[k]
    head = head_model_from_document(document) if document else None
    offsets = np.zeros(len(CHANNELS))
    if head is not None:
        dt = temperature - REFERENCE_TEMPERATURE_C
        for j, channel in enumerate(head.channels):
            offsets[CHANNELS.index(channel)] = head.bias[j] + head.bias_temp_coeff_per_c[j] * dt
    photo = signals - offsets
    variants = {"listing": {**_karel(_faces(photo, "uv"), _faces(photo, "vis"), None, truth),
                            "offsets_subtracted": head is not None, "tables": []}}
    if document is not None:
        from .css_datafile import css_diodes, quantiser_tables

        tables = quantiser_tables(css_diodes(document))
        variants["calibrated"] = {**_karel(_faces(signals, "uv"), _faces(signals, "vis"), tables, truth),
                                  "offsets_subtracted": False, "tables": sorted(tables)}
    faces = []
    for face in FACES:
        item = {"face": face, "thesis_face": THESIS_NUMBER[face]}
        for name, detector in CODE_DETECTORS.items():
            channel = f"{face}_{detector}"
            if head is not None and channel in head.channels:
                normal = head.normals[head.channels.index(channel)]
            else:
                normal = np.asarray(NORMALS[face], float)
            incidence = None if dark else float(np.degrees(np.arccos(np.clip(truth @ normal, -1.0, 1.0))))
            code = DARK_CODE if incidence is None else int(incidence_code(min(incidence, 90.0)))
            item[f"{name}_incidence_deg"] = incidence
            item[f"{name}_true_code"] = code
            item[f"{name}_true_bits"] = str(code_bits(np.int64(code)))
            item[f"{name}_clipped"] = bool(rows.clipped[k, CHANNELS.index(channel)])
        faces.append(item)
    estimate = None
    if document is not None:
        fit_signals = _fit_signals(rows, rows.left_out(_rejected(document)))[k]
        est = apply_css_document(document, fit_signals[None, :], CHANNELS, temperature)
        vector = est.vector[0]
        failed = not np.all(np.isfinite(vector))
        az, el = thesis_az_el(est.zenith_deg[0], est.azimuth_deg[0])
        estimate = {"zenith_deg": None if failed else finite_or_none(est.zenith_deg[0]),
                    "azimuth_deg": None if failed else finite_or_none(est.azimuth_deg[0]),
                    "az_deg": None if failed else finite_or_none(az), "el_deg": None if failed else finite_or_none(el),
                    "sigma_deg": finite_or_none(est.sigma_deg[0]),
                    "sigma_major_deg": finite_or_none(est.sigma_major_deg[0]),
                    "sigma_minor_deg": finite_or_none(est.sigma_minor_deg[0]),
                    "degenerate": bool(est.degenerate[0]), "n_faces_lit": int(est.n_faces_lit[0]),
                    "error_deg": None if failed or truth is None else finite_or_none(_error_deg(truth, vector)),
                    "words": est.describe(0)}
    true_az, true_el = (None, None) if dark else (float(v) for v in thesis_az_el(rows.zenith[k], rows.azimuth[k]))
    reading = {"id": int(rows.id[k]), "key": rows.key[k], "stage": rows.stage[k], "temperature_c": temperature,
               "zenith_deg": finite_or_none(rows.zenith[k]), "azimuth_deg": finite_or_none(rows.azimuth[k]),
               "az_deg": true_az, "el_deg": true_el,
               "clipped": [c for c, bad in zip(CHANNELS, rows.clipped[k]) if bad]}
    return {"run_id": run_id, "method": record["method"] if record else None,
            "chosen": bool(record["chosen"]) if record else None, "reading": reading, "faces": faces,
            "variants": variants, "estimate": estimate, "quantisation_deg": QUANTISATION_DEG,
            "tps_shown": False, "tps_note": TPS_NOTE}


__all__ = ["css_codes", "css_detectors", "css_directions", "css_methods", "NoReading"]
