"""Synthetic horizon bench scans made the long way round, for the horizon family's tests: the disc centre turned by
scipy rotations, each cone's scan sampled round its cone and every sign change of S·n − cos(d_½ + Δρ) bisected — not
the closed form (calibration.horizon.scan) the fit uses. d_½ is where half of the sensor's top-hat IFOV covers the
disc (the 50 % locator on a curved limb, seed 004 §2-4-2), found here by scipy's quad over rings about the boresight
and brentq — not the cap-overlap formula (calibration.horizon.ifov) the fit uses."""

from __future__ import annotations

import math
from functools import cache

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


@cache
def cover_separation(radius_deg: float, half_angle_deg: float, level: float = 0.5) -> float:
    """The boresight's angle [°] from the disc's centre at which a share `level` of the IFOV covers it."""
    return brentq(lambda d: covered_share(d, radius_deg, half_angle_deg) - level, radius_deg - half_angle_deg,
                  radius_deg + half_angle_deg, xtol=1e-13, rtol=1e-15)


def half_cover_separation(radius_deg: float, half_angle_deg: float) -> float:
    """d_½ [°]: the boresight's angle from the disc's centre at which half of the IFOV covers it (ρ for α = 0)."""
    return radius_deg if half_angle_deg == 0.0 else cover_separation(radius_deg, half_angle_deg, 0.5)


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


# --- the simulated sensor's build in the fit's terms ------------------------------------------------------------------
def _straight_edge_share(u):
    """The share of a top-hat IFOV beyond a straight edge, its centre u radii inside: ½ + (u√(1−u²) + asin u)/π."""
    u = np.clip(u, -1.0, 1.0)
    return 0.5 + (u * np.sqrt(1.0 - u * u) + np.arcsin(u)) / np.pi


def _crossing(phase, values, level) -> float:
    """The first crossing of `level` by `values` sampled at `phase`, interpolated linearly."""
    i = int(np.flatnonzero((values[:-1] - level) * (values[1:] - level) <= 0)[0])
    return phase[i] + (level - values[i]) / (values[i + 1] - values[i]) * (phase[i + 1] - phase[i])


def _lag_shifts(n_body, radius, gamma_deg, cone, tau_deg, half_angle_deg, level, step=0.002):
    """How far a first-order lag of `tau_deg` (of phase) moves the falling and rising edges [°] beyond a pure delay
    by τ, at the threshold `level`: the pulse of a straight-edged top hat (the separation from the disc's centre
    along the scan taken exactly), convolved with e^{−s/τ}/τ by the trapezoid rule, its crossings interpolated.
    Also the chord's half-width w and dρ/dw of the crossing condition there."""
    g, sign = np.radians(gamma_deg), 1.0 if cone == 1 else -1.0
    a, b, c = n_body[0] * np.sin(g), n_body[2] * np.sin(g), sign * n_body[1] * np.cos(g)
    centre = np.degrees(np.arctan2(a, b))
    w = np.degrees(np.arccos((np.cos(np.radians(radius)) - c) / np.hypot(a, b)))
    kernel_s = np.arange(0.0, 14.0 * tau_deg, step)
    kernel = np.exp(-kernel_s / tau_deg) / tau_deg * step
    kernel[0] *= 0.5
    shifts = []
    for middle in (centre + w, centre - w):  # the falling edge, the rising one
        phase = np.arange(middle - 9.0, middle + 9.0, step)
        d = np.radians(phase)
        sep = np.degrees(np.arccos(np.clip(a * np.sin(d) + b * np.cos(d) + c, -1.0, 1.0)))
        x = _straight_edge_share((radius - sep) / half_angle_deg)
        padded = np.concatenate([np.full(kernel.size - 1, x[0]), x])
        y = np.convolve(padded, kernel, mode="valid")[: x.size] / kernel.sum()
        shifts.append(_crossing(phase, y, level) - _crossing(phase, x, level) - tau_deg)
    drho_dw = np.hypot(a, b) * np.sin(np.radians(w)) / np.sin(np.radians(radius))
    return shifts[0], shifts[1], drho_dw


def simulated_truth(truth, tilts_deg, poses, *, period_s: float = 1.0, threshold: float = 0.5
                    ) -> HorizonSensorParameters:
    """The simulated sensor's build `truth` (drivers.sim.horizon_optics.HorizonTruth, a top-hat IFOV) on a fixture
    tilted by `tilts_deg` (the world's mount tilts) in the fit's terms, for a plan of `poses` [(roll, pitch, radius)],
    worked out here from the simulator's documented physics (folded: the mount's pitch in the phase offsets).

    * γ_k: the build's; the mount: the world's tilt R_y(t_x)·R_x(−t_y) split as R_x(roll)·R_z(yaw)·R_y(pitch) by scipy.
    * o_k = −phase_offset_k + 360°·τ/T − pitch, plus what the lag adds beyond a pure delay (its third-order term on
      the edge's S-shaped pulse, ≈ −0.4 mdeg at τ = 0.5 ms), averaged over the plan's edges.
    * Δρ = d(C1 + offset) − d(C1): the threshold's offset moves the edge to where that share of the IFOV covers the
      disc (:func:`cover_separation`), plus the lag's narrowing of the chord at a threshold off the pulse's middle
      (its second-order term), averaged likewise.
    """
    if truth.ifov_profile != "tophat":
        raise ValueError("simulated_truth knows the top-hat IFOV only")
    roll, yaw, pitch = Rotation.from_euler("YX", [tilts_deg[0], -tilts_deg[1]], degrees=True).as_euler(
        "XZY", degrees=True)
    mount = Rotation.from_euler("XZY", [roll, yaw, pitch], degrees=True).as_matrix()
    alpha, level = truth.ifov_half_angle_deg, threshold + truth.threshold_offset
    tau = 360.0 * truth.time_constant_s / period_s
    common, widths, radii = {1: [], 2: []}, [], sorted({round(float(r), 6) for _, _, r in poses})
    for table_roll, table_pitch, radius in poses:
        table = Rotation.from_euler("YX", [table_pitch, table_roll], degrees=True).as_matrix()
        n = mount.T @ (table.T @ np.array([0.0, 0.0, 1.0]))
        for cone in (1, 2):
            if tau > 0:
                out, in_, drho_dw = _lag_shifts(n, radius, truth.gamma_deg[cone - 1], cone, tau, alpha, level)
            else:
                out = in_ = drho_dw = 0.0
            common[cone].append((out + in_) / 2.0)
            widths.append(drho_dw * (out - in_) / 2.0)
    threshold_bias = np.mean([cover_separation(r, alpha, level) - cover_separation(r, alpha, threshold)
                              for r in radii])
    return HorizonSensorParameters(
        gamma1_deg=truth.gamma_deg[0], gamma2_deg=truth.gamma_deg[1],
        phase_offset1_deg=-truth.phase_offset_deg[0] + tau + np.mean(common[1]) - pitch,
        phase_offset2_deg=-truth.phase_offset_deg[1] + tau + np.mean(common[2]) - pitch,
        radius_bias_deg=float(threshold_bias + np.mean(widths)), mount_roll_deg=float(roll), mount_yaw_deg=float(yaw),
        ifov_half_angle_deg=alpha)
