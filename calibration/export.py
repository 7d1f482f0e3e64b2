"""Export of a calibration as a C header for the sensor's microcontroller.

The header holds the coefficients and a ``static inline`` function that turns a spot centre into the sun
direction exactly as :meth:`Calibration.apply` does, so the firmware and this library agree to rounding
(a test compiles the header and checks it). Doubles are printed with Python's shortest round-trip repr,
so the C constants are the very same binary values.

References
----------
seed 003, §3.2 and §6: the direction algorithm with its calibration parameters runs on the module's MCU
(STM32F410).
"""

from __future__ import annotations

import math
import re

from .design import SensorDesign
from .errors import CalibrationError
from .geometry import combined_tilt
from .models import Calibration
from .models.physical import PhysicalCalibration
from .models.seed003 import Seed003Calibration, Seed003SectorCalibration, Seed003TiltCalibration
from .pinhole import detector_rotation


def c_double(value: float) -> str:
    """A finite double as C source text: Python's shortest round-trip repr, so C reads the same binary value."""
    value = float(value)
    if not math.isfinite(value):  # a C header with `nan` compiles and answers garbage on the satellite
        raise CalibrationError(f"the calibration holds a non-finite coefficient ({value}); no C header written")
    return repr(value)


def comment_safe(value) -> str:
    """A value as text that cannot end the C comment it sits in."""
    return str(value).replace("*/", "* /").replace("\n", " ")


def c_array(values) -> str:
    """A C initializer ``{a, b, …}`` of finite doubles (:func:`c_double`)."""
    return "{" + ", ".join(c_double(v) for v in values) + "}"


_PRELUDE = """\
#include <math.h>

#define SB_DEG (57.29577951308232)
#define SB_RAD (0.017453292519943295)

/* Wrap an angle to [0, 360) degrees (like numpy.mod, unlike fmod, for negative input). */
static inline double sb_wrap360(double a) {
    double w = fmod(a, 360.0);
    return w < 0.0 ? w + 360.0 : w;
}
"""

_SEED003_BODY = """\
/* Horner evaluation of theta(u) = sum c[i] u^i, u = r / SB_RADIUS_SCALE_PX (seed 003 eq. 9). */
static inline double sb_poly6(const double c[7], double u) {
    double v = c[6];
    for (int i = 5; i >= 0; --i) v = v * u + c[i];
    return v;
}

/* Spot centre [px] -> sun direction in the body frame [deg]. */
static inline void sunbench_sun_direction(double x_px, double y_px, double *zenith_deg, double *azimuth_deg) {
    double dx = x_px - SB_X0_PX, dy = y_px - SB_Y0_PX;
    double r = sqrt(dx * dx + dy * dy);                               /* seed 003 eq. 7 */
    double meas = sb_wrap360(atan2(dx, -dy) * SB_DEG);                /* seed 003 eq. 10 */
    double phi = sb_wrap360(SB_AZIMUTH_SLOPE * meas + SB_AZIMUTH_OFFSET_DEG); /* seed 003 eq. 11 */
    double theta = ZENITH_EXPRESSION;
    if (theta < 0.0) { theta = -theta; phi = sb_wrap360(phi + 180.0); }
    *zenith_deg = theta;
    *azimuth_deg = phi;
}
"""

