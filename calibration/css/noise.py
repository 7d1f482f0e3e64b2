"""Noise of the coarse-sun-sensor detectors: seed 000's chain (§4.1, listings D.1) and a physical model.

Thesis variant — exactly what listings D.1.1–D.1.8 compute (they reproduce §4.1's 7.21, 35.459, 37.529 and
8.3 µV and every entry of Table C.2):

.. math::

    U_n = \\sqrt{(I_b R)^2 + (U_{n,amp}\\sqrt{B})^2 + U_{th}^2 + \\mathrm{NEP}\\sqrt{B}} \\quad (4.6), \\qquad
    \\mathrm{SNR} = 20\\log_{10}\\frac{U_{sig}}{U_n/2} \\quad (4.10)

with U_th² = 4kTBR_in (BPW), the two-impedance eq. 4.11 (EPD, replacing U_th and NEP), or nothing (EPD "NEP"
method), and U_sig = I·R_in (4.9). Where the listings differ from the physics it is kept and said so in a
``# listing:`` comment:

- I_b (350 pA; 50 pA for the TPS) is a bandwidth-free RMS current, so (I_b·R)² has no √B;
- "NEP·√B" is a noise *power* [W] added to squared voltages [V²]: dimensionally wrong (the correct conversion
  is NEP·√B·R_λ·R_in, see the physical variant);
- shot noise is left out (q is defined in every listing but never used);
- the "about 70 °C" worst case is computed at 338.15 K (65 °C), and k = 1.3806e−23 J/K;
- the 16-sample ADC average divides the noise *voltage* by 2 ("power by √16 = 4"); for uncorrelated samples it
  is √16 = 4 in voltage;
- the TPS source resistance is the reference thermistor's R_max1 at the *object* temperature (listings D.1.7/
  D.1.8), not the thermopile's 85–135 kΩ.

Physical variant (:func:`physical_photodiode_noise`, :func:`physical_thermopile_noise`): independent terms added
in quadrature over the noise-equivalent bandwidth B_n = (π/2)·BW of the single-pole stage — shot noise 2q(I + I_d)
B_n, Johnson noise of R_sh ∥ R_in at their own temperatures (eq. 4.11, which is the right formula), amplifier
e_n√B_n and i_n√B_n·Z, the detector's NEP as NEP·√B_n·R_λ·R_in, and ÷√N for an N-sample average. It returns a
:class:`NoiseBudget` whose ``sigma_a`` / ``sigma_v`` a simulator can draw noise from and an estimator weight by.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .detectors import (
    ADC_AVERAGED_SAMPLES,
    BPW_21,
    EPD_365,
    FRONT_END_BPW,
    FRONT_END_EPD,
    FRONT_END_TPS,
    LTC6079,
    TPS_230,
    Amplifier,
    FrontEnd,
    Photodiode,
    Thermopile,
    table_c1_current_a,
)
from .radiation import BOLTZMANN_K

#: Boltzmann's constant as listings D.1 write it [J/K] (the text quotes 1.3806488e−23; SI: 1.380649e−23).
K_BOLTZMANN_LISTINGS = 1.3806e-23
#: Elementary charge [C] (SI exact; the listings' q = 1.602e−19 is never used).
ELEMENTARY_CHARGE = 1.602176634e-19
#: Listing D.1's surface temperatures [°C] and the EPD shunt resistances at them [Ω] (halving per 10 °C).
THESIS_SURFACE_TEMPERATURES_C: tuple[float, ...] = (5.0, 25.0, 45.0, 65.0)
THESIS_SHUNT_RESISTANCES_OHM: tuple[float, ...] = (800e9, 200e9, 50e9, 12.5e9)
#: Listing D.1.2/D.1.3's inside temperatures T_in = 258 + 20·ii, ii = 1 … 4 [K].
THESIS_INSIDE_TEMPERATURES_K: tuple[float, ...] = (278.0, 298.0, 318.0, 338.0)
#: Listing D.1's °C → K offset.
_KELVIN = 273.15
#: The listings' averaging divisor of the noise voltage (eq. 4.10).
THESIS_AVERAGING_DIVISOR = 2.0
#: Table C.2's columns, in its order.
TABLE_C2_COLUMNS: tuple[str, ...] = ("epd_albedo_2imp", "epd_albedo_nep", "epd_sun_2imp", "epd_sun_nep",
                                     "bpw_albedo", "bpw_sun")

# --------------------------------------------------------------------------------------------------------------
# Thesis variant (listings D.1)
# --------------------------------------------------------------------------------------------------------------


def two_impedance_thermal_noise_v2(bandwidth_hz, r_sh_ohm, t_sh_k, r_in_ohm, t_in_k, k=BOLTZMANN_K) -> np.ndarray:
    """Thermal noise of R_sh (at T1) in parallel with R_in (at T2), U_th² = 4kB(T1/R_sh + T2/R_in)/(1/R_sh + 1/R_in)²
    [V²] (seed 000 eq. 4.11; listing D.1.2 line 21).

    Physically sound: each resistor's Johnson current noise 4kT/R, through the parallel impedance. (Eq. 4.11 is
    printed as U_th; it is U_th².)
    """
    g_sh = 1.0 / np.asarray(r_sh_ohm, float)
    g_in = 1.0 / np.asarray(r_in_ohm, float)
    b = np.asarray(bandwidth_hz, float)
    return 4.0 * k * b * (np.asarray(t_sh_k, float) * g_sh + np.asarray(t_in_k, float) * g_in) / (g_sh + g_in) ** 2


def _thesis_epd_common_v2(bandwidth_hz, r_in_ohm, shunt_resistances_ohm, amplifier):
    r_sh = np.asarray(shunt_resistances_ohm, float)
    r_p = np.max(r_in_ohm * r_sh / (r_in_ohm + r_sh))  # listing: Rp = max(Rin∥Rsh) ≈ Rin, the coldest point
    u_b2 = (amplifier.thesis_noise_current_a * r_p) ** 2  # listing: I_b·R with no √B (an RMS current, not a density)
    u_nz2 = (amplifier.voltage_noise_v_per_rthz * np.sqrt(bandwidth_hz)) ** 2
    return u_b2 + u_nz2


def thesis_epd_noise_nep_v(bandwidth_hz=FRONT_END_EPD.bandwidth_hz, r_in_ohm=FRONT_END_EPD.r_in_ohm, *,
                           detector: Photodiode = EPD_365, amplifier: Amplifier = LTC6079,
                           shunt_resistances_ohm=THESIS_SHUNT_RESISTANCES_OHM) -> float:
    """EPD noise voltage, "NEP method" [V RMS, before averaging] (listings D.1.1/D.1.4; §4.1: 35.459 µV).

    U_n = √((I_b·R_p)² + (U_n√B)² + NEP·√B), R_p = max over the R_sh points of R_in ∥ R_sh.
    """
    # listing: "Uthmax2 = 1.8e-14*sqrt(B)" — NEP·√B is a power [W] added as if it were a voltage squared [V²];
    # and the thermal noise of R_in is left out of this method
    nep_term = detector.nep_w_per_rthz * np.sqrt(bandwidth_hz)
    return float(np.sqrt(_thesis_epd_common_v2(bandwidth_hz, r_in_ohm, shunt_resistances_ohm, amplifier) + nep_term))


def thesis_epd_noise_two_impedance_v(bandwidth_hz=FRONT_END_EPD.bandwidth_hz, r_in_ohm=FRONT_END_EPD.r_in_ohm, *,
                                     amplifier: Amplifier = LTC6079,
                                     shunt_resistances_ohm=THESIS_SHUNT_RESISTANCES_OHM,
                                     surface_temperatures_c=THESIS_SURFACE_TEMPERATURES_C,
                                     inside_temperatures_k=THESIS_INSIDE_TEMPERATURES_K,
                                     k=K_BOLTZMANN_LISTINGS) -> float:
    """EPD noise voltage, "two-impedance method" [V RMS, before averaging] (listings D.1.2/D.1.3; §4.1: 37.529 µV).

    U_n = √((I_b·R_p)² + (U_n√B)² + max U_th²), the maximum of eq. 4.11 over the four (R_sh, T1) points and the
    four T2 = T_in (the listing's worst case: 12.5 GΩ, 338 K).
    """
    t_sh = np.asarray(surface_temperatures_c, float) + _KELVIN
    r_sh = np.asarray(shunt_resistances_ohm, float)
    u_th2 = max(float(np.max(two_impedance_thermal_noise_v2(bandwidth_hz, r_sh, t_sh, r_in_ohm, t_in, k)))
                for t_in in inside_temperatures_k)
    return float(np.sqrt(_thesis_epd_common_v2(bandwidth_hz, r_in_ohm, shunt_resistances_ohm, amplifier) + u_th2))


def thesis_bpw_noise_v(bandwidth_hz=FRONT_END_BPW.bandwidth_hz, r_in_ohm=FRONT_END_BPW.r_in_ohm, *,
                       detector: Photodiode = BPW_21, amplifier: Amplifier = LTC6079,
                       surface_temperatures_c=THESIS_SURFACE_TEMPERATURES_C, k=K_BOLTZMANN_LISTINGS) -> float:
    """BPW noise voltage [V RMS, before averaging] (seed 000 eq. 4.6, listings D.1.5/D.1.6; §4.1: 7.21 µV).

    U_n = √((I_b·R_in)² + (U_n√B)² + max_T 4kTBR_in + NEP·√B), T = 5 … 65 °C (so 338.15 K).
    """
    b = bandwidth_hz
    u_b2 = (amplifier.thesis_noise_current_a * r_in_ohm) ** 2  # listing: no √B on the noise current
    u_nz2 = (amplifier.voltage_noise_v_per_rthz * np.sqrt(b)) ** 2
    # listing: the "70 °C worst case" of §4.1 is max(TK) = 338.15 K, i.e. 65 °C
    u_th2 = float(np.max(4.0 * k * (np.asarray(surface_temperatures_c, float) + _KELVIN) * b * r_in_ohm))
    nep_term = detector.nep_w_per_rthz * np.sqrt(b)  # listing: a power [W] added to V² (should be NEP·√B·R_λ·R_in)
    return float(np.sqrt(u_b2 + u_nz2 + u_th2 + nep_term))


def thesis_tps_noise_v(source_resistance_ohm, bandwidth_hz=FRONT_END_TPS.bandwidth_hz, *,
                       thermopile: Thermopile = TPS_230, amplifier: Amplifier = LTC6079) -> np.ndarray:
    """TPS noise voltage [V RMS, before averaging] (listings D.1.7/D.1.8; §4.1: 8.3 µV at 0°, 48 µV at 35°).

    U_n = √((e_TPS√B)² + (U_n√B)² + (I_b·R1)²), e_TPS = 40 nV/√Hz, I_b = 50 pA, R1 = `source_resistance_ohm`.
    The listings take R1 from :func:`thesis_tps_source_resistance`.
    """
    b = bandwidth_hz
    un1 = (thermopile.noise_density_v_per_rthz * np.sqrt(b)) ** 2  # listing calls it "equivalent noise power"; V²
    un3 = amplifier.voltage_noise_v_per_rthz * np.sqrt(b)
    # listing: I_b = 50 pA here against 350 pA for the photodiodes, again without √B
    un4 = amplifier.thesis_noise_current_tps_a * np.asarray(source_resistance_ohm, float)
    return np.sqrt(un1 + un3**2 + un4**2)


def thesis_tps_source_resistance(object_temperature_c, *, thermopile: Thermopile = TPS_230) -> np.ndarray:
    """R1 of listings D.1.7/D.1.8: the thermistor's Table 6 R_max1 at the *object's* temperature [Ω].

    163,900 Ω at 15 °C (Earth at 0°) and 968,201 Ω at −20 °C (Earth at 35°). ⚠ The thermistor measures the
    housing, and the thermopile's own resistance is 85–135 kΩ (digest §9.10); kept to reproduce the thesis.
    """
    return thermopile.thermistor_resistance(object_temperature_c, column="max1")


def thesis_snr_db(signal_v, noise_v, averaging_divisor=THESIS_AVERAGING_DIVISOR) -> np.ndarray:
    """SNR = 20·log10(U_sig/(U_n/2)) [dB] (seed 000 eq. 4.10).

    The listings divide the noise voltage by 2 for the ADC's 16-sample average ("power by √16"); for
    uncorrelated samples the voltage falls by √16 = 4 (pass 4 to get that).
    """
    return 20.0 * np.log10(np.asarray(signal_v, float) / (np.asarray(noise_v, float) / averaging_divisor))


def thesis_snr_table(*, epd_sun_a=None, epd_albedo_a=None, bpw_sun_a=None, bpw_albedo_a=None) -> dict[str, np.ndarray]:
    """Table C.2: SNR [dB] at 0 … 85° (18 rows) for the six columns of :data:`TABLE_C2_COLUMNS`.

    Currents default to Table C.1 (BPW Sun at 30° corrected to 0.898 mA; pass
    ``table_c1_current_a("vis", "sun", printed=True)`` for the printed 0.868 mA). Each column as its listing:
    D.1.2, D.1.1, D.1.3, D.1.4, D.1.5, D.1.6. Listing D.1 loops i = 1:18, so there is no 90° row.
    """
    def rows(given, detector, source):
        return np.asarray(table_c1_current_a(detector, source) if given is None else given, float)[:18]

    r_epd, r_bpw = FRONT_END_EPD.r_in_ohm, FRONT_END_BPW.r_in_ohm
    two_imp, nep, bpw = thesis_epd_noise_two_impedance_v(), thesis_epd_noise_nep_v(), thesis_bpw_noise_v()
    epd_alb, epd_sun = rows(epd_albedo_a, "uv", "albedo"), rows(epd_sun_a, "uv", "sun")
    return {
        "epd_albedo_2imp": thesis_snr_db(epd_alb * r_epd, two_imp),
        "epd_albedo_nep": thesis_snr_db(epd_alb * r_epd, nep),
        "epd_sun_2imp": thesis_snr_db(epd_sun * r_epd, two_imp),
        "epd_sun_nep": thesis_snr_db(epd_sun * r_epd, nep),
        "bpw_albedo": thesis_snr_db(rows(bpw_albedo_a, "vis", "albedo") * r_bpw, bpw),
        "bpw_sun": thesis_snr_db(rows(bpw_sun_a, "vis", "sun") * r_bpw, bpw),
    }


# --------------------------------------------------------------------------------------------------------------
# Physical variant
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class NoiseBudget:
    """RMS noise terms at the amplifier input, each over the noise bandwidth of one sample [V], and their total.

    Attributes
    ----------
    shot_v, johnson_v, amplifier_voltage_v, amplifier_current_v, nep_v : ndarray
        The terms (zeros where a term does not apply; the thermopile's own Johnson noise is ``johnson_v``).
    total_v : ndarray
        √(sum of squares) for one sample.
    sigma_v : ndarray
        ``total_v`` after averaging ``n_average`` uncorrelated samples (÷√N): the σ of one reading [V].
    sigma_a : ndarray
        ``sigma_v`` referred to the photocurrent as the bench reads it, σ_V/R_in [A]; NaN for the thermopile.
    signal_v : ndarray
        The signal at the amplifier input [V] (I·(R_sh ∥ R_in), or the thermopile voltage given).
    noise_bandwidth_hz : float
    n_average : int
    """

    shot_v: np.ndarray
    johnson_v: np.ndarray
    amplifier_voltage_v: np.ndarray
    amplifier_current_v: np.ndarray
    nep_v: np.ndarray
    total_v: np.ndarray
    sigma_v: np.ndarray
    sigma_a: np.ndarray
    signal_v: np.ndarray
    noise_bandwidth_hz: float
    n_average: int

    @property
    def snr_db(self) -> np.ndarray:
        """20·log10(signal/σ) of one averaged reading [dB]."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.signal_v) / self.sigma_v)


def physical_photodiode_noise(photocurrent_a, detector: Photodiode = BPW_21, front_end: FrontEnd = FRONT_END_BPW, *,
                              amplifier: Amplifier = LTC6079, surface_temperature_c=25.0, inside_temperature_c=25.0,
                              dark_current_a=0.0, n_average: int = ADC_AVERAGED_SAMPLES,
                              noise_bandwidth_factor=np.pi / 2, include_nep: bool = True) -> NoiseBudget:
    """Physical noise of a photodiode in photovoltaic mode across its load R_in [V, A] (digest §8.1, [A]).

    With Z = R_sh(T1) ∥ R_in and B_n = `noise_bandwidth_factor`·BW (π/2: the noise bandwidth of a single-pole
    stage; 1 gives the thesis' B):

    - shot noise √(2q(I + I_d)B_n)·Z — missing from the thesis (q unused in listings D.1);
    - Johnson noise of R_sh at T1 (the surface) and R_in at T2 (inside) in parallel, eq. 4.11;
    - amplifier e_n√B_n and i_n√B_n·Z (i_n: :class:`~calibration.css.detectors.Amplifier`);
    - the detector's NEP converted to a voltage, NEP·√B_n·R_λ·R_in (the thesis adds NEP·√B, in W, to V²).
      The datasheet NEP already contains the diode's own dark noise, so it overlaps the two terms above for a
      dark diode; `include_nep` can drop it. At any useful signal shot noise dominates it by orders of magnitude.

    The σ of one reading is the total ÷√`n_average` (uncorrelated samples; the thesis uses ÷2 for 16).
    `photocurrent_a` may be an array; the terms broadcast.
    """
    i = np.asarray(photocurrent_a, float)
    r_in = float(front_end.r_in_ohm)
    t1 = np.asarray(surface_temperature_c, float) + _KELVIN
    t2 = np.asarray(inside_temperature_c, float) + _KELVIN
    r_sh = detector.shunt_resistance(surface_temperature_c)
    z = r_sh * r_in / (r_sh + r_in)
    b = noise_bandwidth_factor * front_end.bandwidth_hz
    shot = np.sqrt(2.0 * ELEMENTARY_CHARGE * np.abs(i + np.asarray(dark_current_a, float)) * b) * z
    johnson = np.sqrt(two_impedance_thermal_noise_v2(b, r_sh, t1, r_in, t2))
    amp_v = amplifier.voltage_noise_v_per_rthz * np.sqrt(b)
    amp_i = amplifier.current_noise_a_per_rthz * np.sqrt(b) * z
    nep = detector.nep_w_per_rthz * np.sqrt(b) * detector.responsivity_a_per_w * r_in if include_nep else 0.0
    shot, johnson, amp_v, amp_i, nep = np.broadcast_arrays(shot, johnson, amp_v, amp_i, nep)
    total = np.sqrt(shot**2 + johnson**2 + amp_v**2 + amp_i**2 + nep**2)
    sigma = total / np.sqrt(n_average)
    return NoiseBudget(shot_v=shot, johnson_v=johnson, amplifier_voltage_v=amp_v, amplifier_current_v=amp_i,
                       nep_v=nep, total_v=total, sigma_v=sigma, sigma_a=sigma / r_in, signal_v=i * z,
                       noise_bandwidth_hz=float(b), n_average=int(n_average))


def physical_thermopile_noise(signal_v=0.0, thermopile: Thermopile = TPS_230, front_end: FrontEnd = FRONT_END_TPS, *,
                              amplifier: Amplifier = LTC6079, temperature_c=25.0, resistance_ohm=None,
                              n_average: int = ADC_AVERAGED_SAMPLES, noise_bandwidth_factor=np.pi / 2) -> NoiseBudget:
    """Physical noise of the thermopile into its preamplifier [V] (digest §8.1, [A]).

    Johnson noise of the thermopile: the datasheet's 40 nV/√Hz (≈ √(4kTR) of ≈ 100 kΩ at 25 °C) unless
    `resistance_ohm` is given, then √(4kTR) at `temperature_c`; amplifier e_n and i_n·R_TP (R_TP the middle of
    85–135 kΩ when not given); over B_n = `noise_bandwidth_factor`·BW; ÷√`n_average`. The source is the
    thermopile, not the thermistor the thesis uses (listings D.1.7/D.1.8). `signal_v` is the thermopile
    voltage, for the SNR only.
    """
    b = noise_bandwidth_factor * front_end.bandwidth_hz
    if resistance_ohm is None:
        r_tp = float(np.mean(thermopile.resistance_range_ohm))
        johnson = thermopile.noise_density_v_per_rthz * np.sqrt(b)
    else:
        r_tp = float(resistance_ohm)
        johnson = np.sqrt(4.0 * BOLTZMANN_K * (np.asarray(temperature_c, float) + _KELVIN) * r_tp * b)
    amp_v = amplifier.voltage_noise_v_per_rthz * np.sqrt(b)
    amp_i = amplifier.current_noise_a_per_rthz * np.sqrt(b) * r_tp
    signal, johnson, amp_v, amp_i = np.broadcast_arrays(np.asarray(signal_v, float), johnson, amp_v, amp_i)
    zero = np.zeros_like(signal)
    total = np.sqrt(johnson**2 + amp_v**2 + amp_i**2)
    sigma = total / np.sqrt(n_average)
    return NoiseBudget(shot_v=zero, johnson_v=johnson, amplifier_voltage_v=amp_v, amplifier_current_v=amp_i,
                       nep_v=zero, total_v=total, sigma_v=sigma, sigma_a=np.full_like(signal, np.nan),
                       signal_v=signal, noise_bandwidth_hz=float(b), n_average=int(n_average))


def thermopile_temperature_noise_k(sigma_v, object_temperature_c, *, thermopile: Thermopile = TPS_230) -> np.ndarray:
    """A thermopile voltage noise as an object-temperature noise, σ_T = σ_V/(dV/dT_obj) [K] (Table 4 slope).

    §4.4 says 8.3 µV moves the measured temperature by about 1 °C; the Table 4 slope near 15 °C (≈ 23 µV/K)
    makes it ≈ 0.36 K (digest §9.11). NaN outside Table 4's −20 … 120 °C.
    """
    return np.asarray(sigma_v, float) / thermopile.output_slope(object_temperature_c)


def snr_db(signal, sigma) -> np.ndarray:
    """20·log10(|signal|/σ) [dB] (no averaging divisor: put it in σ)."""
    return 20.0 * np.log10(np.abs(np.asarray(signal, float)) / np.asarray(sigma, float))
