"""Export of a QD calibration document as a C header for the sensor's microcontroller.

The header defines ``sunbench_qd_angles(currents_a, temperature_c, &alpha_deg, &beta_deg)`` and
``sunbench_qd_sun_direction(currents_a, temperature_c, &zenith_deg, &azimuth_deg)``, each returning 1 with a
direction or 0 where :func:`calibration.qd.document.apply_document` gives NaN, and computing exactly what it
computes (the same dark-current model, eq. 2.1, then eq. 2.2, the eq. 2.3 polynomial, or the physical
model's Gauss–Newton inversion with the same start, steps and acceptance test). Doubles are printed with
Python's shortest round-trip repr (:func:`calibration.export.c_double`), so the constants are the same binary
values. Names carry an ``sbqd_`` / ``SBQD_`` prefix so the QD header can sit beside the CMOS one.

References
----------
seed 002, §1.3 (the sensor's ADC and its commands to the on-board computer), §2.1, eqs. 2.1–2.3.
"""

from __future__ import annotations

import re

import numpy as np

from ..export import c_array, c_double, comment_safe
from ..pinhole import detector_rotation
from .dark import DARK_PARAMETERS
from .document import physical_from_document, validate_document

_PRELUDE = """\
#include <math.h>

#define SBQD_DEG (57.29577951308232)
#define SBQD_RAD (0.017453292519943295)

static inline double sbqd_wrap360(double a) {
    double w = fmod(a, 360.0);
    return w < 0.0 ? w + 360.0 : w;
}
"""

_DARK = {
    "none": "    for (int k = 0; k < 4; ++k) dark[k] = 0.0 * t;\n",
    "constant": "    for (int k = 0; k < 4; ++k) dark[k] = SBQD_DARK[k][0] + 0.0 * t;\n",
    "linear": "    for (int k = 0; k < 4; ++k)  /* seed 002 §2.1 */\n"
              "        dark[k] = SBQD_DARK[k][0] + SBQD_DARK[k][1] * t;\n",
    "exponential": "    for (int k = 0; k < 4; ++k)\n"
                   "        dark[k] = SBQD_DARK[k][0]\n"
                   "                  + SBQD_DARK[k][1] * exp(SBQD_DARK[k][2] * (t - SBQD_DARK_T_REF_C));\n",
}

_PHOTO = """\
/* Photocurrents I - I_d(t) and the eq. 2.1 ratios; 0 when there is no light. */
static inline int sbqd_ratios(const double currents_a[4], double temperature_c, double photo[4], double *u, double *v) {
    double dark[4], total = 0.0;
    sbqd_dark(temperature_c, dark);
    for (int k = 0; k < 4; ++k) { photo[k] = currents_a[k] - dark[k]; total += photo[k]; }
    if (!(total > 0.0) || !isfinite(total)) return 0;
    double su = 0.0, sv = 0.0;
    for (int k = 0; k < 4; ++k) { su += photo[k] * SBQD_LAYOUT[k][0]; sv += photo[k] * SBQD_LAYOUT[k][1]; }
    *u = su / total;  /* seed 002 eq. 2.1 */
    *v = sv / total;
    return 1;
}
"""

_GEOMETRIC = """\
static inline int sunbench_qd_angles(const double currents_a[4], double temperature_c, double *alpha_deg,
                                     double *beta_deg) {
    double photo[4], u, v;
    if (!sbqd_ratios(currents_a, temperature_c, photo, &u, &v)) return 0;
    double xc = 0.5 * SBQD_LENGTH_M * u, yc = 0.5 * SBQD_LENGTH_M * v;
    double c = cos(SBQD_PHI0_DEG * SBQD_RAD), s = sin(SBQD_PHI0_DEG * SBQD_RAD);
    double xr = c * xc - s * yc, yr = s * xc + c * yc;  /* seed 002 eq. 2.2 */
    *alpha_deg = atan((SBQD_X0_M - xr) / SBQD_D_M) * SBQD_DEG + SBQD_ALPHA0_DEG;
    *beta_deg = atan((SBQD_Y0_M - yr) / SBQD_D_M) * SBQD_DEG + SBQD_BETA0_DEG;
    return 1;
}
"""

