"""A CSS head's calibration as a C header: every detector's fitted parameters and its signal model in C.

The header holds, per channel in the head's order (:data:`calibration.css.head.CHANNELS`), the fitted model of
:mod:`calibration.css.diode` — scale S, offset b, the tilted normal n, the response law and its shape, the field-of-
view half-angle θ_c, the temperature coefficients c_T and b_T — as ``static const double`` arrays, and two ``static
inline`` functions that compute what :meth:`calibration.css.diode.DiodeParameters.signal` computes. A ``spline``
detector's response is its spline in piecewise-polynomial form (:mod:`calibration.css.spline`): the breakpoints
x_i = cos θ ascending, and on each interval the cubic's four coefficients in powers of g − x_i, evaluated by
Horner's rule in the same order as Python does, then clamped at zero — the very same spline:

* ``sunbench_css_signal(k, sun, temperature_c)``: the signal channel k reads with the Sun along the unit body vector
  `sun` (m = S (1 + c_T ΔT) R(n·s) E(θ) + b + b_T ΔT);
* ``sunbench_css_relative(k, signal, temperature_c)``: a reading with its offset removed and divided by its
  temperature-corrected scale, R·E: 1 at normal incidence — what an on-board estimator (a least-squares sun vector,
  the thesis' quantiser) starts from.

Doubles are printed as Python's shortest round-trip repr (:func:`calibration.export.c_double`), so C holds the very
same values; a channel the calibration does not hold (not measured, or faulty) has ``SUNBENCH_CSS_CALIBRATED[k]``
0 and answers NaN.

References
----------
seed 000, eq. 3.1 (a detector's signal: a scale times its relative angular response), §3.6 (the head's ADC and
its microcontroller), ch. 7 (b) (what runs on board); research note anchors-sunsensors §5 (Basilisk's
coarseSunSensor: scale · cos · Kelly · FOV + bias).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..export import c_array, c_double, comment_safe
from .diode import FOV_EDGE_WIDTH_DEG, LAW_CODES, REFERENCE_TEMPERATURE_C, SPLINE, DiodeParameters
from .head import CHANNELS
from .spline import spline_basis

#: The response law's code in the header
RESPONSE_CODES = LAW_CODES

_FUNCTIONS = """\
/* Relative response R(g)*E(theta) of channel k at g = cos(incidence) (calibration.css.diode). */
static inline double sunbench_css_response(int k, double g) {
    if (g <= 0.0) return 0.0;
    double r;
    if (SUNBENCH_CSS_RESPONSE[k] == 0) {  /* kelly: g (1 - exp(-g^2/kappa)) / (1 - exp(-1/kappa)) */
        double kappa = SUNBENCH_CSS_SHAPE[k];
        r = g * -expm1(-g * g / kappa) / -expm1(-1.0 / kappa);
    } else if (SUNBENCH_CSS_RESPONSE[k] == 1) {  /* power: g^p */
        r = pow(g, SUNBENCH_CSS_SHAPE[k]);
    } else {  /* spline: max(0, the cubic of g's interval), 0 at and below the first breakpoint (its last knot) */
        const double *x = SUNBENCH_CSS_SPLINE_X[k];
        int n = SUNBENCH_CSS_SPLINE_N[k], i = 0;
        if (g <= x[0]) return 0.0;
        while (i < n - 1 && g >= x[i + 1]) i++;
        const double *c = SUNBENCH_CSS_SPLINE_C[k][i];
        double d = g - x[i];
        r = ((c[3] * d + c[2]) * d + c[1]) * d + c[0];
        if (r < 0.0) r = 0.0;
    }
    double fov = SUNBENCH_CSS_FOV_HALF_DEG[k];
    if (fov >= 0.0) {  /* a linear ramp of full width SUNBENCH_CSS_FOV_EDGE_WIDTH_DEG centred on fov */
        double theta = acos(g > 1.0 ? 1.0 : g) * 57.29577951308232;
        double e = (fov + SUNBENCH_CSS_FOV_EDGE_WIDTH_DEG / 2.0 - theta) / SUNBENCH_CSS_FOV_EDGE_WIDTH_DEG;
        r *= e < 0.0 ? 0.0 : (e > 1.0 ? 1.0 : e);
    }
    return r;
}

/* The signal channel k reads [A or V] with the Sun along the unit body vector sun, the head at temperature_c;
   NaN for a channel the calibration does not hold. */