_PHYSICAL_BODY = """\
/* Spot centre [px] -> sun direction in the body frame [deg]: inverse of the physical pinhole model
   (pinhole, air gap, cover glass with Snell refraction, tilted and rotated detector). */
static inline void sunbench_sun_direction(double x_px, double y_px, double *zenith_deg, double *azimuth_deg) {
    double ux = -(x_px - SB_X0_PX) * SB_PIXEL_PITCH_MM;
    double uy = -SB_HANDEDNESS * (y_px - SB_Y0_PX) * SB_PIXEL_PITCH_MM;
    double rm = sqrt(ux * ux + uy * uy), r = rm, n2 = SB_GLASS_INDEX * SB_GLASS_INDEX;
    if (rm > 0.0) /* undo the non-round aperture's stretch (it keeps the direction) */
        r = rm / (1.0 + SB_APERTURE_C * (ux * ux - uy * uy) / (rm * rm) + SB_APERTURE_S * 2.0 * ux * uy / (rm * rm));
    double th = atan(r / (SB_GAP_MM + SB_GLASS_MM / SB_GLASS_INDEX));
    for (int i = 0; i < 8; ++i) {  /* Newton on r = g tan(th) + t tan(asin(sin(th) / n)) */
        double s = sin(th), c = cos(th), root = sqrt(n2 - s * s);
        double f = SB_GAP_MM * s / c + SB_GLASS_MM * s / root - r;
        double df = SB_GAP_MM / (c * c) + SB_GLASS_MM * c * n2 / (root * root * root);
        th -= f / df;
        if (th < 0.0) th = 0.0;
        if (th > 89.9 * SB_RAD) th = 89.9 * SB_RAD;
    }
    double k = rm > 0.0 ? sin(th) / rm : 0.0;
    double d[3] = {ux * k, uy * k, cos(th)}, s[3];
    for (int i = 0; i < 3; ++i)
        s[i] = SB_DETECTOR[i][0] * d[0] + SB_DETECTOR[i][1] * d[1] + SB_DETECTOR[i][2] * d[2];
    MASK_GLASS_REFINEMENT
    *zenith_deg = atan2(sqrt(s[0] * s[0] + s[1] * s[1]), s[2]) * SB_DEG;
    *azimuth_deg = sb_wrap360(atan2(s[1], s[0]) * SB_DEG);
}
"""

#: The glass-under-mask variant: the forward chief ray (Snell into a plate parallel to the mask, then on to the
#: tilted die) and Newton steps from the on-die inverse, as calibration.pinhole does.
_MASK_FORWARD = """/* Spot [px] of a body-frame sun vector s with the glass bonded under the mask (exact chief ray). */
static inline void sb_forward_mask_glass(const double s[3], double *x_px, double *y_px) {
    double eta = 1.0 / SB_GLASS_INDEX, ci = s[2], ct = sqrt(1.0 - eta * eta * (1.0 - ci * ci));
    double t[3] = {-eta * s[0], -eta * s[1], -eta * s[2] + (eta * ci - ct)};
    double e[3] = {t[0] * SB_GLASS_MM / ct, t[1] * SB_GLASS_MM / ct, t[2] * SB_GLASS_MM / ct};
    double nd[3] = {SB_DETECTOR[0][2], SB_DETECTOR[1][2], SB_DETECTOR[2][2]};
    double un = -(s[0] * nd[0] + s[1] * nd[1] + s[2] * nd[2]);
    double lam = (-(SB_GAP_MM + SB_GLASS_MM) - (e[0] * nd[0] + e[1] * nd[1] + e[2] * nd[2])) / un;
    double h[3] = {e[0] - lam * s[0], e[1] - lam * s[1], e[2] - lam * s[2]};
    double dx = h[0] * SB_DETECTOR[0][0] + h[1] * SB_DETECTOR[1][0] + h[2] * SB_DETECTOR[2][0];
    double dy = h[0] * SB_DETECTOR[0][1] + h[1] * SB_DETECTOR[1][1] + h[2] * SB_DETECTOR[2][1];
    double rho2 = dx * dx + dy * dy, st = 1.0;
    if (rho2 > 0.0) st = 1.0 + SB_APERTURE_C * (dx * dx - dy * dy) / rho2 + SB_APERTURE_S * 2.0 * dx * dy / rho2;
    *x_px = SB_X0_PX + st * dx / SB_PIXEL_PITCH_MM;
    *y_px = SB_Y0_PX + SB_HANDEDNESS * st * dy / SB_PIXEL_PITCH_MM;
}
"""