_POLYNOMIAL = """\
static inline int sunbench_qd_angles(const double currents_a[4], double temperature_c, double *alpha_deg,
                                     double *beta_deg) {
    double photo[4], u, v;
    if (!sbqd_ratios(currents_a, temperature_c, photo, &u, &v)) return 0;
    double pu[SBQD_MAX_POWER + 1], pv[SBQD_MAX_POWER + 1];
    double nu = (u - SBQD_CENTER[0]) / SBQD_SCALE[0], nv = (v - SBQD_CENTER[1]) / SBQD_SCALE[1];
    pu[0] = 1.0; pv[0] = 1.0;
    for (int k = 1; k <= SBQD_MAX_POWER; ++k) { pu[k] = pu[k - 1] * nu; pv[k] = pv[k - 1] * nv; }
    double a = 0.0, b = 0.0;
    for (int k = 0; k < SBQD_N_TERMS; ++k) {  /* seed 002 eq. 2.3 */
        double m = pu[SBQD_TERMS[k][0]] * pv[SBQD_TERMS[k][1]];
        a += SBQD_COEF_ALPHA[k] * m;
        b += SBQD_COEF_BETA[k] * m;
    }
    *alpha_deg = a;
    *beta_deg = b;
    return 1;
}
"""

_PHYSICAL = """\
static inline double sbqd_h(double x, double r) {  /* integral of the half chord from 0 to x */
    if (x < -r) x = -r;
    if (x > r) x = r;
    double q = r * r - x * x;
    return 0.5 * (x * sqrt(q > 0.0 ? q : 0.0) + r * r * asin(x / r));
}

/* Area of the disc of radius r at the origin with x > a and y > b, and its derivatives. */
static inline double sbqd_corner(double a, double b, double r, double *da, double *db) {
    double bb = fabs(b), q = r * r - bb * bb, w = sqrt(q > 0.0 ? q : 0.0);
    double lo = a < -w ? -w : (a > w ? w : a);
    double pos = sbqd_h(w, r) - sbqd_h(lo, r) - bb * (w - lo);
    double qa = r * r - a * a, ha = sqrt(qa > 0.0 ? qa : 0.0), qb = r * r - b * b, hb = sqrt(qb > 0.0 ? qb : 0.0);
    double ea = ha - (b > -ha ? b : -ha), eb = hb - (a > -hb ? a : -hb);
    *da = -(ea > 0.0 ? ea : 0.0);
    *db = -(eb > 0.0 ? eb : 0.0);
    return b >= 0.0 ? pos : 2.0 * (sbqd_h(r, r) - sbqd_h(a, r)) - pos;
}

static inline void sbqd_areas(double cx, double cy, double area[4], double ax[4], double ay[4]) {
    for (int k = 0; k < 4; ++k) {
        double sx = SBQD_LAYOUT[k][0], sy = SBQD_LAYOUT[k][1], ga, gb;
        area[k] = sbqd_corner(0.5 * SBQD_GAP_M - sx * cx, 0.5 * SBQD_GAP_M - sy * cy, SBQD_RADIUS_M, &ga, &gb);
        ax[k] = -sx * ga;
        ay[k] = -sy * gb;
    }
}

static inline double sbqd_gapless(double ratio) {  /* (2/pi)(asin t + t sqrt(1 - t^2)) = ratio */
    double t = ratio * M_PI_4, target = ratio;
    t = t < -0.95 ? -0.95 : (t > 0.95 ? 0.95 : t);
    target = target < -0.999 ? -0.999 : (target > 0.999 ? 0.999 : target);
    for (int i = 0; i < 8; ++i) {
        double q = 1.0 - t * t, root = sqrt(q > 1e-12 ? q : 1e-12);
        double f = (2.0 / M_PI) * (asin(t) + t * root) - target;
        t = t - f / ((4.0 / M_PI) * root);
        t = t < -0.999 ? -0.999 : (t > 0.999 ? 0.999 : t);
    }
    return t * SBQD_RADIUS_M;
}

static inline int sunbench_qd_angles(const double currents_a[4], double temperature_c, double *alpha_deg,
                                     double *beta_deg) {
    double dark[4], share[4], total = 0.0, r = SBQD_RADIUS_M;
    sbqd_dark(temperature_c, dark);
    for (int k = 0; k < 4; ++k) { share[k] = (currents_a[k] - dark[k]) / SBQD_GAINS[k]; total += share[k]; }
    if (!(total > 0.0) || !isfinite(total)) return 0;
    double u = 0.0, v = 0.0;
    for (int k = 0; k < 4; ++k) {
        share[k] /= total;
        u += share[k] * SBQD_LAYOUT[k][0];
        v += share[k] * SBQD_LAYOUT[k][1];
    }
    double cx = sbqd_gapless(u), cy = sbqd_gapless(v), det = 0.0, area[4], ax[4], ay[4];
    for (int it = 0; it < 12; ++it) {  /* Gauss-Newton on the shares, steps limited to r/4 */
        sbqd_areas(cx, cy, area, ax, ay);
        double tot = 0.0, sax = 0.0, say = 0.0, a11 = 0.0, a12 = 0.0, a22 = 0.0, b1 = 0.0, b2 = 0.0;
        for (int k = 0; k < 4; ++k) { tot += area[k]; sax += ax[k]; say += ay[k]; }
        for (int k = 0; k < 4; ++k) {
            double m = area[k] / tot, jx = (ax[k] - m * sax) / tot, jy = (ay[k] - m * say) / tot, res = m - share[k];
            a11 += jx * jx; a12 += jx * jy; a22 += jy * jy; b1 += jx * res; b2 += jy * res;
        }
        det = a11 * a22 - a12 * a12;
        double dx = det > 0.0 ? -(a22 * b1 - a12 * b2) / det : 0.0;
        double dy = det > 0.0 ? -(a11 * b2 - a12 * b1) / det : 0.0;
        double step = hypot(dx, dy), limit = step > 0.25 * r ? 0.25 * r / (step > 1e-300 ? step : 1e-300) : 1.0;
        cx += dx * limit;
        cy += dy * limit;
    }
    sbqd_areas(cx, cy, area, ax, ay);
    double tot = area[0] + area[1] + area[2] + area[3], worst = 0.0;
    for (int k = 0; k < 4; ++k) { double e = fabs(area[k] / tot - share[k]); if (e > worst) worst = e; }
    double scale = (4.0 / (M_PI * r)) * (4.0 / (M_PI * r));
    if (!(det > 1e-6 * scale) || !(worst < 0.05)) return 0;
    double c = cos(SBQD_PHI0_DEG * SBQD_RAD), s = sin(SBQD_PHI0_DEG * SBQD_RAD);
    double rx = c * cx - s * cy, ry = s * cx + c * cy;
    double tx = (SBQD_X0_M - rx) / SBQD_D_M, ty = (SBQD_Y0_M - ry) / SBQD_D_M;
OFFSETS
    return 1;
}
"""

