"""The calibration model of one coarse-sun-sensor detector, and of a head of them.

One detector (a photodiode's current [A] or a thermopile's voltage [V]) reads

    m = S · (1 + c_T (T − 25 °C)) · R(γ) · E(θ) + b + b_T (T − 25 °C)

* γ = n·s, the cosine of the incidence θ of the Sun s on the detector's *true* normal n. n is the face's nominal
  normal n₀ tilted by two small angles about the face's in-plane axes (:data:`TILT_AXES`): n ∝ n₀ + tan t_u · u
  + tan t_v · v, so t_u and t_v are the normal's projection angles on the (n₀, u) and (n₀, v) planes. Unlike the
  normal's body zenith and azimuth they have no singularity on any face (pz's normal has no azimuth to speak of);
  :func:`normal_angles` gives zenith and azimuth for reports.
* R is the angular response law, normalised to R(1) = 1 so that S is the signal at normal incidence:

  - ``kelly``: Basilisk's coarseSunSensor law R = γ (1 − exp(−γ²/κ)) / (1 − exp(−1/κ)) (γ > 0; 0 otherwise), the
    cosine with the extra fall-off near grazing incidence of a real detector; κ → 0 is the plain cosine, κ → ∞
    tends to γ³;
  - ``power``: R = γ^p (γ > 0; 0 otherwise);
  - ``spline``: R a cubic B-spline in γ on fixed knots θ_k over 0…90° (:mod:`calibration.css.spline`), R(1) = 1
    and R = 0 beyond its last knot (and never below 0), its K + 1 coefficients ``spline_1`` … the law's parameters:
    a smooth, flexible response that holds a detector's window, its package's shadow and its field-of-view cut-off
    alike (no E: its θ_c is None).

* E is the field-of-view cut-off at half-angle θ_c: a linear ramp of full width :data:`FOV_EDGE_WIDTH_DEG` centred
  on θ_c, E = clip((θ_c + w/2 − θ) / w, 0, 1), so least squares can move θ_c; no cut-off (E ≡ 1) when θ_c is None.
* S is the signal at normal incidence at the reference irradiance and 25 °C, c_T its relative change per °C;
  b the offset at 25 °C (dark current, the front end's offset), b_T its change per °C.

The noise of one reading is σ² = σ₀² + q·|m| + (r·m)²: a floor σ₀ (Johnson and amplifier noise, the ADC's
resolution), a shot-noise term q·|m| (2 q_e B ∝ the current, seed 000 digest §4.4 and §8.1 item 3) and a relative
term r (the lamp's flicker, gain noise).

Every function is vectorised; :class:`HeadModel` holds K detectors as arrays and gives their signals and the
derivatives with respect to the Sun vector (the sun-vector estimator, :mod:`calibration.css.estimate`).

References
----------
seed 000, eq. 3.1 (I = S_rel(φ)·A·Σ E S Δλ: the signal is a scale times a relative angular response), §3.1–3.4 (the
detectors, their temperature coefficients), digest §8.1 item 1 and §8.3 items 7–8 (fit scale K, dark offset,
normal misalignment, a cosine^n or other angular law, "pchip through knots"), Table C.1 (the response tabulated
against the incidence); research note anchors-sunsensors §5 (Basilisk's
coarseSunSensor: cos · Kelly factor · FOV cut-off, bias, scale factor).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from functools import cached_property

import numpy as np

from .head import CHANNELS, NORMALS, split_channel, vector_angles
from .spline import (
    SPLINE_KNOTS_DEG,
    SplineSet,
    check_knots,
    cosine_coefficients,
    evaluate,
    n_free,
    spline_basis,
    spline_index,
    spline_names,
)

#: Temperature at which S and b are quoted [°C]
REFERENCE_TEMPERATURE_C = 25.0
#: Angular response laws of the model
RESPONSES = ("kelly", "power", "spline")
#: The shape parameter's name by parametric law (the ``spline`` law has its coefficients ``spline_1`` … instead)
SHAPE_NAME = {"kelly": "kappa", "power": "power"}
#: Each law's code (:attr:`HeadModel.law`, the C header's SUNBENCH_CSS_RESPONSE)
LAW_CODES = {"kelly": 0, "power": 1, "spline": 2}
SPLINE = "spline"
#: Full width of the field-of-view edge's linear ramp [°]
FOV_EDGE_WIDTH_DEG = 2.0

#: In-plane axes (u, v) of each face, u × v = n₀: side faces u along increasing azimuth, v = +Z (the normal's
#: elevation); pz u = +X, v = +Y; mz u = +X, v = −Y
TILT_AXES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "px": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "py": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "mx": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "my": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "pz": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "mz": ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
}

#: Names of the model's parameters in the order of a parameter vector (the shape is ``kappa`` or ``power``; the
#: ``spline`` law has no shape and its coefficients ``spline_1`` … after these)
PARAMETER_NAMES = ("scale", "bias", "tilt_u_deg", "tilt_v_deg", "shape", "fov_half_deg", "temp_coeff_per_c",
                   "bias_temp_coeff_per_c")

_DEG = np.pi / 180.0


# -- the normal ---------------------------------------------------------------------------------------------------
def face_axes(face: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n₀, u, v) of `face`: its nominal outward normal and its two in-plane tilt axes (unit vectors, u × v = n₀).

    References
    ----------
    seed 000 ch. 5.3.1 (face numbering and frame, digest §5.3); :data:`TILT_AXES`.
    """
    if face not in TILT_AXES:
        raise ValueError(f"no face {face!r} (faces: {', '.join(TILT_AXES)})")
    u, v = TILT_AXES[face]
    return np.array(NORMALS[face], float), np.array(u, float), np.array(v, float)


