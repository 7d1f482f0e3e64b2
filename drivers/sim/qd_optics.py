"""The simulated quadrant-photodiode (QD) sun sensor's physics (seed 002): optics, dark current, electronics,
thermal control. Its own model — it shares no code with the calibration's (``calibration/`` is never
imported), so a fit against this simulator measures a calibration, not a round trip.

Geometry
--------
Detector frame: the die is the plane z = 0, +z its normal towards the diaphragm; the four quadrants are the
quarters of a square of side L split by a dead cross of width g, numbered as seed 002's eq. 2.1 implies
(digest §2.2): Q1 (−x, −y), Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y). A round diaphragm of diameter D (a thin
mask, parallel to the die) is centred at (x0, y0, d). The die and its mask sit in the sensor body frame (the
CMOS family's: the world's :meth:`~drivers.sim.world.SimWorld.sun_direction_body`, s = (sin z cos a,
sin z sin a, cos z)) turned by three small angles::

    s_die = Rz(φ0)ᵀ · Rx(−β0)ᵀ · Ry(α0)ᵀ · s_body

Ry(α0) turns +z towards +x by α0 and Rx(−β0) turns +z towards +y by β0, so to first order the die sees
projection angles α − α0 and β − β0 (tan α = s_x/s_z, tan β = s_y/s_z) as in eq. 2.2, and Rz(φ0) is eq.
2.2's in-plane rotation (a spot at die coordinates c is at Rz(φ0)·c in body-aligned axes).

Light from a direction s (pointing at the Sun) through the diaphragm point p lands on the die at
p − d·(s_x, s_y)/s_z: the vector from the spot to the pinhole points at the Sun, and the spot moves opposite
to the Sun's tilt (Sun towards +x → spot towards −x → Q1 and Q4 grow). Because mask and die are parallel,
the spot for one direction is the diaphragm's disc itself, shifted, carrying the irradiance E·cos(incidence);
the Sun's disc (angular diameter `source_diameter_deg`, the world's bench value, 0.5° for the default sun
simulator) smears it by d·tan(radius) ≈ 0.13 µm at d = 30 µm.

The overlap is integrated, not approximated: the area of a shifted disc inside each quadrant's rectangle is
exact (closed form, :func:`disc_rect_area`), and the Sun's disc is a sunflower set of `SUN_SAMPLES` directions
over it, each weighted by its cos(incidence). So the response is smooth in the sun direction (no sampling
staircase a calibration would see as noise), and one evaluation costs ~0.5 ms.

Why d ≈ 30 µm and not the thesis' 0.817 mm
------------------------------------------
A quadrant detector measures the spot's position only while the spot straddles the centre: once it lies
wholly on one side of a split line, that side's ratio (difference / sum, eq. 2.1) is ±1 whatever the angle.
The spot's centre moves d·tan α; the field's corner (α, β) = (±40°, ±40°) puts it d·tan 40°·√2 = 1.187·d
from the pinhole's foot. To keep a D = 100 µm spot over the centre there, with |x0|, |y0| of a few µm and
the 5 µm dead cross (whose corner lies 2.5·√2 = 3.5 µm along the diagonal), needs 1.187·d + |(x0, y0)| +
3.5 µm < 50 µm: d = 30 µm leaves 35.6 + 3.6 + 3.5 = 42.7 µm, a margin of 7 µm for the default build (the
smallest quadrant still holds 0.7 % of the spot at the worst corner) and ≥ 6 µm for every fleet build.

The thesis' fitted d = 0.817 mm with y0 = +0.52 mm (digest §5.2) cannot be a QD with a ≤ 100 µm
diaphragm: at boresight the spot (100 µm, plus 0.817 mm·tan 0.53° = 7.6 µm of Sun-disc blur) already sits
0.52 mm off the centre, and a ±40° sweep moves it ±0.686 mm, so it straddles the x axis only while
|y0 − d·tan β| < 54 µm — β between 29.7° and 35.1° — and the y ratio is saturated at ±1 over the rest of the
field (likewise the x ratio for α outside −7.4° … +0.2°). Its eq. 2.1 could only work with a spot
millimetres wide (a defocused or diffusing optic), not a pinhole image. With a 20 µm diaphragm the same
argument asks d ≲ 2 µm. :meth:`QdTruth.centre_margin_um` computes the margin of a build.

Electronics, dark current, temperature
--------------------------------------
Photocurrent = responsivity × per-quadrant mismatch × optical power. Dark current per quadrant
I_d(T) = I_d(25 °C)·2^((T − 25 °C)/T₂) (nA at 25 °C, doubling every T₂ ≈ 9 °C) on the die's true
temperature. Each sample adds shot noise √(q·I/t_int) (bandwidth 1/(2 t_int)) and the amplifier's input noise,
then the ADC quantises ``pedestal + I / (amperes per count)`` and clips to [0, 2^bits − 1]: a saturated channel
reads full scale. The TEC drives the die temperature to the setpoint with a first-order lag τ on the
world's clock (switched off, towards ambient = the world's temperature), regulating on the module's
thermometer, whose reading has a small offset and noise.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from dataclasses import dataclass, field

import numpy as np

Q_E = 1.602176634e-19  # elementary charge [C]
SUN_SAMPLES = 24  # directions over the Sun's disc
DARK_REFERENCE_C = 25.0
#: sign of x and y of each quadrant, Q1 … Q4 (seed 002 eq. 2.1)
QUADRANT_SIGNS = np.array([[-1.0, -1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, 1.0]])

Quad = tuple[float, float, float, float]


@dataclass(frozen=True)
class QdTruth:
    """What one simulated QD module really is (never visible to drivers). Defaults: the bench's example build.

    Optics
    ------
    aperture_diameter_um : diaphragm diameter D (seed 002: ~20 µm optimal, ≤ 100 µm acceptable) [µm]
    height_um : distance d from the die to the diaphragm [µm] (see the module docstring for why ~30 µm)
    detector_side_mm : side L of the square active area [mm]
    gap_um : width of the dead cross between the quadrants [µm]
    x0_um, y0_um : diaphragm centre relative to the die centre, die axes [µm]
    alpha0_deg, beta0_deg, phi0_deg : angular offsets of the die in the body frame (module docstring) [°]

    Photometry
    ----------
    irradiance_w_m2 : irradiance at the sensor, normal incidence, when the world's irradiance() is 1 [W/m²]
    responsivity_a_w : silicon responsivity over the source's spectrum [A/W]
    quadrant_response : relative responsivity of Q1 … Q4 (mismatch of a few %)

    Dark current
    ------------
    dark_na_at_25c : dark current of Q1 … Q4 at 25 °C [nA]
    dark_doubling_c : temperature step that doubles it, Q1 … Q4 [°C]

    Electronics
    -----------
    adc_bits : resolution of each channel's ADC
    full_scale_ua : nominal input range [µA]; amperes per count = full scale / 2^bits
    gain_error : true conversion of Q1 … Q4 relative to nominal (the module reports its true values)
    pedestal_counts : nominal ADC code of zero current (reported by IDENTIFY)
    pedestal_error_counts : true zero code minus nominal, Q1 … Q4 (a dark calibration absorbs it)
    amp_noise_pa : amplifier input noise per sample, rms [pA]
    integration_ms : integration time of one sample [ms]
    overhead_ms : conversion and reply time of a READ [ms]
    max_average : largest averaging count of a READ

    Thermal
    -------
    tec_tau_s : time constant of the die temperature [s]
    tec_range_c : setpoints the TEC accepts [°C]
    thermometer_offset_c : thermometer reading minus true die temperature [°C]
    thermometer_noise_c : rms noise of one temperature reading [°C]
    settle_tolerance_c : |reading − setpoint| that counts as settled [°C]
    """

    serial: str = "QD-0001"
    aperture_diameter_um: float = 100.0
    height_um: float = 30.0
    detector_side_mm: float = 1.0
    gap_um: float = 5.0
    x0_um: float = 2.0
    y0_um: float = -3.0
    alpha0_deg: float = 0.05
    beta0_deg: float = -0.15
    phi0_deg: float = 0.4
    irradiance_w_m2: float = 1000.0
    responsivity_a_w: float = 0.35
    quadrant_response: Quad = (1.0, 1.024, 0.978, 1.011)
    dark_na_at_25c: Quad = (0.85, 1.10, 0.95, 1.30)
    dark_doubling_c: Quad = (9.0, 8.6, 9.3, 8.8)
    adc_bits: int = 16
    full_scale_ua: float = 2.0
    gain_error: Quad = (0.002, -0.003, 0.001, 0.004)
    pedestal_counts: int = 64
    pedestal_error_counts: Quad = (1.5, -2.0, 0.5, 3.0)
    amp_noise_pa: float = 20.0
    integration_ms: float = 1.0
    overhead_ms: float = 0.3
    max_average: int = 1000
    tec_tau_s: float = 20.0
    tec_range_c: tuple[float, float] = (-40.0, 70.0)
    thermometer_offset_c: float = 0.3
    thermometer_noise_c: float = 0.02
    settle_tolerance_c: float = 0.05

    def __post_init__(self) -> None:
        checks = {
            "aperture_diameter_um": self.aperture_diameter_um > 0, "height_um": self.height_um > 0,
            "detector_side_mm": self.detector_side_mm * 1000.0 > self.gap_um >= 0,
            "irradiance_w_m2": self.irradiance_w_m2 >= 0, "responsivity_a_w": self.responsivity_a_w > 0,
            "quadrant_response": len(self.quadrant_response) == 4 and min(self.quadrant_response) > 0,
            "dark_na_at_25c": len(self.dark_na_at_25c) == 4 and min(self.dark_na_at_25c) >= 0,
            "dark_doubling_c": len(self.dark_doubling_c) == 4 and min(self.dark_doubling_c) > 0,
            "adc_bits": 8 <= self.adc_bits <= 24, "full_scale_ua": self.full_scale_ua > 0,
            "gain_error": len(self.gain_error) == 4 and max(abs(g) for g in self.gain_error) < 0.5,
            "pedestal_counts": 0 <= self.pedestal_counts < (1 << self.adc_bits) // 2,
            "pedestal_error_counts": len(self.pedestal_error_counts) == 4,
            "amp_noise_pa": self.amp_noise_pa >= 0, "integration_ms": self.integration_ms > 0,
            "overhead_ms": self.overhead_ms >= 0, "max_average": 1 <= self.max_average <= 65535,
            "tec_tau_s": self.tec_tau_s > 0, "tec_range_c": self.tec_range_c[0] < self.tec_range_c[1],
            "thermometer_noise_c": self.thermometer_noise_c >= 0, "settle_tolerance_c": self.settle_tolerance_c > 0,
        }
        bad = [name for name, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"QD sensor truth out of range: {', '.join(f'{b}={getattr(self, b)!r}' for b in bad)}")

    # -- derived ----------------------------------------------------------------------------------------
    @property
    def nominal_amperes_per_count(self) -> float:
        return self.full_scale_ua * 1e-6 / (1 << self.adc_bits)

    @property
    def amperes_per_count(self) -> np.ndarray:
        """True (and reported) conversion of each channel [A/count]."""
        return self.nominal_amperes_per_count * (1.0 + np.asarray(self.gain_error, dtype=float))

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.adc_bits) - 1

    def die_rotation(self) -> np.ndarray:
        """M with s_die = M · s_body (module docstring)."""
        return (_ry(self.alpha0_deg) @ _rx(-self.beta0_deg) @ _rz(self.phi0_deg)).T

    def eq22_parameters(self) -> dict[str, float]:
        """This build in seed 002 eq. 2.2's terms, the values a geometric fit should come close to: x0, y0 in
        eq. 2.2's rotated (body-aligned) axes, d, α0, β0, φ0 — in mm and degrees. (Eq. 2.2 adds angular
        offsets to projection angles, a first-order stand-in for the die's rotation, and eq. 2.1's ratio is
        not the spot centre, so a fit recovers these only approximately.)"""
        c, s = math.cos(math.radians(self.phi0_deg)), math.sin(math.radians(self.phi0_deg))
        return {"x0_mm": (c * self.x0_um - s * self.y0_um) / 1000.0,
                "y0_mm": (s * self.x0_um + c * self.y0_um) / 1000.0, "d_mm": self.height_um / 1000.0,
                "alpha0_deg": self.alpha0_deg, "beta0_deg": self.beta0_deg, "phi0_deg": self.phi0_deg,
                "L_mm": self.detector_side_mm}

    def centre_margin_um(self, field_deg: float = 40.0, source_diameter_deg: float = 0.53) -> float:
        """How far the spot's edge reaches past the farthest quadrant's inner corner, worst case over the
        ±`field_deg` square of projection angles (its corners) [µm]. Positive: every quadrant stays lit."""
        t = math.tan(math.radians(field_deg))
        blur = self.height_um * math.tan(math.radians(source_diameter_deg / 2)) / math.cos(math.radians(field_deg)) ** 2
        radius = self.aperture_diameter_um / 2 + blur
        worst = math.inf
        m = self.die_rotation()
        for sa in (-1, 1):
            for sb in (-1, 1):
                s = m @ np.array([sa * t, sb * t, 1.0])
                cx, cy = self.x0_um - self.height_um * s[0] / s[2], self.y0_um - self.height_um * s[1] / s[2]
                # the quadrant on the other side of the centre from the spot, and its inner corner
                kx, ky = -math.copysign(1.0, cx), -math.copysign(1.0, cy)
                corner = (kx * self.gap_um / 2, ky * self.gap_um / 2)
                worst = min(worst, radius - math.hypot(cx - corner[0], cy - corner[1]))
        return worst


def _rx(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def qd_fleet_truth(base: QdTruth, serial: str) -> QdTruth:
    """The simulated module of serial `serial`: `base` itself for its own serial, any other a module of the same
    design with its own build errors, drawn around `base` from the serial alone (reproducible in any process,
    whatever was mounted before). Draws are normal, clipped at 3σ, small enough that every fleet build keeps
    the spot over the detector centre across ±40° (the module docstring)."""
    if serial == base.serial:
        return base
    rng = np.random.default_rng([zlib.crc32(serial.encode()), zlib.crc32(b"qd-build")])

    def draw(sd, n=None):
        return np.clip(rng.normal(0.0, 1.0, n), -3.0, 3.0) * sd

    def quad(values, rel_sd):
        return tuple(float(v) for v in np.asarray(values) * (1.0 + draw(rel_sd, 4)))

    return dataclasses.replace(
        base, serial=serial,
        aperture_diameter_um=base.aperture_diameter_um + float(draw(0.5)),
        height_um=base.height_um + float(draw(0.5)),
        x0_um=float(draw(1.0)), y0_um=float(draw(1.0)),
        alpha0_deg=float(draw(0.1)), beta0_deg=float(draw(0.1)), phi0_deg=float(draw(0.5)),
        quadrant_response=quad(np.ones(4), 0.02),
        dark_na_at_25c=tuple(float(v) for v in np.mean(base.dark_na_at_25c) * np.exp(draw(0.3, 4))),
        dark_doubling_c=tuple(float(v) for v in np.mean(base.dark_doubling_c) + draw(0.4, 4)),
        gain_error=tuple(float(v) for v in draw(0.002, 4)),
        pedestal_error_counts=tuple(float(v) for v in draw(2.0, 4)),
        thermometer_offset_c=float(draw(0.3)))


# -- optics -----------------------------------------------------------------------------------------------
def _segment_integral(x, r):
    """∫₀ˣ √(r² − t²) dt for |x| ≤ r."""
    x = np.clip(x, -r, r)
    return 0.5 * (x * np.sqrt(np.maximum(r * r - x * x, 0.0)) + r * r * np.arcsin(x / r))


def disc_quarter_area(u, v, r):
    """Area of the disc of radius `r` centred at the origin inside the quarter-plane {x > u, y > v} (exact).

    ∫ over x > u of the chord length above y = v: where the chord lies wholly above (v ≤ −√(r² − x²)) it is
    2√(r² − x²), where it crosses, √(r² − x²) − v; with the breakpoints at ±√(r² − v²) the integrals are
    closed-form."""
    u = np.clip(u, -r, r)
    v = np.clip(v, -r, r)
    xv = np.sqrt(np.maximum(r * r - v * v, 0.0))
    lo = np.clip(u, -xv, xv)
    crossing = _segment_integral(xv, r) - _segment_integral(lo, r)
    above = crossing - v * (xv - lo)  # v ≥ 0: only the crossing chords count
    whole = 2.0 * (_segment_integral(r, r) - _segment_integral(u, r))
    below = whole - (crossing + v * (xv - lo))  # v < 0: full chords, less what y < v takes inside |x| < xv
    return np.where(v >= 0.0, above, below)


def disc_rect_area(x1, x2, y1, y2, r):
    """Area of the disc of radius `r` at the origin inside the rectangle [x1, x2] × [y1, y2] (x1 ≤ x2, y1 ≤ y2)."""
    return (disc_quarter_area(x1, y1, r) - disc_quarter_area(x2, y1, r) - disc_quarter_area(x1, y2, r)
            + disc_quarter_area(x2, y2, r))


def _sunflower(n: int) -> tuple[np.ndarray, np.ndarray]:
    """`n` (even) points spread evenly over the unit disc: radius, angle. Half of them is a sunflower spiral,
    the other half its mirror through the centre, so their centroid is the disc's centre exactly (a spiral
    alone is off by a few % of the radius, which would bias every simulated direction)."""
    half = n // 2
    k = np.arange(half) + 0.5
    r, psi = np.sqrt(k / half), k * math.pi * (3.0 - math.sqrt(5.0))
    return np.concatenate([r, r]), np.concatenate([psi, psi + math.pi])


class QdOptics:
    """Noise-free photocurrents of one build for a sun direction (module docstring)."""

    def __init__(self, truth: QdTruth):
        self.truth = truth
        self.rotation = truth.die_rotation()
        self._disc_r, self._disc_psi = _sunflower(SUN_SAMPLES)
        t = truth
        self.radius_um = t.aperture_diameter_um / 2.0
        self.area_m2 = math.pi * (self.radius_um * 1e-6) ** 2
        self._lo, self._hi = t.gap_um / 2.0, t.detector_side_mm * 500.0
        self._response_a_w = t.responsivity_a_w * np.asarray(t.quadrant_response, dtype=float)

    def die_direction(self, zenith_deg: float, azimuth_deg: float) -> np.ndarray:
        """Unit sun vector in the die frame."""
        z, a = math.radians(zenith_deg), math.radians(azimuth_deg)
        return self.rotation @ np.array([math.sin(z) * math.cos(a), math.sin(z) * math.sin(a), math.cos(z)])

    def spot_centre_um(self, zenith_deg: float, azimuth_deg: float) -> tuple[float, float]:
        """Centre of the spot of the Sun's centre on the die [µm] (die axes); NaN when the Sun is behind."""
        s = self.die_direction(zenith_deg, azimuth_deg)
        if s[2] <= 0:
            return math.nan, math.nan
        h = self.truth.height_um
        return self.truth.x0_um - h * s[0] / s[2], self.truth.y0_um - h * s[1] / s[2]

    def _sun_samples(self, s: np.ndarray, source_diameter_deg: float) -> np.ndarray:
        """Directions over the Sun's disc around `s` (unit, die frame), shape (n, 3)."""
        e1 = np.cross(s, [0.0, 0.0, 1.0] if abs(s[2]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        theta = math.radians(source_diameter_deg / 2.0) * self._disc_r
        off = np.cos(self._disc_psi)[:, None] * e1 + np.sin(self._disc_psi)[:, None] * e2
        return np.cos(theta)[:, None] * s + np.sin(theta)[:, None] * off

    def quadrant_power_w(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float,
                         source_diameter_deg: float = 0.53) -> np.ndarray:
        """Optical power on Q1 … Q4 [W]."""
        if irradiance_w_m2 <= 0:
            return np.zeros(4)
        dirs = self._sun_samples(self.die_direction(zenith_deg, azimuth_deg), source_diameter_deg)
        cos_i = dirs[:, 2]
        lit = cos_i > 1e-6
        if not lit.any():
            return np.zeros(4)
        dirs, cos_i = dirs[lit], cos_i[lit]
        h, t = self.truth.height_um, self.truth
        cx = t.x0_um - h * dirs[:, 0] / cos_i  # spot centres [µm], one per sun sample
        cy = t.y0_um - h * dirs[:, 1] / cos_i
        sx, sy = QUADRANT_SIGNS[:, :1], QUADRANT_SIGNS[:, 1:]  # (4, 1): reflect each quadrant onto +x, +y
        px, py = sx * cx, sy * cy  # (4, n): the spot centre in the reflected frame
        area_um2 = disc_rect_area(self._lo - px, self._hi - px, self._lo - py, self._hi - py, self.radius_um)
        # each sample carries the irradiance E·cos i over its footprint, 1/n of the Sun's disc
        return irradiance_w_m2 * 1e-12 * (area_um2 * cos_i).sum(axis=1) / self._disc_r.size

    def photocurrents_a(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float,
                        source_diameter_deg: float = 0.53) -> np.ndarray:
        """Photocurrents of Q1 … Q4 (no dark current, no noise) [A]."""
        return self._response_a_w * self.quadrant_power_w(zenith_deg, azimuth_deg, irradiance_w_m2, source_diameter_deg)

    def dark_current_a(self, die_temperature_c: float) -> np.ndarray:
        """Dark currents of Q1 … Q4 at the die's true temperature [A]."""
        t = self.truth
        return (np.asarray(t.dark_na_at_25c) * 1e-9
                * np.exp2((die_temperature_c - DARK_REFERENCE_C) / np.asarray(t.dark_doubling_c)))


# -- electronics ----------------------------------------------------------------------------------------------
@dataclass
class ChannelFaults:
    """Faults of the module's four channels, through the back door; keys are quadrant numbers 1 … 4.

    Attributes
    ----------
    stuck : dict of int to int
        The channel's ADC repeats this code whatever the light.
    dead : set of int
        The photodiode is open: the channel reads its pedestal and amplifier noise only.
    saturated : set of int
        The amplifier is latched at its rail: the channel reads full scale.
    """

    stuck: dict[int, int] = field(default_factory=dict)
    dead: set[int] = field(default_factory=set)
    saturated: set[int] = field(default_factory=set)

    def clear(self) -> None:
        self.stuck.clear()
        self.dead.clear()
        self.saturated.clear()


def sample_counts(truth: QdTruth, currents_a: np.ndarray, n: int, rng: np.random.Generator,
                  faults: ChannelFaults | None = None) -> np.ndarray:
    """ADC codes of `n` samples of the four channels for the true input currents (photo + dark) [A], shape (n, 4)."""
    current = np.array(currents_a, dtype=float)
    if faults is not None:
        for q in faults.dead:
            current[q - 1] = 0.0
    t_int = truth.integration_ms / 1000.0
    sigma = np.sqrt(Q_E * np.maximum(current, 0.0) / t_int + (truth.amp_noise_pa * 1e-12) ** 2)
    noisy = current + sigma * rng.standard_normal((n, 4))
    code = np.asarray(truth.pedestal_counts + np.asarray(truth.pedestal_error_counts)) + noisy / truth.amperes_per_count
    counts = np.clip(np.rint(code), 0, truth.full_scale_counts).astype(np.int64)
    if faults is not None:
        for q in faults.saturated:
            counts[:, q - 1] = truth.full_scale_counts
        for q, value in faults.stuck.items():
            counts[:, q - 1] = int(np.clip(value, 0, truth.full_scale_counts))
    return counts


# -- thermal ---------------------------------------------------------------------------------------------------
class TecModel:
    """The die temperature under the module's TEC: first order towards its target on the simulated clock.

    The TEC regulates on the thermometer, so with the TEC on the true die temperature settles at the setpoint
    minus the thermometer's offset; off, it drifts to `ambient()`."""

    def __init__(self, truth: QdTruth, clock, ambient):
        self.truth = truth
        self.clock = clock
        self.ambient = ambient
        self.enabled = False
        self.setpoint_c = 0.0
        self._t0 = clock.now()
        self._true0 = float(ambient())

    def target_c(self) -> float:
        """True die temperature the die heads for [°C]."""
        return self.setpoint_c - self.truth.thermometer_offset_c if self.enabled else float(self.ambient())

    def true_c(self, at_s: float | None = None) -> float:
        """True die temperature at simulated time `at_s` (now by default) [°C]."""
        t = self.clock.now() if at_s is None else at_s
        target = self.target_c()
        return target + (self._true0 - target) * math.exp(-max(t - self._t0, 0.0) / self.truth.tec_tau_s)

    def measured_c(self, at_s: float | None = None) -> float:
        """What the thermometer reads, without its noise [°C]."""
        return self.true_c(at_s) + self.truth.thermometer_offset_c

    def set(self, enabled: bool, setpoint_c: float) -> None:
        now = self.clock.now()
        self._true0, self._t0 = self.true_c(now), now
        self.enabled, self.setpoint_c = bool(enabled), float(setpoint_c)

    def settled(self, at_s: float | None = None) -> bool:
        return abs(self.true_c(at_s) - self.target_c()) < self.truth.settle_tolerance_c

    def settle_time_s(self) -> float:
        """Simulated time at which the die counts as settled (now if it is)."""
        now = self.clock.now()
        gap = abs(self.true_c(now) - self.target_c())
        tolerance = 0.9 * self.truth.settle_tolerance_c
        if gap <= tolerance:
            return now
        return now + self.truth.tec_tau_s * math.log(gap / tolerance)
