"""Radiation of the Sun and the Earth, and the photocurrents it drives (seed 000 ch. 2, §3.2, eqs 3.1–3.2).

The Sun is a black body of 5780 K (seed 000 §5.2 and listing D.3, used for every thermopile number) or 5800 K
(ch. 2, from Stefan–Boltzmann and the solar diameter); both are constants here, and every function takes the
temperature as an explicit input. Its total irradiance at 1 AU above the atmosphere is 1366 ± 3 W m⁻², its
angular size about 0.5° (a point source). The Earth reflects an albedo of 0.3 (measured 30–31 %) and emits as a
288 K black body (listing D.2 uses 288.15 K); space is 3 K.

Photocurrents follow eqs 3.1 and 3.2: I = S(φ) · A · [albedo ·] Σ E(λ_i)·S_λ(λ_i)·Δλ. Without spectra at hand
(the thesis cites ASTM E-490 AM0 and the datasheet curves but tabulates neither) the sum is replaced by a scale
constant K = Σ E·S·Δλ [A m⁻²] taken from Table C.1's 0° value and the active area (digest §2.3).

For the thermopile, whose window is a 5.5 µm long-pass filter, :func:`band_radiance` integrates Planck's law
over a band exactly (series, no quadrature): the physical alternative to the thesis' linear averaging of
temperatures (:mod:`calibration.css.thermopile`).
"""

from __future__ import annotations

import numpy as np
from scipy.special import bernoulli, factorial

from .detectors import DETECTORS, TPS_230, table_c1_current_a

# --------------------------------------------------------------------------------------------------------------
# Constants (SI 2019 exact values)
# --------------------------------------------------------------------------------------------------------------

PLANCK_H = 6.62607015e-34  # J s
SPEED_OF_LIGHT = 299792458.0  # m/s
BOLTZMANN_K = 1.380649e-23  # J/K
#: σ = 2π⁵k⁴/(15h³c²) [W m⁻² K⁻⁴]
STEFAN_BOLTZMANN = 2.0 * np.pi**5 * BOLTZMANN_K**4 / (15.0 * PLANCK_H**3 * SPEED_OF_LIGHT**2)

#: Effective solar temperature of seed 000 §5.2 and listing D.3 [K] (the one its thermopile numbers use).
SUN_TEMPERATURE_K = 5780.0
#: Effective solar temperature of seed 000 ch. 2 [K] (⚠ digest §9.1: 5800 there, 5780 in §5.2/D.3).
SUN_TEMPERATURE_CH2_K = 5800.0
#: Total solar irradiance above the atmosphere at 1 AU [W m⁻²], and its uncertainty (seed 000 ch. 2).
SOLAR_CONSTANT_W_M2 = 1366.0
SOLAR_CONSTANT_UNCERTAINTY_W_M2 = 3.0
#: Angular diameter of the Sun seen from LEO [°] (seed 000 §5.1).
SUN_ANGULAR_DIAMETER_DEG = 0.5
#: Earth's albedo used by eq. 3.2 (measured 30–31 %).
EARTH_ALBEDO = 0.3
#: Earth's mean temperature, its own emission as a black body [K] (ch. 2; listing D.2 uses 288.15 K).
EARTH_TEMPERATURE_K = 288.0
#: Space background [K].
SPACE_TEMPERATURE_K = 3.0
#: Mean Earth radius for the angular size from orbit [m] ([A]: the thesis gives no altitude).
EARTH_RADIUS_M = 6371.0e3

# --------------------------------------------------------------------------------------------------------------
# Planck's law
# --------------------------------------------------------------------------------------------------------------


def planck_spectral_radiance(wavelength_m, temperature_k) -> np.ndarray:
    """Black-body spectral radiance B_λ(T) = 2hc²/λ⁵ / (exp(hc/(λkT)) − 1) [W m⁻² sr⁻¹ m⁻¹].

    Seed 000 ch. 2 names Planck's law (Fig. A.1); the form is the standard one (digest §2.1 [A]).
    """
    lam = np.asarray(wavelength_m, float)
    t = np.asarray(temperature_k, float)
    with np.errstate(over="ignore", divide="ignore"):
        x = PLANCK_H * SPEED_OF_LIGHT / (lam * BOLTZMANN_K * t)
        return 2.0 * PLANCK_H * SPEED_OF_LIGHT**2 / lam**5 / np.expm1(x)