def tilted_normal(face: str, tilt_u_deg=0.0, tilt_v_deg=0.0) -> np.ndarray:
    """The unit normal n ∝ n₀ + tan t_u · u + tan t_v · v of a detector on `face` [unitless], shape (..., 3).

    References
    ----------
    seed 000 digest §8.3 item 8 (detector normal misalignment; TPS optical axis 0 ± 10°, Table B).
    """
    n0, u, v = face_axes(face)
    a = np.tan(np.asarray(tilt_u_deg, float) * _DEG)[..., None]
    b = np.tan(np.asarray(tilt_v_deg, float) * _DEG)[..., None]
    w = n0 + a * u + b * v
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def tilts_from_normal(face: str, normal) -> tuple[np.ndarray, np.ndarray]:
    """(t_u, t_v) [°] of a normal vector (need not be unit) on `face`: inverse of :func:`tilted_normal`.

    The normal must lie in front of the face (n·n₀ > 0).

    References
    ----------
    seed 000 digest §8.3 item 8.
    """
    n0, u, v = face_axes(face)
    n = np.asarray(normal, float)
    along = n @ n0
    if np.any(along <= 0):
        raise ValueError(f"a normal of face {face} must point out of it (n·n₀ > 0)")
    return np.degrees(np.arctan2(n @ u, along)), np.degrees(np.arctan2(n @ v, along))


def normal_angles(face: str, tilt_u_deg=0.0, tilt_v_deg=0.0) -> tuple[np.ndarray, np.ndarray]:
    """Body zenith and azimuth [°] of the tilted normal (DESIGN.md convention; azimuth 0 on the +Z axis).

    References
    ----------
    seed 000 digest §5.3 (frame); DESIGN.md (zenith from +Z, azimuth from +X toward +Y).
    """
    return vector_angles(tilted_normal(face, tilt_u_deg, tilt_v_deg))


def _normal_partials(face: str, tilt_u_deg, tilt_v_deg):
    """n and ∂n/∂t_u, ∂n/∂t_v [per °], each (..., 3)."""
    n0, u, v = face_axes(face)
    tu = np.asarray(tilt_u_deg, float) * _DEG
    tv = np.asarray(tilt_v_deg, float) * _DEG
    a, b = np.tan(tu)[..., None], np.tan(tv)[..., None]
    w = n0 + a * u + b * v
    length = np.linalg.norm(w, axis=-1, keepdims=True)
    n = w / length
    dn_da = (u - n * (n @ u)[..., None]) / length
    dn_db = (v - n * (n @ v)[..., None]) / length
    return n, dn_da / np.cos(tu)[..., None] ** 2 * _DEG, dn_db / np.cos(tv)[..., None] ** 2 * _DEG


