"""The sensor's pulse along a scan: what the detector sees through its IFOV against phase (seed 004 §2-2, §2-4-2,
§2-4-3; Figs. 2-8, 4-9 to 4-16).

A pulse is the IFOV-weighted mean of a radiance field over the directions about the boresight S_k(δ) (seed 004 eq.
2.5), sampled at phases δ_j = 360° · t_j / T (the thesis sampled every 10⁻⁵, 10⁻⁴ and 10⁻² s at 1 rev/s). The
radiance field is either the Earth's "obscuration" (1 on the Earth, 0 off it: STK's report, Table 4-5) or a limb
radiance as a function of a ray's signed tangent height (:mod:`calibration.horizon.atmosphere`).

* Spherical Earth: everything is a function of the angle η from nadir, so a top-hat IFOV is the exact 1-D ring sum
  of :func:`calibration.horizon.ifov.ring_mean_sphere`; a Gaussian response uses 2-D quadrature.
* WGS84: the satellite's position P [km] in an Earth-centred frame with the polar axis as z, and the rotation taking
  body vectors into that frame; rays' tangent heights from the ellipsoid. Two ways: :func:`ellipsoid_depth`, an exact
  "is this ray on the Earth" (the ellipsoid scaled along z into a sphere, where ray and surface meet exactly when
  they meet on the ellipsoid) for obscuration; :func:`tangent_height_scaled_km`, a fast approximation of the
  geodetic tangent altitude (the scaled sphere's height, corrected by 1 − f sin²λ; within 0.002 km of
  :func:`calibration.horizon.earth.tangent_altitude_km` up to 100 km, tested), or that exact function itself
  (``tangent="exact"``, ~40 µs a ray).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np

from . import earth
from .atmosphere import RADIANCE_CUTOFF_KM, tangent_height_of_angle_km
from .ifov import (
    RESPONSES,
    covered_fraction,
    covered_fraction_along_scan,
    ifov_nodes,
    ring_mean_sphere,
    separation_along_scan_deg,
)
from .locator import moving_average
from .scan import (
    EQUATORIAL_RADIUS_KM,
    FLATTENING,
    THESIS_GAMMA_DEG,
    THESIS_IFOV_HALF_ANGLE_DEG,
    THESIS_SCAN_RATE_HZ,
    earth_angular_radius_deg,
    scan_vector,
)

TANGENT_METHODS = ("scaled", "exact")


@lru_cache(maxsize=32)
def _node_pattern(half_angle_deg: float, response: str, fwhm_deg: float | None, n_radial: int, n_azimuth: int):
    """:func:`calibration.horizon.ifov.ifov_nodes` about the z axis, kept per IFOV: the nodes' components along
    the boresight and the two basis vectors ifov_nodes completes it with (for z: e1 = y, e2 = −x), and the weights.
    Read-only arrays; a pulse turns them onto its boresights (:func:`_ifov_nodes_cached`)."""
    dirs, weights = ifov_nodes(np.array([0.0, 0.0, 1.0]), half_angle_deg, response, fwhm_deg, n_radial, n_azimuth)
    parts = (dirs[:, 2].copy(), dirs[:, 1].copy(), -dirs[:, 0], np.asarray(weights, float).copy())
    for a in parts:
        a.setflags(write=False)
    return parts


def _ifov_nodes_cached(boresights: np.ndarray, half_angle_deg, response: str, fwhm_deg, n_radial: int,
                       n_azimuth: int):
    """``(directions (M, N, 3), weights (N,))`` as :func:`calibration.horizon.ifov.ifov_nodes` gives them for unit
    `boresights` (M, 3) (seed 004 §2-4-2), from the pattern cached per IFOV: the same basis (e1 = b × x̂, or b × ŷ
    when |b_x| ≥ 0.9; e2 = b × e1), so the same nodes to rounding."""
    along, on_e1, on_e2, weights = _node_pattern(float(half_angle_deg), response,
                                                 None if fwhm_deg is None else float(fwhm_deg), int(n_radial),
                                                 int(n_azimuth))
    b = boresights / np.linalg.norm(boresights, axis=-1, keepdims=True)
    helper = np.where(np.abs(b[:, :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    e1 = np.cross(b, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(b, e1)
    dirs = (along[None, :, None] * b[:, None, :] + on_e1[None, :, None] * e1[:, None, :]
            + on_e2[None, :, None] * e2[:, None, :])
    return dirs, weights


def sample_phases_deg(step_s: float, period_s: float = 1.0 / THESIS_SCAN_RATE_HZ, start_s: float = 0.0,
                      duration_s: float | None = None) -> np.ndarray:
    """Phases [°] of samples taken every `step_s` from `start_s` for `duration_s` (default one period): δ = 360° ·
    t / T (seed 004 §2-3; the thesis' steps 10⁻⁵, 10⁻⁴, 10⁻² s, §3-5). Not wrapped (ascending)."""
    if step_s <= 0 or period_s <= 0:
        raise ValueError("the sample step and the scan period must be positive seconds")
    duration = period_s if duration_s is None else duration_s
    n = int(round(duration / step_s))
    if n < 3:
        raise ValueError(f"{duration} s at {step_s} s a sample is fewer than 3 samples")
    return 360.0 * (start_s + step_s * np.arange(n)) / period_s


def _finish(pulse: np.ndarray, filter_window: int | None) -> np.ndarray:
    return pulse if not filter_window or filter_window == 1 else moving_average(pulse, filter_window, circular=False)


def sphere_pulse(phase_deg, nadir_body, altitude_km, radiance: Callable[[np.ndarray], np.ndarray] | None = None,
                 half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, response: str = "top-hat", fwhm_deg: float | None = None,
                 gamma_deg=THESIS_GAMMA_DEG, cone=1, radius_km=EQUATORIAL_RADIUS_KM,
                 filter_window: int | None = None, n_rings: int = 800) -> np.ndarray:
    """Cone `cone`'s pulse over a spherical Earth seen from `altitude_km` with the nadir at `nadir_body` (3,).

    `radiance` maps a signed tangent height [km] to a radiance (e.g. an
    :class:`~calibration.horizon.atmosphere.RadianceTable`); None gives the obscured fraction (0–1, STK's
    obscuration / 100, seed 004 Table 4-5). `response` is the IFOV's ``"top-hat"`` (exact ring sum) or
    ``"gaussian"`` (FWHM `fwhm_deg`, default 2α; 2-D quadrature). `filter_window` applies a centred moving average
    (seed 004 §4-5) of that many samples.
    """
    if response not in RESPONSES:
        raise ValueError(f"response must be one of {RESPONSES}, got {response!r}")
    rho = float(earth_angular_radius_deg(altitude_km, radius_km))
    if radiance is None and response == "top-hat":
        return _finish(covered_fraction_along_scan(phase_deg, nadir_body, rho, half_angle_deg, gamma_deg, cone),
                       filter_window)

    def field_of_angle(eta_deg):
        if radiance is None:
            return (np.asarray(eta_deg) < rho).astype(float)
        return radiance(tangent_height_of_angle_km(eta_deg, altitude_km, radius_km))

    if response == "top-hat":
        cut = np.degrees(np.arcsin(min((radius_km + RADIANCE_CUTOFF_KM) / (radius_km + altitude_km), 1.0)))
        d = separation_along_scan_deg(phase_deg, nadir_body, gamma_deg, cone)
        return _finish(ring_mean_sphere(d, field_of_angle, half_angle_deg, (rho, cut), n_rings), filter_window)
    n = np.asarray(nadir_body, float)
    n = n / np.linalg.norm(n)
    dirs, weights = ifov_nodes(scan_vector(phase_deg, gamma_deg, cone), half_angle_deg, "gaussian", fwhm_deg,
                               n_radial=16, n_azimuth=48)
    eta = np.degrees(np.arccos(np.clip(dirs @ n, -1.0, 1.0)))
    return _finish(np.sum(field_of_angle(eta) * weights, axis=-1), filter_window)


def ellipsoid_depth(position_km, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING) -> Callable:
    """``depth(directions (N, 3)) -> (N,)`` > 0 exactly for rays from `position_km` that meet the WGS84 ellipsoid:
    scaling z by 1/(1 − f) turns the ellipsoid into the sphere of radius a and keeps lines lines, so the depth is
    a − (the scaled ray's closest approach to the centre) [km, scaled] (seed 004 eqs. 2.9–2.10). Use it with
    :func:`calibration.horizon.ifov.covered_fraction` for STK's obscuration on WGS84."""
    p = np.asarray(position_km, float) * np.array([1.0, 1.0, 1.0 / (1.0 - flattening)])
    a = float(a_km)

    def depth(directions):
        u = np.asarray(directions, float) * np.array([1.0, 1.0, 1.0 / (1.0 - flattening)])
        uu = np.sum(u * u, axis=-1)
        s = np.maximum(-(u @ p) / uu, 0.0)
        closest = p + s[..., None] * u
        return a - np.linalg.norm(closest, axis=-1)

    return depth


def tangent_height_scaled_km(position_km, directions, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING):
    """Fast signed tangent height [km] of rays from `position_km` over WGS84 (seed 004 §2-4-1): the closest
    approach in the space where the ellipsoid is the sphere of radius a (z scaled by 1/(1 − f)), its height over that
    sphere times 1 − f sin²λ (λ the closest point's geocentric latitude: similar ellipsoids' height along the normal).
    Within 0.002 km of the geodetic tangent altitude from −50 to 100 km (tested; the terms left are O(f² h));
    negative for rays that meet the Earth (as :func:`calibration.horizon.earth.tangent_altitude_km`)."""
    scale = np.array([1.0, 1.0, 1.0 / (1.0 - flattening)])
    p = np.asarray(position_km, float) * scale
    u = np.asarray(directions, float) * scale
    uu = np.sum(u * u, axis=-1)
    s = np.maximum(-np.sum(u * p, axis=-1) / uu, 0.0)
    closest = p + s[..., None] * u
    height = np.linalg.norm(closest, axis=-1) - a_km
    point = closest / scale
    sin2 = point[..., 2] ** 2 / np.sum(point * point, axis=-1)
    return height * (1.0 - flattening * sin2)


def wgs84_pulse(phase_deg, position_km, body_to_frame, radiance: Callable[[np.ndarray], np.ndarray] | None = None,
                half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, response: str = "top-hat", fwhm_deg: float | None = None,
                gamma_deg=THESIS_GAMMA_DEG, cone=1, tangent: str = "scaled", filter_window: int | None = None,
                n_radial: int = 16, n_azimuth: int = 48) -> np.ndarray:
    """Cone `cone`'s pulse over the WGS84 Earth from the satellite at `position_km` (3,) with `body_to_frame` (3, 3)
    rotating body vectors into the Earth-centred frame (seed 004 §2-4-1 to §2-4-3).

    `radiance` maps a signed tangent height [km] to a radiance; None gives the obscured fraction, computed exactly
    (:func:`ellipsoid_depth` with :func:`~calibration.horizon.ifov.covered_fraction`, top-hat only). Otherwise 2-D
    quadrature over the IFOV (`n_radial` × `n_azimuth` nodes) with the tangent heights from
    :func:`tangent_height_scaled_km` (``tangent="scaled"``) or :func:`calibration.horizon.earth.tangent_altitude_km`
    (``"exact"``).
    """
    if tangent not in TANGENT_METHODS:
        raise ValueError(f"tangent must be one of {TANGENT_METHODS}, got {tangent!r}")
    rot = np.asarray(body_to_frame, float)
    if rot.shape != (3, 3):
        raise ValueError(f"body_to_frame must be a 3×3 rotation, got shape {rot.shape}")
    p = np.asarray(position_km, float)
    boresights = scan_vector(np.atleast_1d(phase_deg), gamma_deg, cone) @ rot.T
    if radiance is None:
        if response != "top-hat":
            raise ValueError("the exact WGS84 obscuration is for a top-hat IFOV; pass a radiance for a Gaussian one")
        depth = ellipsoid_depth(p)
        out = np.array([covered_fraction(b, depth, half_angle_deg) for b in boresights])
        return _finish(out.reshape(np.shape(phase_deg)), filter_window)
    if response not in RESPONSES:
        raise ValueError(f"response must be one of {RESPONSES}, got {response!r}")
    dirs, weights = _ifov_nodes_cached(boresights, half_angle_deg, response, fwhm_deg, n_radial, n_azimuth)
    if tangent == "scaled":
        heights = tangent_height_scaled_km(p, dirs)
    else:
        heights = earth.tangent_altitude_km(p, dirs)
    out = np.sum(radiance(heights) * weights, axis=-1)
    return _finish(out.reshape(np.shape(phase_deg)), filter_window)
