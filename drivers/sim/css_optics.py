"""Physics of the simulated coarse-sun-sensor (CSS) head of seed 000 — the simulator's own, not the fit's.

The head is a cube with a triplet at each face's centre (seed 000 §3.1, digest §5.3): an EPD-365 UV photodiode
(``uv``), a BPW 21 visible photodiode (``vis``) and a TPS 230 thermopile (``ir``). Faces are named by their outward
normal (``px`` = +X … ``mz`` = −Z; the thesis' faces 1 … 6 are px, py, mx, my, pz, mz), channels are
``<face>_<type>`` face-major (px_uv, px_vis, px_ir, py_uv …). This module knows those names itself: drivers do not
import calibration/ (tests/test_conventions.py), and the bench checks the two lists agree.

Each detector's signal (amperes for the photodiodes in photovoltaic mode, volts for the thermopile) is

    signal = scale · (1 + c_T (T − 25 °C)) · E/E_ref · response(incidence) + bias + b_T (T − 25 °C)

with the incidence measured on the detector's *true* normal (the face's, tilted by its build error). The
response law (``DiodeTruth.response``):

* ``fresnel`` (default, the physical one): the cosine of the projected area, the window's Fresnel transmittance
  (flat glass of index 1.5, unpolarised light, relative to normal incidence) and the shadow of the package's cap:
  the detector (a disc of radius r) under a round aperture (radius a, height h above it) is lit where the
  aperture's image, displaced by h·tan θ, overlaps it — a soft field-of-view edge from atan((a − r)/h) to
  atan((a + r)/h). The thermopile's law is its datasheet field-of-view curve (seed 000 Table B/D.2 points, 82° at
  50 %), pchip-interpolated, times the cap's shadow.
* ``kelly``: Basilisk's coarseSunSensor law γ (1 − exp(−γ²/κ)), γ = cos θ, with a linear-ramp field-of-view edge of
  full width ``edge_width_deg`` centred on ``fov_half_deg`` — a law a calibration can hold exactly, for coverage
  tests.
* ``power``: γ^p with the same edge.
* ``thesis``: the curve seed 000 used for every photodiode (digest §3.5: Table C.1's sun/0° column is the TPS
  field-of-view table through pchip), no cap.

Light reaches a detector from the source (the lab's sun simulator or the Sun, a point source) and, in orbit
studies, from the Earth (:class:`EarthScene`): a uniformly lit Lambertian disc of angular radius ρ seen in
direction e, whose radiance gives a face at normal incidence a·f·E·sin²ρ (its irradiance integrated numerically
over the disc through each detector's response), and the thermopiles see its 288 K against 3 K space.

Noise (:meth:`CssOptics.noise_sd`) is the physical chain of seed 000 §4 as its digest §8.1 item 3 corrects it:
shot noise 2q I B, the Johnson noise of R_sh ∥ R_in (photodiodes) at the head's temperature, the amplifier's
voltage and current noise over the bandwidth GBW/G, the thermopile's 40 nV/√Hz, all ÷ √N for the N samples the
ADC averages (16); the ADC's quantisation is the electronics' (:class:`CssChannels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from .device import ChannelFaults

FACES = ("px", "py", "mx", "my", "pz", "mz")
TYPES = ("uv", "vis", "ir")
CHANNELS = tuple(f"{face}_{kind}" for face in FACES for kind in TYPES)
NORMALS = {"px": (1.0, 0.0, 0.0), "py": (0.0, 1.0, 0.0), "mx": (-1.0, 0.0, 0.0),
           "my": (0.0, -1.0, 0.0), "pz": (0.0, 0.0, 1.0), "mz": (0.0, 0.0, -1.0)}

Q_E = 1.602176634e-19  # C
K_B = 1.380649e-23  # J/K
SIGMA_SB = 5.670374419e-8  # W m⁻² K⁻⁴

#: TPS 230 datasheet field of view (relative sensitivity against angle from the axis [°]), seed 000 listing D.2
TPS_FOV_DEG = (0.0, 20.0, 40.0, 60.0, 80.0, 90.0)
TPS_FOV_SENSITIVITY = (1.0, 0.95, 0.5, 0.05, 0.005, 0.0)
_TPS_CURVE = PchipInterpolator(TPS_FOV_DEG, TPS_FOV_SENSITIVITY)


@dataclass(frozen=True)
class FrontEnd:
    """One detector type's front end (seed 000 §3.6 and §4.2): load, amplifier, bandwidth, ADC range."""

    load_ohm: float  # R_in: the photodiode's load (photovoltaic mode); the thermopile's source resistance
    gain: float  # 1 + R2/R1 (eq. 4.1)
    amp_voltage_noise_v_rthz: float = 18e-9  # LTC6079 e_n
    amp_current_noise_a_rthz: float = 0.56e-15  # LTC6079 i_n (the thesis' 350 pA is a total, not a density)
    detector_noise_v_rthz: float = 0.0  # the thermopile's own 40 nV/√Hz
    shunt_ohm_at_25c: float = math.inf  # R_sh, halving every 10 °C (EPD, seed 000 §3.2)
    full_scale: float = 1.0  # [A] or [V]: the ADC's range above the pedestal
    bipolar: bool = False  # the thermopile's voltage has either sign: mid-scale pedestal

    @property
    def bandwidth_hz(self) -> float:
        """GBW / G with the LTC6079's 360 kHz (eq. 4.2)."""
        return 360e3 / self.gain