# -- the angular response -----------------------------------------------------------------------------------------
def kelly_response(cos_incidence, kappa) -> np.ndarray:
    """Basilisk's coarseSunSensor response γ (1 − exp(−γ²/κ)), normalised to 1 at normal incidence [unitless].

    0 where γ ≤ 0 (the Sun behind the detector). κ > 0.

    References
    ----------
    research note anchors-sunsensors §5 (Basilisk coarseSunSensor: normalized cosine times the Kelly factor
    f = 1 − exp(−γ²/κ)); seed 000 eq. 3.1 (S_rel(φ)).
    """
    return _kelly(np.asarray(cos_incidence, float), np.asarray(kappa, float))[0]


def power_response(cos_incidence, power) -> np.ndarray:
    """γ^p for γ > 0, 0 otherwise [unitless] (a cosine^n law).

    References
    ----------
    seed 000 digest §8.3 item 7 (fit the angular response as cosine^n); research note anchors-sunsensors §5
    (Basilisk's kPower).
    """
    return _power(np.asarray(cos_incidence, float), np.asarray(power, float))[0]


def fov_edge(incidence_deg, fov_half_deg, width_deg: float = FOV_EDGE_WIDTH_DEG) -> np.ndarray:
    """Field-of-view cut-off: a linear ramp from 1 to 0 of full width `width_deg` centred on `fov_half_deg` [°].

    `fov_half_deg` None (or NaN) is no cut-off: 1 everywhere.

    References
    ----------
    research note anchors-sunsensors §5 (Basilisk coarseSunSensor: FOV half-angle cut-off); seed 000 Table B
    (TPS 230 field of view 82° at 50 %), digest §3.2–3.3 (BPW ±55°, EPD 50° acceptance).
    """
    theta = np.asarray(incidence_deg, float)
    if fov_half_deg is None:
        return np.ones_like(theta)
    fov = np.asarray(fov_half_deg, float)
    ramp = np.clip((fov + width_deg / 2.0 - theta) / width_deg, 0.0, 1.0)
    return np.where(np.isnan(fov), 1.0, ramp)


def relative_response(cos_incidence, response: str, shape, fov_half_deg=None) -> np.ndarray:
    """R(γ)·E(θ) of a parametric law (``kelly`` or ``power``): the detector's response relative to normal incidence
    (module docstring) [unitless]. A ``spline`` detector's is :meth:`DiodeParameters.relative_response`.

    References
    ----------
    seed 000 eq. 3.1 (S_rel); research note anchors-sunsensors §5 (cos · Kelly · FOV).
    """
    if response not in SHAPE_NAME:
        raise ValueError(f"relative_response takes a parametric law ({', '.join(SHAPE_NAME)}), got {response!r}; a "
                         "spline detector's is DiodeParameters.relative_response")
    g = np.asarray(cos_incidence, float)
    fov = np.nan if fov_half_deg is None else fov_half_deg
    return _response(g, np.asarray(LAW_CODES[response]), np.asarray(shape, float), np.asarray(fov, float))[0]


def _kelly(g, kappa):
    """Normalised Kelly law and its partials d/dγ, d/dκ."""
    lit = g > 0
    gl = np.where(lit, g, 0.0)
    k = np.maximum(kappa, 1e-12)
    e = np.exp(-gl * gl / k)
    num = gl * -np.expm1(-gl * gl / k)
    den = -np.expm1(-1.0 / k)
    d_num_dg = -np.expm1(-gl * gl / k) + 2.0 * gl * gl * e / k
    d_num_dk = -gl**3 * e / k**2
    d_den_dk = -np.exp(-1.0 / k) / k**2
    value = np.where(lit, num / den, 0.0)
    dg = np.where(lit, d_num_dg / den, 0.0)
    dk = np.where(lit, (d_num_dk * den - num * d_den_dk) / den**2, 0.0)
    return value, dg, dk


def _power(g, p):
    """γ^p and its partials d/dγ, d/dp."""
    lit = g > 0
    gl = np.where(lit, g, 1.0)
    value = gl**p
    dg = p * gl ** (p - 1.0)
    dp = value * np.log(gl)
    return np.where(lit, value, 0.0), np.where(lit, dg, 0.0), np.where(lit, dp, 0.0)