_ADDITIVE = """\
    *alpha_deg = atan(tx) * SBQD_DEG + SBQD_ALPHA0_DEG;
    *beta_deg = atan(ty) * SBQD_DEG + SBQD_BETA0_DEG;"""

_ROTATION = """\
    double b[3];
    for (int i = 0; i < 3; ++i) b[i] = SBQD_DIE[i][0] * tx + SBQD_DIE[i][1] * ty + SBQD_DIE[i][2];
    *alpha_deg = atan2(b[0], b[2]) * SBQD_DEG;
    *beta_deg = atan2(b[1], b[2]) * SBQD_DEG;"""

_DIRECTION = """\
/* Currents [A] and temperature [C] -> sun direction in the body frame [deg]; 1 on success. */
static inline int sunbench_qd_sun_direction(const double currents_a[4], double temperature_c, double *zenith_deg,
                                            double *azimuth_deg) {
    double a, b;
    if (!sunbench_qd_angles(currents_a, temperature_c, &a, &b)) return 0;
    double x = tan(a * SBQD_RAD), y = tan(b * SBQD_RAD), n = sqrt(x * x + y * y + 1.0);
    x /= n; y /= n;
    *zenith_deg = atan2(hypot(x, y), 1.0 / n) * SBQD_DEG;
    *azimuth_deg = sbqd_wrap360(atan2(y, x) * SBQD_DEG);
    return 1;
}
"""


def _value(doc, name):
    return doc["parameters"][name]["value"]


def _dark_constants(dark: dict) -> list[str]:
    kind = dark["model"]
    names = DARK_PARAMETERS[kind]
    lines = [f"/* dark current, seed 002 §2.1: {kind} model */"]
    if names:
        rows = [c_array(q[n]["value"] for n in names) for q in dark["quadrants"]]
        lines.append(f"static const double SBQD_DARK[4][{len(names)}] = {{\n    " + ",\n    ".join(rows) + "};")
    if kind == "exponential":
        lines.append(f"static const double SBQD_DARK_T_REF_C = {c_double(dark['t_ref_c'])};")
    return lines