#: Front ends by type: EPD 100 kΩ, G 4.3; BPW 2.2 kΩ, G 4.3; TPS behind G 403 (seed 000 §3.6). The ranges are the
#: simulated module's own: the thesis' BPW would saturate in the full Sun (digest §3.6 ⚠), so its channel is a
#: transimpedance stage whose range holds 1.7 suns.
FRONT_ENDS = {
    "uv": FrontEnd(load_ohm=100e3, gain=4.3, shunt_ohm_at_25c=200e9, full_scale=12e-6),
    "vis": FrontEnd(load_ohm=2.2e3, gain=4.3, full_scale=2.0e-3),
    "ir": FrontEnd(load_ohm=110e3, gain=330e3 / 820 + 1, detector_noise_v_rthz=40e-9, full_scale=5e-3, bipolar=True),
}

#: Package geometry (aperture radius a, detector radius r, aperture height h) [mm] of the ``fresnel`` law's cap shadow
CAPS = {"uv": (1.9, 0.62, 0.60), "vis": (2.6, 1.55, 0.95), "ir": (1.75, 0.25, 0.35)}


@dataclass(frozen=True)
class DiodeTruth:
    """One detector as built.

    Attributes
    ----------
    channel : str
        ``<face>_<type>``.
    normal_zenith_deg, normal_azimuth_deg : float
        The detector's true normal in the head's body frame [°].
    scale : float
        Signal at normal incidence, reference irradiance and 25 °C [A] (photodiodes) or [V] (thermopile).
    bias : float
        Offset at 25 °C [A] or [V] (front-end offset, dark current).
    response : str
        ``fresnel``, ``kelly``, ``power`` or ``thesis`` (module docstring).
    kelly_kappa, power : float
        The ``kelly`` and ``power`` laws' parameters.
    fov_half_deg, edge_width_deg : float
        Field-of-view cut-off of the ``kelly`` and ``power`` laws: a linear ramp of full width `edge_width_deg`
        centred on `fov_half_deg` [°].
    temp_coeff_per_c : float
        Relative change of the responsivity per °C (BPW 21: −0.05 %/K).
    bias_temp_coeff : float
        Change of the offset per °C [A/°C] or [V/°C] (the thermopile sees a scene colder than itself as the head
        warms: about −26 µV/K near 25 °C, seed 000 Table 4).
    """

    channel: str
    normal_zenith_deg: float
    normal_azimuth_deg: float
    scale: float
    bias: float = 0.0
    response: str = "fresnel"
    kelly_kappa: float = 0.12
    power: float = 1.2
    fov_half_deg: float = 80.0
    edge_width_deg: float = 2.0
    temp_coeff_per_c: float = 0.0
    bias_temp_coeff: float = 0.0

    @property
    def kind(self) -> str:
        return self.channel.split("_", 1)[1]

    @property
    def normal(self) -> np.ndarray:
        th, ph = math.radians(self.normal_zenith_deg), math.radians(self.normal_azimuth_deg)
        return np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])