def _edge(g, fov):
    """E(θ(γ)) and its partials d/dγ, d/dθ_c; NaN θ_c: E ≡ 1."""
    if np.all(np.isnan(fov)):
        shape = np.broadcast_shapes(np.shape(g), np.shape(fov))
        return np.ones(shape), np.zeros(shape), np.zeros(shape)
    theta = np.degrees(np.arccos(np.clip(g, -1.0, 1.0)))
    none = np.isnan(fov)
    fv = np.where(none, 0.0, fov)
    x = (fv + FOV_EDGE_WIDTH_DEG / 2.0 - theta) / FOV_EDGE_WIDTH_DEG
    inside = (x > 0.0) & (x < 1.0) & ~none
    value = np.where(none, 1.0, np.clip(x, 0.0, 1.0))
    dtheta_dg = -1.0 / (_DEG * np.sqrt(np.maximum(1.0 - g * g, 1e-300)))
    d_fov = np.where(inside, 1.0 / FOV_EDGE_WIDTH_DEG, 0.0)
    dg = np.where(inside, -dtheta_dg / FOV_EDGE_WIDTH_DEG, 0.0)
    return value, dg, d_fov


def _response(g, law, shape, fov, splines=()):
    """R·E and partials d/dγ, d/dshape, d/dθ_c (arrays broadcast together; `law` codes of :data:`LAW_CODES`).

    `splines`: (columns, :class:`~calibration.css.spline.SplineSet`) of the ``spline`` detectors, evaluated on the
    last axis of `g` (:attr:`HeadModel.spline_set`); their shape partial is 0."""
    law = np.asarray(law)
    kelly, power = law == LAW_CODES["kelly"], law == LAW_CODES["power"]
    if np.all(kelly):
        r, r_g, r_s = _kelly(g, shape)
    elif np.all(power):
        r, r_g, r_s = _power(g, shape)
    elif not np.any(kelly | power):
        r = r_g = r_s = np.zeros(np.broadcast_shapes(np.shape(g), law.shape))
    else:
        rk, rk_g, rk_s = _kelly(g, np.where(kelly, shape, 1.0))
        rp, rp_g, rp_s = _power(g, np.where(power, shape, 1.0))
        r, r_g, r_s = (np.where(kelly, a, np.where(power, b, 0.0)) for a, b in ((rk, rp), (rk_g, rp_g), (rk_s, rp_s)))
    if splines:
        r, r_g, r_s = (np.array(np.broadcast_to(a, np.broadcast_shapes(np.shape(g), law.shape))) for a in (r, r_g, r_s))
        cols, spline_set = splines
        r[..., cols], r_g[..., cols] = spline_set.evaluate(g[..., cols])
        r_s[..., cols] = 0.0
    e, e_g, e_f = _edge(g, fov)
    return r * e, r_g * e + r * e_g, r_s * e, r * e_f


