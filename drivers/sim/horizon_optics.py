"""Physics of the simulated scanning Earth-horizon sensor (seed 004's dual-cone scanner) on an IR Earth-simulator
bench — the simulator's own, never the calibration's model (it imports nothing of calibration/).

**Scan.** Cone k (1, 2; s_1 = +1, s_2 = −1) looks along ``S_k(δ) = (sin δ sin γ_k, s_k cos γ_k, cos δ sin γ_k)`` in
the body frame (seed 004 eq. 2.5 and the package's conventions: the half-cone γ_k from the spin axis ±Y_s, the
phase δ from Z_s towards X_s). The module's phase is counted from its index mark; cone k's mirror really looks at
``δ = δ_module + phase_offset_k`` (the index mark's angle and the fixed mirror's azimuth: the build's phase
reference error). The rotor is sampled ``samples_per_revolution`` times a revolution by its encoder, so sample j
sits at δ_module = 360° j / N and at time j T / N of a revolution of period T.

**Scene.** The Earth simulator is a warm spherical cap of radius D (the bench's source distance) centred on the
nominal sensor point N0 (the sensor's position at the table's zero), its axis along lab +z, cut by an iris to the
angular radius ρ about that axis, on a cold background (the cooled shroud that fills the rest of the view). A ray
P + s u from the sensor's true position P meets the sphere at X (s > 0); it sees the disc when the angle between
X − N0 and the axis is at most ρ. From N0 the disc is exactly the cone S·n = cos ρ about the disc centre n; from any
other P (a lever arm, the fixture's offset) the parallax is in the intersection. The scene's band radiance is the
14–16 µm Planck radiance (digest §2.2: the CO₂ band) of the disc's or the background's temperature, or the cold
cover's (the background's) when the cover is closed; a blinding source (the back door's) is a small hot cap on the
same sphere.

**Detector.** The bolometer integrates the radiance over its IFOV — a top hat of half-angle α or a Gaussian whose
half maximum is at α (truncated at 2.5 α). When the scene seen from the sensor is a cap (the sensor at the sphere's
centre N0, so no parallax, and no blinding source) the radiance depends only on the angle from the disc's centre, and
the IFOV's mean is a 1-D integral over rings about the boresight (:func:`cap_ifov_fraction`): the share of the ring of
radius r inside the cap, acos((cos ρ − cos d cos r) / (sin d sin r)) / π, weighted by the profile, with Gauss–Legendre
on either side of the ring that grazes the rim (r = |ρ − d|) and a quadratic change of variable that takes out the
square-root kink there — the same for every orientation of the edge, to ~1e-12 of the pulse. Otherwise (parallax,
a blinding source) by quadrature over a sunflower pattern of points, each point seeing an edge as a ramp over its own
cell (so the sum is smooth in the edge's position: no staircase of 1/points steps), and only for the samples near an
edge (elsewhere the IFOV sees one radiance); that quadrature moves an edge by a few millidegrees with its orientation.
Its first-order time constant τ lags the signal (the exact response at the samples to an input linear between them,
in its periodic steady state: a ramp comes out τ late). Then the module's amplifier (counts per unit radiance above
the cold background's, on a pedestal), Gaussian noise per sample and an `adc_bits` converter clipped at full scale.

**Locator** (the module's firmware, :func:`locate_edges`): the normalised constant-threshold locator of seed 004
eq. 2.1 as documented in :mod:`drivers.horizon_protocol`, in two passes. The first takes the levels from the pulse's
lowest and highest quarters and finds the Earth (the longest run above the threshold) and its two edges; the second
takes the levels from the plateaus — the median of the Earth's samples more than `plateau_margin` samples from
either edge, and of the space's likewise (the margin is two IFOV diameters of phase, so a plateau sample sees only
disc or only background: a short chord, whose top is narrow, does not lower its Earth level) — and locates the edges
again at the threshold ``space + (C1 + bias) (Earth − space)`` (the comparator's offset `threshold_offset` is the
build's), with a 5 % hysteresis and linear interpolation between samples.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import numpy as np

#: Planck's radiation constants: c1L = 2hc² [W µm⁴ m⁻² sr⁻¹], c2 = hc/k [µm K]
C1L = 1.191042972e8
C2 = 14387.7688
#: The detector's band [µm] (seed 004 §2-1: the 14–16 µm CO₂ band)
BAND_UM = (14.0, 16.0)
CONE_SIGNS = (1.0, -1.0)
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
PATTERN_POINTS = 600  # quadrature points over the IFOV
GAUSSIAN_TRUNCATION = 2.5  # the Gaussian IFOV's points reach out to this many half-maximum radii
RING_NODES = 24  # Gauss–Legendre nodes on either side of the grazing ring (cap_ifov_fraction)
#: A sensor closer than this fraction of the sphere's radius to its centre sees the disc as a cap (no parallax)
CAP_TOLERANCE = 1e-9


def band_radiance(temperature_k, band_um=BAND_UM, points: int = 41) -> np.ndarray:
    """Blackbody radiance in the band [W m⁻² sr⁻¹] at `temperature_k` [K] (Planck's law, Simpson's rule)."""
    t = np.asarray(temperature_k, dtype=float)[..., None]
    lam = np.linspace(*band_um, points)
    with np.errstate(over="ignore", divide="ignore"):
        spectral = np.where(t > 0, C1L / lam ** 5 / np.expm1(C2 / (lam * np.maximum(t, 1e-9))), 0.0)
    weights = np.ones(points)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    return spectral @ weights * (lam[1] - lam[0]) / 3.0


@dataclass(frozen=True)
class HorizonTruth:
    """What a simulated horizon sensor really is (never visible to drivers).

    Attributes
    ----------
    serial : str
    gamma_deg : (float, float)
        True half-cone angles γ1, γ2 [°].
    phase_offset_deg : (float, float)
        Where each cone really looks when the module's phase is 0 (index mark + fixed mirror azimuth) [°].
    threshold_offset : float
        The locator's comparator offset, as a fraction of the pulse added to C1.
    time_constant_s : float
        The bolometer's first-order time constant τ [s].
    ifov_half_angle_deg : float
    ifov_profile : {"tophat", "gaussian"}
    """

    serial: str
    gamma_deg: tuple[float, float]
    phase_offset_deg: tuple[float, float]
    threshold_offset: float
    time_constant_s: float
    ifov_half_angle_deg: float = 2.0
    ifov_profile: str = "tophat"


def draw_build(serial: str, seed: int | None, *, gamma_deg: float, gamma_sd_deg: float, phase_sd_deg: float,
               threshold_sd: float, time_constant_s: float, time_constant_sd: float, ifov_half_angle_deg: float,
               ifov_profile: str) -> HorizonTruth:
    """A sensor of the design drawn from `seed` (None: the nominal sensor, no build errors); draws are clipped at
    3σ. Used for a fleet with the seed taken from the serial alone."""
    if seed is None:
        return HorizonTruth(serial, (gamma_deg, gamma_deg), (0.0, 0.0), 0.0, time_constant_s, ifov_half_angle_deg,
                            ifov_profile)
    rng = np.random.default_rng(seed)
    draw = lambda sd: float(np.clip(rng.normal(), -3.0, 3.0)) * sd  # noqa: E731
    return HorizonTruth(serial, (gamma_deg + draw(gamma_sd_deg), gamma_deg + draw(gamma_sd_deg)),
                        (draw(phase_sd_deg), draw(phase_sd_deg)), draw(threshold_sd),
                        max(time_constant_s * (1.0 + draw(time_constant_sd)), 0.0), ifov_half_angle_deg,
                        ifov_profile)


def fleet_seed(serial: str) -> int:
    """The build seed of serial `serial`: from the serial alone, reproducible in any process."""
    return zlib.crc32(f"horizon-build:{serial}".encode())


@dataclass(frozen=True)
class Scene:
    """What the sensor faces, in the lab frame [mm, °, K] (module docstring).

    Attributes
    ----------
    centre_mm : (3,) array
        N0, the centre of the Earth simulator's sphere (the nominal sensor point).
    axis : (3,) array
        Unit vector from N0 to the disc's centre.
    sphere_radius_mm : float
        D, the source distance.
    disc_radius_deg : float
        ρ, the iris's true angular radius.
    disc_k, background_k : float
        The disc's and the background's temperatures (the cover's, when closed, is the background's).
    cover_open : bool
    blind_direction : (3,) array or None
        A blinding source's direction from N0 (unit), or None.
    blind_radius_deg, blind_k : float
    """

    centre_mm: np.ndarray
    axis: np.ndarray
    sphere_radius_mm: float
    disc_radius_deg: float
    disc_k: float
    background_k: float
    cover_open: bool = True
    blind_direction: np.ndarray | None = None
    blind_radius_deg: float = 1.0
    blind_k: float = 1500.0


def scan_directions(phase_deg, gamma_deg: float, sign: float) -> np.ndarray:
    """S(δ) in the body frame for the phases δ [°], shape (N, 3) (module docstring)."""
    d, g = np.radians(np.asarray(phase_deg, float)), math.radians(gamma_deg)
    return np.stack([np.sin(d) * math.sin(g), np.full_like(d, sign * math.cos(g)), np.cos(d) * math.sin(g)], -1)


def ifov_pattern(half_angle_deg: float, profile: str, points: int = PATTERN_POINTS):
    """Quadrature of the IFOV: (radius [rad], azimuth [rad], weight) of `points` sunflower points; weights sum
    to 1. A top hat covers the half-angle; a Gaussian (half maximum at the half-angle) reaches 2.5 times it."""
    if profile not in ("tophat", "gaussian"):
        raise ValueError(f"`ifov_profile` must be 'tophat' or 'gaussian', got {profile!r}")
    alpha = math.radians(half_angle_deg)
    reach = alpha * (GAUSSIAN_TRUNCATION if profile == "gaussian" else 1.0)
    i = np.arange(points)
    r = reach * np.sqrt((i + 0.5) / points)
    phi = i * GOLDEN_ANGLE
    w = np.exp(-math.log(2.0) * (r / alpha) ** 2) if profile == "gaussian" else np.ones(points)
    return r, phi, w / w.sum()


def _profile_weight(r, half_angle_rad: float, profile: str) -> np.ndarray:
    """The IFOV's response at angle `r` [rad] from its axis (1 on a top hat; a Gaussian's is ½ at the half-angle)."""
    if profile == "gaussian":
        return np.exp(-math.log(2.0) * (r / half_angle_rad) ** 2)
    return np.ones_like(r)


def cap_ifov_fraction(separation_deg, cap_radius_deg: float, half_angle_deg: float, profile: str = "tophat",
                      nodes: int = RING_NODES) -> np.ndarray:
    """The share (0–1) of the IFOV's response that falls inside a cap of angular radius ρ = `cap_radius_deg` when the
    boresight is `separation_deg` (d) from the cap's centre (module docstring).

    Rings of radius r about the boresight: a ring lies inside the cap over the azimuths where
    cos d cos r + sin d sin r cos φ ≥ cos ρ, a share acos((cos ρ − cos d cos r) / (sin d sin r)) / π of it, and it
    weighs w(r) sin r dr. The share has a square-root kink at the ring that grazes the rim, r = |ρ − d|: the integral
    is split there and each side mapped by r = kink ∓ L s² so Gauss–Legendre in s converges fast."""
    if profile not in ("tophat", "gaussian"):
        raise ValueError(f"`ifov_profile` must be 'tophat' or 'gaussian', got {profile!r}")
    d = np.radians(np.asarray(separation_deg, float))[..., None]
    rho, alpha = math.radians(cap_radius_deg), math.radians(half_angle_deg)
    reach = alpha * (GAUSSIAN_TRUNCATION if profile == "gaussian" else 1.0)
    s, ws = np.polynomial.legendre.leggauss(nodes)
    s, ws = 0.5 * (s + 1.0), 0.5 * ws  # on [0, 1]
    kink = np.clip(np.abs(rho - d), 0.0, reach)
    below, above = kink, reach - kink  # the lengths of [0, kink] and [kink, reach]
    r = np.concatenate([kink - below * s ** 2, kink + above * s ** 2], axis=-1)
    jacobian = np.concatenate([2.0 * below * s * ws, 2.0 * above * s * ws], axis=-1)
    weight = _profile_weight(r, alpha, profile) * np.sin(r) * jacobian
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_phi = (math.cos(rho) - np.cos(d) * np.cos(r)) / (np.sin(d) * np.sin(r))
    share = np.arccos(np.clip(np.nan_to_num(cos_phi, nan=1.0, posinf=1.0, neginf=-1.0), -1.0, 1.0)) / math.pi
    # a ring about a boresight on the cap's centre (sin d = 0) is all in or all out
    share = np.where(np.sin(d) * np.sin(r) > 0, share, (np.cos(r - d) >= math.cos(rho)).astype(float))
    return np.sum(weight * share, axis=-1) / np.sum(weight, axis=-1)


def _hits(position, directions, scene: Scene) -> np.ndarray:
    """Unit vectors from N0 to where rays from `position` along `directions` (…, 3, lab) meet the sphere."""
    q = position - scene.centre_mm
    qu = directions @ q
    s = -qu + np.sqrt(qu ** 2 - (q @ q - scene.sphere_radius_mm ** 2))
    return (q + s[..., None] * directions) / scene.sphere_radius_mm


def _inside(cosine, radius_deg: float, soft_deg: float) -> np.ndarray:
    """1 inside a cap of angular radius `radius_deg` (the cosine of the angle from its centre given), 0 outside; with
    `soft_deg` > 0 a linear ramp that wide across the edge (a quadrature point's share of its cell)."""
    if soft_deg <= 0:
        return (cosine >= math.cos(math.radians(radius_deg))).astype(float)
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    return np.clip(0.5 + (radius_deg - angle) / soft_deg, 0.0, 1.0)


def scene_radiance(position, directions, scene: Scene, soft_deg: float = 0.0) -> np.ndarray:
    """Band radiance [W m⁻² sr⁻¹] seen along `directions` (…, 3, lab) from `position` [mm]; `soft_deg` blurs the
    edges over a quadrature cell (:func:`_inside`)."""
    background = float(band_radiance(scene.background_k))
    if not scene.cover_open:
        return np.full(directions.shape[:-1], background)
    hit = _hits(position, directions, scene)
    on_disc = _inside(hit @ scene.axis, scene.disc_radius_deg, soft_deg)
    out = background + on_disc * (float(band_radiance(scene.disc_k)) - background)
    if scene.blind_direction is not None:
        in_source = _inside(hit @ scene.blind_direction, scene.blind_radius_deg, soft_deg)
        out = out + in_source * (float(band_radiance(scene.blind_k)) - out)
    return out


def ifov_radiance(rotation, position, body_directions, phase_deg, truth: HorizonTruth, scene: Scene,
                  chunk: int = 400) -> np.ndarray:
    """The radiance the IFOV integrates for each boresight `body_directions` (N, 3) at `phase_deg` (N,) [°]: exact
    when the scene is a cap (:func:`cap_ifov_fraction`), otherwise a quadrature that runs only where an edge of the
    disc or of a blinding source is within reach of the IFOV (module docstring)."""
    lab = body_directions @ rotation.T
    if scene.cover_open and scene.blind_direction is None and \
            np.linalg.norm(position - scene.centre_mm) <= CAP_TOLERANCE * scene.sphere_radius_mm:
        # the disc seen from its sphere's centre is a cap: the IFOV's exact mean (module docstring)
        separation = np.degrees(np.arccos(np.clip(lab @ scene.axis, -1.0, 1.0)))
        background = float(band_radiance(scene.background_k))
        reach = truth.ifov_half_angle_deg * (GAUSSIAN_TRUNCATION if truth.ifov_profile == "gaussian" else 1.0)
        share = (separation < scene.disc_radius_deg).astype(float)
        near = np.flatnonzero(np.abs(separation - scene.disc_radius_deg) < reach)  # elsewhere all disc or all sky
        share[near] = cap_ifov_fraction(separation[near], scene.disc_radius_deg, truth.ifov_half_angle_deg,
                                        truth.ifov_profile)
        return background + share * (float(band_radiance(scene.disc_k)) - background)
    out = scene_radiance(position, lab, scene)
    if not scene.cover_open:
        return out
    r, phi, w = ifov_pattern(truth.ifov_half_angle_deg, truth.ifov_profile)
    q = float(np.linalg.norm(position - scene.centre_mm))
    stretch = (scene.sphere_radius_mm + q) / max(scene.sphere_radius_mm - q, 1e-9)  # parallax's largest magnification
    reach = math.degrees(r.max()) * stretch * 1.2 + 0.2
    hit = _hits(position, lab, scene)
    angle = np.degrees(np.arccos(np.clip(hit @ scene.axis, -1.0, 1.0)))
    near = np.abs(angle - scene.disc_radius_deg) < reach
    if scene.blind_direction is not None:
        to_source = np.degrees(np.arccos(np.clip(hit @ scene.blind_direction, -1.0, 1.0)))
        near |= to_source < scene.blind_radius_deg + reach
    index = np.flatnonzero(near)
    if not index.size:
        return out
    cell_deg = math.degrees(r.max()) * math.sqrt(math.pi / r.size) * stretch  # one point's share of the IFOV
    d = np.radians(np.asarray(phase_deg, float))
    # the IFOV's frame about each boresight: e1 along the scan (dS/dδ), e2 = S × e1
    e1_body = np.stack([np.cos(d), np.zeros_like(d), -np.sin(d)], -1)
    offsets_a, offsets_b = np.sin(r) * np.cos(phi), np.sin(r) * np.sin(phi)
    for start in range(0, index.size, chunk):
        i = index[start:start + chunk]
        s, e1 = lab[i], e1_body[i] @ rotation.T
        e2 = np.cross(s, e1)
        rays = (np.cos(r)[None, :, None] * s[:, None, :] + offsets_a[None, :, None] * e1[:, None, :]
                + offsets_b[None, :, None] * e2[:, None, :])
        out[i] = scene_radiance(position, rays, scene, soft_deg=cell_deg) @ w
    return out


def detector_lag(signal, sample_s: float, time_constant_s: float) -> np.ndarray:
    """A first-order lag of time constant τ on a periodic signal sampled every `sample_s` [s], in its periodic
    steady state (the revolution before had the same scene): the exact response at the samples to the input taken
    linear between them (so a ramp comes out delayed by exactly τ)."""
    from scipy.signal import lfilter  # here: scipy.signal brings scipy.stats, ~0.6 s on every `sunbench` start

    x = np.asarray(signal, float)
    if time_constant_s <= 0:
        return x.copy()
    h = sample_s / time_constant_s
    a = math.exp(-h)
    b1 = (1.0 - a) / h - a  # the previous sample's share; b0 + b1 = 1 − a
    b = [1.0 - a - b1, b1]
    zi = [(1.0 - b[0]) * x[-1]]  # the filter's state under a constant input x[-1]
    warm, state = lfilter(b, [1.0, -a], x, zi=zi)  # one revolution to reach the periodic steady state
    y, _ = lfilter(b, [1.0, -a], x, zi=state)
    return y


@dataclass(frozen=True)
class Edges:
    """What the locator found in one cone's pulse: sample positions (fractional sample indices, NaN when not
    found) of the falling and rising edges, the levels and the threshold [counts]."""

    out_index: float
    in_index: float
    space: float
    earth: float
    threshold: float
    saturated: bool = False


def _earth_edges(x: np.ndarray, level: float, band: float):
    """The Earth (the longest run above `level`, decided with the hysteresis `band`) and its edges in the pulse `x`:
    ``(fall, rise, first, last)`` — the interpolated falling and rising crossings (fractional sample indices, NaN
    when not found) and the run's first and last sample indices — or None when there is no such run."""
    n = x.size
    state = np.where(x > level + band, 1, np.where(x < level - band, -1, 0))
    if not ((state == 1).any() and (state == -1).any()):
        return None
    first = int(np.flatnonzero(state)[0])
    order = np.roll(np.arange(n), -first)  # start on a decided sample, then carry each decision forward
    decided = state[order]
    filled = decided[np.maximum.accumulate(np.where(decided != 0, np.arange(n), 0))]
    runs = np.flatnonzero(filled != np.roll(filled, 1))  # where a run starts (in `order`)
    if runs.size < 2:
        return None
    lengths = np.diff(np.append(runs, runs[0] + n))
    high = [k for k in range(runs.size) if filled[runs[k]] == 1]
    k = max(high, key=lambda j: lengths[j])  # the Earth: the longest run above the threshold
    start, end = int(runs[k]), int(runs[k] + lengths[k])  # the run covers order[start:end]; the next starts at end

    def crossing(a: int, b: int, rising: bool) -> float:
        """The interpolated crossing of `level` between positions a … b of `order` (b > a), the first after the
        last decided sample on the old side."""
        idx = order[np.arange(a, b + 1) % n]
        vals = x[idx]
        old = np.flatnonzero((vals < level - band) if rising else (vals > level + band))
        j0 = int(old[-1]) if old.size else 0
        for j in range(j0, len(vals) - 1):
            if (vals[j] < level <= vals[j + 1]) if rising else (vals[j] > level >= vals[j + 1]):
                return (idx[j] + (level - vals[j]) / (vals[j + 1] - vals[j])) % n
        return math.nan

    # the rising edge lies between the previous run's last decided low sample and this run's first high one
    rise = crossing(int(runs[k - 1]) if k else int(runs[-1]) - n, start, rising=True)
    fall = crossing(start, end, rising=False)
    return fall, rise, int(order[start]), int(order[(end - 1) % n])


def _plateau(x: np.ndarray, begin: float, finish: float, margin: int) -> np.ndarray:
    """The samples of `x` from `begin` to `finish` (fractional indices, going forward round the revolution) that lie
    more than `margin` samples from both."""
    n = x.size
    end = begin + (finish - begin) % n
    first, last = math.floor(begin + margin) + 1, math.ceil(end - margin) - 1
    return x[np.arange(first, last + 1) % n] if last >= first else x[:0]


def locate_edges(samples, threshold: float, *, min_contrast: float, full_scale: float,
                 hysteresis: float = 0.05, plateau_margin: int | None = None) -> Edges:
    """The module's normalised constant-threshold locator on one cone's pulse (module docstring; seed 004 eq. 2.1
    with linear interpolation). `threshold` is C1 plus the comparator's offset; `plateau_margin` [samples] how far
    from either edge a sample must lie to count for the levels (None: a twelfth of the revolution). A plateau that
    comes out empty (a chord shorter than twice the margin) keeps the first pass's quarter level."""
    x = np.asarray(samples, float)
    n = x.size
    margin = n // 12 if plateau_margin is None else int(plateau_margin)
    saturated = bool((x >= full_scale).any())
    lo, hi = float(x.min()), float(x.max())
    span = hi - lo
    space = float(x[x <= lo + span / 4].mean())
    earth = float(x[x >= hi - span / 4].mean())
    level = space + threshold * (earth - space)
    if span < min_contrast:
        return Edges(math.nan, math.nan, space, earth, level, saturated)
    found = _earth_edges(x, level, hysteresis * (earth - space))
    if found is None:
        return Edges(math.nan, math.nan, space, earth, level, saturated)
    fall, rise, first, last = found
    # the second pass: the levels from the plateaus, away from the edges (a short chord's top is not the Earth's)
    begin, finish = (first - 0.5 if math.isnan(rise) else rise), (last + 0.5 if math.isnan(fall) else fall)
    on_earth, on_space = _plateau(x, begin, finish, margin), _plateau(x, finish, begin, margin)
    earth = float(np.median(on_earth)) if on_earth.size else earth
    space = float(np.median(on_space)) if on_space.size else space
    level = space + threshold * (earth - space)
    found = _earth_edges(x, level, hysteresis * (earth - space))
    if found is None:
        return Edges(math.nan, math.nan, space, earth, level, saturated)
    return Edges(found[0], found[1], space, earth, level, saturated)


@dataclass
class Revolution:
    """One simulated revolution: its period [s], both cones' samples (2, N) [counts] and the locator's edges."""

    period_s: float
    samples: np.ndarray
    edges: tuple[Edges, Edges]
    temperature_c: float = 0.0
    extra: dict = field(default_factory=dict)
