"""Seed 004's printed numbers (Heiran 2021, ch. 4–5) as constants, and the statistics its error tables report.

Every table is transcribed from the source text (../shared/seeds/004_315b151fca5ecac1.txt), in the digest's column
order (the printed Table 4-1 header swaps latitude and longitude; Table 4-4's header repeats "roll error"). Known
defects are kept as printed and flagged:

* Table 4-6, 07:30: the pitch error is printed **0.127**; 85.4534 − 85.4408 = 0.0126, and only 0.0126 gives the
  printed mean 0.0985 (0.127 gives 0.1099) — :data:`TABLE_4_6_PITCH_ERROR_0730_CORRECTED`.
* Table 4-8's mean pitch error is 0.1241° in §4-5 and 0.1240° in Table 5-1 and the abstract; the ten values give
  0.12414, so §4-5's 0.1241 is the rounding and Table 5-1 truncates.
* Table 4-3's means are printed 0.00042204° (roll) and 0.0032° (pitch); its ten printed values give 0.00042140°
  and 0.00332° (→ 0.0033). The roll mean is reproduced if the first entry, printed −0.0010 (4 decimals where the
  others have 8), was −0.00100636; the pitch mean cannot come from the printed pitch values (each would have to be
  ≥ 0.00007 smaller on average, more than their ±0.00005 rounding allows).

The statistics are seed 004 eqs. 3.1–3.2: the mean of |error|, and a σ. Eq. 3.2 as printed mixes the values with the
mean |error| (digest §5.1); :func:`signed_std_deg` is the population σ of the signed errors (the digest's "signed σ").
"""

from __future__ import annotations

import numpy as np

#: The ten 1-s windows of 12 April 2020 (seed 004 §3-5), their start times (UTC assumed; the thesis does not say).
WINDOWS: tuple[str, ...] = ("07:30:00", "07:40:00", "07:50:00", "08:00:00", "08:10:00", "08:20:00", "08:30:00",
                            "08:40:00", "08:50:00", "09:00:00")
#: The date of the windows (seed 004 §3-5; the PSG appendix says 2021, STK 2020).
DATE = "2020-04-12"

#: Table 4-1: STK's geodetic altitude [km] of MicroMAS-2A at each window's start.
TABLE_4_1_ALTITUDE_KM = (504.6520, 523.9763, 542.2035, 540.8800, 522.5518, 506.7403, 504.1337, 505.6648, 501.9295,
                         500.5034)
#: Table 4-1: the sub-satellite geodetic latitude and longitude [°] (columns swapped back, digest §5.2).
TABLE_4_1_LATITUDE_DEG = (0.320, 37.900, 74.285, 65.067, 28.050, -9.549, -47.180, -81.522, -55.231, -17.638)
TABLE_4_1_LONGITUDE_DEG = (175.458, 169.696, 147.982, 11.767, -0.499, -5.720, -12.529, -65.229, -173.646, 177.931)
#: Table 4-1: STK's YPR321 attitude in ICRF [°] at each window's start (roll, pitch, yaw).
TABLE_4_1_ROLL_DEG = (94.036, 167.059, 171.515, 174.584, -179.063, -30.648, -11.367, -7.707, -4.393, 6.477)
TABLE_4_1_PITCH_DEG = (85.447, 50.928, 13.277, -24.375, -61.945, -78.882, -41.568, -3.541, 34.525, 72.245)
TABLE_4_1_YAW_DEG = (78.576, 7.088, 4.573, 4.874, 9.457, 156.38, 174.077, 175.575, 174.652, 165.432)

#: Table 4-2: spherical Earth, cone 1, the time [s] of STK's "first sample after the change" of the boresight's
#: Earth intersection (10⁻⁵ s report step), per window, and its two (unexplained) angle columns as printed.
TABLE_4_2_CROSSING_TIME_S = (0.18443, 0.18444, 0.18445, 0.18446, 0.18447, 0.18448, 0.18449, 0.18450, 0.18451,
                             0.18452)
TABLE_4_2_LONGITUDE_DEG = (20.537, 20.603, 20.675, 20.754, 20.842, 20.941, 21.061, 21.220, 99.000, 99.000)
TABLE_4_2_LATITUDE_DEG = (-132.338, -132.319, -132.295, -132.275, -132.250, -132.221, -132.186, -132.140, 999.000,
                          999.000)
#: STK's report step for the point-FOV cases [s] (seed 004 §3-5, App. 1).
STK_REPORT_STEP_S = 1e-5