#: Nominal signal at normal incidence under one AM0 Sun (1366 W/m²): Table C.1's 0° values for EPD and BPW; the
#: TPS behind its 5.5 µm filter takes ~1.5 % of the Sun's power on 0.2 mm² at 42 V/W
NOMINAL_SCALE = {"uv": 6.18e-6, "vis": 1.17e-3, "ir": 0.13e-3}
TEMP_COEFF = {"uv": 1.0e-3, "vis": -0.5e-3, "ir": -0.5e-3}
BIAS = {"uv": 0.05e-9, "vis": 4.5e-9, "ir": 2e-6}
BIAS_TEMP_COEFF = {"uv": 0.0, "vis": 0.05e-9, "ir": -26e-6}


@dataclass(frozen=True)
class CssTruth:
    """A head as built: `diodes` in :data:`CHANNELS` order."""

    serial: str
    diodes: tuple[DiodeTruth, ...]
    samples_averaged: int = 16

    def __post_init__(self) -> None:
        if tuple(d.channel for d in self.diodes) != CHANNELS:
            raise ValueError(f"a head has the 18 detectors {', '.join(CHANNELS)} in that order")

    def diode(self, channel: str) -> DiodeTruth:
        return self.diodes[CHANNELS.index(channel)]


def _face_angles(face: str) -> tuple[float, float]:
    x, y, z = NORMALS[face]
    return math.degrees(math.acos(z)), math.degrees(math.atan2(y, x)) % 360.0


def css_truth(serial: str = "CSS-0001", seed: int | None = None, response: str = "fresnel", *,
              tilt_sd_deg: float = 1.0, scale_sd: float = 0.03) -> CssTruth:
    """A head: nominal detectors, or with build errors drawn from `seed` (normal tilts of `tilt_sd_deg` per axis,
    relative scale spread `scale_sd`, offsets around their nominal values); every detector uses `response`."""
    rng = np.random.default_rng(seed) if seed is not None else None
    diodes = []
    for name in CHANNELS:
        face, kind = name.split("_")
        zenith, azimuth = _face_angles(face)
        scale, bias = NOMINAL_SCALE[kind], BIAS[kind]
        if rng is not None:
            normal = np.array(NORMALS[face]) + np.radians(tilt_sd_deg) * rng.standard_normal(3)
            normal /= np.linalg.norm(normal)
            zenith = math.degrees(math.acos(normal[2]))
            azimuth = math.degrees(math.atan2(normal[1], normal[0])) % 360.0
            scale *= 1 + scale_sd * rng.standard_normal()
            bias *= 1 + 0.5 * rng.standard_normal()
        diodes.append(DiodeTruth(name, zenith, azimuth, scale, bias, response,
                                 fov_half_deg=85.0 if kind == "ir" else 80.0, temp_coeff_per_c=TEMP_COEFF[kind],
                                 bias_temp_coeff=BIAS_TEMP_COEFF[kind]))
    return CssTruth(serial, tuple(diodes))


