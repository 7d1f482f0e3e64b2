"""Datasheet constants of the three coarse-sun-sensor detectors, their front ends, and Table C.1 (seed 000).

Each face of seed 000's cube carries a triplet (digest §3.1): an EPD-365-0-1.4 UV photodiode (channel ``uv``),
a BPW 21 visible photodiode (``vis``) and a TPS 230 thermopile (``ir``). The photodiodes run in photovoltaic
mode into a load R_in; every detector feeds an LTC6079 non-inverting preamplifier (gain eq. 4.1, bandwidth
eq. 4.2) and an ADuC842 ADC that averages 16 samples (seed 000 §4.1).

=================  =======================================================================================
object             what it holds
=================  =======================================================================================
``EPD_365``        :class:`Photodiode`, appendix B.2 (digest §3.2), the R_sh(T) halving rule of listing D.1.3
``BPW_21``         :class:`Photodiode`, appendix B.3 (digest §3.3)
``TPS_230``        :class:`Thermopile`, appendix B.1 (digest §3.4): Table 4 (V_out vs T_obj), Table 6 (thermistor)
``LTC6079``        :class:`Amplifier`: GBW 360 kHz, the listings' noise constants
``FRONT_ENDS``     :class:`FrontEnd` per channel (R1, R2, R_in; §4.1, listings D.1)
``TABLE_C1_*``     Table C.1: photocurrents vs incidence angle, Sun and albedo (read-only arrays)
=================  =======================================================================================

Values tagged [A] in a comment are not in the thesis (derived or assumed here); everything else is quoted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

# --------------------------------------------------------------------------------------------------------------
# Photodiodes
# --------------------------------------------------------------------------------------------------------------

#: The temperature every datasheet value below refers to [°C].
DATASHEET_TEMPERATURE_C = 25.0


@dataclass(frozen=True)
class Photodiode:
    """Datasheet constants of a photodiode run in photovoltaic mode (seed 000 §3.1, appendix B).

    Attributes
    ----------
    name, channel : str
        Part name and the head's detector type (``uv`` or ``vis``).
    active_area_m2 : float
        The area eq. 3.1/3.2 use [m²] (seed 000 §3.2: EPD 1.2 mm², BPW 7.5 mm²).
    datasheet_area_m2 : float
        The datasheet's radiant-sensitive area [m²] (BPW 21: 7.34 mm², digest §9.3).
    peak_wavelength_m : float
        Wavelength of peak responsivity [m].
    spectral_range_m : (float, float)
        Sensitivity range [m] (EPD: 1 % points; BPW: 10 % points).
    responsivity_a_per_w : float
        Spectral responsivity at the peak [A/W].
    nep_w_per_rthz : float
        Noise-equivalent power [W/√Hz].
    detectivity_cm_rthz_per_w : float
        Specific detectivity D* [cm·√Hz/W].
    capacitance_f : float
        Junction capacitance at 0 V [F].
    shunt_resistance_25c_ohm : float
        Shunt resistance at 25 °C [Ω].
    dark_current_a : float
        Typical dark current at the datasheet bias ``dark_current_bias_v`` [A].
    dark_current_bias_v : float
        The reverse bias that dark current is specified at [V].
    tc_dark_current_per_k : float
        Relative temperature coefficient of the dark current [1/K].
    tc_short_circuit_current_per_k : float | None
        Relative temperature coefficient of the photocurrent I_SC [1/K] (BPW 21: −0.05 %/K).
    tc_open_circuit_voltage_v_per_k : float | None
        Temperature coefficient of the open-circuit voltage [V/K] (BPW 21: −2.6 mV/K).
    half_angle_deg : float | None
        Half angle of the directional characteristic at 50 % [°] (BPW 21: ±55°).
    acceptance_angle_deg : float | None
        "Acceptance angle at 50 % S_λ" as printed (EPD: 50°; the datasheet does not say full or half angle).
    spectral_bandwidth_m : float | None
        Spectral bandwidth at 50 % [m] (EPD: 85 nm).
    photometric_sensitivity_a_per_lx : float | None
        Photocurrent per illuminance [A/lx] (BPW 21: 10 nA/lx, ≥ 5.5, at V_R = 5 V, illuminant A).
    """

    name: str
    channel: str
    active_area_m2: float
    datasheet_area_m2: float
    peak_wavelength_m: float
    spectral_range_m: tuple[float, float]
    responsivity_a_per_w: float
    nep_w_per_rthz: float
    detectivity_cm_rthz_per_w: float
    capacitance_f: float
    shunt_resistance_25c_ohm: float
    dark_current_a: float
    dark_current_bias_v: float
    tc_dark_current_per_k: float
    tc_short_circuit_current_per_k: float | None = None
    tc_open_circuit_voltage_v_per_k: float | None = None
    half_angle_deg: float | None = None
    acceptance_angle_deg: float | None = None
    spectral_bandwidth_m: float | None = None
    photometric_sensitivity_a_per_lx: float | None = None

    def shunt_resistance(self, temperature_c) -> np.ndarray:
        """Shunt resistance at `temperature_c` [Ω]: halves for every 10 °C rise (seed 000 §4.1, listing D.1.3).

        R_sh(T) = R_sh(25 °C) · 2^(−(T − 25 °C)/10); for the EPD this gives the listings' 800, 200, 50 and
        12.5 GΩ at 5, 25, 45 and 65 °C. (The EPD datasheet itself does not state the rule; for the BPW 21 it
        is assumed [A].)
        """
        t = np.asarray(temperature_c, float)
        return self.shunt_resistance_25c_ohm * 2.0 ** (-(t - DATASHEET_TEMPERATURE_C) / 10.0)

    def dark_current(self, temperature_c) -> np.ndarray:
        """Dark current at `temperature_c` [A], compounding ``tc_dark_current_per_k`` from 25 °C (datasheet)."""
        t = np.asarray(temperature_c, float)
        return self.dark_current_a * (1.0 + self.tc_dark_current_per_k) ** (t - DATASHEET_TEMPERATURE_C)


#: EPIGAP EPD-365-0-1.4, GaP Schottky UV photodiode (appendix B.2, preliminary datasheet 11.04.2007).
EPD_365 = Photodiode(
    name="EPD-365-0-1.4",
    channel="uv",
    active_area_m2=1.2e-6,
    datasheet_area_m2=1.2e-6,
    peak_wavelength_m=365e-9,
    spectral_range_m=(245e-9, 400e-9),
    responsivity_a_per_w=0.07,
    nep_w_per_rthz=1.8e-14,
    detectivity_cm_rthz_per_w=5.9e12,
    capacitance_f=250e-12,
    shunt_resistance_25c_ohm=200e9,  # typ. (150 GΩ min) at V_R = 10 mV
    dark_current_a=5e-12,  # at V_R = 5 V (30 pA max)
    dark_current_bias_v=5.0,
    tc_dark_current_per_k=0.07,
    acceptance_angle_deg=50.0,
    spectral_bandwidth_m=85e-9,
)

#: Siemens BPW 21 silicon photodiode, V_λ-matched (appendix B.3; T_A = 25 °C, standard illuminant A).
BPW_21 = Photodiode(
    name="BPW 21",
    channel="vis",
    active_area_m2=7.5e-6,  # the thesis' eq. 3.1 value; the datasheet says 7.34 mm² (digest §9.3)
    datasheet_area_m2=7.34e-6,
    peak_wavelength_m=550e-9,
    spectral_range_m=(350e-9, 820e-9),
    responsivity_a_per_w=0.34,
    nep_w_per_rthz=7.2e-14,
    detectivity_cm_rthz_per_w=1e12,
    capacitance_f=580e-12,
    # [A] not in the datasheet: 10 mV / 8 pA (its dark current at V_R = 10 mV), a small-signal estimate
    shunt_resistance_25c_ohm=10e-3 / 8e-12,
    dark_current_a=8e-12,  # at V_R = 10 mV (2 nA at 5 V)
    dark_current_bias_v=10e-3,
    # [A] not in the datasheet: silicon dark current doubling per 10 K, consistent with the R_sh halving rule
    tc_dark_current_per_k=2.0 ** 0.1 - 1.0,
    tc_short_circuit_current_per_k=-0.0005,
    tc_open_circuit_voltage_v_per_k=-2.6e-3,
    half_angle_deg=55.0,
    photometric_sensitivity_a_per_lx=10e-9,
)

# --------------------------------------------------------------------------------------------------------------
# Thermopile
# --------------------------------------------------------------------------------------------------------------

#: Table 4 of the TPS 230 datasheet: object temperature [°C] (sensor at 25 °C) ...
TPS_TABLE4_T_OBJ_C: tuple[float, ...] = (-20, -10, 0, 10, 20, 25, 30, 40, 50, 60, 70, 80, 90, 100, 120)
#: ... and typical thermopile output voltage [V].
TPS_TABLE4_V_OUT_V: tuple[float, ...] = tuple(v * 1e-3 for v in (
    -0.94, -0.77, -0.58, -0.36, -0.13, 0.00, 0.13, 0.42, 0.73, 1.06, 1.43, 1.82, 2.24, 2.68, 3.66))

#: Table 6 of the TPS 230 datasheet, thermistor resistance [Ω]: temperatures [°C] ...
THERMISTOR_TABLE6_T_C: tuple[float, ...] = tuple(float(t) for t in range(-20, 101, 5))
#: ... and the five columns. R_min1/R_max1: total-tolerance limits; R_min2/R_max2: β-tolerance limits.
THERMISTOR_TABLE6_OHM: dict[str, tuple[float, ...]] = {
    "min1": (862756, 655207, 501697, 387196, 301098, 235852, 186038, 147731, 118070, 95000, 76707, 62328, 50926,
             41833, 34541, 28662, 23898, 20017, 16842, 14231, 12075, 10286, 8796, 7550, 6504),
    "min2": (909418, 690548, 528693, 407985, 317232, 248468, 195972, 155608, 124357, 100000, 80791, 65649, 53643,
             44067, 36387, 30195, 25176, 21089, 17744, 14994, 12721, 10838, 9268, 7956, 6853),
    "nom": (915479, 694575, 531349, 409715, 318336, 249149, 196369, 155815, 124439, 100000, 80843, 65732, 53743,
            44175, 36497, 30303, 25280, 21187, 17836, 15079, 12800, 10910, 9334, 8016, 6908),
    "max2": (921581, 698625, 534018, 411452, 319444, 249832, 196767, 156022, 124521, 100000, 80895, 65815, 53843,
             44283, 36608, 30412, 25385, 21286, 17928, 15165, 12879, 10983, 9401, 8077, 6964),
    "max1": (968201, 733944, 561001, 432234, 335574, 262445, 206701, 163900, 130808, 105000, 84978, 69137, 56559,
             46516, 38453, 31944, 26663, 22357, 18830, 15927, 13526, 11534, 9872, 8481, 7313),
}


@dataclass(frozen=True)
class Thermopile:
    """Datasheet constants of the PerkinElmer TPS 230 / 3365 thermopile (appendix B.1, rev. 2007-11-12).

    Attributes
    ----------
    sensitive_area_m2 : float
        Absorber area [m²] (0.2 mm², Ø 0.5 mm).
    resistance_range_ohm : (float, float)
        Thermopile resistance R_TP, min and max [Ω].
    responsivity_v_per_w : float
        S_v at T_obj 500 K, T_amb 298 K, 1 Hz [V/W].
    average_sensitivity_v_per_k : ((float, float), ...)
        (T_obj [K], ΔU/ΔT [V/K]) pairs at T_amb 298 K.
    time_constant_s : float
    noise_density_v_per_rthz : float
        Noise voltage [V/√Hz] (≈ Johnson noise of R_TP ≈ 100 kΩ at 25 °C).
    tc_resistance_per_k, tc_sensitivity_per_k : float
        Relative temperature coefficients of R_TP and of the sensitivity [1/K].
    field_of_view_deg : float
        Full field of view at 50 % target signal [°].
    optical_axis_tolerance_deg : float
    cut_on_wavelength_m, cut_on_range_m : float, (float, float)
        Long-pass filter cut-on (5 % point) at 25 °C, typical and its limits [m].
    passband_transmittance : float
        Average transmittance over ``passband_m`` (> 77 %, 75 % min).
    passband_m : (float, float)
    blocking_transmittance : float
        Upper bound of the average transmittance below ``blocking_below_m`` (< 0.5 % below 5 µm).
    blocking_below_m : float
    reference_temperature_c : float
        Ambient (sensor) temperature of Table 4 [°C].
    thermistor_r25_ohm, thermistor_beta_k, thermistor_beta_tolerance : float
        Reference thermistor: R25, β (defined 25/100 °C) and its relative tolerance.
    """

    sensitive_area_m2: float = 0.2e-6
    resistance_range_ohm: tuple[float, float] = (85e3, 135e3)
    responsivity_v_per_w: float = 42.0
    average_sensitivity_v_per_k: tuple[tuple[float, float], ...] = ((313.0, 28e-6), (373.0, 36e-6))
    time_constant_s: float = 15e-3
    noise_density_v_per_rthz: float = 40e-9
    tc_resistance_per_k: float = 0.0003
    tc_sensitivity_per_k: float = -0.0005
    field_of_view_deg: float = 82.0
    optical_axis_tolerance_deg: float = 10.0
    cut_on_wavelength_m: float = 5.5e-6
    cut_on_range_m: tuple[float, float] = (5.2e-6, 5.8e-6)
    passband_transmittance: float = 0.77
    passband_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    blocking_transmittance: float = 0.005
    blocking_below_m: float = 5e-6
    reference_temperature_c: float = 25.0
    thermistor_r25_ohm: float = 100e3
    thermistor_beta_k: float = 3964.0
    thermistor_beta_tolerance: float = 0.003

    def output_voltage(self, object_temperature_c) -> np.ndarray:
        """Typical output voltage for an object at `object_temperature_c`, sensor at 25 °C [V] (Table 4).

        Monotone cubic (pchip) interpolation through Table 4, −20 … 120 °C; NaN outside (the thesis decided
        not to extrapolate the curve, seed 000 §5.2).
        """
        curve = PchipInterpolator(TPS_TABLE4_T_OBJ_C, TPS_TABLE4_V_OUT_V, extrapolate=False)
        return curve(np.asarray(object_temperature_c, float))

    def output_slope(self, object_temperature_c) -> np.ndarray:
        """dV_out/dT_obj of the Table 4 curve at `object_temperature_c` [V/K] (NaN outside −20 … 120 °C)."""
        curve = PchipInterpolator(TPS_TABLE4_T_OBJ_C, TPS_TABLE4_V_OUT_V, extrapolate=False)
        return curve.derivative()(np.asarray(object_temperature_c, float))

    def thermistor_resistance(self, temperature_c, column: str = "nom") -> np.ndarray:
        """Thermistor resistance from Table 6 [Ω]; exact at its 5 °C nodes, log-linear between, NaN outside.

        `column` is one of ``min1``, ``min2``, ``nom``, ``max2``, ``max1`` (listings D.1.7/D.1.8 use ``max1``).
        """
        if column not in THERMISTOR_TABLE6_OHM:
            raise ValueError(f"no Table 6 column {column!r} (columns: {', '.join(THERMISTOR_TABLE6_OHM)})")
        t = np.asarray(temperature_c, float)
        nodes = np.asarray(THERMISTOR_TABLE6_T_C)
        table = np.asarray(THERMISTOR_TABLE6_OHM[column], float)
        r = np.exp(np.interp(t, nodes, np.log(table), left=np.nan, right=np.nan))
        idx = np.clip(np.searchsorted(nodes, t), 0, nodes.size - 1)
        return np.where(nodes[idx] == t, table[idx], r)  # the table's own value at a node, not exp(log(R))

    def thermistor_beta_resistance(self, temperature_c) -> np.ndarray:
        """Thermistor resistance from the β model R = R25·exp(β (1/T − 1/T25)) [Ω] (datasheet Table 5)."""
        t_k = np.asarray(temperature_c, float) + 273.15
        return self.thermistor_r25_ohm * np.exp(self.thermistor_beta_k * (1.0 / t_k - 1.0 / 298.15))


#: PerkinElmer TPS 230 / 3365.
TPS_230 = Thermopile()

#: The detectors by the head's detector type (calibration.css.head.DETECTORS).
DETECTORS: dict[str, Photodiode | Thermopile] = {"uv": EPD_365, "vis": BPW_21, "ir": TPS_230}

# --------------------------------------------------------------------------------------------------------------
# Amplifier, ADC and front ends
# --------------------------------------------------------------------------------------------------------------


def non_inverting_gain(r1_ohm, r2_ohm):
    """Gain of the non-inverting preamplifier, G = 1 + R2/R1 (seed 000 eq. 4.1)."""
    return 1.0 + np.asarray(r2_ohm, float) / np.asarray(r1_ohm, float)


def amplifier_bandwidth_hz(gbw_hz, gain):
    """Closed-loop bandwidth BW = GBW/G [Hz] (seed 000 eq. 4.2)."""
    return np.asarray(gbw_hz, float) / np.asarray(gain, float)


@dataclass(frozen=True)
class Amplifier:
    """The preamplifier's constants as seed 000 uses them (§4.1, listings D.1).

    Attributes
    ----------
    gbw_hz : float
        Gain-bandwidth product over the whole operating range (LTC6079 datasheet, quoted in §4.1).
    voltage_noise_v_per_rthz : float
        Input voltage-noise density U_n [V/√Hz] (18 nV/√Hz, §4.1).
    thesis_noise_current_a : float
        "Amplifier noise current" I_b of listings D.1.1–D.1.6 [A] (350 pA). The listings use it as a
        bandwidth-free RMS current (U_b = I_b·R).
    thesis_noise_current_tps_a : float
        The same constant in listings D.1.7/D.1.8 [A] (50 pA; ⚠ inconsistent with the 350 pA above).
    current_noise_a_per_rthz : float
        Input current-noise density [A/√Hz] for the physical noise model. [A] Not in the thesis; the LTC6079
        has CMOS inputs, whose current noise (fA/√Hz) is negligible against 18 nV/√Hz on these source
        impedances, so 0 by default. Set it from the datasheet when one is at hand.
    """

    name: str = "LTC6079"
    gbw_hz: float = 360e3
    voltage_noise_v_per_rthz: float = 18e-9
    thesis_noise_current_a: float = 350e-12
    thesis_noise_current_tps_a: float = 50e-12
    current_noise_a_per_rthz: float = 0.0


#: The preamplifier of every channel.
LTC6079 = Amplifier()

#: Samples the ADuC842 averages per reading (seed 000 §4.1).
ADC_AVERAGED_SAMPLES = 16


@dataclass(frozen=True)
class FrontEnd:
    """A detector's preamplifier configuration (seed 000 §4.1, listings D.1).

    Attributes
    ----------
    r1_ohm, r2_ohm : float
        Gain-setting resistors of the non-inverting stage (eq. 4.1).
    r_in_ohm : float | None
        Photodiode load resistor R_in [Ω] (EPD 100 kΩ: listings only; BPW 2200 Ω); None for the thermopile,
        whose source is the thermopile itself.
    gbw_hz : float
        The amplifier's gain-bandwidth product.
    """

    r1_ohm: float
    r2_ohm: float
    r_in_ohm: float | None
    gbw_hz: float = LTC6079.gbw_hz

    @property
    def gain(self) -> float:
        """G = 1 + R2/R1 (eq. 4.1)."""
        return float(non_inverting_gain(self.r1_ohm, self.r2_ohm))

    @property
    def bandwidth_hz(self) -> float:
        """BW = GBW/G (eq. 4.2): 83,720.93 Hz (EPD, BPW) and 892.3282 Hz (TPS)."""
        return float(amplifier_bandwidth_hz(self.gbw_hz, self.gain))


#: EPD: R1 = 100 kΩ, R2 = 330 kΩ (§4.1); R_in = 100 kΩ (listings D.1.1–D.1.4; the text never states it).
FRONT_END_EPD = FrontEnd(r1_ohm=100e3, r2_ohm=330e3, r_in_ohm=100e3)
#: BPW: R1 = 100 kΩ, R2 = 330 kΩ, R_in = 2200 Ω (§4.1, listings D.1.5/D.1.6).
FRONT_END_BPW = FrontEnd(r1_ohm=100e3, r2_ohm=330e3, r_in_ohm=2200.0)
#: TPS: R1 = 820 Ω, R2 = 330 kΩ (§4.1).
FRONT_END_TPS = FrontEnd(r1_ohm=820.0, r2_ohm=330e3, r_in_ohm=None)

#: The front ends by the head's detector type.
FRONT_ENDS: dict[str, FrontEnd] = {"uv": FRONT_END_EPD, "vis": FRONT_END_BPW, "ir": FRONT_END_TPS}

# --------------------------------------------------------------------------------------------------------------
# Table C.1: photocurrents versus incidence angle (from Kandimala 2012, seed 000 ref. [4])
# --------------------------------------------------------------------------------------------------------------


def _read_only(values) -> np.ndarray:
    array = np.array(values, float)
    array.setflags(write=False)
    return array


#: Incidence angle from the detector normal [°], 0 … 90 in 5° steps.
TABLE_C1_ANGLE_DEG = _read_only(np.arange(0.0, 91.0, 5.0))
#: EPD-365, Sun [A].
TABLE_C1_EPD_SUN_A = _read_only([
    6.18e-06, 6.16e-06, 6.10e-06, 6.00e-06, 5.87e-06, 5.49e-06, 4.76e-06, 3.89e-06, 3.09e-06, 2.29e-06,
    1.42e-06, 6.84e-07, 3.09e-07, 1.99e-07, 1.19e-07, 6.40e-08, 3.09e-08, 9.55e-09, 0.0])
#: EPD-365, Earth albedo [A].
TABLE_C1_EPD_ALBEDO_A = _read_only([
    1.08e-06, 1.08e-06, 1.07e-06, 1.05e-06, 1.01e-06, 9.70e-07, 9.23e-07, 8.74e-07, 8.24e-07, 7.79e-07,
    7.33e-07, 6.82e-07, 6.27e-07, 5.71e-07, 5.14e-07, 4.59e-07, 4.05e-07, 3.56e-07, 3.11e-07])
#: BPW 21, Sun [A], exactly as Table C.1 prints it (30°: 8.68E-04).
TABLE_C1_BPW_SUN_PRINTED_A = _read_only([
    1.17e-03, 1.16e-03, 1.15e-03, 1.13e-03, 1.11e-03, 1.04e-03, 8.68e-04, 7.34e-04, 5.83e-04, 4.32e-04,
    2.67e-04, 1.29e-04, 5.83e-05, 3.75e-05, 2.24e-05, 1.21e-05, 5.83e-06, 1.80e-06, 0.0])
#: BPW 21, Sun [A], with 30° corrected to 8.98E-04. The printed 8.68E-04 is taken as a typo (digest §3.5, §9.7):
#: the thesis' own quantiser kvabpwsun (listing D.6) uses 0.898 mA, Table C.2's 114.78 dB at 30° is reproduced
#: only with 0.898 mA (8.68E-04 gives 114.48 dB), and the EPD's 30°/0° ratio (0.770) predicts 0.90 mA.
TABLE_C1_BPW_SUN_A = _read_only(np.where(TABLE_C1_ANGLE_DEG == 30.0, 8.98e-04, TABLE_C1_BPW_SUN_PRINTED_A))
#: BPW 21, Earth albedo [A].
TABLE_C1_BPW_ALBEDO_A = _read_only([
    2.66e-04, 2.66e-04, 2.64e-04, 2.58e-04, 2.50e-04, 2.40e-04, 2.28e-04, 2.16e-04, 2.04e-04, 1.92e-04,
    1.81e-04, 1.69e-04, 1.55e-04, 1.41e-04, 1.27e-04, 1.13e-04, 1.00e-04, 8.79e-05, 7.70e-05])

_TABLE_C1 = {
    ("uv", "sun"): TABLE_C1_EPD_SUN_A, ("uv", "albedo"): TABLE_C1_EPD_ALBEDO_A,
    ("vis", "sun"): TABLE_C1_BPW_SUN_A, ("vis", "albedo"): TABLE_C1_BPW_ALBEDO_A,
}


def table_c1_current_a(detector: str, source: str, *, printed: bool = False) -> np.ndarray:
    """A Table C.1 column [A] at :data:`TABLE_C1_ANGLE_DEG`.

    `detector` is ``uv`` (EPD-365) or ``vis`` (BPW 21), `source` ``sun`` or ``albedo``. The BPW Sun column has
    30° corrected to 8.98E-04 unless `printed` is true (see :data:`TABLE_C1_BPW_SUN_A`).
    """
    if (detector, source) not in _TABLE_C1:
        raise ValueError(f"Table C.1 has no column for detector {detector!r} and source {source!r} "
                         "(detectors: uv, vis; sources: sun, albedo)")
    if printed and (detector, source) == ("vis", "sun"):
        return TABLE_C1_BPW_SUN_PRINTED_A
    return _TABLE_C1[(detector, source)]