def planck_spectral_exitance(wavelength_m, temperature_k) -> np.ndarray:
    """Black-body spectral exitance M_λ(T) = π·B_λ(T) [W m⁻² m⁻¹] (a Lambertian emitter)."""
    return np.pi * planck_spectral_radiance(wavelength_m, temperature_k)


def blackbody_exitance(temperature_k) -> np.ndarray:
    """Total exitance M = σT⁴ [W m⁻²] (Stefan–Boltzmann, seed 000 ch. 2)."""
    return STEFAN_BOLTZMANN * np.asarray(temperature_k, float) ** 4


_SERIES_TERMS = 60  # exp(−60) ≈ 1e−26: the large-x series is exact to double precision for x ≥ 1
_BERNOULLI = bernoulli(24)


def _planck_tail(x) -> np.ndarray:
    """∫_x^∞ t³/(eᵗ − 1) dt, the dimensionless Planck integral above x = hc/(λkT) (so below λ).

    x ≥ 1: Σ_n e^(−nx)(x³/n + 3x²/n² + 6x/n³ + 6/n⁴); x < 1: π⁴/15 − Σ_k B_k x^(k+3)/(k!(k+3)) (Bernoulli
    numbers, converging for x < 2π).
    """
    x = np.asarray(x, float)
    out = np.empty_like(x)
    big = x >= 1.0
    xb = x[big][..., None]
    n = np.arange(1, _SERIES_TERMS + 1, dtype=float)
    out[big] = np.sum(np.exp(-n * xb) * (xb**3 / n + 3 * xb**2 / n**2 + 6 * xb / n**3 + 6 / n**4), axis=-1)
    xs = x[~big][..., None]
    k = np.arange(len(_BERNOULLI), dtype=float)
    head = np.sum(_BERNOULLI * xs ** (k + 3) / (factorial(k) * (k + 3)), axis=-1)
    out[~big] = np.pi**4 / 15.0 - head
    return out


def band_radiance(temperature_k, wavelength_lo_m=0.0, wavelength_hi_m=np.inf, transmittance=1.0) -> np.ndarray:
    """Black-body radiance in a band, τ·∫_{λ_lo}^{λ_hi} B_λ(T) dλ [W m⁻² sr⁻¹], exactly (series).

    The whole spectrum (0 … ∞) gives σT⁴/π. `transmittance` is a flat in-band transmittance (a filter's
    average). For the TPS 230 see :func:`thermopile_band_radiance`.
    """
    t = np.asarray(temperature_k, float)
    lo = np.asarray(wavelength_lo_m, float)
    hi = np.asarray(wavelength_hi_m, float)
    t, lo, hi = np.broadcast_arrays(t, lo, hi)
    c2 = PLANCK_H * SPEED_OF_LIGHT / BOLTZMANN_K
    with np.errstate(divide="ignore"):
        x_lo = np.where(lo > 0, c2 / (lo * t), np.inf)  # short-wavelength edge ↔ large x
        x_hi = np.where(np.isfinite(hi), c2 / (hi * t), 0.0)
    tail_lo = np.where(np.isfinite(x_lo), _planck_tail(np.where(np.isfinite(x_lo), x_lo, 1.0)), 0.0)
    tail_hi = _planck_tail(x_hi)
    scale = 2.0 * BOLTZMANN_K**4 * t**4 / (PLANCK_H**3 * SPEED_OF_LIGHT**2)
    return np.asarray(transmittance, float) * scale * (tail_hi - tail_lo)


def band_fraction(temperature_k, wavelength_lo_m=0.0, wavelength_hi_m=np.inf) -> np.ndarray:
    """Fraction of a black body's total exitance emitted between the two wavelengths (0 … 1)."""
    return np.pi * band_radiance(temperature_k, wavelength_lo_m, wavelength_hi_m) / blackbody_exitance(temperature_k)


def thermopile_band_radiance(temperature_k, *, thermopile=TPS_230, wavelength_hi_m=np.inf,
                             transmittance=None) -> np.ndarray:
    """Radiance a TPS 230 sees through its long-pass window: from its 5.5 µm cut-on up [W m⁻² sr⁻¹].

    Flat transmittance (default the datasheet's > 77 % average over 7.5–13.5 µm) from the cut-on up to
    `wavelength_hi_m` (∞ by default: the datasheet's transmission curve was lost in extraction, so the long-wave
    end is not known; set it to e.g. 14 µm for a typical absorber). [A] The model is the digest's §8.1 mode B.
    """
    tau = thermopile.passband_transmittance if transmittance is None else transmittance
    return band_radiance(temperature_k, thermopile.cut_on_wavelength_m, wavelength_hi_m, tau)


