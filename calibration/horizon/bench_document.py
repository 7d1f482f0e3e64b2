"""A horizon sensor's bench calibration as a versioned JSON document, read back and checked, and as a C header.

The document (:func:`horizon_document`) is a plain dict of JSON types:

.. code-block:: text

    {"format": "sunbench-horizon-calibration", "version": 1, "family": "horizon", "sensor_id": str | null,
     "model": {"crossing": str, "ifov": str, "phase": str, "mount": str, "mount_pitch": str},
     "design": {"ifov_half_angle_deg": float, "locator_level": float},
     "parameters": {name: {"value": float, "sd": float | null, "fitted": bool, "nominal": float, "unit": "deg",
                           "note": str (a parameter not fitted: why)}},
     "covariance": {"names": [str], "matrix": [[float]]}, "correlation": {"names": [str], "matrix": [[float]]},
     "identifiability": {"condition_number": float, "trades": [str]},
     "fit": {"chi2_dof": float, "dof": int, "uncertainty_scale": float ≥ 1, "rms_deg": float, "n_scans": int,
             "n_edges": int, "n_missing": int, "noise": {"cone1_out": {"sigma_deg", "dof"}, …}, "noise_source": str},
     "plan": {"disc_radii_deg": [float], "roll_span_deg": [min, max], "pitch_span_deg": [min, max]},
     "heldout": {"radius_out": [{"disc_radius_deg", "n_scans", "n_edges", "phase_rms_deg", "phase_rms_sigma",
                                 "calibrated": {roll/pitch rms, max, mean, n_scans, n_failed}, "parameters"}],
                 "check": {… "calibrated": {…}, "nominal": {…}} | null, "at_nodes": {…}} | null,
     "warnings": [str], "rejected": [{"row_id", "cone", "edge", "roll_deg", "pitch_deg", "disc_radius_deg",
                                      "residual_deg", "reason"}]}

``parameters`` names: :data:`calibration.horizon.bench_fit.ALL_PARAMETERS` (γ1, γ2, o1, o2, Δρ, the mount's roll, yaw
and pitch; the pitch never fitted, folded into the offsets). A cone of which the fitted scans hold no edge (no scans of
it, a dead detector, a pulse saturated all run) leaves its γ_k and o_k unfitted: ``"fitted": false``, ``sd`` null, the
value the fit started from (the nominal one) and a ``note`` saying so. ``design`` holds what the crossing model knows
and never fits: the IFOV's half-angle α of its curvature bias b(ρ, α) and the locator's level it is taken at (seed 004
§2-4-2, eq. 2.1, C1 = 0.5); a document without it was fitted without that bias and reads back with α = 0.
:func:`sensor_parameters_from_document` gives them back as
:class:`~calibration.horizon.bench_fit.HorizonSensorParameters`; :func:`c_header` writes what a microcontroller
computing roll and pitch from crossing times needs (the corrected γ_k, o_k and Δρ, α, the mount as a matrix).

References
----------
seed 004 eqs. 2.1, 2.3–2.7; DESIGN.md (every calibration is a versioned JSON document, a C header where an MCU uses it).
"""

from __future__ import annotations

import numpy as np

from ..errors import CalibrationFormatError
from ..plain import plain
from .bench_fit import (
    ALL_PARAMETERS,
    LOCATOR_LEVEL,
    NOMINAL,
    HorizonBenchFit,
    HorizonSensorParameters,
    mount_rotation,
)

FORMAT = "sunbench-horizon-calibration"
HORIZON_FORMAT_VERSION = 1
FAMILY = "horizon"

MODEL = {
    "crossing": "S_k(δ)·n_b = cos(ρ − b(ρ, α) + radius_bias), S_k(δ) = (sin δ sin γ_k, s_k cos γ_k, cos δ sin γ_k), "
                "s_1 = +1, s_2 = −1 (seed 004 eqs. 2.5, 2.7 corrected)",
    "ifov": "b(ρ, α) = ρ − d, d the boresight's angle from the disc's centre at which half of a top-hat IFOV of "
            "half-angle α (design.ifov_half_angle_deg) covers the disc: the curvature bias of the normalised "
            "constant-threshold locator, ≈ cot ρ·α²/6 (seed 004 §2-4-2, eq. 2.1, C1 = 0.5); known, not fitted",
    "phase": "δ_reported = δ + phase_offset_k, δ = 360°·t/T from the index mark",
    "mount": "n_b = Mᵀ·n_t, M = R_x(mount_roll)·R_z(mount_yaw)·R_y(mount_pitch) (active), n_t = (−sin θ, sin φ cos θ, "
             "cos φ cos θ) the disc centre the table set at roll φ, pitch θ",
    "mount_pitch": "a turn about the spin axis Y_s is a phase offset of both cones: never fitted, given (default 0) "
                   "and otherwise folded into the phase offsets",
}


