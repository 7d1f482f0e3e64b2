"""The field of view's partial obscuration by the Earth (seed 004 §2-4-2, §4-4, Table 4-5).

The thesis' sensor sees through a circular instantaneous field of view (IFOV) of half-angle α = 2° (STK's "simple
conic"); near the horizon part of it covers the Earth and part the sky. STK's "Obscuration" report is the percentage
of the IFOV's solid angle covered by the Earth, and the thesis' case C declares a crossing where it passes 50 % (the
normalised constant locator of seed 004 eq. 2.1 with C1 = 0.5).

* Spherical Earth: the Earth is a spherical cap of angular radius ρ about the nadir, the IFOV a cap of radius α about
  the boresight, so the obscured fraction is the overlap of two caps on the unit sphere divided by the IFOV's solid
  angle — closed form (:func:`cap_overlap_sr`) and a function of the boresight's angle from nadir only.
* Any convex Earth (WGS84 from outside): :func:`covered_fraction` integrates over the IFOV in polar co-ordinates
  about a point inside both regions, with the edge found on each ray by bisection on a "depth" callable and the
  azimuth integral split where the edge meets the IFOV's rim, so Gauss–Legendre converges exponentially.
* Any radiance: :func:`ifov_nodes` / :func:`ifov_mean` (top-hat or Gaussian response, plain quadrature), and
  :func:`ring_mean_sphere`, the exact 1-D form of a top-hat IFOV over a radiance symmetric about the nadir.

The 50 % locator is biased by the limb's curvature: with the boresight exactly on a horizon of radius ρ, less than
half of the IFOV covers the (convex) disc, so 50 % is reached with the boresight a little inside it, at the separation
:func:`level_separation_deg` < ρ (≈ ρ − cot ρ · α²/6 for small α: 0.0047° at ρ = 67.9°, α = 2°). Feeding that
separation to a solver as the disc's radius removes the bias exactly on a sphere (:func:`locator_radius_bias_deg`,
:func:`locator_phase_bias_deg`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .scan import THESIS_GAMMA_DEG, THESIS_IFOV_HALF_ANGLE_DEG, crossing_phases_for_nadir, scan_vector

_TOP_HAT = "top-hat"
_GAUSSIAN = "gaussian"
RESPONSES = (_TOP_HAT, _GAUSSIAN)
_ITERATIONS = 52  # bisection steps over at most the IFOV's radius: 2⁻⁵² of it, below a double's resolution


def cap_solid_angle_sr(radius_deg) -> np.ndarray:
    """Solid angle [sr] of a spherical cap of angular radius `radius_deg`: 2π (1 − cos r) (seed 004 §2-4-2, the
    IFOV's solid angle that STK's obscuration is a percentage of)."""
    return 2.0 * np.pi * (1.0 - np.cos(np.radians(np.asarray(radius_deg, float))))


def cap_overlap_sr(radius_a_deg, radius_b_deg, separation_deg) -> np.ndarray:
    """Solid angle [sr] common to two spherical caps of angular radii r_a, r_b whose centres are `separation_deg`
    apart — the Earth (r_a = ρ) covering the IFOV (r_b = α) of seed 004 §2-4-2 on a spherical Earth.

    Closed form (Gauss–Bonnet on the lens; e.g. Tovchigrechko & Vakser 2001): Ω = 2 [(π − P) − A cos r_a − B cos r_b]
    where P, A, B are the angles, at a point where the two rims cross and at the two centres, of the spherical
    triangle with sides r_a, r_b, d. The angles come from the half-angle formulas (tan(X/2) = √(sin(s − u) sin(s − v)
    / (sin s sin(s − w))), s the half-perimeter, u, v the sides at X), which stay accurate as the caps become tangent
    where the usual arccos form loses half the digits. The smaller cap's solid angle when one holds the other, 0 when
    they are apart, Ω_a + Ω_b − 4π when r_a + r_b + d ≥ 360° (their complements are apart). Radii in (0, 180)°,
    d in [0, 180]°.
    """
    ra, rb, d = np.broadcast_arrays(*(np.radians(np.asarray(x, float)) for x in (radius_a_deg, radius_b_deg,
                                                                                   separation_deg)))
    if np.any((ra <= 0) | (ra >= np.pi) | (rb <= 0) | (rb >= np.pi)):
        raise ValueError("cap radii must lie in (0, 180) degrees")
    if np.any((d < 0) | (d > np.pi)):
        raise ValueError("the caps' separation must lie in [0, 180] degrees")
    cap_a, cap_b = 2.0 * np.pi * (1.0 - np.cos(ra)), 2.0 * np.pi * (1.0 - np.cos(rb))
    s = 0.5 * (ra + rb + d)
    sin_s, sin_sd = np.sin(s), np.clip(np.sin(s - d), 0.0, None)
    sin_sa, sin_sb = np.clip(np.sin(s - ra), 0.0, None), np.clip(np.sin(s - rb), 0.0, None)
    with np.errstate(invalid="ignore"):
        pi_minus_p = 2.0 * np.arctan2(np.sqrt(sin_s * sin_sd), np.sqrt(sin_sa * sin_sb))
        angle_a = 2.0 * np.arctan2(np.sqrt(sin_sd * sin_sa), np.sqrt(sin_s * sin_sb))
        angle_b = 2.0 * np.arctan2(np.sqrt(sin_sd * sin_sb), np.sqrt(sin_s * sin_sa))
        lens = 2.0 * (pi_minus_p - angle_a * np.cos(ra) - angle_b * np.cos(rb))
    out = np.where((d > np.abs(ra - rb)) & (d < ra + rb), np.clip(lens, 0.0, None), 0.0)
    out = np.where(d <= np.abs(ra - rb), np.minimum(cap_a, cap_b), out)
    return np.where(ra + rb + d >= 2.0 * np.pi, cap_a + cap_b - 4.0 * np.pi, out)


def covered_fraction_sphere(separation_deg, rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG) -> np.ndarray:
    """Fraction (0–1) of a circular IFOV of half-angle α covered by a spherical Earth of angular radius ρ when the
    boresight is `separation_deg` from the nadir: STK's "Obscuration" / 100 (seed 004 §4-4, Table 4-5)."""
    return cap_overlap_sr(rho_deg, half_angle_deg, separation_deg) / cap_solid_angle_sr(half_angle_deg)