#: Table 4-3 (case A, spherical Earth): roll and pitch [°] in the orbit frame, i.e. the errors.
TABLE_4_3_ROLL_ERROR_DEG = (-0.0010, 0.00015205, 0.00024321, 0.00039051, 0.00035745, -0.00058657, 0.00027494,
                            -0.00020215, -0.00036466, -0.00064250)
TABLE_4_3_PITCH_ERROR_DEG = (-0.0030, -0.0033, -0.0034, -0.0035, -0.0045, -0.0030, -0.0034, -0.0031, -0.0030,
                             -0.0030)
TABLE_4_3_MEAN_ABS_DEG = {"roll": 0.00042204, "pitch": 0.0032}

#: Tables 4-4, 4-6, 4-8: roll/pitch solved ("sim") and STK's ("real", YPR321 in ICRF) [°], and the printed errors.
TABLE_4_4 = {
    "roll_sim": (94.2332, 167.1204, 171.5591, 174.6239, -179.0306, -30.5773, -11.3207, -7.6699, -4.3604, 6.4967),
    "pitch_sim": (85.4308, 50.7583, 13.1910, -24.2619, -61.8097, -78.8251, -41.4030, -3.5112, 34.3847, 72.1624),
    "roll_error": (-0.1937, 0.0548, 0.0415, 0.0370, 0.0218, 0.0050, 0.0416, 0.0350, 0.0293, -0.0068),
    "pitch_error": (-0.0099, -0.1387, -0.0544, 0.1443, 0.1669, 0.0282, 0.1337, -0.0015, -0.1720, -0.1134),
}
TABLE_4_6 = {
    "roll_sim": (94.1706, 167.1697, 171.6032, 174.6711, -178.9545, -30.6978, -11.3684, -7.6899, -4.4211, 6.3739),
    "pitch_sim": (85.4534, 50.7773, 13.2134, -24.2394, -61.7883, -78.8251, -41.4142, -3.5190, 34.3705, 72.1566),
    "roll_error": (-0.2563, 0.1042, 0.0856, 0.0842, 0.0979, -0.1155, -0.0061, 0.0151, -0.0314, -0.1295),
    "pitch_error": (0.127, -0.1197, -0.0320, 0.1668, 0.1882, 0.0282, 0.1223, -0.0093, -0.1862, -0.1192),
}
TABLE_4_8 = {
    "roll_sim": (94.2297, 167.5834, 171.5560, 174.6213, -178.2433, -30.5632, -11.3151, -7.9758, -4.5372, 5.8889),
    "pitch_sim": (85.4276, 50.9195, 13.1906, -24.2623, -61.5810, -78.8259, -41.4030, -3.6074, 34.3424, 72.1374),
    "roll_error": (-0.1972, 0.5179, 0.0385, 0.0344, 0.8091, 0.0191, 0.0472, -0.2708, -0.1476, -0.6146),
    "pitch_error": (-0.0132, 0.0225, -0.0548, 0.1439, 0.3956, 0.0274, 0.1337, -0.0977, -0.2142, -0.1384),
}
#: The "real" roll and pitch [°] common to Tables 4-4, 4-6 and 4-8 (they differ from Table 4-1 by up to 0.39°).
TABLE_4_REAL_ROLL_DEG = (94.4269, 167.0655, 171.5175, 174.5870, -179.0524, -30.5823, -11.3623, -7.7050, -4.3896,
                         6.5035)
TABLE_4_REAL_PITCH_DEG = (85.4408, 50.8970, 13.2454, -24.4062, -61.9766, -78.8533, -41.5367, -3.5097, 34.5567,
                          72.2758)
for _table in (TABLE_4_4, TABLE_4_6, TABLE_4_8):
    _table["roll_real"], _table["pitch_real"] = TABLE_4_REAL_ROLL_DEG, TABLE_4_REAL_PITCH_DEG
#: The 07:30 pitch error of Table 4-6 as its own columns give it (printed 0.127).
TABLE_4_6_PITCH_ERROR_0730_CORRECTED = 0.0126
#: The printed means of |error| [°] (§4-3, §4-4, §4-5); case D's pitch: 0.1241 in §4-5, 0.1240 in Table 5-1.
TABLE_4_4_MEAN_ABS_DEG = {"roll": 0.0467, "pitch": 0.0963}
TABLE_4_6_MEAN_ABS_DEG = {"roll": 0.0926, "pitch": 0.0985}
TABLE_4_8_MEAN_ABS_DEG = {"roll": 0.2696, "pitch": 0.1241}
TABLE_4_8_MEAN_ABS_PITCH_TABLE_5_1_DEG = 0.1240