def horizon_document(fit: HorizonBenchFit) -> dict:
    """The calibration document (module docstring) of a :func:`~calibration.horizon.bench_fit.fit_horizon_bench`
    result, checked by :func:`validate_horizon_document`.

    References
    ----------
    DESIGN.md (versioned calibration documents); seed 004 eqs. 2.5–2.7.
    """
    nominal = NOMINAL.to_dict()
    parameters = {n: {"value": v, "sd": fit.sd.get(n), "fitted": n in fit.free, "nominal": nominal[n], "unit": "deg"}
                  for n, v in fit.parameters.to_dict().items()}
    for name, entry in parameters.items():
        if not entry["fitted"]:
            entry["note"] = _not_fitted_note(name, entry["value"])
    doc = {"format": FORMAT, "version": HORIZON_FORMAT_VERSION, "family": FAMILY, "sensor_id": fit.sensor_id,
           "model": dict(MODEL), "parameters": parameters,
           "design": {"ifov_half_angle_deg": fit.parameters.ifov_half_angle_deg, "locator_level": LOCATOR_LEVEL},
           "covariance": {"names": list(fit.free), "matrix": np.asarray(fit.covariance)},
           "correlation": {"names": list(fit.free), "matrix": np.asarray(fit.correlation)},
           "identifiability": {"condition_number": fit.condition_number, "trades": list(fit.trades)},
           "fit": {"chi2_dof": fit.chi2_dof, "dof": fit.dof, "uncertainty_scale": fit.uncertainty_scale,
                   "rms_deg": fit.rms_deg, "n_scans": fit.n_scans, "n_edges": fit.n_edges, "n_missing": fit.n_missing,
                   "noise": fit.noise.to_dict(), "noise_source": fit.noise.source},
           "plan": {"disc_radii_deg": list(fit.radii_deg), "roll_span_deg": list(fit.roll_span_deg),
                    "pitch_span_deg": list(fit.pitch_span_deg)},
           "heldout": fit.heldout, "warnings": [str(w) for w in fit.warnings],
           "rejected": [r.to_dict() for r in fit.rejected]}
    doc = plain(doc)
    validate_horizon_document(doc)
    return doc


def _not_fitted_note(name: str, value: float) -> str:
    """Why a parameter of the document was not fitted, in words."""
    if name == "mount_pitch_deg":
        return ("given, never fitted: a turn about the spin axis is a phase offset of both cones (model.mount_pitch); "
                f"{value:g}°")
    cone = name[-5]  # gamma1_deg, phase_offset2_deg: the cone's digit
    return (f"not fitted: the fitted scans hold no edge of cone {cone} (no scans of it, a dead detector, or its pulse "
            f"saturated all run); kept at {value:g}° (the fit's start, the nominal sensor's by default)")