# -- response laws ----------------------------------------------------------------------------------------------
def fresnel_transmittance(theta_rad, n: float = 1.5) -> np.ndarray:
    """Unpolarised transmittance of one air–glass surface at incidence θ (Fresnel's equations) [unitless]."""
    ci = np.cos(theta_rad)
    st = np.sin(theta_rad) / n
    ct = np.sqrt(np.clip(1.0 - st * st, 0.0, 1.0))
    rs = ((ci - n * ct) / (ci + n * ct)) ** 2
    rp = ((ct - n * ci) / (ct + n * ci)) ** 2
    return 1.0 - 0.5 * (rs + rp)


def cap_overlap(theta_rad, aperture_mm: float, detector_mm: float, height_mm: float) -> np.ndarray:
    """Share of a round detector (radius r) lit through a round aperture (radius a, height h above it) for light
    at incidence θ: the area where the two discs overlap, displaced by h·tan θ, over the detector's area."""
    d = height_mm * np.tan(np.clip(theta_rad, 0.0, math.radians(89.999)))
    a, r = aperture_mm, detector_mm
    full = d <= abs(a - r)
    none = d >= a + r
    dd = np.where(full | none, (a + r) / 2, d)  # keeps the lens formula finite where it is not used
    c1 = np.clip((dd * dd + r * r - a * a) / (2 * dd * r), -1, 1)
    c2 = np.clip((dd * dd + a * a - r * r) / (2 * dd * a), -1, 1)
    lens = (r * r * np.arccos(c1) + a * a * np.arccos(c2)
            - 0.5 * np.sqrt(np.clip((-dd + r + a) * (dd + r - a) * (dd - r + a) * (dd + r + a), 0, None)))
    share = lens / (math.pi * r * r)
    inside = min(a, r) ** 2 / (r * r)
    return np.where(full, inside, np.where(none, 0.0, share))


def _edge(theta_deg, centre_deg: float, width_deg: float) -> np.ndarray:
    if width_deg <= 0:
        return (theta_deg < centre_deg).astype(float)
    return np.clip((centre_deg + width_deg / 2 - theta_deg) / width_deg, 0.0, 1.0)


def response(diode: DiodeTruth, cos_incidence) -> np.ndarray:
    """The detector's relative response (1 at normal incidence) to a point source at the given cosines."""
    g = np.clip(np.asarray(cos_incidence, float), -1.0, 1.0)
    lit = g > 0
    theta = np.arccos(np.where(lit, g, 0.0))
    theta_deg = np.degrees(theta)
    law = diode.response
    kind = diode.kind
    if law == "fresnel":
        a, r, h = CAPS[kind]
        cap = cap_overlap(theta, a, r, h) / cap_overlap(0.0, a, r, h)
        if kind == "ir":
            out = _TPS_CURVE(np.minimum(theta_deg, 90.0)) * cap
        else:
            out = g * fresnel_transmittance(theta) / fresnel_transmittance(0.0) * cap
    elif law == "kelly":
        out = g * (1.0 - np.exp(-g * g / diode.kelly_kappa)) / (1.0 - math.exp(-1.0 / diode.kelly_kappa))
        out = out * _edge(theta_deg, diode.fov_half_deg, diode.edge_width_deg)
    elif law == "power":
        out = np.where(lit, g, 0.0) ** diode.power * _edge(theta_deg, diode.fov_half_deg, diode.edge_width_deg)
    elif law == "thesis":
        out = _TPS_CURVE(np.minimum(theta_deg, 90.0))
    else:
        raise ValueError(f"no response law {law!r} (fresnel, kelly, power, thesis)")
    return np.where(lit, np.maximum(out, 0.0), 0.0)


def band_exitance(temperature_k: float, low_m: float = 5.5e-6, high_m: float = 40e-6) -> float:
    """Black-body exitance between two wavelengths (the TPS 230's filter passes beyond 5.5 µm) [W/m²]: Planck's law
    integrated numerically on a logarithmic grid."""
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    lam = np.geomspace(low_m, high_m, 2000)
    spectral = 2 * math.pi * h * c * c / lam ** 5 / np.expm1(h * c / (lam * k * temperature_k))
    return float(np.sum(0.5 * (spectral[1:] + spectral[:-1]) * np.diff(lam)))