# --------------------------------------------------------------------------------------------------------------
# Sun and Earth
# --------------------------------------------------------------------------------------------------------------


def sun_spectral_irradiance(wavelength_m, temperature_k=SUN_TEMPERATURE_K,
                            total_irradiance_w_m2=SOLAR_CONSTANT_W_M2) -> np.ndarray:
    """Solar spectral irradiance as a black body of `temperature_k` scaled to `total_irradiance_w_m2` [W m⁻² m⁻¹].

    E_λ = π·B_λ(T) · E_total/(σT⁴): the shape of a black body (seed 000 ch. 2, Fig. 2.2 compares AM0 with
    5800 K), the total of the 1366 W m⁻² solar constant. A stand-in for ASTM E-490 AM0, which the thesis uses
    but does not tabulate.
    """
    return planck_spectral_exitance(wavelength_m, temperature_k) * (
        np.asarray(total_irradiance_w_m2, float) / blackbody_exitance(temperature_k))


def sun_irradiance_from_disc(temperature_k=SUN_TEMPERATURE_K, angular_diameter_deg=SUN_ANGULAR_DIAMETER_DEG):
    """Irradiance of a black-body disc of the given angular diameter, σT⁴·sin²(d/2) [W m⁻²].

    A consistency check of the thesis' round numbers: 5780 K and 0.5° give ≈ 1205 W m⁻², 5780 K and the true
    0.533° give ≈ 1369 W m⁻² (the 0.5° is "about").
    """
    half = np.radians(np.asarray(angular_diameter_deg, float)) / 2.0
    return blackbody_exitance(temperature_k) * np.sin(half) ** 2


def albedo_spectral_irradiance(wavelength_m, albedo=EARTH_ALBEDO, **sun) -> np.ndarray:
    """Sunlight reflected by the Earth as eq. 3.2 counts it: albedo × solar spectral irradiance [W m⁻² m⁻¹].

    Grey albedo (the same at every wavelength); how much of the Earth a detector sees is in S_mean(φ)
    (:func:`calibration.css.angular.albedo_mean_response`), not here. `sun` goes to :func:`sun_spectral_irradiance`.
    """
    return np.asarray(albedo, float) * sun_spectral_irradiance(wavelength_m, **sun)


def earth_spectral_radiance(wavelength_m, temperature_k=EARTH_TEMPERATURE_K) -> np.ndarray:
    """Earth's own (long-wave) emission as a black body, B_λ(T) [W m⁻² sr⁻¹ m⁻¹] (ch. 2: 288 K, peak ≈ 10 µm)."""
    return planck_spectral_radiance(wavelength_m, temperature_k)


def earth_angular_radius_deg(altitude_m, earth_radius_m=EARTH_RADIUS_M) -> np.ndarray:
    """Half-angle of the Earth's disc seen from `altitude_m`, asin(R/(R + h)) [°] (digest §2.2 [A]).

    The thesis gives "about 130°" for the full angle (65° half-angle, h ≈ 660 km) and no altitude.
    """
    h = np.asarray(altitude_m, float)
    return np.degrees(np.arcsin(earth_radius_m / (earth_radius_m + h)))


# --------------------------------------------------------------------------------------------------------------
# Photocurrents: eqs 3.1 and 3.2
# --------------------------------------------------------------------------------------------------------------


def spectral_sum(wavelength_m, power_density, spectral_sensitivity) -> float:
    """K = Σ_i E(λ_i)·S(λ_i)·Δλ_i, Δλ_i = λ_(i+1) − λ_i [A m⁻²] (the sum of seed 000 eqs 3.1/3.2).

    `power_density` in W m⁻² m⁻¹, `spectral_sensitivity` in A/W, on the same ascending wavelength grid [m].
    The printed sum runs i = 1 … n with Δλ = λ_(i+1) − λ_i, undefined for i = n; it runs to n − 1 here
    (a left Riemann sum).
    """
    lam = np.asarray(wavelength_m, float)
    e = np.asarray(power_density, float)
    s = np.asarray(spectral_sensitivity, float)
    if lam.ndim != 1 or lam.shape != e.shape or lam.shape != s.shape or lam.size < 2:
        raise ValueError("wavelength, power density and sensitivity must be 1-D arrays of one length ≥ 2")
    if np.any(np.diff(lam) <= 0):
        raise ValueError("the wavelength grid must be strictly ascending")
    return float(np.sum(e[:-1] * s[:-1] * np.diff(lam)))