#: Table 4-5: cone 1, 07:30 window, STK's obscuration of the 2° IFOV by the Earth [%] against time [s].
TABLE_4_5_TIME_S = (0.1895, 0.1896, 0.1897, 0.1898, 0.1899, 0.1900, 0.1901, 0.1902, 0.1903, 0.1904)
TABLE_4_5_OBSCURATION_PERCENT = (3.287081, 2.752614, 2.24338, 1.767259, 1.340805, 0.944311, 0.599057, 0.308985,
                                 0.090645, 0.0)

#: Table 5-1: mean |error| [°] per stacked case: (case, roll per factor, roll cumulative, pitch per factor,
#: pitch cumulative).
TABLE_5_1: tuple[tuple[str, float, float, float, float], ...] = (
    ("spherical", 0.0004, 0.0004, 0.0032, 0.0032),
    ("+ellipsoid", 0.0463, 0.0467, 0.0931, 0.0963),
    ("+ifov", 0.0459, 0.0926, 0.0022, 0.0985),
    ("+atmosphere", 0.1770, 0.2696, 0.0255, 0.1240),
)

#: The thesis' orbit (Table 3-1, n2yo): MicroMAS-2A, NORAD 43131.
MICROMAS_INCLINATION_DEG = 97.4
MICROMAS_PERIOD_MIN = 94.3
MICROMAS_PERIGEE_KM = 486.1
MICROMAS_APOGEE_KM = 495.8
MICROMAS_SEMI_MAJOR_AXIS_KM = 6861.0


def window_index(window) -> int:
    """The index 0–9 of a thesis window given as its index or its start time "HH:MM[:SS]" (seed 004 §3-5)."""
    if isinstance(window, (int, np.integer)) and not isinstance(window, bool):
        if not 0 <= int(window) < len(WINDOWS):
            raise ValueError(f"seed 004 has windows 0–{len(WINDOWS) - 1}, got {window}")
        return int(window)
    text = str(window)
    for i, start in enumerate(WINDOWS):
        if text in (start, start[:5]):
            return i
    raise ValueError(f"not one of seed 004's windows {WINDOWS}: {window!r}")


def mean_abs_error_deg(errors_deg) -> float:
    """x̄ = (1/n) Σ |x_i − x̂_i| over the errors x_i − x̂_i [°] (seed 004 eq. 3.1)."""
    e = np.asarray(errors_deg, float)
    if e.size == 0:
        raise ValueError("no errors to average")
    return float(np.mean(np.abs(e)))


def signed_std_deg(errors_deg) -> float:
    """The population standard deviation of the signed errors [°] (seed 004 eq. 3.2 read as σ of the errors about
    their mean; the printed form mixes the values with the mean |error|, digest §5.1)."""
    e = np.asarray(errors_deg, float)
    if e.size == 0:
        raise ValueError("no errors to take a spread of")
    return float(np.std(e))


def max_abs_error_deg(errors_deg) -> float:
    """max |error| [°] (the digest's per-table maximum, seed 004 Tables 4-3–4-8)."""
    e = np.asarray(errors_deg, float)
    if e.size == 0:
        raise ValueError("no errors")
    return float(np.max(np.abs(e)))


def error_statistics(errors_deg) -> dict[str, float]:
    """``{"mean_abs", "signed_std", "max_abs", "bias"}`` [°] of a column of errors (seed 004 eqs. 3.1–3.2)."""
    e = np.asarray(errors_deg, float)
    return {"mean_abs": mean_abs_error_deg(e), "signed_std": signed_std_deg(e), "max_abs": max_abs_error_deg(e),
            "bias": float(np.mean(e))}


def table_errors_deg(table: dict, axis: str, recompute: bool = False) -> np.ndarray:
    """A table's error column for `axis` ("roll" | "pitch") [°]: as printed, or recomputed as sim − real (the
    thesis' errors, digest §5.3 — which also corrects Table 4-6's 0.127) (seed 004 Tables 4-4, 4-6, 4-8)."""
    if axis not in ("roll", "pitch"):
        raise ValueError(f"axis is 'roll' or 'pitch', got {axis!r}")
    if not recompute:
        return np.asarray(table[f"{axis}_error"], float)
    diff = np.asarray(table[f"{axis}_sim"], float) - np.asarray(table[f"{axis}_real"], float)
    return (diff + 180.0) % 360.0 - 180.0  # roll wraps at ±180° (08:10: −179.0306 vs −179.0524)


def stacked_case_increments(cumulative_means) -> np.ndarray:
    """Table 5-1's "per factor" column: the differences of successive cumulative means of |error| [°] (the first
    is the first mean) — seed 004 Table 5-1; not isolated effects (digest §5.3)."""
    c = np.asarray(cumulative_means, float)
    return np.concatenate([c[:1], np.diff(c)])