def c_header(document: dict, *, provenance: dict | None = None) -> str:
    """C header text of a QD calibration document (module docstring).

    Parameters
    ----------
    document : dict
        A QD calibration document (:mod:`calibration.qd.document`).
    provenance : dict, optional
        Short texts (source run, date, held-out accuracy) for the opening comment.

    References
    ----------
    seed 002, §2.1, eqs. 2.1–2.3.
    """
    validate_document(document)
    method, model = document["method"], document["model"]
    layout = np.asarray(model["layout"], float)
    constants = _dark_constants(document["dark"])
    constants.append("static const double SBQD_LAYOUT[4][2] = {" + ", ".join(c_array(r) for r in layout) + "};"
                     "  /* (sign x, sign y) of quadrants 1-4 */")
    if method == "geometric":
        constants += [f"static const double SBQD_LENGTH_M = {c_double(model['length_m'])};  /* L of eq. 2.1 */"]
        constants += [f"static const double SBQD_{n.upper()} = {c_double(_value(document, n))};"
                      for n in ("x0_m", "y0_m", "alpha0_deg", "beta0_deg", "phi0_deg", "d_m")]
        body = _GEOMETRIC
    elif method == "polynomial":
        terms = [tuple(int(v) for v in t) for t in model["terms"]]
        constants += [f"#define SBQD_N_TERMS {len(terms)}",
                      f"#define SBQD_MAX_POWER {max(max(t) for t in terms)}",
                      "static const int SBQD_TERMS[SBQD_N_TERMS][2] = {"
                      + ", ".join(f"{{{i}, {j}}}" for i, j in terms) + "};",
                      f"static const double SBQD_CENTER[2] = {c_array(model['center'])};",
                      f"static const double SBQD_SCALE[2] = {c_array(model['scale'])};",
                      f"static const double SBQD_COEF_ALPHA[SBQD_N_TERMS] = {c_array(_value(document, 'coef_alpha'))};",
                      f"static const double SBQD_COEF_BETA[SBQD_N_TERMS] = {c_array(_value(document, 'coef_beta'))};"]
        body = _POLYNOMIAL
    else:
        p = physical_from_document(document)
        constants += [f"static const double SBQD_{n.upper()} = {c_double(getattr(p, n))};"
                      for n in ("x0_m", "y0_m", "alpha0_deg", "beta0_deg", "phi0_deg", "d_m", "gap_m", "radius_m")]
        constants.append(f"static const double SBQD_GAINS[4] = {c_array(p.gains)};")
        if p.offsets == "rotation":
            m = detector_rotation(p.alpha0_deg, p.beta0_deg, 0.0)  # as calibration.qd.physical turns the die
            constants.append("/* die axes in the body frame: R_y(alpha0) R_x(-beta0) */")
            rows = ",\n    ".join(c_array(r) for r in m)
            constants.append("static const double SBQD_DIE[3][3] = {\n    " + rows + "};")
        body = _PHYSICAL.replace("OFFSETS", _ROTATION if p.offsets == "rotation" else _ADDITIVE)
    sensor_id = document.get("sensor_id")
    tag = re.sub(r"[^A-Za-z0-9]", "_", sensor_id or "SENSOR").upper()
    guard = f"SUNBENCH_QD_CALIBRATION_{tag}_H"
    comment = "".join(f"\n   {key}: {comment_safe(value)}" for key, value in (provenance or {}).items()
                      if value is not None)
    lines = [
        f"/* sunbench QD calibration: method {comment_safe(method)}, sensor {comment_safe(sensor_id or 'unknown')}.",
        "   Generated by `sunbench`; do not edit. Currents in amperes (quadrants 1-4), temperature in Celsius,",
        "   angles in degrees; body frame +z = boresight, tan(alpha) = s_x/s_z, tan(beta) = s_y/s_z." + comment + " */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "",
        _PRELUDE,
        "#ifndef M_PI",
        "#define M_PI 3.14159265358979323846",
        "#endif",
        "#ifndef M_PI_4",
        "#define M_PI_4 0.78539816339744830962",
        "#endif",
        f'#define SBQD_CALIBRATION_METHOD "{method}"',
        *constants,
        "",
        "static inline void sbqd_dark(double t, double dark[4]) {",
        _DARK[document["dark"]["model"]].rstrip("\n"),
        "}",
        "",
        _PHOTO,
        body,
        _DIRECTION,
        f"#endif /* {guard} */",
        "",
    ]
    return "\n".join(lines)