def table_c1_scale_constant(detector: str, source: str = "sun", albedo=EARTH_ALBEDO) -> float:
    """The scale K [A m⁻²] that makes eq. 3.1 (`source` ``sun``) or 3.2 (``albedo``) return Table C.1 at 0°.

    Sun: K = I_sun(0°)/A: EPD 6.18 µA/1.2 mm² = 5.15 A m⁻², BPW 1.17 mA/7.5 mm² = 156 A m⁻² (digest §2.3).
    Albedo: K = I_albedo(0°)/(A·albedo) with S_mean(0°) = 1: EPD 3.0 A m⁻², BPW 118 A m⁻². ⚠ Eq. 3.2 would have
    the albedo K equal the Sun K; Table C.1 does not (albedo/Sun at 0° is 0.175 for the EPD and 0.227 for the BPW,
    digest §3.5 finding 3), so the two are kept apart. `detector` is ``uv`` or ``vis``.
    """
    area = DETECTORS[detector].active_area_m2
    current = table_c1_current_a(detector, source)[0]
    return float(current / area) if source == "sun" else float(current / (area * albedo))


def _scale(scale_a_per_m2, spectra, detector, source, albedo) -> float:
    given = [x is not None for x in spectra]
    if all(given):
        if scale_a_per_m2 is not None:
            raise ValueError("give either the spectra or scale_a_per_m2, not both")
        return spectral_sum(*spectra)
    if any(given):
        raise ValueError("give all three of wavelength_m, power_density and spectral_sensitivity, or none")
    if scale_a_per_m2 is not None:
        return float(scale_a_per_m2)
    if detector is None:
        raise ValueError("no spectra and no scale: give scale_a_per_m2 or a detector (uv, vis) for Table C.1's")
    return table_c1_scale_constant(detector, source, albedo)


def sun_photocurrent_a(s_rel, active_area_m2, *, wavelength_m=None, power_density=None, spectral_sensitivity=None,
                       scale_a_per_m2=None, detector: str | None = None) -> np.ndarray:
    """Photocurrent with the Sun in view, I_SUN = S_rel(φ)·A·Σ E·S·Δλ [A] (seed 000 eq. 3.1).

    `s_rel` is the relative angular sensitivity (e.g. :func:`calibration.css.angular.thesis_fov_response`),
    `active_area_m2` the detector area. The sum comes from the spectra when all three are given
    (:func:`spectral_sum`), else from `scale_a_per_m2`, else from Table C.1 for `detector`
    (:func:`table_c1_scale_constant`). (The printed equation writes S_real; the text means S_rel.)
    """
    k = _scale(scale_a_per_m2, (wavelength_m, power_density, spectral_sensitivity), detector, "sun", EARTH_ALBEDO)
    return np.asarray(s_rel, float) * float(active_area_m2) * k


def albedo_photocurrent_a(s_mean, active_area_m2, *, albedo=EARTH_ALBEDO, wavelength_m=None, power_density=None,
                          spectral_sensitivity=None, scale_a_per_m2=None, detector: str | None = None) -> np.ndarray:
    """Photocurrent lit by Earth albedo, I_ALBEDO = S_mean(φ)·A·albedo·Σ E·S·Δλ [A] (seed 000 eq. 3.2).

    `s_mean` is the mean sensitivity over the visible Earth disc at pointing angle φ
    (:func:`calibration.css.angular.albedo_mean_response`). The sum is found as for :func:`sun_photocurrent_a`;
    with `detector` it is Table C.1's albedo scale, so that the result reproduces Table C.1's albedo column.
    """
    k = _scale(scale_a_per_m2, (wavelength_m, power_density, spectral_sensitivity), detector, "albedo", albedo)
    return np.asarray(s_mean, float) * float(active_area_m2) * np.asarray(albedo, float) * k