def _number(value, what: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise CalibrationFormatError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def validate_horizon_document(doc) -> None:
    """Raise :class:`~calibration.errors.CalibrationFormatError` (naming the problem) unless `doc` is a horizon
    calibration this version reads: its format, family and version, every parameter a finite number (γ_k in (0, 90)°,
    |Δρ| < 10°, the mount within ±20°), the stated 1σ non-negative and the covariance square over the fitted names.

    References
    ----------
    DESIGN.md (versioned calibration documents; typed errors).
    """
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CalibrationFormatError(f"not a horizon calibration (expected \"format\": \"{FORMAT}\")")
    if doc.get("family") != FAMILY:
        raise CalibrationFormatError(f"not a horizon calibration (family {doc.get('family')!r})")
    if doc.get("version") != HORIZON_FORMAT_VERSION:
        raise CalibrationFormatError(f"horizon calibration version {doc.get('version')!r} is not supported (this "
                                     f"sunbench reads version {HORIZON_FORMAT_VERSION})")
    params = doc.get("parameters")
    if not isinstance(params, dict):
        raise CalibrationFormatError("horizon calibration without \"parameters\"")
    for name in ALL_PARAMETERS:
        entry = params.get(name)
        if not isinstance(entry, dict) or "value" not in entry:
            raise CalibrationFormatError(f"parameter `{name}` missing")
        value = _number(entry["value"], f"parameter `{name}`")
        sd = _number(entry.get("sd"), f"parameter `{name}`: sd", allow_none=True)
        if sd is not None and sd < 0:
            raise CalibrationFormatError(f"parameter `{name}`: sd {sd} is negative")
        if not isinstance(entry.get("note", ""), str):
            raise CalibrationFormatError(f"parameter `{name}`: the note must be text, got {entry['note']!r}")
        if name.startswith("gamma") and not 0.0 < value < 90.0:
            raise CalibrationFormatError(f"parameter `{name}`: a cone half-angle of {value}° is not in (0, 90)°")
        if name == "radius_bias_deg" and abs(value) >= 10.0:
            raise CalibrationFormatError(f"parameter `{name}`: {value}° is no threshold bias (|Δρ| < 10°)")
        if name.startswith("mount") and abs(value) > 20.0:
            raise CalibrationFormatError(f"parameter `{name}`: {value}° is no mounting offset (within ±20°)")
    design = doc.get("design")
    if design is not None:
        alpha = _number(design.get("ifov_half_angle_deg") if isinstance(design, dict) else None,
                        "design: ifov_half_angle_deg")
        if not 0.0 <= alpha < 10.0:
            raise CalibrationFormatError(f"design: an IFOV half-angle of {alpha}° is not in [0, 10)°")
        level = design.get("locator_level", LOCATOR_LEVEL)
        if _number(level, "design: locator_level") != LOCATOR_LEVEL:
            raise CalibrationFormatError(f"design: the crossing model takes the IFOV's bias at the locator level "
                                         f"{LOCATOR_LEVEL}, not {level!r}")
    covariance = doc.get("covariance")
    if covariance is not None:
        names, matrix = (covariance.get("names"), covariance.get("matrix")) if isinstance(covariance, dict) else \
            (None, None)
        if not isinstance(names, list) or any(n not in ALL_PARAMETERS for n in names):
            raise CalibrationFormatError("covariance: `names` must list fitted parameters")
        if not isinstance(matrix, list) or len(matrix) != len(names) or any(
                not isinstance(row, list) or len(row) != len(names) for row in matrix):
            raise CalibrationFormatError(f"covariance: the matrix must be {len(names)}×{len(names)}")
    scale = (doc.get("fit") or {}).get("uncertainty_scale", 1.0)
    if _number(scale, "fit: uncertainty_scale") < 1.0:
        raise CalibrationFormatError(f"fit: uncertainty_scale must be at least 1, got {scale!r}")


def sensor_parameters_from_document(doc: dict) -> HorizonSensorParameters:
    """The calibrated sensor of a (checked) document, with the design's IFOV half-angle α of its crossing model (0 for
    a document without ``design``: fitted without the IFOV's curvature bias)."""
    validate_horizon_document(doc)
    alpha = float(doc["design"]["ifov_half_angle_deg"]) if doc.get("design") is not None else 0.0
    return HorizonSensorParameters(**{n: float(doc["parameters"][n]["value"]) for n in ALL_PARAMETERS},
                                   ifov_half_angle_deg=alpha)


def _c_number(value: float) -> str:
    return f"{value:.9g}"


#: The header's model radius: ρ − b + Δρ with b's leading term cot ρ · a²/6, a = radians(α) (seed 004 §2-4-2); it
#: differs from the exact cap overlap of :func:`~calibration.horizon.bench_fit.model_disc_radius_deg` by < 3e-6° for
#: α ≤ 2° (< 1e-6° for ρ ≥ 64°) and < 1e-4° for α ≤ 5°, over ρ of 50…78°
_C_MODEL_RADIUS = [
    "/* The angular radius [deg] of the circle about the disc's centre on which the sensor reports the edge of a disc",
    " * of angular radius rho_deg: rho - b + SUNBENCH_HORIZON_RADIUS_BIAS_DEG, b ~ cot(rho) * a^2 / 6 [rad] with",
    " * a = radians(SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG): within 3e-6 deg of the exact IFOV overlap for a <= 2 deg */",
    "static inline double sunbench_horizon_model_radius_deg(double rho_deg)",
    "{",
    "    const double deg = 3.14159265358979323846 / 180.0;",
    "    const double a = SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG * deg;",
    "    return rho_deg - a * a / (6.0 * tan(rho_deg * deg)) / deg + SUNBENCH_HORIZON_RADIUS_BIAS_DEG;",
    "}",
]


def c_header(doc: dict, *, provenance: dict | None = None) -> str:
    """A C header of a horizon calibration for the sensor's MCU: the corrected cone half-angles, phase offsets and
    threshold bias and the design's IFOV half-angle as ``#define``s, and the mount rotation M (row-major, body axes in
    the table's frame as columns), so that firmware solving seed 004 eq. 2.7 for roll and pitch uses γ_k, subtracts
    o_k from each cone's phase and takes ρ − b(ρ, α) + Δρ for the Earth's angular radius of eq. 2.3 (b the IFOV's
    curvature bias at the 50 % threshold, seed 004 §2-4-2; the header's ``sunbench_horizon_model_radius_deg(ρ)``
    computes it with b's leading term cot ρ · a²/6, a = α in radians: within 3e-6° of the fit's exact model for α ≤ 2°).

    References
    ----------
    seed 004 eqs. 2.3, 2.5–2.7; DESIGN.md (a C header where a microcontroller uses the calibration).
    """
    validate_horizon_document(doc)
    p = sensor_parameters_from_document(doc)
    sensor = doc.get("sensor_id") or "unnamed"
    guard = "SUNBENCH_HORIZON_CALIBRATION_H"
    lines = ["/* Horizon sensor calibration (seed 004): generated by sunbench, do not edit.", f" * sensor: {sensor}"]
    for key, value in (provenance or {}).items():
        if value is not None:
            lines.append(f" * {key}: {value}")
    lines += [" * phase_k = 360 * t / T - SUNBENCH_HORIZON_PHASE_OFFSETk_DEG; crossing where",
              " * S_k(phase)·n = cos(rho - b + SUNBENCH_HORIZON_RADIUS_BIAS_DEG), S_k = (sin d sin g_k, s_k cos g_k,"
              " cos d sin g_k),",
              " * b = the IFOV's curvature bias at the 50 % threshold, b ~ cot(rho) * a^2 / 6 [rad]",
              " *     with a = radians(SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG), the IFOV's half-angle in radians",
              " * (sunbench_horizon_model_radius_deg() below gives rho - b + SUNBENCH_HORIZON_RADIUS_BIAS_DEG [deg])",
              " */", f"#ifndef {guard}", f"#define {guard}", "", "#include <math.h>", ""]
    names = {"gamma1_deg": "GAMMA1_DEG", "gamma2_deg": "GAMMA2_DEG", "phase_offset1_deg": "PHASE_OFFSET1_DEG",
             "phase_offset2_deg": "PHASE_OFFSET2_DEG", "radius_bias_deg": "RADIUS_BIAS_DEG"}
    for name, macro in names.items():
        entry = doc["parameters"][name]
        sd = entry.get("sd")
        comment = f"  /* ± {sd:.2g} deg (1 sigma) */" if sd is not None else "  /* nominal, not fitted */"
        lines.append(f"#define SUNBENCH_HORIZON_{macro} ({_c_number(getattr(p, name))}){comment}")
    lines.append(f"#define SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG ({_c_number(p.ifov_half_angle_deg)})"
                 "  /* the design's, not fitted */")
    m = mount_rotation(p)
    lines += ["", "/* The mount M: body axes (columns) in the bench table's frame; n_body = M^T n_table */",
              "static const double SUNBENCH_HORIZON_MOUNT[3][3] = {"]
    lines += ["    {" + ", ".join(_c_number(v) for v in row) + "}," for row in m]
    lines += ["};", ""] + _C_MODEL_RADIUS + ["", f"#endif /* {guard} */", ""]
    return "\n".join(lines)