# -- one detector ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DiodeParameters:
    """A calibrated detector (module docstring).

    Attributes
    ----------
    channel : str
        ``<face>_<detector>`` (:data:`calibration.css.head.CHANNELS`).
    response : {"kelly", "power", "spline"}
    scale : float
        S: signal at normal incidence, reference irradiance, 25 °C [A] (photodiodes) or [V] (thermopile).
    bias : float
        b: the signal with no light at 25 °C [A or V].
    tilt_u_deg, tilt_v_deg : float
        The normal's tilts about the face's in-plane axes (:data:`TILT_AXES`) [°].
    shape : float
        κ of the Kelly law or p of the power law [unitless]; unused by the spline law.
    fov_half_deg : float or None
        θ_c [°]; None: no cut-off (always, as fitted, for the spline law: its spline holds the cut-off).
    temp_coeff_per_c : float
        c_T [1/°C].
    bias_temp_coeff_per_c : float
        b_T [A/°C or V/°C].
    sigma0, shot, noise_rel : float
        The noise model σ² = σ₀² + q·|m| + (r·m)²: σ₀ [A or V], q [A or V], r [unitless].
    full_scale : float or None
        Readings at or above this are saturated and never used [A or V].
    model_sd : float
        RMS error of the model itself (its misfit beyond the noise at calibration, on lit readings) [A or V]: the
        sun-vector estimator weights a lit reading by √(σ² + model_sd²).
    spline : tuple of float
        The spline law's free coefficients c_1 … c_{K+1} (``spline_1`` …; :mod:`calibration.css.spline`); empty for
        the other laws. Default for the spline law: the spline nearest the plain cosine.
    spline_knots_deg : tuple of float
        The spline law's knots θ_0 = 0 … θ_K [°] (default :data:`calibration.css.spline.SPLINE_KNOTS_DEG`).
    """

    channel: str
    response: str = "kelly"
    scale: float = 1.0
    bias: float = 0.0
    tilt_u_deg: float = 0.0
    tilt_v_deg: float = 0.0
    shape: float = 0.1
    fov_half_deg: float | None = None
    temp_coeff_per_c: float = 0.0
    bias_temp_coeff_per_c: float = 0.0
    sigma0: float = 0.0
    shot: float = 0.0
    noise_rel: float = 0.0
    full_scale: float | None = None
    model_sd: float = 0.0
    spline: tuple = ()
    spline_knots_deg: tuple = ()

    def __post_init__(self) -> None:
        split_channel(self.channel)
        if self.response not in RESPONSES:
            raise ValueError(f"no response law {self.response!r} (laws: {', '.join(RESPONSES)})")
        if self.response == SPLINE:
            knots = check_knots(self.spline_knots_deg or SPLINE_KNOTS_DEG)
            coef = tuple(float(v) for v in (self.spline if len(self.spline) else cosine_coefficients(knots)))
            if len(coef) != n_free(knots):
                raise ValueError(f"{self.channel}: a spline on {len(knots)} knots has {n_free(knots)} coefficients, "
                                 f"got {len(coef)}")
            object.__setattr__(self, "spline_knots_deg", knots)
            object.__setattr__(self, "spline", coef)
        elif len(self.spline) or len(self.spline_knots_deg):
            raise ValueError(f"{self.channel}: spline coefficients belong to the spline law, not {self.response}")

    @property
    def face(self) -> str:
        return split_channel(self.channel)[0]

    @property
    def detector(self) -> str:
        return split_channel(self.channel)[1]

    @property
    def normal(self) -> np.ndarray:
        """The true unit normal in the body frame."""
        return tilted_normal(self.face, self.tilt_u_deg, self.tilt_v_deg)

    @property
    def normal_zenith_azimuth_deg(self) -> tuple[float, float]:
        zen, az = normal_angles(self.face, self.tilt_u_deg, self.tilt_v_deg)
        return float(zen), float(az)

    @property
    def spline_names(self) -> tuple:
        """``spline_1`` … of the spline law's coefficients (empty for the other laws)."""
        return spline_names(len(self.spline))

    def values(self) -> dict:
        """Parameter name → value, the shape under its own name (``kappa`` or ``power``); the spline law's
        coefficients as ``spline_1`` … (it has no shape)."""
        out = {name: getattr(self, name) for name in PARAMETER_NAMES}
        shape = out.pop("shape")
        if self.response == SPLINE:
            out.update(zip(self.spline_names, self.spline))
        else:
            out[SHAPE_NAME[self.response]] = shape
        return out

    def get(self, name: str) -> float | None:
        """One parameter's value by name (:data:`PARAMETER_NAMES`, ``kappa``/``power``, ``spline_<k>``)."""
        k = spline_index(name)
        if k is not None:
            return self.spline[k]
        return getattr(self, "shape" if name in ("kappa", "power") else name)

    def with_values(self, **values) -> DiodeParameters:
        """A copy with some values replaced (``kappa``/``power`` accepted for ``shape``, ``spline_<k>`` for one of
        the spline's coefficients)."""
        for alias in ("kappa", "power"):
            if alias in values:
                values["shape"] = values.pop(alias)
        ks = {spline_index(name): name for name in values if spline_index(name) is not None}
        if ks:
            coef = list(values.pop("spline", self.spline))
            for k, name in ks.items():
                coef[k] = float(values.pop(name))
            values["spline"] = tuple(coef)
        return replace(self, **values)

    def relative_response(self, cos_incidence) -> np.ndarray:
        """R(γ)·E(θ) of this detector at cosines of incidence [unitless] (module docstring).

        References
        ----------
        seed 000 eq. 3.1 (S_rel).
        """
        return HeadModel.from_parameters([self]).responses_at(np.asarray(cos_incidence, float)[..., None])[..., 0]

    def signal(self, sun_vectors, temperature_c=REFERENCE_TEMPERATURE_C, *, irradiance=1.0) -> np.ndarray:
        """Noise-free signal [A or V] for unit sun vectors (..., 3) in the body frame (module docstring).

        References
        ----------
        seed 000 eq. 3.1; research note anchors-sunsensors §5 (Basilisk: scale · cos · Kelly · FOV + bias).
        """
        return HeadModel.from_parameters([self]).signals(sun_vectors, temperature_c, irradiance=irradiance)[..., 0]

    def noise_sd(self, signal) -> np.ndarray:
        """1σ noise of one reading at `signal` [A or V] (module docstring).

        References
        ----------
        seed 000 §4 (noise of the detectors and front ends), digest §4.4 (shot noise).
        """
        return noise_sd(signal, self.sigma0, self.shot, self.noise_rel)