_MASK_REFINEMENT = """for (int it = 0; it < 6; ++it) {  /* Newton in the tangent plane on the glass-under-mask model */
        double ref[3] = {0.0, 0.0, 1.0};
        if (fabs(s[2]) >= 0.9) { ref[0] = 1.0; ref[2] = 0.0; }
        double dot = ref[0] * s[0] + ref[1] * s[1] + ref[2] * s[2];
        double e1[3] = {ref[0] - dot * s[0], ref[1] - dot * s[1], ref[2] - dot * s[2]};
        double n1 = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        for (int i = 0; i < 3; ++i) e1[i] /= n1;
        double e2[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
        double fx, fy, jac[2][2], hstep = 1e-7;
        sb_forward_mask_glass(s, &fx, &fy);
        for (int j = 0; j < 2; ++j) {
            const double *e = j == 0 ? e1 : e2;
            double sp[3] = {s[0] + hstep * e[0], s[1] + hstep * e[1], s[2] + hstep * e[2]}, gx, gy;
            double np_ = sqrt(sp[0] * sp[0] + sp[1] * sp[1] + sp[2] * sp[2]);
            for (int i = 0; i < 3; ++i) sp[i] /= np_;
            sb_forward_mask_glass(sp, &gx, &gy);
            jac[0][j] = (gx - fx) / hstep;
            jac[1][j] = (gy - fy) / hstep;
        }
        double det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        double rx = x_px - fx, ry = y_px - fy;
        double a = (jac[1][1] * rx - jac[0][1] * ry) / det, b = (jac[0][0] * ry - jac[1][0] * rx) / det;
        for (int i = 0; i < 3; ++i) s[i] += a * e1[i] + b * e2[i];
        double ns = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        for (int i = 0; i < 3; ++i) s[i] /= ns;
    }"""


def _seed003_constants(cal: Seed003Calibration) -> list[str]:
    return [
        f"static const double SB_X0_PX = {c_double(cal.x0_px)};",
        f"static const double SB_Y0_PX = {c_double(cal.y0_px)};",
        f"static const double SB_RADIUS_SCALE_PX = {c_double(cal.radius_scale_px)};",
        f"static const double SB_ZENITH_COEF[7] = {c_array(cal.zenith_coefficients)};",
        f"static const double SB_AZIMUTH_SLOPE = {c_double(cal.azimuth_slope)};",
        f"static const double SB_AZIMUTH_OFFSET_DEG = {c_double(cal.azimuth_offset_deg)};",
    ]


def _seed003_header(cal: Seed003Calibration) -> tuple[list[str], str]:
    constants = _seed003_constants(cal)
    zenith = "sb_poly6(SB_ZENITH_COEF, r / SB_RADIUS_SCALE_PX)"
    if isinstance(cal, Seed003TiltCalibration):
        tilt, tilt_azimuth = combined_tilt(cal.tilt_x_deg, cal.tilt_y_deg)  # seed 003 eq. 14
        constants += [f"static const double SB_TILT_DEG = {c_double(tilt)};  /* theta' of eq. 14 */",
                      f"static const double SB_TILT_AZIMUTH_DEG = {c_double(tilt_azimuth)};  /* phi' of eq. 14 */"]
        zenith += (" + asin(sin(SB_TILT_DEG * SB_RAD) * cos((phi - SB_TILT_AZIMUTH_DEG) * SB_RAD)) * SB_DEG"
                   "  /* eqs. 15-16 */")
    if isinstance(cal, Seed003SectorCalibration):
        rows = [c_array(c if len(c) else cal.zenith_coefficients) for c in cal.sector_coefficients]
        reach = cal.sector_radius_max_px or (float("inf"),) * 8
        constants.append("static const double SB_SECTOR_COEF[8][7] = {\n    " + ",\n    ".join(rows) + "};")
        constants.append("/* beyond its fitted radius a sector hands over to the pooled polynomial */")
        constants.append("static const double SB_SECTOR_REACH_PX[8] = "
                         + c_array(x * 1.01 if len(c) else -1.0 for x, c in zip(reach, cal.sector_coefficients)) + ";")
        zenith = ("(r <= SB_SECTOR_REACH_PX[((int)floor(phi / 45.0)) % 8] ? "
                  "sb_poly6(SB_SECTOR_COEF[((int)floor(phi / 45.0)) % 8], r / SB_RADIUS_SCALE_PX) : "
                  "sb_poly6(SB_ZENITH_COEF, r / SB_RADIUS_SCALE_PX))  /* §4.5 */")
    return constants, _SEED003_BODY.replace("ZENITH_EXPRESSION", zenith)


