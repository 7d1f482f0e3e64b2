"""The TPS 230 thermopile's "seen temperature" (seed 000 eq. 3.3, §5.2, listings D.2–D.4, Fig. 5.2).

Eq. 3.3 as printed uses SpectralSum(φ) in both terms (digest §9.4); listings D.2–D.4 use the complement for
space, so the working model is a sensitivity-weighted *linear average of scene temperatures* over a 1-D angular
cut through the detector's normal:

.. math:: T_{seen} = \\frac{\\sum_\\theta S(\\theta)\\,T_{scene}(\\theta)}{\\sum_\\theta S(\\theta)}

with S the field-of-view curve of :func:`calibration.css.angular.thesis_fov_response`. The scripts are
reproduced literally (:func:`d2_earth_seen_temperature_c` 13.9118 °C, :func:`d3_sun_seen_temperature_c`
−234.1285 °C, :func:`d4_seen_temperature_curve_c` the curve H(i) of Fig. 5.2, −202.38 °C at 90°), and
generalised to any Earth size and pointing (:func:`seen_temperature_k`, exact integrals of the pchip curve).

A thermopile really responds to band-limited radiance (≈ T⁴ above 5.5 µm), not to temperature;
:func:`seen_brightness_temperature_k` averages radiance instead and converts back to a temperature, the physical
alternative (digest §3.4 ⚠, §8.1 mode B). Both stay 1-D cuts, not solid-angle integrals, like the thesis.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from .angular import thesis_fov_curve, thesis_fov_integral
from .detectors import TPS_230, Thermopile
from .radiation import SPACE_TEMPERATURE_K, SUN_ANGULAR_DIAMETER_DEG, SUN_TEMPERATURE_K, thermopile_band_radiance

#: Earth's temperature in listing D.2 [K] (15 °C; D.4 uses 288 K).
EARTH_TEMPERATURE_D2_K = 288.15
#: Earth's angular half-size in listing D.2: 27 samples × 2.5° [°] (the text says 65°, digest §9.2).
EARTH_HALF_ANGLE_D2_DEG = 67.5
#: Earth's angular size in listing D.4: 136 one-degree samples, i.e. 68° each side of its centre [°].
EARTH_HALF_ANGLE_D4_DEG = 68.0
#: The algorithm's Earth/Sun threshold ``TvisEarth`` of listing D.5 [°C] (Fig. 5.2 at 90°).
T_VIS_EARTH_C = -202.4


def weighted_seen_temperature(weights, temperatures) -> np.ndarray:
    """Σ w·T / Σ w over the last axis: the working form of eq. 3.3 (listings D.2–D.4)."""
    w = np.asarray(weights, float)
    return np.sum(w * np.asarray(temperatures, float), axis=-1) / np.sum(w, axis=-1)


def _listing_sensitivity(step_deg: float) -> np.ndarray:
    """``interp1(angle, sensitivity, -90:step:90, 'pchip')`` of listings D.2–D.4."""
    n = int(round(180.0 / step_deg)) + 1
    return thesis_fov_curve()(np.linspace(-90.0, 90.0, n))


def d2_earth_seen_temperature_c(earth_k=EARTH_TEMPERATURE_D2_K, space_k=SPACE_TEMPERATURE_K,
                                earth_samples: int = 27) -> float:
    """Earth seen at 0° by the TPS, as listing D.2 computes it [°C] (seed 000 §5.2: 13.91 °C).

    The pchip curve on a 0.5° grid, resampled every 5 samples (2.5°, "Scale is changed from 1° to 5°" in the
    listing's comment) for 36 samples per side; the first `earth_samples` (27 → 67.5°) see the Earth, the rest
    space; each side sample counts twice, the on-axis one once:
    ``T = earth·(1 + sumA)/(1 + sumC) + space·sumB/(1 + sumC) − 273.15``.
    """
    s = _listing_sensitivity(0.5)
    pos = int(np.argmax(s))
    sensity = s[pos + 5 * np.arange(1, 37)]
    sum_a = 2.0 * np.sum(sensity[:earth_samples])
    sum_b = 2.0 * np.sum(sensity[earth_samples:])
    sum_c = 2.0 * np.sum(sensity)
    return float(earth_k * (1.0 + sum_a) / (1.0 + sum_c) + space_k * sum_b / (1.0 + sum_c) - 273.15)


def d3_sun_seen_temperature_c(sun_k=SUN_TEMPERATURE_K, space_k=SPACE_TEMPERATURE_K) -> float:
    """The Sun seen at 0° by the TPS, as listing D.3 computes it [°C] (seed 000 §5.2: −234.13 °C).

    The Sun fills one 0.5° sample (weight 1, on axis); every other sample of the 0.5° grid sees space:
    ``T = sun/(1 + sumA) + space·sumA/(1 + sumA) − 273.15`` with sumA twice the sum over −90 … −0.5°.
    """
    s = _listing_sensitivity(0.5)
    sum_a = 2.0 * np.sum(s[:180])
    return float(sun_k / (1.0 + sum_a) + space_k * sum_a / (1.0 + sum_a) - 273.15)


def d4_seen_temperature_curve_c(earth_k=288.0, space_k=SPACE_TEMPERATURE_K, earth_samples: int = 136,
                                celsius_offset=273.0) -> np.ndarray:
    """The curve H of listing D.4 / Fig. 5.2: TPS seen temperature against Earth rotation i [°C], shape (360,).

    ``H[i]`` is the listing's ``H(i)`` for i = 1 … 359 and ``H[0]`` its ``H(360)`` (a full turn): a 360-sample
    ring of temperatures (Earth = `earth_samples` one-degree samples, 113 … 248, centred at 180.5; space
    elsewhere) times the 1° pchip sensitivity padded to 360 samples (peak at 180) and circularly shifted by i,
    over the sum of the sensitivities, minus 273 (the listing's offset). Because of the half-sample geometry
    H[i] belongs to an off-nadir angle of i − 0.5°; H[90] = −202.38 °C is the thesis' −202.4 °C at 90°.
    """
    s = _listing_sensitivity(1.0)
    ring = np.concatenate([np.zeros(89), s, np.zeros(90)])
    start = 180 - earth_samples // 2  # 0-based: 112 for 136 samples, i.e. MATLAB's T(113:248)
    scene = np.full(360, float(space_k))
    scene[start:start + earth_samples] = earth_k
    shifts = np.arange(360)
    h = np.array([scene @ np.roll(ring, i) for i in shifts]) / np.sum(s) - celsius_offset
    return h


def fig52_seen_temperature_c(i) -> np.ndarray:
    """H(i) of Fig. 5.2 (listing D.4 with its constants) at integer rotation(s) `i` [°] (taken mod 360) [°C]."""
    idx = np.mod(np.asarray(i, int), 360)
    return d4_seen_temperature_curve_c()[idx]


def _fraction_in_view(lower_deg, upper_deg, response, step_deg):
    """Share of the 1-D sensitivity integral between two signed angles (exact for the thesis curve)."""
    if response is None:
        return thesis_fov_integral(lower_deg, upper_deg) / thesis_fov_integral(-90.0, 90.0)
    theta = np.arange(-90.0 + step_deg / 2.0, 90.0, step_deg)  # midpoint rule
    w = np.asarray(response(theta), float)
    lo = np.asarray(lower_deg, float)[..., None]
    hi = np.asarray(upper_deg, float)[..., None]
    return np.sum(w * ((theta >= lo) & (theta <= hi)), axis=-1) / np.sum(w)


def seen_temperature_k(earth_half_angle_deg, off_nadir_deg, earth_k=EARTH_TEMPERATURE_D2_K,
                       space_k=SPACE_TEMPERATURE_K, *, response=None, step_deg=0.01) -> np.ndarray:
    """TPS seen temperature of an Earth disc at any size and pointing, the thesis' linear model [K].

    In the 1-D cut the Earth spans off_nadir ± earth_half_angle (angles from the detector normal, the part
    within ±90° counts); T = f·T_earth + (1 − f)·T_space with f the Earth's share of ∫S dθ. `response` None
    uses the thesis' pchip curve with exact integrals; any other callable of the angle [°] is integrated by
    the midpoint rule at `step_deg`. Vectorised over both angles. With 68° and off-nadir i − 0.5° it follows
    listing D.4's H(i) (+273 K) to the listing's 1° sampling; with 65° it is the text's 130° Earth.
    """
    rho = np.asarray(earth_half_angle_deg, float)
    alpha = np.asarray(off_nadir_deg, float)
    rho, alpha = np.broadcast_arrays(rho, alpha)
    f = _fraction_in_view(alpha - rho, alpha + rho, response, step_deg)
    return f * earth_k + (1.0 - f) * space_k


#: The name the CSS design brief uses for :func:`seen_temperature_k` (returns kelvin).
seen_temperature = seen_temperature_k


def sun_seen_temperature_k(off_axis_deg=0.0, sun_k=SUN_TEMPERATURE_K, space_k=SPACE_TEMPERATURE_K, *,
                           sun_diameter_deg=SUN_ANGULAR_DIAMETER_DEG, response=None, step_deg=0.01) -> np.ndarray:
    """TPS seen temperature of the Sun (a `sun_diameter_deg` disc) at `off_axis_deg`, the thesis' model [K].

    Listing D.3 generalised: the Sun's share of ∫S dθ over its 0.5° in the 1-D cut; ≈ −234.1 °C on axis.
    """
    a = np.asarray(off_axis_deg, float)
    f = _fraction_in_view(a - sun_diameter_deg / 2.0, a + sun_diameter_deg / 2.0, response, step_deg)
    return f * sun_k + (1.0 - f) * space_k


def band_brightness_temperature_k(radiance, *, thermopile: Thermopile = TPS_230, wavelength_hi_m=np.inf,
                                  transmittance=None) -> np.ndarray:
    """The black-body temperature whose band radiance through the TPS window is `radiance` [K].

    Inverse of :func:`calibration.css.radiation.thermopile_band_radiance` (same band arguments), solved on
    5 K … 10⁶ K; a radiance below that of 5 K (≈ 1e−225 W m⁻² sr⁻¹ above 5.5 µm: space) returns 0.
    """
    kwargs = dict(thermopile=thermopile, wavelength_hi_m=wavelength_hi_m, transmittance=transmittance)
    t_lo, t_hi = 5.0, 1e6
    floor = float(thermopile_band_radiance(t_lo, **kwargs))

    def solve(target: float) -> float:
        if target <= floor:
            return 0.0
        log_target = np.log(target)

        def gap(log_t):
            return np.log(float(thermopile_band_radiance(np.exp(log_t), **kwargs))) - log_target

        return float(np.exp(brentq(gap, np.log(t_lo), np.log(t_hi), xtol=1e-14)))

    return np.vectorize(solve, otypes=[float])(np.asarray(radiance, float))


def seen_brightness_temperature_k(earth_half_angle_deg, off_nadir_deg, earth_k=EARTH_TEMPERATURE_D2_K,
                                  space_k=SPACE_TEMPERATURE_K, *, sun_off_axis_deg=None, sun_k=SUN_TEMPERATURE_K,
                                  sun_diameter_deg=SUN_ANGULAR_DIAMETER_DEG, thermopile: Thermopile = TPS_230,
                                  response=None, step_deg=0.01) -> np.ndarray:
    """Physical alternative to :func:`seen_temperature_k`: average band radiance, not temperature [K].

    The same 1-D cut and weights; the scene's band radiance through the TPS window (5.5 µm long-pass) is
    averaged and converted back to the black-body temperature giving that radiance. Optionally adds the Sun at
    `sun_off_axis_deg` (its share taken from space; pass ``earth_half_angle_deg=0`` for Sun only). Because
    radiance grows ≈ T⁴ and faster in the band, the Sun reads far hotter than the thesis' −234 °C.
    """
    rho = np.asarray(earth_half_angle_deg, float)
    alpha = np.asarray(off_nadir_deg, float)
    rho, alpha = np.broadcast_arrays(rho, alpha)
    f_earth = _fraction_in_view(alpha - rho, alpha + rho, response, step_deg)
    f_sun = 0.0
    if sun_off_axis_deg is not None:
        s = np.asarray(sun_off_axis_deg, float)
        f_sun = _fraction_in_view(s - sun_diameter_deg / 2.0, s + sun_diameter_deg / 2.0, response, step_deg)

    def band(t):
        return thermopile_band_radiance(t, thermopile=thermopile)

    mean = f_earth * band(earth_k) + f_sun * band(sun_k) + (1.0 - f_earth - f_sun) * band(space_k)
    return band_brightness_temperature_k(mean, thermopile=thermopile)