def noise_sd(signal, sigma0, shot=0.0, noise_rel=0.0) -> np.ndarray:
    """σ = √(σ₀² + q·|m| + (r·m)²) [units of the signal].

    References
    ----------
    seed 000 §4 (eqs. 4.3–4.11: the noise floor of the front end), digest §4.4 and §8.1 item 3 (shot noise 2qIB).
    """
    m = np.abs(np.asarray(signal, float))
    sigma0, shot, rel = (np.asarray(v, float) for v in (sigma0, shot, noise_rel))
    return np.sqrt(sigma0**2 + shot * m + (rel * m) ** 2)


def signal_partials(params: DiodeParameters, sun_vectors, temperature_c, lit) -> tuple[np.ndarray, dict]:
    """The signal m and its partial derivatives with respect to every parameter of :data:`PARAMETER_NAMES`.

    Parameters
    ----------
    params : DiodeParameters
        With ``fov_half_deg`` None the θ_c partial is 0.
    sun_vectors : ndarray, shape (N, 3)
        Unit sun vectors (any finite value on dark rows).
    temperature_c : ndarray, shape (N,)
    lit : ndarray of bool, shape (N,)
        False on dark rows (the light off: m = b + b_T ΔT).

    Returns
    -------
    m : ndarray (N,)
    partials : dict of name → ndarray (N,)
        Per unit of each parameter (per ° for the angles); the spline law's ``spline_1`` … too (its ``shape``
        partial is 0).

    References
    ----------
    seed 000 eq. 3.1; research note anchors-sunsensors §5.
    """
    s = np.asarray(sun_vectors, float)
    dt = np.asarray(temperature_c, float) - REFERENCE_TEMPERATURE_C
    lit = np.asarray(lit, bool)
    n, dn_u, dn_v = _normal_partials(params.face, params.tilt_u_deg, params.tilt_v_deg)
    g = np.where(lit, s @ n, 0.0)
    fov = np.asarray(np.nan if params.fov_half_deg is None else params.fov_half_deg, float)
    basis_values = None
    if params.response == SPLINE:
        basis = spline_basis(params.spline_knots_deg)
        r, r_g = evaluate(basis.breakpoints, basis.polynomial(params.spline), g)
        e, e_g, e_f = _edge(g, fov)
        f, f_g, f_s, f_fov = r * e, r_g * e + r * e_g, np.zeros_like(g), r * e_f
        basis_values = np.where(lit & (r > 0.0), basis.free_basis(g)[0] * e, 0.0)  # R = max(0, spline)
    else:
        f, f_g, f_s, f_fov = _response(g, np.asarray(LAW_CODES[params.response]), np.asarray(params.shape, float),
                                       fov)
    f, f_g, f_s, f_fov = (np.where(lit, a, 0.0) for a in (f, f_g, f_s, f_fov))
    gain = 1.0 + params.temp_coeff_per_c * dt
    amp = params.scale * gain
    m = amp * f + params.bias + params.bias_temp_coeff_per_c * dt
    partials = {
        "scale": gain * f,
        "bias": np.ones_like(m),
        "tilt_u_deg": amp * f_g * (s @ dn_u),
        "tilt_v_deg": amp * f_g * (s @ dn_v),
        "shape": amp * f_s,
        "fov_half_deg": amp * f_fov,
        "temp_coeff_per_c": params.scale * dt * f,
        "bias_temp_coeff_per_c": dt * np.ones_like(m),
    }
    if basis_values is not None:
        partials.update(zip(params.spline_names, amp * basis_values))
    return m, partials