# -- the Earth --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EarthScene:
    """The Earth as a detector in orbit sees it.

    Attributes
    ----------
    direction : array (3,)
        Unit vector to the Earth's centre in the body frame.
    angular_radius_deg : float
        ρ = asin(R_E / (R_E + h)) [°] (65° at about 660 km, seed 000 §2.2).
    albedo : float
        Share of the sunlight the lit disc returns (0.3, seed 000 §2.2).
    lit_fraction : float
        Share of the visible disc in daylight (0 on the night side: IR only), when `sun_direction` is not given.
    temperature_k : float
        The Earth's own emission as a black body (288 K) against space at 3 K.
    sun_direction : array (3,) or None
        The Sun's direction in the same frame: each point of the disc then returns a·E·max(0, cos z)/π, z the
        solar zenith at the ground point the line of sight meets (a crescent Earth near the terminator), instead
        of a uniformly lit disc.
    """

    direction: tuple[float, float, float]
    angular_radius_deg: float = 65.0
    albedo: float = 0.3
    lit_fraction: float = 1.0
    temperature_k: float = 288.0
    sun_direction: tuple[float, float, float] | None = None

    def ground_cosines(self, lines_of_sight) -> np.ndarray:
        """cos of the solar zenith at the ground points that unit `lines_of_sight` (K, 3) meet (the Earth a sphere
        of angular radius ρ at unit distance R/sin ρ), negative on the night side; needs `sun_direction`."""
        e = np.asarray(self.direction, float)
        e = e / np.linalg.norm(e)
        sun = np.asarray(self.sun_direction, float)
        sun = sun / np.linalg.norm(sun)
        rho = math.radians(self.angular_radius_deg)
        radius, distance = math.sin(rho), 1.0  # lengths in units of the distance to the Earth's centre
        u = np.asarray(lines_of_sight, float)
        ue = u @ e
        t = distance * ue - np.sqrt(np.clip(radius ** 2 - distance ** 2 * (1.0 - ue ** 2), 0.0, None))
        ground = (t[:, None] * u - distance * e) / radius
        return ground @ sun


