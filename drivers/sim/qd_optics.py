"""The simulated quadrant-photodiode (QD) sun sensor's physics (seed 002): optics, dark current, electronics,
thermal control. Its own model — it shares no code with the calibration's (``calibration/`` is never
imported), so a fit against this simulator measures a calibration, not a round trip.

Geometry
--------
Detector frame: the die is the plane z = 0, +z its normal towards the diaphragm; the four quadrants are the
quarters of a square of side L split by a dead cross of width g, numbered as seed 002's eq. 2.1 implies
(digest §2.2): Q1 (−x, −y), Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y). A round diaphragm of diameter D (a hole
through a mask of thickness t parallel to the die, see below) has its mid-plane's centre at (x0, y0, d). The die
and its mask sit in the sensor body frame (the CMOS family's: the world's
:meth:`~drivers.sim.world.SimWorld.sun_direction_body`, s = (sin z cos a, sin z sin a, cos z)) turned by
three small angles::

    s_die = Rz(φ0)ᵀ · Rx(−β0)ᵀ · Ry(α0)ᵀ · s_body

Ry(α0) turns +z towards +x by α0 and Rx(−β0) turns +z towards +y by β0, so to first order the die sees
projection angles α − α0 and β − β0 (tan α = s_x/s_z, tan β = s_y/s_z) as in eq. 2.2, and Rz(φ0) is eq.
2.2's in-plane rotation (a spot at die coordinates c is at Rz(φ0)·c in body-aligned axes).

Light from a direction s (pointing at the Sun) through the diaphragm point p lands on the die at
p − d·(s_x, s_y)/s_z: the vector from the spot to the pinhole points at the Sun, and the spot moves opposite
to the Sun's tilt (Sun towards +x → spot towards −x → Q1 and Q4 grow). The spot carries the irradiance
E·cos(incidence); the Sun's disc (angular diameter `source_diameter_deg`, the world's bench value, 0.5° for
the default sun simulator) smears it by d·tan(radius) ≈ 0.13 µm at d = 30 µm.

The overlap is integrated, not approximated: the area of the spot inside each quadrant's rectangle is exact
(closed form, :func:`lens_rect_area`), and the Sun's disc is a sunflower set of `SUN_SAMPLES` directions over
it, each weighted by its cos(incidence). So the response is smooth in the sun direction (no sampling
staircase a calibration would see as noise), and one evaluation costs about a millisecond.

What a real module adds to that picture
---------------------------------------
Three effects a real module has and the calibration's physical model (a sharp disc of the diaphragm's size,
shares of per-quadrant gains) does not. Each is a field of :class:`QdTruth`, drawn per serial for a fleet;
setting it to zero gives the ideal module back.

*Finite diaphragm thickness* (`diaphragm_thickness_um`, t). The diaphragm is a hole through a layer of
thickness t, its mid-plane at the height d (`height_um`): bottom face at d − t/2, top face at d + t/2. A ray
passes only if it clears both openings, so the spot is the intersection of the two openings' shadows — two
discs of the diaphragm's radius whose centres are (x0, y0) − (d ∓ t/2)·T, T = (s_x, s_y)/s_z: a lens t·tan(i)
narrower along the Sun's azimuth than the disc (i the incidence), its area 2r²·acos(δ/2r) − (δ/2)·√(4r² − δ²)
with δ = t·tan(i) (≈ 6 % less light at 45° for t = 5 µm), its centre (x0, y0) − d·T: shifted by t·tan(i)/2
from the bottom opening's shadow towards the spot's direction of motion. :func:`lens_rect_area` gives the
lens' area inside a rectangle exactly, by Green's theorem along the boundary of the convex region disc ∩ disc
∩ rectangle (arcs of either circle and pieces of the edges, each kept where its midpoint lies inside the other
constraints). The hole's own wall is taken as black (no light reflected by it).

*Stray light from the housing* (`bore_radius_mm`, `bore_height_mm`, `window_radius_mm`, `wall_reflectance`).
Seed 002 §5.2 blames "re-reflections from internal parts of the sensor housing" for its errors at the field's
edge. The housing above the diaphragm is modelled as a cylindrical bore of radius R_h and height H, coaxial
with the die's normal and centred on the diaphragm, closed at the top by a cover with a round window of
radius R_w < R_h (wide enough for the diaphragm to see the Sun over the whole field: R_w/H = tan 52.4° by
default). The direct beam through the window reaches the wall once H·tan(i) > R_h − R_w — beyond a cut-off
incidence atan((R_h − R_w)/H), 31° by default — on the side away from the Sun, in a band at the bottom of
the bore: the wall point at azimuth ψ and height z is lit when its ray traced back towards the Sun leaves
through the window, which bounds the band in closed form (ψ within acos((m² + q)/2m) of the anti-Sun azimuth,
or acos(√q) once m ≥ √q, m = H·tan(i)/R_h, q = 1 − (R_w/R_h)²; z between H − R_h·(a ± √(a² − q))/tan(i),
a = −cos(ψ − ψ_sun), the lower bound reaching above the bore's bottom only beyond i ≈ 54°). The wall
is a Lambertian reflector of reflectance ρ: each element, lit with E·sin(i)·a, sends through the diaphragm
the radiance ρ·E_wall/π from the direction of the wall point w = (R_h cos ψ, R_h sin ψ, z), so the diaphragm
images the lit band — it lands on the die d·R_h/z from the spot's origin, on the Sun's side: opposite the
direct spot, mostly in the diagonally opposite quadrant, pulling the reading towards the centre. Each element
adds ρ·E_wall/π · (R_h/|w|)·(z/|w|)/|w|² · dA times the area of its own footprint (the same lens, now for
the direction w) on each quadrant; the band is integrated by Gauss–Legendre (`STRAY_NODES`² nodes mapped
onto it, so the result is smooth in the Sun's direction). The footprint of light from low on the wall falls
off the die or is cut by the diaphragm's thickness. With the default bore the stray light on the die grows
from 0 at 31° to 0.74 %·ρ of the direct light at the field's corner (i = 49.9°); ρ = 0.5 is a bare,
bead-blasted aluminium bore (black anodising: ~0.05). Single bounce only; the cover's underside, the mask's
top and the window's own reflections are not modelled, nor does the window ever shade the direct beam.

*Electrical crosstalk* (`crosstalk`). A fraction k of each quadrant's photocurrent appears on the channel of
each of its two geometric neighbours in the quadrant ring — Q1 (−,−), Q3 (+,−), Q2 (+,+), Q4 (−,+), so Q1–Q3,
Q3–Q2, Q2–Q4 and Q4–Q1 couple and the diagonal pairs Q1–Q2 and Q3–Q4 do not (the thesis' numbering is
diagonal, digest §7 item 2) — through the front end's shared ground return and board leakage; the channel
keeps its own current (I_channel = C·I_quadrant, C = 1 on the diagonal, k_pair between neighbours). It acts on
the photocurrent; the dark current's share (a few pA) would be removed with the dark current by a dark
calibration, which measures the same mixture.

Why d ≈ 30 µm and not the thesis' 0.817 mm
------------------------------------------
A quadrant detector measures the spot's position only while the spot straddles the centre: once it lies
wholly on one side of a split line, that side's ratio (difference / sum, eq. 2.1) is ±1 whatever the angle.
The spot's centre moves d·tan α; the field's corner (α, β) = (±40°, ±40°) puts it d·tan 40°·√2 = 1.187·d
from the pinhole's foot. To keep a D = 100 µm spot over the centre there, with |x0|, |y0| of a few µm and
the 5 µm dead cross (whose corner lies 2.5·√2 = 3.5 µm along the diagonal), needs 1.187·d + |(x0, y0)| +
3.5 µm < 50 µm: d = 30 µm leaves 35.6 + 3.6 + 3.5 = 42.7 µm, a margin of 7 µm for a thin diaphragm. A
diaphragm of thickness t passes only the lens its top opening's shadow, at d + t/2, also covers: with t = 5 µm
that reaches 1.187·32.5 = 38.6 µm, a margin of 4.4 µm for the default build (the smallest quadrant still holds
0.26 % of the spot at the worst corner) and ≥ 3.4 µm for every fleet build.

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
from dataclasses import dataclass

import numpy as np

from .device import ChannelFaults

Q_E = 1.602176634e-19  # elementary charge [C]
SUN_SAMPLES = 24  # directions over the Sun's disc
DARK_REFERENCE_C = 25.0
#: sign of x and y of each quadrant, Q1 … Q4 (seed 002 eq. 2.1)
QUADRANT_SIGNS = np.array([[-1.0, -1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, 1.0]])
#: the quadrant ring's adjacent pairs (0-based), in the order of :attr:`QdTruth.crosstalk`: Q1–Q3, Q3–Q2, Q2–Q4,
#: Q4–Q1 — quadrants whose signs differ in exactly one axis (the thesis' numbering is diagonal)
RING_PAIRS = ((0, 2), (2, 1), (1, 3), (3, 0))
STRAY_NODES = 10  # Gauss–Legendre nodes per dimension over the lit band of the housing's wall

Quad = tuple[float, float, float, float]


@dataclass(frozen=True)
class QdTruth:
    """What one simulated QD module really is (never visible to drivers). Defaults: the bench's example build.

    Optics
    ------
    aperture_diameter_um : diaphragm diameter D (seed 002: ~20 µm optimal, ≤ 100 µm acceptable) [µm]
    height_um : distance d from the die to the diaphragm's mid-plane [µm] (the module docstring says why ~30 µm)
    diaphragm_thickness_um : thickness t of the mask the diaphragm is cut through; its faces are at d ∓ t/2 and
        the spot is the lens both openings pass (module docstring, "What a real module adds") [µm]
    detector_side_mm : side L of the square active area [mm]
    gap_um : width of the dead cross between the quadrants [µm]
    x0_um, y0_um : diaphragm centre relative to the die centre, die axes [µm]
    alpha0_deg, beta0_deg, phi0_deg : angular offsets of the die in the body frame (module docstring) [°]

    Housing (stray light; module docstring, "What a real module adds")
    -------------------------------------------------------------------
    bore_radius_mm : inner radius R_h of the housing's cylindrical bore above the diaphragm [mm]
    bore_height_mm : height H of the bore, from the diaphragm to the cover's window [mm]
    window_radius_mm : radius R_w of the window in the cover (R_w < R_h); the wall is lit beyond the incidence
        atan((R_h − R_w)/H) [mm]
    wall_reflectance : diffuse (Lambertian) reflectance ρ of the bore's wall; 0 turns the stray light off

    Photometry
    ----------
    irradiance_w_m2 : irradiance at the sensor, normal incidence, when the world's irradiance() is 1 [W/m²]
    responsivity_a_w : silicon responsivity over the source's spectrum [A/W]
    quadrant_response : relative responsivity of Q1 … Q4 (mismatch of a few %)
    crosstalk : fraction of a quadrant's photocurrent that appears on the channel of each geometric neighbour,
        per adjacent pair in the ring order Q1–Q3, Q3–Q2, Q2–Q4, Q4–Q1 (the diagonal pairs do not couple; the
        channel keeps its own current)

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
    diaphragm_thickness_um: float = 1.0  # a thin-film mask on a 30 µm spacer (a 5 µm foil: see the tests)
    detector_side_mm: float = 1.0
    gap_um: float = 5.0
    x0_um: float = 2.0
    y0_um: float = -3.0
    alpha0_deg: float = 0.05
    beta0_deg: float = -0.15
    phi0_deg: float = 0.4
    bore_radius_mm: float = 1.9
    bore_height_mm: float = 1.0
    window_radius_mm: float = 1.3
    wall_reflectance: float = 0.5
    irradiance_w_m2: float = 1000.0
    responsivity_a_w: float = 0.35
    quadrant_response: Quad = (1.0, 1.024, 0.978, 1.011)
    crosstalk: Quad = (0.0030, 0.0027, 0.0034, 0.0031)
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
            "diaphragm_thickness_um": 0 <= self.diaphragm_thickness_um < 2 * self.height_um,
            "bore_height_mm": self.bore_height_mm > 0,
            "window_radius_mm": 0 < self.window_radius_mm < self.bore_radius_mm,
            "wall_reflectance": 0 <= self.wall_reflectance <= 1,
            "crosstalk": len(self.crosstalk) == 4 and all(0 <= k < 0.1 for k in self.crosstalk),
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

    @property
    def stray_cutoff_deg(self) -> float:
        """Incidence beyond which the direct beam through the window reaches the bore's wall [°]."""
        return math.degrees(math.atan2(self.bore_radius_mm - self.window_radius_mm, self.bore_height_mm))

    def crosstalk_matrix(self) -> np.ndarray:
        """C with channel currents = C · quadrant photocurrents: 1 on the diagonal, each adjacent pair's fraction
        between geometric neighbours (quadrants whose signs differ in one axis), 0 between diagonal ones."""
        c = np.eye(4)
        for k, (i, j) in zip(self.crosstalk, RING_PAIRS):
            c[i, j] = c[j, i] = k
        return c

    def centre_margin_um(self, field_deg: float = 40.0, source_diameter_deg: float = 0.53) -> float:
        """How far the spot's edge reaches past the farthest quadrant's inner corner, worst case over the
        ±`field_deg` square of projection angles (its corners) [µm]. Positive: every quadrant stays lit. With a
        thick diaphragm the spot is the lens of the two openings' shadows: the corner must lie in both."""
        t = math.tan(math.radians(field_deg))
        blur = self.height_um * math.tan(math.radians(source_diameter_deg / 2)) / math.cos(math.radians(field_deg)) ** 2
        radius = self.aperture_diameter_um / 2 + blur
        half = self.diaphragm_thickness_um / 2
        worst = math.inf
        m = self.die_rotation()
        for sa in (-1, 1):
            for sb in (-1, 1):
                s = m @ np.array([sa * t, sb * t, 1.0])
                tx, ty = s[0] / s[2], s[1] / s[2]
                cx, cy = self.x0_um - self.height_um * tx, self.y0_um - self.height_um * ty
                # the quadrant on the other side of the centre from the spot, and its inner corner
                kx, ky = -math.copysign(1.0, cx), -math.copysign(1.0, cy)
                corner = (kx * self.gap_um / 2, ky * self.gap_um / 2)
                for h in (self.height_um - half, self.height_um + half):  # the bottom and top openings' shadows
                    ox, oy = self.x0_um - h * tx, self.y0_um - h * ty
                    worst = min(worst, radius - math.hypot(ox - corner[0], oy - corner[1]))
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
    the spot over the detector centre across ±40° (the module docstring). The effects the calibration does not
    model are drawn too: the mask's thickness (±0.4 µm, 1σ), the housing's machining (±10 µm on the bore and
    window), the wall's finish (±15 % reflectance) and each adjacent pair's crosstalk (±20 %)."""
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
        thermometer_offset_c=float(draw(0.3)),
        diaphragm_thickness_um=max(base.diaphragm_thickness_um + float(draw(0.4)), 0.0),
        bore_radius_mm=base.bore_radius_mm + float(draw(0.01)),
        bore_height_mm=base.bore_height_mm + float(draw(0.01)),
        window_radius_mm=base.window_radius_mm + float(draw(0.01)),
        wall_reflectance=float(min(base.wall_reflectance * math.exp(float(draw(0.15))), 1.0)),
        crosstalk=tuple(float(v) for v in np.mean(base.crosstalk) * np.exp(draw(0.2, 4))))


# -- optics -----------------------------------------------------------------------------------------------
def _arc_term(cx, cy, r, p1, p2):
    """½∫(x dy − y dx) along the circle of centre (cx, cy) and radius r from angle p1 to p2 (counter-clockwise)."""
    return 0.5 * (r * r * (p2 - p1) + cx * r * (np.sin(p2) - np.sin(p1)) - cy * r * (np.cos(p2) - np.cos(p1)))


def lens_rect_area(ax, ay, bx, by, r, x1, x2, y1, y2):
    """Area of disc A ∩ disc B ∩ [x1, x2] × [y1, y2] (exact), the discs of equal radius `r` centred at (ax, ay) and
    (bx, by); every argument but `r` broadcasts (x1 ≤ x2, y1 ≤ y2).

    The region is convex (an intersection of convex sets), so its area is Green's ½∮(x dy − y dx) along its
    boundary, made of arcs of the two circles and pieces of the rectangle's edges. Each circle is cut at every
    angle where it meets the other circle or an edge's line (10 angles, harmless extra cuts where there is no
    meeting), each edge at its meetings with the circles; a piece counts when its midpoint lies inside the
    other constraints. Where the circles coincide (A = B) only A's arcs count (the tests check that case against
    the disc's own closed form)."""
    ax, ay, bx, by, x1, x2, y1, y2 = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                                           for v in (ax, ay, bx, by, x1, x2, y1, y2)))
    ox, oy = 0.5 * (ax + bx), 0.5 * (ay + by)  # origin at the lens' middle: no cancellation of large products
    ax, bx, x1, x2 = ax - ox, bx - ox, x1 - ox, x2 - ox
    ay, by, y1, y2 = ay - oy, by - oy, y1 - oy, y2 - oy
    tol = 1e-9 * r * r
    total = np.zeros(ax.shape)
    for cx, cy, px, py, strict in ((ax, ay, bx, by, False), (bx, by, ax, ay, True)):
        base = np.arctan2(py - cy, px - cx)
        w = np.arccos(np.clip(np.hypot(px - cx, py - cy) / (2.0 * r), -1.0, 1.0))
        xl, xh = np.arccos(np.clip((x1 - cx) / r, -1.0, 1.0)), np.arccos(np.clip((x2 - cx) / r, -1.0, 1.0))
        yl, yh = np.arcsin(np.clip((y1 - cy) / r, -1.0, 1.0)), np.arcsin(np.clip((y2 - cy) / r, -1.0, 1.0))
        cuts = np.stack([base - w, base + w, xl, -xl, xh, -xh, yl, math.pi - yl, yh, math.pi - yh], axis=-1)
        cuts = np.sort(np.mod(cuts, 2.0 * math.pi), axis=-1)
        cuts = np.concatenate([cuts, cuts[..., :1] + 2.0 * math.pi], axis=-1)
        p1, p2 = cuts[..., :-1], cuts[..., 1:]
        mid = 0.5 * (p1 + p2)
        c_x, c_y = cx[..., None], cy[..., None]
        mx, my = c_x + r * np.cos(mid), c_y + r * np.sin(mid)
        d2 = (mx - px[..., None]) ** 2 + (my - py[..., None]) ** 2
        inside = (d2 < r * r - tol) if strict else (d2 <= r * r + tol)
        inside &= (mx >= x1[..., None]) & (mx <= x2[..., None]) & (my >= y1[..., None]) & (my <= y2[..., None])
        total += np.where(inside, _arc_term(c_x, c_y, r, p1, p2), 0.0).sum(axis=-1)
    corners = ((x1, y1), (x2, y1), (x2, y2), (x1, y2))  # counter-clockwise
    for k in range(4):
        (sx, sy), (qx, qy) = corners[k], corners[(k + 1) % 4]
        ex, ey = qx - sx, qy - sy
        ee = ex * ex + ey * ey
        safe = np.where(ee > 0, ee, 1.0)
        cuts = [np.zeros(ax.shape), np.ones(ax.shape)]
        for cx, cy in ((ax, ay), (bx, by)):  # where the edge meets each circle: |s + u·e − c| = r
            fx, fy = sx - cx, sy - cy
            fe = fx * ex + fy * ey
            root = np.sqrt(np.maximum(fe * fe - ee * (fx * fx + fy * fy - r * r), 0.0))
            cuts += [np.clip((-fe - root) / safe, 0.0, 1.0), np.clip((-fe + root) / safe, 0.0, 1.0)]
        u = np.sort(np.stack(cuts, axis=-1), axis=-1)
        u1, u2 = u[..., :-1], u[..., 1:]
        s_x, s_y, e_x, e_y = sx[..., None], sy[..., None], ex[..., None], ey[..., None]
        mx, my = s_x + 0.5 * (u1 + u2) * e_x, s_y + 0.5 * (u1 + u2) * e_y
        inside = (((mx - ax[..., None]) ** 2 + (my - ay[..., None]) ** 2 <= r * r)
                  & ((mx - bx[..., None]) ** 2 + (my - by[..., None]) ** 2 <= r * r))
        xa, ya, xb, yb = s_x + u1 * e_x, s_y + u1 * e_y, s_x + u2 * e_x, s_y + u2 * e_y
        total += np.where(inside, 0.5 * (xa * yb - ya * xb), 0.0).sum(axis=-1)
    return total


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
        # everything that depends on the build alone, once: a READ evaluates the rest
        self.truth = t = truth
        self.rotation = truth.die_rotation()
        self._disc_r, psi = _sunflower(SUN_SAMPLES)
        self._disc_cos, self._disc_sin = np.cos(psi)[:, None], np.sin(psi)[:, None]
        self._gauss_x, self._gauss_w = np.polynomial.legendre.leggauss(STRAY_NODES)
        self.radius_um = t.aperture_diameter_um / 2.0
        # heights of the diaphragm's bottom and top openings [µm]
        self._lower_um = t.height_um - t.diaphragm_thickness_um / 2.0
        self._upper_um = t.height_um + t.diaphragm_thickness_um / 2.0
        self._lo, self._hi = t.gap_um / 2.0, t.detector_side_mm * 500.0
        self._response_a_w = t.responsivity_a_w * np.asarray(t.quadrant_response, dtype=float)
        self._crosstalk = t.crosstalk_matrix()
        self._dark_a = np.asarray(t.dark_na_at_25c) * 1e-9
        self._dark_doubling_c = np.asarray(t.dark_doubling_c)
        self._stray_q = 1.0 - (t.window_radius_mm / t.bore_radius_mm) ** 2  # q of the module docstring

    def die_direction(self, zenith_deg: float, azimuth_deg: float) -> np.ndarray:
        """Unit sun vector in the die frame."""
        z, a = math.radians(zenith_deg), math.radians(azimuth_deg)
        return self.rotation @ np.array([math.sin(z) * math.cos(a), math.sin(z) * math.sin(a), math.cos(z)])

    def _sun_samples(self, s: np.ndarray, source_diameter_deg: float) -> np.ndarray:
        """Directions over the Sun's disc around `s` (unit, die frame), shape (n, 3)."""
        e1 = np.cross(s, [0.0, 0.0, 1.0] if abs(s[2]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        theta = math.radians(source_diameter_deg / 2.0) * self._disc_r
        off = self._disc_cos * e1 + self._disc_sin * e2
        return np.cos(theta)[:, None] * s + np.sin(theta)[:, None] * off

    def _footprint_areas_um2(self, tx, ty) -> np.ndarray:
        """Area of the light through the diaphragm from directions of tangents (tx, ty) (die frame; any shape)
        on each quadrant, shape (4, *shape) [µm²]: the lens of the bottom and top openings' shadows."""
        t, lower, upper = self.truth, self._lower_um, self._upper_um
        tx, ty = np.asarray(tx, dtype=float)[None], np.asarray(ty, dtype=float)[None]
        extra = (1,) * (tx.ndim - 1)
        sx, sy = QUADRANT_SIGNS[:, 0].reshape(4, *extra), QUADRANT_SIGNS[:, 1].reshape(4, *extra)
        # reflect each quadrant onto +x, +y: the centres' signs flip, the rectangle is [lo, hi]²
        ax, ay = sx * (t.x0_um - lower * tx), sy * (t.y0_um - lower * ty)
        bx, by = sx * (t.x0_um - upper * tx), sy * (t.y0_um - upper * ty)
        return lens_rect_area(ax, ay, bx, by, self.radius_um, self._lo, self._hi, self._lo, self._hi)

    def spot_power_w(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float,
                     source_diameter_deg: float = 0.53) -> np.ndarray:
        """Optical power of the direct sunlight on Q1 … Q4 [W]."""
        if irradiance_w_m2 <= 0:
            return np.zeros(4)
        dirs = self._sun_samples(self.die_direction(zenith_deg, azimuth_deg), source_diameter_deg)
        cos_i = dirs[:, 2]
        lit = cos_i > 1e-6
        if not lit.any():
            return np.zeros(4)
        dirs, cos_i = dirs[lit], cos_i[lit]
        area_um2 = self._footprint_areas_um2(dirs[:, 0] / cos_i, dirs[:, 1] / cos_i)
        # each sample carries the irradiance E·cos i over its footprint, 1/n of the Sun's disc
        return irradiance_w_m2 * 1e-12 * (area_um2 * cos_i).sum(axis=1) / self._disc_r.size

    def stray_power_w(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float) -> np.ndarray:
        """Optical power on Q1 … Q4 of the sunlight scattered by the housing's wall through the diaphragm [W]
        (module docstring, "Stray light from the housing"; the Sun taken as a point)."""
        t = self.truth
        s = self.die_direction(zenith_deg, azimuth_deg)
        sin_i = math.hypot(s[0], s[1])
        if irradiance_w_m2 <= 0 or t.wall_reflectance <= 0 or s[2] <= 1e-6:
            return np.zeros(4)
        tan_i = sin_i / s[2]
        rh, h = t.bore_radius_mm, t.bore_height_mm
        if h * tan_i <= rh - t.window_radius_mm:
            return np.zeros(4)  # below the cut-off: the beam through the window misses the wall
        psi_sun = math.atan2(s[1], s[0])
        q = self._stray_q
        m = h * tan_i / rh
        # the lit band: azimuths within `half` of the anti-Sun one; there, depths below the top u1 … u2 (the ray
        # traced back from the wall passes the window), cut by the bore's height
        a_min = math.sqrt(q) if m >= math.sqrt(q) else (m * m + q) / (2.0 * m)
        half = math.acos(min(a_min, 1.0))
        gx, gw = self._gauss_x, self._gauss_w
        psi = psi_sun + math.pi + half * gx
        a = -np.cos(psi - psi_sun)  # > 0 over the band: the wall faces the Sun
        root = np.sqrt(np.maximum(a * a - q, 0.0))
        top = np.clip(h - rh * (a - root) / tan_i, 0.0, h)  # the band's top and bottom [mm]
        bottom = np.clip(h - rh * (a + root) / tan_i, 0.0, h)
        span = np.maximum(top - bottom, 0.0)[:, None]
        z = bottom[:, None] + span * 0.5 * (1.0 + gx[None, :])  # (ψ node, z node) [mm]
        weight = (half * gw)[:, None] * (span * 0.5 * gw[None, :]) * rh  # dA = R_h dψ dz [mm²]
        dist2 = rh * rh + z * z
        wall_irradiance = irradiance_w_m2 * sin_i * a[:, None]
        # radiance ρ E_wall / π, seen from the diaphragm under cos(emission) = R_h/|w|, arriving at
        # cos(incidence) = z/|w| on the die plane, over the solid angle dA/|w|²  → die-plane irradiance
        irradiance = (t.wall_reflectance * wall_irradiance / math.pi * (rh * z / (dist2 * dist2)) * weight)
        areas = self._footprint_areas_um2(rh * np.cos(psi)[:, None] / z, rh * np.sin(psi)[:, None] / z)
        return 1e-12 * (areas * irradiance).sum(axis=(1, 2))

    def quadrant_power_w(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float,
                         source_diameter_deg: float = 0.53) -> np.ndarray:
        """Optical power on Q1 … Q4 [W]: the direct spot and the housing's stray light."""
        return (self.spot_power_w(zenith_deg, azimuth_deg, irradiance_w_m2, source_diameter_deg)
                + self.stray_power_w(zenith_deg, azimuth_deg, irradiance_w_m2))

    def photocurrents_a(self, zenith_deg: float, azimuth_deg: float, irradiance_w_m2: float,
                        source_diameter_deg: float = 0.53) -> np.ndarray:
        """Photocurrents of the channels of Q1 … Q4 (no dark current, no noise) [A]: each quadrant's responsivity
        times its optical power, mixed between neighbours by the crosstalk."""
        quadrant = self._response_a_w * self.quadrant_power_w(zenith_deg, azimuth_deg, irradiance_w_m2,
                                                              source_diameter_deg)
        return self._crosstalk @ quadrant

    def dark_current_a(self, die_temperature_c: float) -> np.ndarray:
        """Dark currents of Q1 … Q4 at the die's true temperature [A]."""
        return self._dark_a * np.exp2((die_temperature_c - DARK_REFERENCE_C) / self._dark_doubling_c)


# -- electronics ----------------------------------------------------------------------------------------------
class QdChannels:
    """The four channels' amplifiers and ADCs of one build (module docstring, "Electronics, dark current,
    temperature"), their constants taken once."""

    def __init__(self, truth: QdTruth):
        self.full_scale_counts = truth.full_scale_counts
        self._t_int_s = truth.integration_ms / 1000.0
        self._amp_noise_a2 = (truth.amp_noise_pa * 1e-12) ** 2
        self._zero_counts = np.asarray(truth.pedestal_counts + np.asarray(truth.pedestal_error_counts))
        self._amperes_per_count = truth.amperes_per_count

    def sample_counts(self, currents_a: np.ndarray, n: int, rng: np.random.Generator,
                      faults: ChannelFaults | None = None) -> np.ndarray:
        """ADC codes of `n` samples of the four channels for the true input currents (photo + dark) [A], shape
        (n, 4)."""
        current = np.array(currents_a, dtype=float)
        if faults is not None:
            for q in faults.dead:
                current[q - 1] = 0.0
        sigma = np.sqrt(Q_E * np.maximum(current, 0.0) / self._t_int_s + self._amp_noise_a2)
        noisy = current + sigma * rng.standard_normal((n, 4))
        full = self.full_scale_counts
        counts = np.clip(np.rint(self._zero_counts + noisy / self._amperes_per_count), 0, full).astype(np.int64)
        if faults is not None:
            for q in faults.saturated:
                counts[:, q - 1] = full
            for q, value in faults.stuck.items():
                counts[:, q - 1] = int(np.clip(value, 0, full))
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
