"""Synthetic horizon bench scans made the long way round, for the horizon family's tests: the disc centre turned by
scipy rotations, each cone's scan sampled round its cone and every sign change of S·n − cos(d_½ + Δρ) bisected — not
the closed form (calibration.horizon.scan) the fit uses. d_½ is where half of the sensor's top-hat IFOV covers the
disc (the 50 % locator on a curved limb, seed 004 §2-4-2), found here by scipy's quad over rings about the boresight
and brentq — not the cap-overlap formula (calibration.horizon.ifov) the fit uses."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from calibration.horizon.bench_fit import HorizonBenchData, HorizonSensorParameters
from calibration.horizon.scan import earth_angular_radius_deg

TRUTH = HorizonSensorParameters(gamma1_deg=70.03, gamma2_deg=69.96, phase_offset1_deg=0.12, phase_offset2_deg=-0.08,
                                radius_bias_deg=0.045, mount_roll_deg=0.3, mount_yaw_deg=0.15, mount_pitch_deg=-0.2)
#: What a bench can recover: the mount's pitch is a phase offset of both cones (bench_fit's docstring)
RECOVERABLE = TRUTH.folded()
RADII = tuple(float(r) for r in earth_angular_radius_deg([400.0, 500.0, 700.0]))
ROLLS = np.arange(-30.0, 30.1, 10.0)
PITCHES = np.arange(-15.0, 15.1, 7.5)
NOISE_DEG = 0.01


def covered_share(separation_deg: float, radius_deg: float, half_angle_deg: float) -> float:
    """The share of a top-hat IFOV of half-angle α covered by a disc of angular radius ρ with the boresight d from
    its centre: ∫ sin r · (the share of the ring r inside the disc) dr / (1 − cos α), the ring's share
    acos((cos ρ − cos d cos r) / (sin d sin r)) / π, by scipy's quad with the grazing ring r = |ρ − d| as a break."""
    d, rho, alpha = (math.radians(x) for x in (separation_deg, radius_deg, half_angle_deg))

    def ring(r):
        c = (math.cos(rho) - math.cos(d) * math.cos(r)) / (math.sin(d) * math.sin(r))
        return math.sin(r) * math.acos(min(1.0, max(-1.0, c))) / math.pi

    kink = abs(rho - d)
    value = quad(ring, 0.0, alpha, points=[kink] if 0 < kink < alpha else None, epsabs=1e-15, epsrel=1e-13,
                 limit=200)[0]
    return value / (1.0 - math.cos(alpha))


@lru_cache(maxsize=None)
def half_cover_separation(radius_deg: float, half_angle_deg: float) -> float:
    """d_½ [°]: the boresight's angle from the disc's centre at which half of the IFOV covers it (ρ for α = 0)."""
    if half_angle_deg == 0.0:
        return radius_deg
    return brentq(lambda d: covered_share(d, radius_deg, half_angle_deg) - 0.5, radius_deg - half_angle_deg,
                  radius_deg + half_angle_deg, xtol=1e-13, rtol=1e-15)


def crossings(roll, pitch, radius, cone, truth: HorizonSensorParameters, samples: int = 7200):
    """The reported (out, in) phases [°] found the long way: the disc centre turned by scipy rotations (the table's
    roll/pitch R_y(θ)·R_x(φ) in the active sense, the frame rotation of seed 004 eq. 2.6, then the mount's
    R_x·R_z·R_y), the scan sampled round the cone and each sign change of S·n − cos(d_½ + Δρ) bisected to 1e-10°
    (d_½ of :func:`half_cover_separation` with the truth's IFOV half-angle)."""
    table = Rotation.from_euler("YX", [pitch, roll], degrees=True).as_matrix()
    mount = Rotation.from_euler("XZY", [truth.mount_roll_deg, truth.mount_yaw_deg, truth.mount_pitch_deg],
                                degrees=True).as_matrix()
    n = mount.T @ (table.T @ np.array([0.0, 0.0, 1.0]))
    gamma = np.radians(truth.gamma1_deg if cone == 1 else truth.gamma2_deg)
    sign = 1.0 if cone == 1 else -1.0
    cos_rho = np.cos(np.radians(half_cover_separation(float(radius), truth.ifov_half_angle_deg)
                                + truth.radius_bias_deg))

    def f(delta_deg):
        d = np.radians(delta_deg)
        return np.sin(d) * np.sin(gamma) * n[0] + sign * np.cos(gamma) * n[1] + np.cos(d) * np.sin(gamma) * n[2] \
            - cos_rho

    grid = np.linspace(0.0, 360.0, samples + 1)
    values = f(grid)
    found = {}
    for i in np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:])):
        lo, hi = grid[i], grid[i + 1]
        for _ in range(60):
            mid = (lo + hi) / 2
            if np.sign(f(mid)) == np.sign(f(lo)):
                lo = mid
            else:
                hi = mid
        found["out" if values[i] > 0 else "in"] = (lo + hi) / 2
    offset = truth.phase_offset1_deg if cone == 1 else truth.phase_offset2_deg
    return (found["out"] + offset) % 360.0, (found["in"] + offset) % 360.0


def synthetic(truth=TRUTH, *, radii=RADII, rolls=ROLLS, pitches=PITCHES, repeats=3, noise=NOISE_DEG, seed=0,
              check=None) -> HorizonBenchData:
    """Scans of both cones at every (radius, roll, pitch), `repeats` each with Gaussian phase noise; `check`: poses
    [(roll, pitch, radius)] measured as check rows."""
    rng = np.random.default_rng(seed)
    poses = [(r, p, rho, False) for rho in radii for r in rolls for p in pitches]
    poses += [(r, p, rho, True) for r, p, rho in (check or ())]
    rows = {k: [] for k in ("roll", "pitch", "cone", "out", "in", "rho", "scan", "repeat", "check")}
    scan = 0
    for roll, pitch, rho, is_check in poses:
        exact = {cone: crossings(roll, pitch, rho, cone, truth) for cone in (1, 2)}
        for k in range(repeats):
            for cone in (1, 2):
                out, in_ = exact[cone]
                for key, value in (("roll", roll), ("pitch", pitch), ("cone", cone), ("rho", rho), ("scan", scan),
                                   ("repeat", k), ("check", is_check), ("out", out + rng.normal(0, noise)),
                                   ("in", in_ + rng.normal(0, noise))):
                    rows[key].append(value)
            scan += 1
    return HorizonBenchData(rows["roll"], rows["pitch"], rows["cone"], rows["out"], rows["in"], rows["rho"],
                            scan=rows["scan"], repeat=rows["repeat"], check=rows["check"], sensor_id="HZ-T")