# -- a head ---------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HeadModel:
    """K calibrated detectors as arrays, in `channels` order (module docstring).

    Attributes
    ----------
    channels : tuple of str
    normals : ndarray (K, 3)
        True unit normals.
    scale, bias, shape, fov_half_deg, temp_coeff_per_c, bias_temp_coeff_per_c : ndarray (K,)
        As :class:`DiodeParameters`; θ_c NaN for no cut-off.
    law : ndarray of int (K,)
        Each detector's response law, :data:`LAW_CODES`.
    sigma0, shot, noise_rel : ndarray (K,)
        Noise model.
    full_scale : ndarray (K,)
        Saturation level, +inf when unknown.
    model_sd : ndarray (K,)
        The model's own RMS error [A or V] (:class:`DiodeParameters`).
    spline_pp : tuple
        Per detector: (breakpoints, polynomial (K, 4)) of its spline (:mod:`calibration.css.spline`), None for the
        parametric laws.
    """

    channels: tuple
    normals: np.ndarray
    scale: np.ndarray
    bias: np.ndarray
    shape: np.ndarray
    fov_half_deg: np.ndarray
    temp_coeff_per_c: np.ndarray
    bias_temp_coeff_per_c: np.ndarray
    law: np.ndarray
    sigma0: np.ndarray
    shot: np.ndarray
    noise_rel: np.ndarray
    full_scale: np.ndarray
    model_sd: np.ndarray
    spline_pp: tuple = field(default=(), repr=False)
    parameters: tuple = field(default=(), repr=False)

    @classmethod
    def from_parameters(cls, parameters) -> HeadModel:
        """The head of some calibrated detectors (each channel at most once).

        References
        ----------
        seed 000 ch. 5.3.1 (a triplet on each face); research note anchors-sunsensors §5 (CSSConstellation).
        """
        params = tuple(parameters)
        names = [p.channel for p in params]
        if len(set(names)) != len(names):
            raise ValueError(f"a head holds each channel once, got {names}")
        arr = lambda name: np.array([getattr(p, name) for p in params], float)  # noqa: E731
        return cls(tuple(names), np.array([p.normal for p in params], float).reshape(-1, 3), arr("scale"),
                   arr("bias"), arr("shape"),
                   np.array([np.nan if p.fov_half_deg is None else p.fov_half_deg for p in params], float),
                   arr("temp_coeff_per_c"), arr("bias_temp_coeff_per_c"),
                   np.array([LAW_CODES[p.response] for p in params], int), arr("sigma0"), arr("shot"),
                   arr("noise_rel"),
                   np.array([np.inf if p.full_scale is None else p.full_scale for p in params], float),
                   arr("model_sd"), tuple(_spline_pp(p) for p in params), params)

    def __len__(self) -> int:
        return len(self.channels)

    def subset(self, channels) -> HeadModel:
        """The detectors `channels` (in that order)."""
        idx = [self.channels.index(c) for c in channels]
        if self.parameters:
            return HeadModel.from_parameters([self.parameters[i] for i in idx])
        kw = {f.name: getattr(self, f.name)[idx] for f in fields(self)
              if f.name not in ("channels", "parameters", "spline_pp")}
        pp = tuple(self.spline_pp[i] for i in idx) if self.spline_pp else ()
        return HeadModel(tuple(channels), **kw, spline_pp=pp)

    @cached_property
    def spline_set(self) -> tuple:
        """(columns, :class:`~calibration.css.spline.SplineSet`) of the spline detectors; () without one."""
        cols = [j for j, pp in enumerate(self.spline_pp) if pp is not None]
        return (np.array(cols), SplineSet([self.spline_pp[j] for j in cols])) if cols else ()

    def _response(self, g):
        return _response(g, self.law, self.shape, self.fov_half_deg, self.spline_set)

    def _gain(self, temperature_c, irradiance):
        dt = np.asarray(temperature_c, float)[..., None] - REFERENCE_TEMPERATURE_C
        return (np.asarray(irradiance, float)[..., None] * self.scale * (1.0 + self.temp_coeff_per_c * dt),
                self.bias + self.bias_temp_coeff_per_c * dt)

    def dark_signals(self, temperature_c=REFERENCE_TEMPERATURE_C) -> np.ndarray:
        """b + b_T ΔT of every detector [A or V], shape (..., K).

        References
        ----------
        seed 000 §3.1 (photovoltaic mode; the front end's offset), digest §8.1 item 1 (I_dark(T)).
        """
        return self._gain(temperature_c, 1.0)[1]

    def signals(self, sun_vectors, temperature_c=REFERENCE_TEMPERATURE_C, *, irradiance=1.0) -> np.ndarray:
        """Noise-free signals [A or V] of every detector for unit sun vectors (..., 3): shape (..., K).

        References
        ----------
        seed 000 eq. 3.1; research note anchors-sunsensors §5 (Basilisk coarseSunSensor).
        """
        s = np.asarray(sun_vectors, float)
        g = s @ self.normals.T
        amp, dark = self._gain(temperature_c, irradiance)
        return amp * self._response(g)[0] + dark

    def signals_and_gradient(self, sun_vectors, temperature_c=REFERENCE_TEMPERATURE_C, *,
                             irradiance=1.0) -> tuple[np.ndarray, np.ndarray]:
        """Signals (..., K) and their gradients with respect to the sun vector ∂m/∂s (..., K, 3).

        References
        ----------
        seed 000 eq. 3.1; research note anchors-sunsensors §5.
        """
        s = np.asarray(sun_vectors, float)
        g = s @ self.normals.T
        amp, dark = self._gain(temperature_c, irradiance)
        f, f_g, _, _ = self._response(g)
        return amp * f + dark, (amp * f_g)[..., None] * self.normals

    def noise_sd(self, signals) -> np.ndarray:
        """1σ noise of readings `signals` (..., K) [A or V].

        References
        ----------
        seed 000 §4, digest §4.4 (shot noise).
        """
        return noise_sd(signals, self.sigma0, self.shot, self.noise_rel)

    def weight_sd(self, signals) -> np.ndarray:
        """√(σ² + model_sd²): what a lit reading (..., K) is worth to the estimator [A or V].

        References
        ----------
        seed 000 §4 (noise); research note anchors-sunsensors §6 (honest uncertainties).
        """
        return np.sqrt(self.noise_sd(signals) ** 2 + self.model_sd**2)

    def responses_at(self, cos_incidence) -> np.ndarray:
        """R·E of every detector at cosines of incidence (..., K) [unitless].

        References
        ----------
        seed 000 eq. 3.1 (S_rel).
        """
        g = np.asarray(cos_incidence, float)
        return self._response(g)[0]

    def relative_responses(self, vectors) -> np.ndarray:
        """R·E of every detector for unit directions (..., 3): shape (..., K) [unitless].

        References
        ----------
        seed 000 eq. 3.1 (S_rel).
        """
        g = np.asarray(vectors, float) @ self.normals.T
        return self._response(g)[0]


def _spline_pp(params: DiodeParameters):
    """(breakpoints, polynomial) of a spline detector's response, None for the parametric laws."""
    if params.response != SPLINE:
        return None
    basis = spline_basis(params.spline_knots_deg)
    return basis.breakpoints, basis.polynomial(params.spline)


def nominal_parameters(channel: str, *, response: str = "kelly", scale: float = 1.0) -> DiodeParameters:
    """A detector on its nominal face normal with a plain-cosine-like law (κ 0.1, p 1, the spline nearest the
    cosine) and no cut-off.

    References
    ----------
    seed 000 ch. 5.3.1 (nominal faces), digest §8.1 item 1 (b) (ideal cosine).
    """
    if channel not in CHANNELS:
        raise ValueError(f"no channel {channel!r}")
    return DiodeParameters(channel, response, scale=scale, shape=0.1 if response == "kelly" else 1.0)
