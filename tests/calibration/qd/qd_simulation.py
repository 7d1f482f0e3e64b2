"""Independent generators of QD bench data for the tests: none of them calls calibration.qd's models.

* :func:`thesis_spots` — the thesis' eq. 2.2 sensor by vector geometry: the Sun's ray through the pinhole,
  intersected with the detector plane, projected on the QD's rotated axes;
* :func:`separable_currents` — currents that reproduce eq. 2.1 exactly for a spot at (x_c, y_c) (digest §2.3);
* :func:`brute_force_currents` — the physical sensor by brute force: points sampled over the diaphragm
  (a turned lattice) × directions sampled over the Sun's disc, each ray landed on the detector and counted
  in its quadrant (dead cross excluded), weighted by cos(incidence).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

#: eq. 2.1's quadrant signs, written out again here (Q1 (−,−), Q2 (+,+), Q3 (+,−), Q4 (−,+)).
SIGNS = np.array([[-1, -1], [1, 1], [1, -1], [-1, 1]], dtype=float)

#: The thesis' fitted geometric parameters (seed 002 §5.2), typed in again rather than imported.
THESIS = dict(x0_m=-5.17e-5, y0_m=5.20e-4, alpha0_deg=8.6e-3, beta0_deg=-0.15, phi0_deg=5.14e-4, d_m=8.17e-4)


def grid(half_width_deg=40.0, step_deg=5.0):
    """(α, β) of a square grid, flattened."""
    v = np.arange(-half_width_deg, half_width_deg + 1e-9, step_deg)
    a, b = np.meshgrid(v, v, indexing="ij")
    return a.ravel(), b.ravel()


def sun_vectors(alpha_deg, beta_deg):
    """Unit Sun vectors whose tangents are tan α, tan β (the definition of the projection angles)."""
    v = np.stack([np.tan(np.radians(alpha_deg)), np.tan(np.radians(beta_deg)), np.ones(np.shape(alpha_deg))], -1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def zenith_azimuth(alpha_deg, beta_deg):
    v = sun_vectors(alpha_deg, beta_deg)
    return (np.degrees(np.arccos(np.clip(v[..., 2], -1, 1))),
            np.mod(np.degrees(np.arctan2(v[..., 1], v[..., 0])), 360.0))


def thesis_spots(alpha_deg, beta_deg, p=THESIS):
    """Spot centre (x_c, y_c) [m] of the thesis' sensor by vector geometry.

    The offset-corrected Sun direction u (eq. 2.2's α − α0, β − β0), the ray from the pinhole P = (x0, y0, d)
    travelling along −u hits z = 0 at P − (d / u_z) u; its coordinates along the QD's axes (the housing axes
    turned by −φ: e_x = (cos φ, −sin φ)... written as the columns of R(φ)) are the spot centre.
    """
    u = sun_vectors(np.asarray(alpha_deg) - p["alpha0_deg"], np.asarray(beta_deg) - p["beta0_deg"])
    pinhole = np.array([p["x0_m"], p["y0_m"], p["d_m"]])
    hit = pinhole - (p["d_m"] / u[..., 2])[..., None] * u
    phi = np.radians(p["phi0_deg"])
    ex, ey = np.array([np.cos(phi), np.sin(phi), 0.0]), np.array([-np.sin(phi), np.cos(phi), 0.0])
    return hit @ ex, hit @ ey


def separable_currents(xc_m, yc_m, length_m, total_a=1e-6):
    """Currents reproducing eq. 2.1 for a spot at (x_c, y_c): I_k = S (1 + s_x u)(1 + s_y v) / 4."""
    u, v = 2 * np.asarray(xc_m) / length_m, 2 * np.asarray(yc_m) / length_m
    return total_a * (1 + SIGNS[:, 0] * u[..., None]) * (1 + SIGNS[:, 1] * v[..., None]) / 4.0


@dataclass(frozen=True)
class Sensor:
    """The truth of a physical QD sensor (the simulator's kind of parameters)."""

    radius_m: float = 50e-6
    d_m: float = 30e-6
    x0_m: float = 3e-6
    y0_m: float = -2e-6
    alpha0_deg: float = 0.12
    beta0_deg: float = -0.15
    phi0_deg: float = 0.4
    gap_m: float = 4e-6
    gains: tuple = (1.0, 1.03, 0.97, 1.02)
    k_a_per_m2: float = 600.0  # irradiance × responsivity: ≈ 4.7 µA on a 100 µm spot
    sun_radius_deg: float = 0.265
    dark_a: tuple = (0.8e-9, 1.0e-9, 0.9e-9, 1.2e-9)  # at 25 °C
    dark_doubling_c: tuple = (9.0, 10.0, 8.5, 9.5)
    extra: dict = field(default_factory=dict)

    def dark(self, temperature_c):
        t = np.asarray(temperature_c, dtype=float)[..., None]
        return np.asarray(self.dark_a) * 2.0 ** ((t - 25.0) / np.asarray(self.dark_doubling_c))


def _die_matrix(s: Sensor):
    # the die's axes in the body frame: R_y(α0) R_x(−β0), built with scipy's intrinsic Euler angles
    return Rotation.from_euler("YX", [s.alpha0_deg, -s.beta0_deg], degrees=True).as_matrix()


#: The hole's sample lattice is turned by this angle against the QD's gap lines: a lattice aligned with a
#: straight edge miscounts it by whole rows, a turned one (slope 1/golden ratio) by a few points only.
LATTICE_TURN_DEG = float(np.degrees(np.arctan(2.0 / (1.0 + 5.0**0.5))))


def _hole_samples(radius, spacing, rng):
    """Points of a turned square lattice (random offset) inside the diaphragm, equal area each."""
    n = int(np.ceil(1.5 * radius / spacing))
    c = np.arange(-n, n) * spacing
    gx, gy = np.meshgrid(c, c)
    pts = np.stack([gx.ravel(), gy.ravel()], 1) + rng.uniform(0.0, spacing, 2)
    th = np.radians(LATTICE_TURN_DEG)
    pts = pts @ np.array([[np.cos(th), np.sin(th)], [-np.sin(th), np.cos(th)]])
    return pts[np.hypot(pts[:, 0], pts[:, 1]) < radius]


def _sun_offsets(radius_deg):
    """Directions over the Sun's disc: its centre and a ring of six at 0.65 of its radius (equal weights)."""
    r = np.radians(radius_deg)
    ang = 2 * np.pi * np.arange(6) / 6
    return np.concatenate([[[0.0, 0.0]], 0.65 * r * np.stack([np.cos(ang), np.sin(ang)], 1)])


def brute_force_currents(alpha_deg, beta_deg, sensor: Sensor = Sensor(), *, spacing_m=0.5e-6, seed=0):
    """Photocurrents (N, 4) [A] of the physical sensor by counting rays per quadrant (module docstring)."""
    rng = np.random.default_rng(seed)
    alpha, beta = np.atleast_1d(alpha_deg).astype(float), np.atleast_1d(beta_deg).astype(float)
    m = _die_matrix(sensor)
    offsets = _sun_offsets(sensor.sun_radius_deg)
    holes = [_hole_samples(sensor.radius_m, spacing_m, rng) for _ in offsets]
    cphi, sphi = np.cos(np.radians(sensor.phi0_deg)), np.sin(np.radians(sensor.phi0_deg))
    half_gap = sensor.gap_m / 2
    out = np.zeros((alpha.size, 4))
    centres = sun_vectors(alpha, beta)
    for i, s0 in enumerate(centres):
        e1 = np.cross(s0, [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s0, e1)
        for (ox, oy), hole in zip(offsets, holes):
            s = s0 + ox * e1 + oy * e2
            s /= np.linalg.norm(s)
            sd = m.T @ s  # in the die's axes
            shift = -sensor.d_m * sd[:2] / sd[2]
            px = sensor.x0_m + hole[:, 0] + shift[0]
            py = sensor.y0_m + hole[:, 1] + shift[1]
            qx, qy = cphi * px + sphi * py, -sphi * px + cphi * py  # on the QD's axes
            right, left = qx > half_gap, qx < -half_gap
            up, down = qy > half_gap, qy < -half_gap
            counts = np.array([np.sum(left & down), np.sum(right & up), np.sum(right & down), np.sum(left & up)])
            out[i] += counts / hole.shape[0] * sd[2]
    area = np.pi * sensor.radius_m**2
    return out / len(offsets) * area * sensor.k_a_per_m2 * np.asarray(sensor.gains)


def measure(photocurrents_a, temperature_c, sensor: Sensor, rng, *, amp_noise_a=0.2e-9, bandwidth_hz=500.0,
            lsb_a=0.05e-9, full_scale_a=20e-6):
    """Readings: dark current added, shot + amplifier noise, ADC quantisation and saturation."""
    q = 1.602176634e-19
    i = np.asarray(photocurrents_a) + sensor.dark(temperature_c)
    sigma = np.sqrt(2 * q * np.abs(i) * bandwidth_hz + amp_noise_a**2)
    i = i + rng.normal(0.0, 1.0, i.shape) * sigma
    return np.clip(np.round(i / lsb_a) * lsb_a, 0.0, full_scale_a)


#: The simulated physical sensor of the tests (the simulator's kind of build errors). Here, not in conftest.py:
#: a test module's `from conftest import …` takes whichever conftest was imported first (tests/web has one).
SENSOR = Sensor()
#: Row of the glint planted in the bench data (0-based; its row_id is one more).
GLINT_ROW = 100