def _disc_quadrature(direction, radius_deg: float, rings: int = 16, spokes: int = 32):
    """Directions over a disc of angular radius ρ around `direction` and their solid angles [sr]."""
    e = np.asarray(direction, float)
    e = e / np.linalg.norm(e)
    helper = np.array([1.0, 0.0, 0.0]) if abs(e[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(e, helper)
    u /= np.linalg.norm(u)
    v = np.cross(e, u)
    rho = math.radians(radius_deg)
    edges = np.linspace(0.0, rho, rings + 1)
    mid = 0.5 * (edges[1:] + edges[:-1])
    ring_sr = 2 * math.pi * (np.cos(edges[:-1]) - np.cos(edges[1:]))
    phi = (np.arange(spokes) + 0.5) * 2 * math.pi / spokes
    s, c = np.sin(mid)[:, None], np.cos(mid)[:, None]
    dirs = c[..., None] * e + s[..., None] * (np.cos(phi)[None, :, None] * u + np.sin(phi)[None, :, None] * v)
    weights = np.repeat(ring_sr[:, None] / spokes, spokes, axis=1)
    return dirs.reshape(-1, 3), weights.ravel()


class CssOptics:
    """The head's detectors under a source (and the Earth, in orbit studies)."""

    def __init__(self, truth: CssTruth):
        self.truth = truth
        self._normals = np.array([d.normal for d in truth.diodes])
        self._scale = np.array([d.scale for d in truth.diodes])
        self._bias = np.array([d.bias for d in truth.diodes])
        self._tc = np.array([d.temp_coeff_per_c for d in truth.diodes])
        self._btc = np.array([d.bias_temp_coeff for d in truth.diodes])
        self._kinds = [d.kind for d in truth.diodes]

    def responses(self, vectors) -> np.ndarray:
        """Relative response of every detector to point sources in body directions `vectors` (..., 3): (..., 18)."""
        cosines = np.asarray(vectors, float) @ self._normals.T
        out = np.empty(cosines.shape)
        for i, diode in enumerate(self.truth.diodes):
            out[..., i] = response(diode, cosines[..., i])
        return out

    def earth_signals(self, earth: EarthScene, temperature_c: float = 25.0) -> np.ndarray:
        """Noise-free signal the Earth adds to each detector (18,): albedo on the photodiodes, IR on the thermopiles.

        A Lambertian disc of radiance L = a·f·E/π gives a face at normal incidence a·f·E·sin²ρ; the integral here
        runs through each detector's own response. The thermopile's is the Earth's black-body radiance in its band
        (beyond the 5.5 µm cut-on) over the same integral, relative to the Sun's in-band radiance × its solid angle,
        which its `scale` stands for: the Earth outshines the Sun on a thermopile some forty times (its offset —
        the detector's own emission against the scene — is the bench's, a room at 25 °C; in orbit it differs)."""
        dirs, weights = _disc_quadrature(earth.direction, earth.angular_radius_deg)
        responses = self.responses(dirs) * weights[:, None]
        seen = responses.sum(axis=0) / math.pi  # a uniform unit-radiance disc
        gain = self._scale * (1 + self._tc * (temperature_c - 25.0))
        is_ir = np.array([k == "ir" for k in self._kinds])
        if earth.sun_direction is None:
            albedo = earth.albedo * earth.lit_fraction * seen
        else:  # each ground point returns a·E·cos z/π
            lit = np.maximum(earth.ground_cosines(dirs), 0.0)
            albedo = earth.albedo * (responses * lit[:, None]).sum(axis=0) / math.pi
        sun_sr = math.pi * math.radians(0.2666) ** 2
        ir = seen * math.pi * band_exitance(earth.temperature_k) / (band_exitance(5780.0) * sun_sr)
        return gain * np.where(is_ir, ir, albedo)

    def signals(self, sun_vector, irradiance: float = 1.0, temperature_c: float = 25.0,
                earth: EarthScene | None = None) -> np.ndarray:
        """Noise-free signals of the 18 detectors [A or V], shape (..., 18).

        `sun_vector` (..., 3) unit direction to the source in the body frame; `irradiance` relative to the
        reference (0 in eclipse or with the shutter closed); `temperature_c` the head's; `earth` adds the Earth."""
        sun = np.asarray(sun_vector, float)
        gain = self._scale * (1 + self._tc * (np.asarray(temperature_c, float)[..., None] - 25.0))
        out = gain * irradiance * self.responses(sun)
        out = out + self._bias + self._btc * (np.asarray(temperature_c, float)[..., None] - 25.0)
        if earth is not None:
            out = out + self.earth_signals(earth, float(np.mean(temperature_c)))
        return out

    def noise_sd(self, signals, temperature_c: float = 25.0) -> np.ndarray:
        """1σ noise of one averaged reading of each detector [A or V], shape of `signals` (module docstring)."""
        s = np.asarray(signals, float)
        t_k = temperature_c + 273.15
        n = self.truth.samples_averaged
        out = np.empty(s.shape)
        for i, kind in enumerate(self._kinds):
            fe = FRONT_ENDS[kind]
            b = fe.bandwidth_hz
            if kind == "ir":
                v2 = (fe.detector_noise_v_rthz ** 2 + fe.amp_voltage_noise_v_rthz ** 2) * b \
                    + (fe.amp_current_noise_a_rthz * fe.load_ohm) ** 2 * b + 4 * K_B * t_k * fe.load_ohm * b
                out[..., i] = math.sqrt(v2)
                continue
            r_sh = fe.shunt_ohm_at_25c * 2.0 ** (-(temperature_c - 25.0) / 10.0)
            r_p = 1.0 / (1.0 / fe.load_ohm + (0.0 if math.isinf(r_sh) else 1.0 / r_sh))
            i2 = 2 * Q_E * np.abs(s[..., i]) * b + 4 * K_B * t_k * b / r_p \
                + fe.amp_current_noise_a_rthz ** 2 * b + (fe.amp_voltage_noise_v_rthz / r_p) ** 2 * b
            out[..., i] = np.sqrt(i2)
        return out / math.sqrt(n)

    def reading(self, rng: np.random.Generator, sun_vector, irradiance: float = 1.0, temperature_c: float = 25.0,
                earth: EarthScene | None = None) -> np.ndarray:
        """Noisy signals (the electronics' quantisation aside), shape (..., 18)."""
        clean = self.signals(sun_vector, irradiance, temperature_c, earth)
        return clean + self.noise_sd(clean, temperature_c) * rng.standard_normal(clean.shape)

    def tps_seen_temperature_c(self, earth: EarthScene | None, sun_vector=None, sun_visible: bool = True) -> np.ndarray:
        """Each face's thermopile "seen temperature" (seed 000 eq. 3.3, the thesis' linear average of the scene's
        temperatures weighted by the detector's sensitivity), over the whole sphere in solid angle rather than the
        thesis' 1-D cut: Earth at its temperature, the Sun (5780 K over its 0.53° disc), space at 3 K. Shape (6,)."""
        ir = [i for i, k in enumerate(self._kinds) if k == "ir"]
        sphere, w_sphere = _disc_quadrature((0.0, 0.0, 1.0), 180.0, rings=90, spokes=72)
        total = (self.responses(sphere)[:, ir] * w_sphere[:, None]).sum(axis=0)
        temp = 3.0 * np.ones(len(ir))
        if earth is not None:
            dirs, w = _disc_quadrature(earth.direction, earth.angular_radius_deg)
            seen = (self.responses(dirs)[:, ir] * w[:, None]).sum(axis=0)
            temp = temp + (earth.temperature_k - 3.0) * seen / total
        if sun_vector is not None and sun_visible:
            sun_sr = math.pi * math.radians(0.2666) ** 2
            temp = temp + (5780.0 - 3.0) * self.responses(np.asarray(sun_vector, float))[ir] * sun_sr / total
        return temp - 273.15


# -- electronics ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CssChannels:
    """The 18 channels' ADCs: `bits`, unipolar ranges from zero (photodiodes) or bipolar around mid-scale
    (thermopiles), each type's full scale from :data:`FRONT_ENDS`."""

    bits: int = 16

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.bits) - 1

    def pedestals(self) -> np.ndarray:
        """Counts of a zero signal per channel."""
        half = (1 << (self.bits - 1))
        return np.array([half if FRONT_ENDS[c.split("_")[1]].bipolar else 64 for c in CHANNELS])

    def units_per_count(self) -> np.ndarray:
        """[A/count] or [V/count] per channel."""
        out = []
        for c in CHANNELS:
            fe = FRONT_ENDS[c.split("_")[1]]
            span = (1 << (self.bits - 1)) if fe.bipolar else self.full_scale_counts - 64
            out.append(fe.full_scale / span)
        return np.array(out)

    def counts(self, signals, faults: ChannelFaults | None = None) -> np.ndarray:
        """ADC codes of noisy signals (..., 18), clipped to the range; the stuck and saturated faults applied (a dead
        detector loses its light before its front end: the caller leaves it out of `signals`)."""
        s = np.asarray(signals, float)
        pedestal = self.pedestals()
        codes = np.clip(np.rint(pedestal + s / self.units_per_count()), 0, self.full_scale_counts).astype(np.int64)
        if faults is not None:
            for name in faults.saturated:
                codes[..., CHANNELS.index(name)] = self.full_scale_counts
            for name, value in faults.stuck.items():
                codes[..., CHANNELS.index(name)] = int(np.clip(value, 0, self.full_scale_counts))
        return codes