def _physical_header(cal: PhysicalCalibration) -> tuple[list[str], str]:
    m = detector_rotation(cal.tilt_x_deg, cal.tilt_y_deg, cal.rotation_deg)
    constants = [
        f"static const double SB_X0_PX = {c_double(cal.x0_px)};",
        f"static const double SB_Y0_PX = {c_double(cal.y0_px)};",
        f"static const double SB_GAP_MM = {c_double(cal.gap_mm)};",
        f"static const double SB_GLASS_MM = {c_double(cal.glass_mm)};",
        f"static const double SB_GLASS_INDEX = {c_double(cal.glass_index)};",
        f"static const double SB_PIXEL_PITCH_MM = {c_double(cal.pixel_pitch_mm)};",
        f"static const double SB_HANDEDNESS = {'-1.0' if cal.mirrored else '1.0'};",
        f"static const double SB_APERTURE_C = {c_double(cal.aperture_c)};",
        f"static const double SB_APERTURE_S = {c_double(cal.aperture_s)};",
        f"/* detector tilt alpha = {cal.tilt_x_deg!r} deg, beta = {cal.tilt_y_deg!r} deg, "
        f"in-plane rotation = {cal.rotation_deg!r} deg */",
        "static const double SB_DETECTOR[3][3] = {\n    " + ",\n    ".join(c_array(row) for row in m) + "};",
    ]
    if cal.glass_on_mask and cal.glass_mm > 0:
        return constants, _MASK_FORWARD + "\n" + _PHYSICAL_BODY.replace("MASK_GLASS_REFINEMENT", _MASK_REFINEMENT)
    return constants, _PHYSICAL_BODY.replace("    MASK_GLASS_REFINEMENT\n", "")


def c_header(calibration: Calibration, *, sensor_id: str | None = None, design: SensorDesign | None = None,
             provenance: dict | None = None) -> str:
    """C header text for `calibration`, defining ``sunbench_sun_direction(x_px, y_px, &zenith, &azimuth)``,
    with the detector's design (size, pixel pitch) when it is known and `provenance` (e.g. source run, date,
    software, held-out accuracy: short texts) in its opening comment."""
    if isinstance(calibration, PhysicalCalibration):
        constants, body = _physical_header(calibration)
    elif isinstance(calibration, Seed003Calibration):
        constants, body = _seed003_header(calibration)
    else:
        raise TypeError(f"no C export for {type(calibration).__name__}")
    tag = re.sub(r"[^A-Za-z0-9]", "_", sensor_id or "SENSOR").upper()
    guard = f"SUNBENCH_CALIBRATION_{tag}_H"
    lines = [
        f"/* sunbench calibration: method {calibration.method}, sensor {sensor_id or 'unknown'}.",
        "   Generated by `sunbench`; do not edit. Angles in degrees, spot centres in pixels",
        "   (x right, y down, origin at the centre of pixel 0,0); body frame +z = boresight."
        + "".join(f"\n   {key}: {comment_safe(value)}"
                  for key, value in (provenance or {}).items() if value is not None)
        + " */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "",
        _PRELUDE,
        f'#define SB_CALIBRATION_METHOD "{calibration.method}"',
        *([f"#define SB_DETECTOR_WIDTH_PX {design.width_px}", f"#define SB_DETECTOR_HEIGHT_PX {design.height_px}",
           f"#define SB_DESIGN_PIXEL_PITCH_MM {c_double(design.pixel_pitch_mm)}"] if design is not None else []),
        *constants,
        "",
        body,
        f"#endif /* {guard} */",
        "",
    ]
    return "\n".join(lines)