static inline double sunbench_css_signal(int k, const double sun[3], double temperature_c) {
    if (k < 0 || k >= SUNBENCH_CSS_N_CHANNELS || !SUNBENCH_CSS_CALIBRATED[k]) return NAN;
    double dt = temperature_c - SUNBENCH_CSS_REFERENCE_TEMPERATURE_C;
    const double *n = SUNBENCH_CSS_NORMAL[k];
    double g = n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2];
    return SUNBENCH_CSS_SCALE[k] * (1.0 + SUNBENCH_CSS_TEMP_COEFF_PER_C[k] * dt) * sunbench_css_response(k, g)
        + SUNBENCH_CSS_BIAS[k] + SUNBENCH_CSS_BIAS_TEMP_COEFF_PER_C[k] * dt;
}

/* A reading of channel k with its offset removed and divided by its temperature-corrected scale: R*E, 1 at normal
   incidence; NaN for a channel the calibration does not hold. */
static inline double sunbench_css_relative(int k, double signal, double temperature_c) {
    if (k < 0 || k >= SUNBENCH_CSS_N_CHANNELS || !SUNBENCH_CSS_CALIBRATED[k]) return NAN;
    double dt = temperature_c - SUNBENCH_CSS_REFERENCE_TEMPERATURE_C;
    return (signal - SUNBENCH_CSS_BIAS[k] - SUNBENCH_CSS_BIAS_TEMP_COEFF_PER_C[k] * dt)
        / (SUNBENCH_CSS_SCALE[k] * (1.0 + SUNBENCH_CSS_TEMP_COEFF_PER_C[k] * dt));
}
"""


def _piecewise(diode: DiodeParameters):
    """(breakpoints, polynomial (K, 4)) of a spline detector: what :func:`calibration.css.spline.evaluate` uses."""
    basis = spline_basis(diode.spline_knots_deg)
    return basis.breakpoints, basis.polynomial(diode.spline)


def c_header(diodes: Sequence[DiodeParameters], *, sensor_id: str | None = None,
             provenance: Mapping[str, object] | None = None) -> str:
    """The C99 header of a head's calibrated detectors (module docstring).

    Parameters
    ----------
    diodes : sequence of DiodeParameters
        The calibrated detectors (any subset of the 18, any order); the others are marked uncalibrated.
    sensor_id : str, optional
    provenance : mapping, optional
        Short texts (source, date, software, held-out accuracy) for the opening comment.

    Raises
    ------
    CalibrationError
        A non-finite parameter (:func:`calibration.export.c_double`).

    References
    ----------
    seed 000 eq. 3.1; research note anchors-sunsensors §5.
    """
    by_channel = {d.channel: d for d in diodes}
    unknown = sorted(set(by_channel) - set(CHANNELS))
    if unknown:
        raise ValueError(f"no channel {', '.join(unknown)} (channels: {', '.join(CHANNELS)})")
    rows = [by_channel.get(c) for c in CHANNELS]

    def column(get, missing=0.0) -> str:
        return c_array([missing if d is None else get(d) for d in rows])

    normals = ", ".join(c_array([0.0, 0.0, 0.0] if d is None else [float(v) for v in d.normal]) for d in rows)
    # the spline detectors' piecewise polynomials, padded to the longest (breakpoints with 1, coefficients with 0)
    pps = [None if d is None or d.response != SPLINE else _piecewise(d) for d in rows]
    width = max([1] + [x.size - 1 for x, _ in (p for p in pps if p is not None)])
    spline_n = [0 if p is None else p[0].size - 1 for p in pps]
    spline_x = ", ".join(c_array(([0.0] * (width + 1)) if p is None else list(p[0]) + [1.0] * (width + 1 - p[0].size))
                         for p in pps)
    spline_c = ", ".join("{" + ", ".join(c_array(list(row)) for row in (
        np.zeros((width, 4)) if p is None else np.vstack([p[1], np.zeros((width - p[1].shape[0], 4))]))) + "}"
                         for p in pps)
    comment = "".join(f"\n   {key}: {comment_safe(value)}" for key, value in (provenance or {}).items()
                      if value is not None)
    lines = [
        "/* sunbench CSS head calibration: seed 000 (Karel 2013) eq. 3.1, every detector's fitted model.",
        "   Generated by `sunbench`; do not edit. Channels k = 0..17: faces px, py, mx, my, pz, mz (outward normals",
        "   +X, +Y, -X, -Y, +Z, -Z; the thesis' faces 1..6), each uv, vis (photodiodes, A), ir (thermopile, V).",
        "   Signal model: m = S (1 + cT (T - 25)) R(n.s) E(theta) + b + bT (T - 25)."
        + (f"\n   sensor: {comment_safe(sensor_id)}" if sensor_id else "") + comment + " */",
        "#ifndef SUNBENCH_CSS_CALIBRATION_H",
        "#define SUNBENCH_CSS_CALIBRATION_H",
        "",
        "#include <math.h>",
        "",
        f"#define SUNBENCH_CSS_N_CHANNELS {len(CHANNELS)}",
        f"#define SUNBENCH_CSS_REFERENCE_TEMPERATURE_C {c_double(REFERENCE_TEMPERATURE_C)}",
        f"#define SUNBENCH_CSS_FOV_EDGE_WIDTH_DEG {c_double(FOV_EDGE_WIDTH_DEG)}",
        "",
        "static const char *const SUNBENCH_CSS_CHANNELS[SUNBENCH_CSS_N_CHANNELS] = {"
        + ", ".join(f'"{c}"' for c in CHANNELS) + "};",
        "/* 1: the calibration holds the channel; 0: not measured or faulty (its functions answer NaN) */",
        "static const int SUNBENCH_CSS_CALIBRATED[SUNBENCH_CSS_N_CHANNELS] = {"
        + ", ".join("0" if d is None else "1" for d in rows) + "};",
        "/* the response law: 0 kelly (shape kappa), 1 power (shape p), 2 spline (SUNBENCH_CSS_SPLINE_*) */",
        "static const int SUNBENCH_CSS_RESPONSE[SUNBENCH_CSS_N_CHANNELS] = {"
        + ", ".join("0" if d is None else str(RESPONSE_CODES[d.response]) for d in rows) + "};",
        "/* S: the signal at normal incidence, 25 degC, the bench's irradiance [A or V] */",
        f"static const double SUNBENCH_CSS_SCALE[SUNBENCH_CSS_N_CHANNELS] = {column(lambda d: d.scale, 1.0)};",
        "/* b: the signal with no light at 25 degC [A or V] */",
        f"static const double SUNBENCH_CSS_BIAS[SUNBENCH_CSS_N_CHANNELS] = {column(lambda d: d.bias)};",
        "/* n: the detector's unit normal in the head's body frame */",
        f"static const double SUNBENCH_CSS_NORMAL[SUNBENCH_CSS_N_CHANNELS][3] = {{{normals}}};",
        "/* the response law's shape (kappa or p) */",
        f"static const double SUNBENCH_CSS_SHAPE[SUNBENCH_CSS_N_CHANNELS] = {column(lambda d: d.shape, 1.0)};",
        "/* theta_c: the field of view's half-angle [deg]; -1: no cut-off */",
        "static const double SUNBENCH_CSS_FOV_HALF_DEG[SUNBENCH_CSS_N_CHANNELS] = "
        f"{column(lambda d: -1.0 if d.fov_half_deg is None else d.fov_half_deg, -1.0)};",
        "/* the spline law: intervals of each channel's piecewise cubic in g = cos(incidence) (0: not a spline) */",
        f"#define SUNBENCH_CSS_SPLINE_MAX_INTERVALS {width}",
        "static const int SUNBENCH_CSS_SPLINE_N[SUNBENCH_CSS_N_CHANNELS] = {" + ", ".join(map(str, spline_n)) + "};",
        "/* its breakpoints x_0 < x_1 < ... ascending in g: x_0 the cosine of its last knot, x_n = 1 */",
        "static const double SUNBENCH_CSS_SPLINE_X[SUNBENCH_CSS_N_CHANNELS][SUNBENCH_CSS_SPLINE_MAX_INTERVALS + 1] = "
        f"{{{spline_x}}};",
        "/* on [x_i, x_i+1): c0 + c1 d + c2 d^2 + c3 d^3, d = g - x_i */",
        "static const double SUNBENCH_CSS_SPLINE_C[SUNBENCH_CSS_N_CHANNELS][SUNBENCH_CSS_SPLINE_MAX_INTERVALS][4] = "
        f"{{{spline_c}}};",
        "/* cT: the scale's relative change per degC [1/degC] */",
        "static const double SUNBENCH_CSS_TEMP_COEFF_PER_C[SUNBENCH_CSS_N_CHANNELS] = "
        f"{column(lambda d: d.temp_coeff_per_c)};",
        "/* bT: the offset's change per degC [A/degC or V/degC] */",
        "static const double SUNBENCH_CSS_BIAS_TEMP_COEFF_PER_C[SUNBENCH_CSS_N_CHANNELS] = "
        f"{column(lambda d: d.bias_temp_coeff_per_c)};",
        "",
        _FUNCTIONS,
        "#endif /* SUNBENCH_CSS_CALIBRATION_H */",
        "",
    ]
    return "\n".join(lines)