def separation_along_scan_deg(phase_deg, nadir_body, gamma_deg=THESIS_GAMMA_DEG, cone=1) -> np.ndarray:
    """Angle [°] between cone `cone`'s boresight at phase δ and the direction `nadir_body` (3,): acos(S_k(δ)·n)
    (seed 004 eqs. 2.5, 2.7)."""
    n = np.asarray(nadir_body, float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    s = scan_vector(phase_deg, gamma_deg, cone)
    return np.degrees(np.arccos(np.clip(np.sum(s * n, axis=-1), -1.0, 1.0)))


def covered_fraction_along_scan(phase_deg, nadir_body, rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG,
                                gamma_deg=THESIS_GAMMA_DEG, cone=1) -> np.ndarray:
    """The obscured fraction (0–1) of cone `cone`'s IFOV along its scan over a spherical Earth of angular radius ρ
    about `nadir_body` — the STK obscuration report of seed 004 Table 4-5 (÷ 100)."""
    d = separation_along_scan_deg(phase_deg, nadir_body, gamma_deg, cone)
    return covered_fraction_sphere(d, rho_deg, half_angle_deg)


def _bisect(fn: Callable[[np.ndarray], np.ndarray], lo, hi, iterations: int = 64) -> np.ndarray:
    """Vectorised bisection for a sign change of fn between lo and hi (fn(lo) and fn(hi) of opposite signs)."""
    lo, hi = np.array(lo, float, copy=True), np.array(hi, float, copy=True)
    lo, hi = np.broadcast_arrays(lo, hi)
    lo, hi = lo.copy(), hi.copy()
    positive_at_lo = fn(lo) > 0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        same = (fn(mid) > 0) == positive_at_lo
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
    return 0.5 * (lo + hi)


def level_separation_deg(rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, level=0.5) -> np.ndarray:
    """The boresight's angle from nadir [°] at which a fraction `level` of the IFOV covers a spherical Earth of
    angular radius ρ — where seed 004's normalised constant locator (eq. 2.1, C1 = `level`) fires on an obscuration
    pulse. Equals ρ for a straight limb; a little less (the disc is convex) for a curved one."""
    level = np.asarray(level, float)
    if np.any((level <= 0) | (level >= 1)):
        raise ValueError(f"the locator's level must lie strictly between 0 and 1, got {level!r}")
    rho, alpha, level = np.broadcast_arrays(np.asarray(rho_deg, float), np.asarray(half_angle_deg, float), level)
    return _bisect(lambda d: covered_fraction_sphere(d, rho, alpha) - level, rho - alpha, rho + alpha, 60)


def locator_radius_bias_deg(rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, level=0.5) -> np.ndarray:
    """ρ − d_level [°]: how far inside a spherical disc of angular radius ρ the boresight is when the obscuration
    locator (seed 004 eq. 2.1, C1 = `level`) fires. For C1 = 0.5 and small α it is ≈ cot ρ · α²/6 (the limb's
    geodesic curvature cot ρ; 0.0047° at ρ = 67.9°, α = 2°). Solving with ρ − bias as the disc's radius removes it."""
    return np.asarray(rho_deg, float) - level_separation_deg(rho_deg, half_angle_deg, level)


def locator_phase_bias_deg(nadir_body, rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, level=0.5,
                           gamma_deg=THESIS_GAMMA_DEG, cone=1):
    """Phase errors [°] ``(Δδ_out, Δδ_in)`` of the obscuration locator (seed 004 eq. 2.1, C1 = `level`) against the
    boresight crossings of seed 004 eq. 2.7 for cone `cone` and a spherical disc of radius ρ about `nadir_body`.

    The locator fires at separation d_level < ρ, i.e. before the boresight leaves the disc (Δδ_out < 0) and after it
    comes back (Δδ_in > 0); the size grows as the scan meets the horizon more obliquely (γ, roll, pitch).
    """
    d = level_separation_deg(rho_deg, half_angle_deg, level)
    out_l, in_l = crossing_phases_for_nadir(nadir_body, d, gamma_deg, cone)
    out_b, in_b = crossing_phases_for_nadir(nadir_body, rho_deg, gamma_deg, cone)
    wrap = lambda x: (x + 180.0) % 360.0 - 180.0  # noqa: E731 - a one-line phase difference
    return wrap(out_l - out_b), wrap(in_l - in_b)


def last_contact_phases_deg(nadir_body, rho_deg, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG,
                            gamma_deg=THESIS_GAMMA_DEG, cone=1):
    """Phases [°] ``(out, in)`` where the IFOV's rim just touches a spherical disc of radius ρ (separation ρ + α):
    the obscuration leaves 0 there — seed 004 Table 4-5 reaches 0 at t ≈ 0.1904 s, 2.13° of phase after the boresight
    crossing (digest §4.1: 2·asin(sin(α/2)/sin γ) along the scan circle when the horizon is crossed square-on)."""
    return crossing_phases_for_nadir(nadir_body, np.asarray(rho_deg, float) + half_angle_deg, gamma_deg, cone)


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing `axis` (…, 3) to a right-handed orthonormal basis."""
    helper = np.where(np.abs(axis[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    return e1, np.cross(axis, e1)


def _ray(centre, e1, e2, radius_rad, azimuth_rad) -> np.ndarray:
    """Directions at angle `radius_rad` from `centre` towards azimuth `azimuth_rad` (measured from e1 to e2)."""
    r, a = np.asarray(radius_rad)[..., None], np.asarray(azimuth_rad)[..., None]
    return np.cos(r) * centre + np.sin(r) * (np.cos(a) * e1 + np.sin(a) * e2)


def _unit(vector, name: str) -> np.ndarray:
    v = np.asarray(vector, float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} must be a 3-vector (…, 3), got shape {v.shape}")
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise ValueError(f"{name} must not be zero")
    return v / norm


def covered_fraction(boresight, depth: Callable[[np.ndarray], np.ndarray],
                     half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, nodes_per_arc: int = 48,
                     rim_samples: int = 256) -> float:
    """Fraction (0–1) of a circular IFOV about `boresight` (3,) covered by a convex Earth — STK's obscuration of
    seed 004 §4-4 for any Earth shape, e.g. WGS84 through a tangent-altitude function.

    Parameters
    ----------
    boresight : array_like (3,)
        The IFOV's axis (any frame; `depth` must use the same one).
    depth : callable
        ``depth(directions (N, 3)) -> (N,)``: continuous, > 0 for directions that meet the Earth, < 0 for those that
        miss it (e.g. ``n·u − cos ρ`` for a sphere, or minus a ray's tangent altitude). The Earth seen from outside
        must be convex (true for a sphere and an ellipsoid).
    half_angle_deg : float
        The IFOV's half-angle α [°].
    nodes_per_arc, rim_samples : int
        Gauss–Legendre nodes per azimuth arc; samples of the IFOV's rim used to find where the edge crosses it.

    Returns
    -------
    float
        The covered fraction. Rays are taken from a point inside both regions (the intersection of two convex sets
        is star-shaped about it), the edge is found on each by bisection (to 1e-16 rad) and the azimuth integral is
        split where the edge meets the rim, so the result agrees with the closed form of :func:`cap_overlap_sr` to
        ~1e-12 on a sphere. A sliver thinner than the rim sampling can be missed (fraction < ~1e-6).
    """
    b = _unit(boresight, "boresight")
    if b.shape != (3,):
        raise ValueError("covered_fraction takes one boresight (3,); loop over several")
    alpha = np.radians(float(half_angle_deg))
    if not 0 < alpha < np.pi / 2:
        raise ValueError(f"the IFOV half-angle must lie in (0, 90) degrees, got {half_angle_deg!r}")
    e1, e2 = _basis(b)
    beta = np.linspace(0.0, 2.0 * np.pi, rim_samples, endpoint=False)
    rim_depth = depth(_ray(b, e1, e2, np.full_like(beta, alpha), beta))
    centre_depth = float(depth(b[None, :])[0])
    if np.all(rim_depth > 0) and centre_depth > 0:
        return 1.0
    if np.all(rim_depth <= 0) and centre_depth <= 0:
        return 0.0
    # a point c well inside both the IFOV and the Earth: halfway from where the radius towards the rim's deepest
    # point enters the Earth (the boresight itself if it is on the Earth) to the rim
    k = int(np.argmax(rim_depth))
    entry = 0.0 if centre_depth > 0 else float(_bisect(lambda r: depth(_ray(b, e1, e2, r, beta[k])), 0.0, alpha,
                                                       _ITERATIONS))
    c = _ray(b, e1, e2, 0.5 * (entry + alpha), beta[k])
    if not depth(c[None, :])[0] > 0:
        return 0.0  # a sliver at the rounding level: the rim only grazes the Earth
    f1, f2 = _basis(c)
    # where the Earth's edge crosses the rim: the kinks of the azimuth integrand about c
    sign = rim_depth > 0
    changes = np.nonzero(sign != np.roll(sign, -1))[0]
    if changes.size:
        at = _bisect(lambda x: depth(_ray(b, e1, e2, np.full_like(x, alpha), x)), beta[changes],
                     beta[changes] + 2.0 * np.pi / rim_samples, _ITERATIONS)
        q = _ray(b, e1, e2, np.full_like(at, alpha), at)
        kinks = np.sort(np.mod(np.arctan2(q @ f2, q @ f1), 2.0 * np.pi))
    else:
        kinks = np.array([0.0])
    edges = np.append(kinks, kinks[0] + 2.0 * np.pi)
    x, w = np.polynomial.legendre.leggauss(nodes_per_arc)
    half = 0.5 * np.diff(edges)
    psi = (edges[:-1, None] + half[:, None] * (x[None, :] + 1.0)).ravel()
    weights = (half[:, None] * w[None, :]).ravel()
    # the IFOV's rim seen from c: A cos r + B sin r = cos α
    u = np.cos(psi)[:, None] * f1 + np.sin(psi)[:, None] * f2
    a_, b_ = float(c @ b), u @ b
    r_rim = np.arctan2(b_, a_) + np.arccos(np.clip(np.cos(alpha) / np.hypot(a_, b_), -1.0, 1.0))
    inside = depth(_ray(c, f1, f2, r_rim, psi)) > 0
    r_edge = np.where(inside, r_rim, 0.0)
    if np.any(~inside):
        idx = np.nonzero(~inside)[0]
        r_edge[idx] = _bisect(lambda r: depth(_ray(c, f1, f2, r, psi[idx])), np.zeros(idx.size), r_rim[idx],
                              _ITERATIONS)
    area = float(np.sum(weights * (1.0 - np.cos(r_edge))))
    return area / (2.0 * np.pi * (1.0 - np.cos(alpha)))


def ifov_nodes(boresight, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, response: str = _TOP_HAT,
               fwhm_deg: float | None = None, n_radial: int = 12, n_azimuth: int = 32):
    """Quadrature nodes over a circular IFOV about `boresight` (…, 3): ``(directions (…, N, 3), weights (N,))`` with
    the weights summing to 1, so Σ w L(u) is the IFOV's mean radiance (seed 004 §2-4-2; PSG's Gaussian beam of FWHM
    4° in Appendix 2).

    `response` is ``"top-hat"`` (uniform within α) or ``"gaussian"`` (exp(−4 ln 2 r²/FWHM²), FWHM `fwhm_deg`, default
    2α, truncated at 1.5 FWHM). Gauss–Legendre in 1 − cos r (the solid-angle measure) times a uniform azimuth.
    """
    if response not in RESPONSES:
        raise ValueError(f"response must be one of {RESPONSES}, got {response!r}")
    b = _unit(boresight, "boresight")
    alpha = np.radians(float(half_angle_deg))
    fwhm = np.radians(float(fwhm_deg)) if fwhm_deg is not None else 2.0 * alpha
    r_max = alpha if response == _TOP_HAT else 1.5 * fwhm
    x, w = np.polynomial.legendre.leggauss(n_radial)
    span = 1.0 - np.cos(r_max)
    r = np.arccos(1.0 - 0.5 * span * (x + 1.0))
    wr = 0.5 * span * w
    if response == _GAUSSIAN:
        wr = wr * np.exp(-4.0 * np.log(2.0) * r**2 / fwhm**2)
    psi = np.linspace(0.0, 2.0 * np.pi, n_azimuth, endpoint=False)
    rr, pp = np.meshgrid(r, psi, indexing="ij")
    weights = np.broadcast_to(wr[:, None], rr.shape).ravel()
    weights = weights / weights.sum()
    e1, e2 = _basis(b)
    rr, pp = rr.ravel(), pp.ravel()
    dirs = (np.cos(rr)[:, None] * b[..., None, :]
            + np.sin(rr)[:, None] * (np.cos(pp)[:, None] * e1[..., None, :] + np.sin(pp)[:, None] * e2[..., None, :]))
    return dirs, weights


def ifov_mean(boresight, radiance: Callable[[np.ndarray], np.ndarray], half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG,
              response: str = _TOP_HAT, fwhm_deg: float | None = None, n_radial: int = 12,
              n_azimuth: int = 32) -> np.ndarray:
    """The IFOV-weighted mean of ``radiance(directions (…, 3)) -> (…)`` about `boresight` (…, 3): what the detector
    sees (seed 004 §2-4-2, §2-4-3). Plain quadrature (:func:`ifov_nodes`): within ~1e-2 of a step across a sharp
    edge (fast for smooth radiances); use :func:`covered_fraction` or :func:`ring_mean_sphere` where an exact edge
    matters."""
    dirs, weights = ifov_nodes(boresight, half_angle_deg, response, fwhm_deg, n_radial, n_azimuth)
    return np.sum(radiance(dirs) * weights, axis=-1)


def ring_mean_sphere(separation_deg, radiance_of_angle: Callable[[np.ndarray], np.ndarray],
                     half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, breaks_deg=(), n_rings: int = 800) -> np.ndarray:
    """Mean over a top-hat IFOV of a radiance that depends only on the angle η from nadir (a spherical Earth and a
    horizontally uniform atmosphere, seed 004 §2-4-3), with the boresight `separation_deg` from nadir.

    The IFOV's solid angle within η of nadir is the cap overlap A(η) = :func:`cap_overlap_sr` (η, α, d), so the mean
    is (1/Ω_α) ∫ L(η) dA(η): a 1-D Stieltjes sum over `n_rings` rings, with `breaks_deg` (angles where L jumps, e.g.
    the horizon ρ and the 100 km cut-off) inserted as ring edges so a jump costs no accuracy. `radiance_of_angle`
    takes η [°] (any shape) and returns L(η).
    """
    d = np.atleast_1d(np.asarray(separation_deg, float))
    alpha = float(half_angle_deg)
    lo = np.clip(d - alpha, 1e-9, None)
    hi = np.minimum(d + alpha, 180.0 - 1e-9)
    u = np.linspace(0.0, 1.0, n_rings + 1)
    grid = lo[:, None] + (hi - lo)[:, None] * u[None, :]
    breaks = np.atleast_1d(np.asarray(breaks_deg, float))
    if breaks.size:
        grid = np.sort(np.concatenate([grid, np.clip(np.broadcast_to(breaks, (d.size, breaks.size)),
                                                     lo[:, None], hi[:, None])], axis=1), axis=1)
    area = cap_overlap_sr(np.clip(grid, 1e-9, 180.0 - 1e-9), alpha, d[:, None])
    mid = 0.5 * (grid[:, 1:] + grid[:, :-1])
    mean = np.sum(radiance_of_angle(mid) * np.diff(area, axis=1), axis=1) / cap_solid_angle_sr(alpha)
    return mean.reshape(np.shape(separation_deg))
