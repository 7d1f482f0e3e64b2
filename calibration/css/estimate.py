"""The Sun's direction from one reading of every detector of a calibrated CSS head: weighted least squares.

For one reading m_i of each detector i (a UV or visible photodiode or a thermopile on any face) and the head's
calibration (:class:`~calibration.css.diode.HeadModel`), the unit sun vector ŝ minimises

    χ²(s) = Σ_i ((m_i − model_i(s) − a_i) / σ_i)²

over the unit sphere (two parameters: a step in the tangent plane at the current s, then renormalised), with σ_i
the detector's noise at its reading (σ² = σ₀² + q|m| + (r m)², from the calibration; plus the model's own error
where the detector is lit, and the Earth signal's uncertainty) and a_i the Earth's signal when an albedo estimate
is given (:class:`AlbedoScene`, :func:`albedo_signals`), else 0. Every detector with a reading below its full
scale enters χ², lit or not: an unlit detector that reads its offset says the Sun is outside its field.

The search, for all readings at once (vectorised over readings: about 0.5 ms per reading of 18 detectors on one
core, 100 000 readings in about a minute):

1. two starts, the better kept: the normalised Σ (m_i − b_i − a_i)/S_i · n_i over the lit detectors (those more
   than :data:`LIT_SIGMAS` σ above their offset), and n·s = cos γ̂ solved over the lit detectors with each cos γ̂
   from its reading through its own response;
2. Levenberg–Marquardt on the sphere;
3. two lit axes: both intersections of the two faces' cones are tried; any faint or dark axis
   (:data:`FAINT_RATIO`): the mirror image across the plane normal to it is tried. The better is kept, and a
   reading where another fits within Δχ² :data:`AMBIGUITY_CHI2` (more than :data:`AMBIGUITY_MIN_DEG` away) is
   flagged ``ambiguous``;
4. readings still fitted poorly (χ² over :data:`RESTART_CHI2` × dof, a lit detector predicted dark) start again
   from the best directions of a grid over the sphere.

The 1σ uncertainty is the inverse of JᵀJ over the lit detectors (the whitened Jacobian at ŝ; a dark detector bounds
the Sun to outside its field, an inequality that measures nothing inside the bound), in degrees on the tangent
plane: the cone radius √(trace C) (the RMS of the angle between ŝ and the truth, as :mod:`calibration.uncertainty`
reports it) and the error ellipse's semi-axes. It is then checked along the ellipse's axes: where a 1σ step raises
χ² by less than 0.64 (two cones meeting near tangency, the Sun at a field's edge) the axis is widened until it
raises it by 1; a χ² the noise cannot explain scales the covariance by χ²/dof.

Fewer than two non-coplanar lit faces (one face, or two opposite faces) leave the direction on a cone around one
normal, and an ambiguous pair leaves it at one of two places: the estimate is flagged ``degenerate`` and its
uncertainty is infinite — it is not pretended.

References
----------
seed 000 ch. 5.3.2 (the Sun's direction as the intersection of the cones of two or three lit faces), digest §5.4 ⚠
(the thesis' one-face azimuth is exact only at el = 0: compute directions with vectors) and §8.3 item 8 ("a
least-squares source vector s = argmin Σ_f (m_f − K_f·R(n_f·s))², as an improved estimator alongside the thesis
algorithm"), §8.2 item 5 (the Earth as an extended disc, albedo 0.3), eq. 3.2 (albedo current through the mean
response over the Earth's disc); research note anchors-sunsensors §5 (Basilisk CSS with an albedo input).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .diode import REFERENCE_TEMPERATURE_C, HeadModel
from .head import split_channel, vector_angles

#: A detector more than this many σ above its offset (and the Earth's signal) is lit.
LIT_SIGMAS = 5.0
#: Levenberg–Marquardt iterations at most.
MAX_ITERATIONS = 100
#: A step below this ends the iteration [rad].
STEP_TOLERANCE_RAD = 1e-10
#: JᵀJ whose condition number exceeds this leaves the direction undetermined.
CONDITION_LIMIT = 1e12
#: A fit whose χ² exceeds this × its degrees of freedom is started again from the best of a grid of directions.
RESTART_CHI2 = 25.0
#: Directions of that grid, and starts taken from it.
RESTART_GRID = 2000
RESTART_STARTS = 6
#: The mirror solution of two lit faces within this Δχ² of the best leaves the direction ambiguous.
AMBIGUITY_CHI2 = 9.0
#: ... unless the two lie closer than this [°].
AMBIGUITY_MIN_DEG = 0.5
#: A face whose detectors read less than this share of their normal-incidence signal is faint: its mirror
#: solution is tried (the Sun at 70–90° from a face is where an angular law is least certain).
FAINT_RATIO = 0.3
#: χ² above dof + this × √(2 dof) is inconsistent with the noise: the covariance is scaled by χ²/dof.
INCONSISTENT_SIGMAS = 5.0
#: The widest 1σ the profile check widens an axis to [°].
MAX_WIDEN_DEG = 30.0
#: Readings handled at once (memory: readings × detectors × quadrature points for the albedo).
CHUNK = 2048


@dataclass(frozen=True)
class AlbedoScene:
    """What the estimator is told of the Earth, to add its signal to each detector's model.

    Attributes
    ----------
    earth_vector : array_like (3,) or (N, 3)
        Direction to the Earth's centre in the body frame (need not be unit).
    earth_radius_deg : float or array_like (N,)
        The Earth's angular radius ρ [°] (65° at about 660 km, seed 000 §2.2).
    signal_at_normal : dict, optional
        The Earth's signal [A or V] of a detector whose normal points at the Earth's centre, by detector type
        (``"uv"``, ``"vis"``, ``"ir"``) or by channel (a channel's entry wins).
    relative_at_normal : dict, optional
        The same in units of each detector's own calibrated scale S (1 = its signal from the Sun at normal
        incidence), by type or channel: the albedo on a photodiode goes through the same responsivity (seed 000
        eq. 3.2), so one number per detector type serves the whole head. Added to `signal_at_normal`.
    relative_sd : float
        Relative 1σ of the predicted Earth signal (the albedo varies with clouds and ground; the disc is not
        uniform): added in quadrature to each detector's noise, so a detector the Earth outshines the Sun on
        counts for little.
    """

    earth_vector: object
    earth_radius_deg: object = 65.0
    signal_at_normal: dict | None = None
    relative_at_normal: dict | None = None
    relative_sd: float = 0.02


def _basis(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit `vectors` (N, 3) and to each other (a right-handed frame with them)."""
    helper = np.zeros_like(vectors)
    axis = np.argmin(np.abs(vectors), axis=1)
    helper[np.arange(vectors.shape[0]), axis] = 1.0
    e1 = helper - np.sum(helper * vectors, axis=1, keepdims=True) * vectors
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(vectors, e1)


def disc_quadrature(radius_deg, *, rings: int = 12, spokes: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes of a spherical cap of angular radius ρ around +Z: cos of their angle from the axis, their azimuths
    [rad] and solid-angle weights [sr] (Gauss–Legendre in cos, uniform in azimuth; weights sum to 2π(1 − cos ρ)).

    References
    ----------
    seed 000 eq. 3.2 and §2.2 (the Earth an extended source of ≈ 130°: the mean response over its disc).
    """
    x, w = np.polynomial.legendre.leggauss(rings)
    c = np.cos(np.radians(np.asarray(radius_deg, float)))[..., None]
    u = (1.0 + c) / 2.0 + (1.0 - c) / 2.0 * x
    weights = (1.0 - c) / 2.0 * w * (2.0 * np.pi / spokes)
    psi = (np.arange(spokes) + 0.5) * 2.0 * np.pi / spokes
    return u, psi, weights


def disc_response(model: HeadModel, earth_vector, earth_radius_deg, *, rings: int = 16,
                  spokes: int = 32) -> np.ndarray:
    """Each detector's response to a uniform disc (the Earth) relative to the same disc centred on its normal.

    ∫_disc R_i(n_i·ω) E_i dΩ / ∫_cap(n_i) R_i E_i dΩ, numerically (:func:`disc_quadrature`), with each detector's
    own calibrated angular response (for a cosine detector the disc's cosine-weighted solid angle).

    Parameters
    ----------
    model : HeadModel
    earth_vector : array_like (3,) or (N, 3)
        Direction of the disc's centre in the body frame.
    earth_radius_deg : float or array_like (N,)
        The disc's angular radius [°].

    Returns
    -------
    ndarray (K,) or (N, K) [unitless]

    References
    ----------
    seed 000 eq. 3.2 (S_mean(φ): the mean sensitivity over the visible Earth disc), §2.2 (Earth ≈ 130°), digest
    §3.5 item 2 (the albedo response stays non-zero at 90°).
    """
    e = np.asarray(earth_vector, float)
    single = e.ndim == 1
    e = np.atleast_2d(e)
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    rho = np.broadcast_to(np.asarray(earth_radius_deg, float), (e.shape[0],))
    u, psi, w = disc_quadrature(rho, rings=rings, spokes=spokes)  # (N, rings), (spokes,), (N, rings)
    a, b = _basis(e)
    sin = np.sqrt(np.clip(1.0 - u * u, 0.0, None))
    # directions (N, rings, spokes, 3)
    cos_psi, sin_psi = np.cos(psi)[None, None, :, None], np.sin(psi)[None, None, :, None]
    side = cos_psi * a[:, None, None, :] + sin_psi * b[:, None, None, :]
    omega = u[..., None, None] * e[:, None, None, :] + sin[..., None, None] * side
    resp = model.relative_responses(omega)  # (N, rings, spokes, K)
    seen = np.einsum("nrsk,nr->nk", resp, w)
    # the same disc centred on each detector's normal: there n·ω = u on every spoke
    own = np.einsum("nrk,nr->nk", model.responses_at(np.repeat(u[..., None], len(model), axis=-1)), w) * psi.size
    ratio = np.where(own > 0, seen / np.where(own > 0, own, 1.0), 0.0)
    return ratio[0] if single else ratio


def albedo_signals(model: HeadModel, scene: AlbedoScene, temperature_c=25.0) -> np.ndarray:
    """The Earth's signal on each detector [A or V]: its signal at normal incidence × :func:`disc_response`.

    Returns (K,) for one Earth direction and temperature, (N, K) for N.

    References
    ----------
    seed 000 eq. 3.2 (I_ALBEDO = S_mean(φ) · A · 0.3 · Σ E S Δλ), §2.2 (albedo 0.3, Earth ≈ 130°).
    """
    def per_channel(table):
        table = dict(table or {})
        return np.array([table.get(c, table.get(split_channel(c)[1], 0.0)) for c in model.channels], float)

    gain = model.scale * (1.0 + model.temp_coeff_per_c * (np.asarray(temperature_c, float)[..., None]
                                                           - REFERENCE_TEMPERATURE_C))
    level = per_channel(scene.signal_at_normal) + per_channel(scene.relative_at_normal) * gain
    return disc_response(model, scene.earth_vector, scene.earth_radius_deg) * level


@dataclass(frozen=True)
class SunEstimate:
    """Sun directions estimated from readings (module docstring); arrays over the N readings.

    Attributes
    ----------
    channels : tuple of str
        The detectors of the head model, the order of `used` and `lit`.
    vector : ndarray (N, 3)
        Unit sun vector in the body frame (NaN where no detector is lit).
    zenith_deg, azimuth_deg : ndarray (N,)
        [°] (DESIGN.md convention).
    sigma_deg : ndarray (N,)
        1σ cone radius √(trace C) [°]; inf when degenerate.
    sigma_major_deg, sigma_minor_deg : ndarray (N,)
        Semi-axes of the 1σ error ellipse [°]; inf when degenerate.
    major_angle_deg : ndarray (N,)
        Direction of the major axis, from "toward larger zenith" toward "larger azimuth" [°].
    covariance_deg2 : ndarray (N, 2, 2)
        C in the basis (toward larger zenith, toward larger azimuth) [°²].
    chi2 : ndarray (N,)
        χ² at the solution, over `n_used` − 2 degrees of freedom.
    n_used : ndarray of int (N,)
    used, lit : ndarray of bool (N, K)
        Detectors that entered χ², and those of them lit.
    n_faces_lit : ndarray of int (N,)
    degenerate : ndarray of bool (N,)
        Fewer than two non-coplanar lit faces, a singular JᵀJ, or an ambiguous pair: the direction is not
        determined.
    converged : ndarray of bool (N,)
    ambiguous : ndarray of bool (N,)
        Two lit faces, and the mirror image of the solution across the plane of their normals fits as well
        (Δχ² < :data:`AMBIGUITY_CHI2`): the two cones meet twice and the unlit faces do not tell which.
    """

    channels: tuple
    vector: np.ndarray
    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    sigma_deg: np.ndarray
    sigma_major_deg: np.ndarray
    sigma_minor_deg: np.ndarray
    major_angle_deg: np.ndarray
    covariance_deg2: np.ndarray
    chi2: np.ndarray
    n_used: np.ndarray
    used: np.ndarray
    lit: np.ndarray
    n_faces_lit: np.ndarray
    degenerate: np.ndarray
    converged: np.ndarray
    ambiguous: np.ndarray

    def __len__(self) -> int:
        return self.vector.shape[0]

    @property
    def dof(self) -> np.ndarray:
        return self.n_used - 2

    def scaled(self, factor: float) -> SunEstimate:
        """The same estimates with the stated uncertainty multiplied by `factor` (a calibration's held-out
        normalised error, :func:`calibration.css.calibrate.apply_css_document`).

        References
        ----------
        research note anchors-sunsensors §6 (report what held-out points show).
        """
        f = float(factor)
        return replace(self, sigma_deg=self.sigma_deg * f, sigma_major_deg=self.sigma_major_deg * f,
                       sigma_minor_deg=self.sigma_minor_deg * f, covariance_deg2=self.covariance_deg2 * f * f)

    def describe(self, i: int = 0) -> str:
        """One reading's estimate in words."""
        if not np.all(np.isfinite(self.vector[i])):
            return "no estimate: no detector is lit (eclipse, or the light is off)"
        where = f"zenith {self.zenith_deg[i]:.2f}°, azimuth {self.azimuth_deg[i]:.2f}°"
        if self.ambiguous[i]:
            return (f"{where} — ambiguous: two lit faces, and the mirror direction across the plane of their "
                    "normals fits the readings as well; no unlit face tells them apart")
        if self.degenerate[i]:
            return (f"{where} — degenerate: {self.n_faces_lit[i]} lit face(s), fewer than two non-coplanar ones; the "
                    "direction lies anywhere on a cone around one face's normal and has no finite uncertainty")
        return (f"{where} ± {self.sigma_deg[i]:.3f}° (1σ; ellipse {self.sigma_major_deg[i]:.3f}° × "
                f"{self.sigma_minor_deg[i]:.3f}°), χ² {self.chi2[i]:.1f} over {self.dof[i]} dof, "
                f"{self.n_faces_lit[i]} lit faces")

    def to_dict(self) -> dict:
        """JSON types (lists over the readings)."""
        plain = lambda a: [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]  # noqa: E731
        return {"channels": list(self.channels), "zenith_deg": plain(self.zenith_deg),
                "azimuth_deg": plain(self.azimuth_deg), "sigma_deg": plain(self.sigma_deg),
                "sigma_major_deg": plain(self.sigma_major_deg), "sigma_minor_deg": plain(self.sigma_minor_deg),
                "chi2": plain(self.chi2), "n_used": [int(v) for v in self.n_used],
                "n_faces_lit": [int(v) for v in self.n_faces_lit], "degenerate": [bool(v) for v in self.degenerate],
                "ambiguous": [bool(v) for v in self.ambiguous],
                "converged": [bool(v) for v in self.converged]}


def _arrange(model: HeadModel, signals, channels):
    """Readings (N, K) in the model's order (NaN for a detector without a reading) and the batch shape."""
    sig = np.asarray(signals, float)
    if sig.ndim == 0:
        raise ValueError("`signals` must hold one reading per channel")
    if channels is None:
        if sig.shape[-1] != len(model):
            raise ValueError(f"`signals` has {sig.shape[-1]} columns for the model's {len(model)} detectors; pass "
                             "`channels`")
        return sig.reshape(-1, len(model))
    channels = tuple(channels)
    if sig.shape[-1] != len(channels):
        raise ValueError(f"`signals` has {sig.shape[-1]} columns for {len(channels)} channels")
    flat = sig.reshape(-1, len(channels))
    out = np.full((flat.shape[0], len(model)), np.nan)
    for j, c in enumerate(channels):
        if c in model.channels:
            out[:, model.channels.index(c)] = flat[:, j]
    return out


def _invert_response(model: HeadModel, ratio) -> np.ndarray:
    """cos γ in [0, 1] at which each detector's R·E equals `ratio` (N, K), by bisection (R·E rises with cos γ)."""
    lo = np.zeros_like(ratio)
    hi = np.ones_like(ratio)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        below = model.responses_at(mid) < ratio
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


class _Readings:
    """One chunk's readings, whitened, and the model's whitened residuals and Jacobian at given sun vectors."""

    def __init__(self, model: HeadModel, m0, inv_sigma, temp, irr, albedo):
        self.model, self.m0, self.inv_sigma, self.temp, self.irr, self.albedo = model, m0, inv_sigma, temp, irr, albedo

    def chi2(self, vectors, idx):
        pred = self.model.signals(vectors, self.temp[idx], irradiance=self.irr[idx])
        r = (self.m0[idx] - pred - self.albedo[idx]) * self.inv_sigma[idx]
        return np.sum(r * r, axis=1)

    def evaluate(self, vectors, idx):
        pred, grad = self.model.signals_and_gradient(vectors, self.temp[idx], irradiance=self.irr[idx])
        r = (self.m0[idx] - pred - self.albedo[idx]) * self.inv_sigma[idx]
        return r, grad * self.inv_sigma[idx][..., None], np.sum(r * r, axis=1)


def _levenberg_marquardt(readings: _Readings, idx, start, max_iterations):
    """Minimise χ² over unit vectors for the readings `idx` from `start` (n, 3): (s, χ², converged)."""
    s = np.array(start, float)
    n = idx.size
    chi2 = readings.evaluate(s, idx)[2] if n else np.zeros(0)
    lam = np.full(n, 1e-3)
    converged = np.zeros(n, bool)
    active = np.arange(n)
    for _ in range(max_iterations):
        if active.size == 0:
            break
        sa = s[active]
        r, grad, c2 = readings.evaluate(sa, idx[active])
        e1, e2 = _basis(sa)
        j = np.stack([np.einsum("nkc,nc->nk", grad, e1), np.einsum("nkc,nc->nk", grad, e2)], axis=-1)  # (n, K, 2)
        a = np.einsum("nki,nkj->nij", j, j)
        g = np.einsum("nki,nk->ni", j, r)
        damp = a + lam[active, None, None] * (np.eye(2) * np.diagonal(a, axis1=1, axis2=2)[:, None, :]
                                              + 1e-12 * np.eye(2) * np.trace(a, axis1=1, axis2=2)[:, None, None])
        det = damp[:, 0, 0] * damp[:, 1, 1] - damp[:, 0, 1] * damp[:, 1, 0]
        det = np.where(det != 0, det, np.inf)
        d1 = (damp[:, 1, 1] * g[:, 0] - damp[:, 0, 1] * g[:, 1]) / det
        d2 = (damp[:, 0, 0] * g[:, 1] - damp[:, 1, 0] * g[:, 0]) / det
        step = np.hypot(d1, d2)
        limit = np.minimum(1.0, 0.5 / np.maximum(step, 1e-300))
        d1, d2 = d1 * limit, d2 * limit
        trial = sa + d1[:, None] * e1 + d2[:, None] * e2
        trial /= np.linalg.norm(trial, axis=1, keepdims=True)
        c2_trial = readings.evaluate(trial, idx[active])[2]
        better = c2_trial <= c2
        s[active[better]] = trial[better]
        chi2[active] = np.where(better, c2_trial, c2)
        lam[active] = np.where(better, np.maximum(lam[active] / 3.0, 1e-9), lam[active] * 4.0)
        done = better & ((step * limit < STEP_TOLERANCE_RAD) | (c2 - c2_trial <= 1e-12 * (1.0 + c2)))
        done |= lam[active] > 1e12  # no step, however short, goes downhill: a minimum (at a field edge's corner)
        converged[active[done]] = True
        active = active[~done]
    return s, chi2, converged


def fibonacci_sphere(n: int) -> np.ndarray:
    """`n` nearly evenly spread unit vectors (a Fibonacci lattice), shape (n, 3).

    References
    ----------
    seed 000 digest §8.4 item 12 (Monte Carlo over orientations: directions spread over the sphere).
    """
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


#: Directions searched for the readings a descent did not fit (≈ 2.9° apart)
_GRID = fibonacci_sphere(RESTART_GRID)


def _grid_starts(readings: _Readings, idx, count: int = RESTART_STARTS) -> np.ndarray:
    """The `count` directions of :data:`_GRID` with the lowest χ² for each reading of `idx`: (n, count, 3)."""
    out = np.empty((idx.size, count, 3))
    per = max(1, 200_000 // _GRID.shape[0])  # readings per block
    for lo in range(0, idx.size, per):
        block = idx[lo:lo + per]
        vec = np.tile(_GRID, (block.size, 1))
        c2 = readings.chi2(vec, np.repeat(block, _GRID.shape[0])).reshape(block.size, -1)
        best = np.argpartition(c2, count - 1, axis=1)[:, :count]
        out[lo:lo + block.size] = _GRID[best]
    return out


def _solve_chunk(model: HeadModel, m, temp, irr, albedo, albedo_sd, max_iterations):
    """Starts, vectorised Levenberg–Marquardt on the unit sphere, the mirror solution of two lit faces, restarts
    where the fit stays poor, and the covariance, for one chunk of readings."""
    n, k = m.shape
    full = model.full_scale[None, :]
    used = np.isfinite(m) & (m < full)
    m0 = np.where(used, m, 0.0)
    noise = np.sqrt(model.noise_sd(m0) ** 2 + albedo_sd**2)
    dark = model.dark_signals(temp) + albedo
    excess = m0 - dark
    lit = used & (excess > LIT_SIGMAS * noise)
    sigma = np.sqrt(noise**2 + np.where(lit, model.model_sd**2, 0.0))  # the model's own error where it is lit
    sigma = np.where(sigma > 0, sigma, np.inf)
    gain = model.scale * (1.0 + model.temp_coeff_per_c * (temp[:, None] - REFERENCE_TEMPERATURE_C)) * irr[:, None]
    ratio = np.where(lit, excess / gain, 0.0)
    start = ratio @ model.normals  # the normalised Σ (m − b)/S · n
    norm = np.linalg.norm(start, axis=1)
    has = norm > 0
    s = np.where(has[:, None], start / np.where(has, norm, 1.0)[:, None], np.nan)
    inv_sigma = np.where(used, 1.0 / sigma, 0.0)
    readings = _Readings(model, m0, inv_sigma, temp, irr, albedo)
    # a second start: each lit detector's cos γ from its reading through its own response, then n·s = cos γ
    # solved by least squares over the lit detectors (the start above is biased where R is far from a cosine)
    cos_hat = _invert_response(model, np.clip(ratio, 0.0, 1.0))
    wl = lit.astype(float)
    ntn = np.einsum("nk,ki,kj->nij", wl, model.normals, model.normals) + 1e-9 * np.eye(3)
    ntc = np.einsum("nk,nk,ki->ni", wl, cos_hat, model.normals)
    alt = np.linalg.solve(ntn, ntc[..., None])[..., 0]
    alt_norm = np.linalg.norm(alt, axis=1)
    alt = np.where((alt_norm > 0)[:, None], alt / np.where(alt_norm > 0, alt_norm, 1.0)[:, None], np.nan)
    chi2 = np.full(n, np.nan)
    converged = np.zeros(n, bool)
    ambiguous = np.zeros(n, bool)
    idx = np.flatnonzero(has)
    if idx.size:
        c2_sum = readings.evaluate(s[idx], idx)[2]
        ok_alt = np.all(np.isfinite(alt[idx]), axis=1)
        c2_alt = np.full(idx.size, np.inf)
        if ok_alt.any():
            c2_alt[ok_alt] = readings.evaluate(alt[idx[ok_alt]], idx[ok_alt])[2]
        s[idx] = np.where((c2_alt < c2_sum)[:, None], alt[idx], s[idx])
        s[idx], chi2[idx], converged[idx] = _levenberg_marquardt(readings, idx, s[idx], max_iterations)
        # two lit axes: the two cones meet twice; start from both intersections (each face's cos γ the mean of its
        # lit detectors'), keep the better, and call the reading ambiguous when the other fits as well
        axes_of = np.argmax(np.abs(model.normals), axis=1)
        axes_lit = np.stack([np.any(lit & (axes_of == a)[None, :], axis=1) for a in range(3)], axis=1)
        two = idx[axes_lit[idx].sum(axis=1) == 2]
        if two.size:
            pairs = np.sort(np.argsort(~axes_lit[two], axis=1, kind="stable")[:, :2], axis=1)
            normals, cosines = [], []
            for col in range(2):
                on = lit[two] & (axes_of[None, :] == pairs[:, col:col + 1])
                w = on.astype(float)
                nf = w @ model.normals
                normals.append(nf / np.linalg.norm(nf, axis=1, keepdims=True))
                cosines.append(np.sum(w * cos_hat[two], axis=1) / w.sum(axis=1))
            n1, n2 = normals
            c12 = np.sum(n1 * n2, axis=1)
            det = 1.0 - c12**2
            a1 = (cosines[0] - c12 * cosines[1]) / det
            a2 = (cosines[1] - c12 * cosines[0]) / det
            base = a1[:, None] * n1 + a2[:, None] * n2
            cross = np.cross(n1, n2)
            cross /= np.linalg.norm(cross, axis=1, keepdims=True)
            t = np.sqrt(np.clip(1.0 - np.sum(base * base, axis=1), 0.0, None))[:, None]
            found = []
            for sign in (1.0, -1.0):
                cand = base + sign * t * cross
                cand /= np.linalg.norm(cand, axis=1, keepdims=True)
                found.append(_levenberg_marquardt(readings, two, cand, max_iterations))
            vecs = np.stack([s[two], found[0][0], found[1][0]], axis=1)  # (n, 3, 3)
            c2s = np.stack([chi2[two], found[0][1], found[1][1]], axis=1)
            convs = np.stack([converged[two], found[0][2], found[1][2]], axis=1)
            c2s = np.where(np.isfinite(c2s), c2s, np.inf)
            order = np.argsort(c2s, axis=1)
            rows = np.arange(two.size)
            best, runner = order[:, 0], order[:, 1:]
            s[two], chi2[two], converged[two] = vecs[rows, best], c2s[rows, best], convs[rows, best]
            for col in range(2):
                other = runner[:, col]
                sep = np.degrees(np.arccos(np.clip(np.sum(vecs[rows, other] * s[two], axis=1), -1.0, 1.0)))
                ambiguous[two] |= (c2s[rows, other] - chi2[two] < AMBIGUITY_CHI2) & (sep > AMBIGUITY_MIN_DEG) \
                    & convs[rows, other]
        # a faint or dark axis says little about the sign of the Sun's component along it: try the mirror image
        # across the plane normal to it; keep the better, and call the reading ambiguous when both fit
        for a in range(3):
            on_axis = axes_of == a
            faint = idx[np.max(np.where(on_axis[None, :], ratio[idx], 0.0), axis=1) < FAINT_RATIO]
            if faint.size == 0:
                continue
            mirror = s[faint].copy()
            mirror[:, a] = -mirror[:, a]
            sm, c2m, convm = _levenberg_marquardt(readings, faint, mirror, max_iterations)
            sep = np.degrees(np.arccos(np.clip(np.sum(sm * s[faint], axis=1), -1.0, 1.0)))
            close = np.abs(c2m - chi2[faint]) < AMBIGUITY_CHI2
            ambiguous[faint] |= close & (sep > AMBIGUITY_MIN_DEG) & convm & converged[faint]
            swap = convm & (c2m < chi2[faint])
            s[faint[swap]], chi2[faint[swap]], converged[faint[swap]] = sm[swap], c2m[swap], True
        # restarts where the descent ended far above the noise, did not converge, or calls a lit detector dark
        dof = np.maximum(used[idx].sum(axis=1) - 2, 1)
        pred = model.signals(s[idx], temp[idx], irradiance=irr[idx]) + albedo[idx]
        unexplained = np.any(lit[idx] & (pred - dark[idx] < sigma[idx]), axis=1)
        poor = idx[(chi2[idx] > RESTART_CHI2 * dof) | ~converged[idx] | unexplained]
        if poor.size:
            starts = _grid_starts(readings, poor)
            rep = np.repeat(poor, starts.shape[1])
            sr, c2r, convr = _levenberg_marquardt(readings, rep, starts.reshape(-1, 3), max_iterations)
            c2r = np.where(np.isfinite(c2r), c2r, np.inf).reshape(poor.size, -1)
            best = np.argmin(c2r, axis=1)
            c2_best = c2r[np.arange(poor.size), best]
            win = c2_best < np.where(np.isfinite(chi2[poor]), chi2[poor], np.inf)
            conv_best = convr.reshape(poor.size, -1)[np.arange(poor.size), best]
            sr = sr.reshape(poor.size, -1, 3)[np.arange(poor.size), best]
            s[poor[win]], chi2[poor[win]], converged[poor[win]] = sr[win], c2_best[win], conv_best[win]
    # the covariance at the solution, in the (toward larger zenith, toward larger azimuth) basis
    cov = np.full((n, 2, 2), np.nan)
    if idx.size:
        sa = s[idx]
        r, grad, c2 = readings.evaluate(sa, idx)
        chi2[idx] = c2
        zen, az = vector_angles(sa)
        th, ph = np.radians(zen), np.radians(az)
        e_zen = np.stack([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)], axis=-1)
        e_az = np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], axis=-1)
        # only lit detectors inform the covariance: a dark one bounds the Sun to outside its field (an
        # inequality), and its steep edge at the solution is no measurement of where inside the bound the Sun is
        grad = grad * lit[idx][..., None]
        j = np.stack([np.einsum("nkc,nc->nk", grad, e_zen), np.einsum("nkc,nc->nk", grad, e_az)], axis=-1)
        a = np.einsum("nki,nkj->nij", j, j)
        det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] ** 2
        tr = a[:, 0, 0] + a[:, 1, 1]
        good = (det > tr * tr / CONDITION_LIMIT) & (tr > 0)
        inv = np.stack([np.stack([a[:, 1, 1], -a[:, 0, 1]], -1), np.stack([-a[:, 1, 0], a[:, 0, 0]], -1)], -2)
        inv = inv / np.where(good, det, 1.0)[:, None, None]
        cov[idx] = np.where(good[:, None, None], inv * np.degrees(1.0) ** 2, np.inf)
        fin = idx[good]
        if fin.size:
            cov[fin] = _widen_along_axes(readings, fin, s[fin], cov[fin], e_zen[good], e_az[good], chi2[fin])
        # a χ² the noise cannot explain (p ≲ 1e-5) scales the covariance by χ²/dof (the Birge ratio)
        dof = np.maximum(used[idx].sum(axis=1) - 2, 1)
        inconsistent = chi2[idx] > dof + INCONSISTENT_SIGMAS * np.sqrt(2.0 * dof)
        cov[idx] = cov[idx] * np.where(inconsistent, chi2[idx] / dof, 1.0)[:, None, None]
    return s, chi2, cov, used, lit, converged, ambiguous


def _widen_along_axes(readings: _Readings, idx, s, cov, e_zen, e_az, chi2_min):
    """The linearised covariance (deg², basis e_zen, e_az) checked along its principal axes: a 1σ step must raise
    χ² by about 1 (at least 0.64); where the valley is flatter (two cones meeting near tangency, the Sun at the
    edge of a field) the axis is widened, by doubling then bisection, until the flatter side rises by 1."""
    lam, vec = np.linalg.eigh(cov)  # ascending
    lam = np.maximum(lam, 0.0)
    out_lam = lam.copy()
    for k in range(2):
        sigma = np.sqrt(lam[:, k])
        d = vec[:, 0, k][:, None] * e_zen + vec[:, 1, k][:, None] * e_az

        def rise(f, sigma=sigma, d=d):
            th = np.radians(np.minimum(f * sigma, MAX_WIDEN_DEG))[:, None]
            c2 = [readings.chi2(s * np.cos(th) + sign * d * np.sin(th), idx) for sign in (1.0, -1.0)]
            return np.minimum(c2[0], c2[1]) - chi2_min

        flat = rise(1.0) < 0.64
        if not flat.any():
            continue
        lo = np.ones(idx.size)
        hi = np.ones(idx.size)
        todo = flat.copy()
        for _ in range(12):  # doubling: hi with a rise of 1 or more (or the cap)
            hi = np.where(todo, hi * 2.0, hi)
            r = rise(hi)
            lo = np.where(todo & (r < 1.0), hi, lo)
            todo &= (r < 1.0) & (hi * sigma < MAX_WIDEN_DEG)
            if not todo.any():
                break
        lo = np.where(flat, hi / 2.0, lo)
        for _ in range(6):  # bisection between lo and hi
            mid = 0.5 * (lo + hi)
            r = rise(mid)
            lo = np.where(flat & (r < 1.0), mid, lo)
            hi = np.where(flat & (r >= 1.0), mid, hi)
        f = np.where(flat, np.minimum(hi, MAX_WIDEN_DEG / np.maximum(sigma, 1e-300)), 1.0)
        out_lam[:, k] = lam[:, k] * f * f
    return np.einsum("nik,nk,njk->nij", vec, out_lam, vec)


def estimate_sun(model: HeadModel, signals, temperature_c=25.0, *, channels=None, irradiance=1.0, albedo=None,
                 albedo_relative_sd: float | None = None, max_iterations: int = MAX_ITERATIONS) -> SunEstimate:
    """The Sun's direction from readings of a calibrated head (module docstring).

    Parameters
    ----------
    model : HeadModel
        The calibrated detectors (:meth:`HeadModel.from_parameters`, or
        :func:`calibration.css.calibrate.head_model_from_document`); only these are used.
    signals : array_like (..., C)
        Readings [A or V]; NaN: no reading. Columns in the model's order, or in `channels`' order.
    temperature_c : float or array_like (...)
        Head temperature [°C], broadcast against the readings.
    channels : sequence of str, optional
        The channels of `signals`' columns (channels the model lacks are ignored).
    irradiance : float or array_like (...)
        The source's irradiance relative to the calibration's reference (1 on the bench that calibrated it).
    albedo : AlbedoScene, callable or array_like, optional
        The Earth's signal on each detector: an :class:`AlbedoScene` (:func:`albedo_signals`), a callable
        ``albedo(channels, normals) -> (..., K)`` of the model's channels and (K, 3) normals, or an array
        broadcastable to (N, K) [A or V].
    albedo_relative_sd : float, optional
        Relative 1σ of that Earth signal, added to each detector's noise (default the scene's `relative_sd`, 0
        for a callable or an array).
    max_iterations : int

    Returns
    -------
    SunEstimate
        Arrays over the N readings (the batch dimensions of `signals` flattened; one reading gives N = 1).

    References
    ----------
    seed 000 ch. 5.3.2, digest §5.4 and §8.3 item 8 (least-squares source vector); eq. 3.2 (albedo).
    """
    m = _arrange(model, signals, channels)
    n, k = m.shape
    temp = np.broadcast_to(np.asarray(temperature_c, float).ravel() if np.ndim(temperature_c) else
                           np.asarray(temperature_c, float), (n,)).astype(float)
    irr = np.broadcast_to(np.asarray(irradiance, float).ravel() if np.ndim(irradiance) else
                          np.asarray(irradiance, float), (n,)).astype(float)
    rel_sd = albedo_relative_sd
    if albedo is None:
        alb = np.zeros((n, k))
    elif isinstance(albedo, AlbedoScene):
        alb = np.broadcast_to(albedo_signals(model, albedo, temp if np.ndim(albedo.earth_vector) > 1 else
                                             temp[:1]), (n, k))
        rel_sd = albedo.relative_sd if rel_sd is None else rel_sd
    elif callable(albedo):
        alb = np.broadcast_to(np.asarray(albedo(model.channels, model.normals), float).reshape(-1, k), (n, k))
    else:
        alb = np.broadcast_to(np.asarray(albedo, float).reshape(-1, k), (n, k))
    alb_sd = np.abs(alb) * (rel_sd or 0.0)
    s = np.full((n, 3), np.nan)
    chi2 = np.full(n, np.nan)
    cov = np.full((n, 2, 2), np.nan)
    used = np.zeros((n, k), bool)
    lit = np.zeros((n, k), bool)
    converged = np.zeros(n, bool)
    ambiguous = np.zeros(n, bool)
    for lo in range(0, n, CHUNK):
        sl = slice(lo, min(n, lo + CHUNK))
        s[sl], chi2[sl], cov[sl], used[sl], lit[sl], converged[sl], ambiguous[sl] = _solve_chunk(
            model, m[sl], temp[sl], irr[sl], np.asarray(alb[sl], float), np.asarray(alb_sd[sl], float),
            max_iterations)
    faces = [split_channel(c)[0] for c in model.channels]
    axis_of = {"px": 0, "mx": 0, "py": 1, "my": 1, "pz": 2, "mz": 2}
    face_names = sorted(set(faces))
    face_lit = np.stack([lit[:, [i for i, f in enumerate(faces) if f == face]].any(axis=1) for face in face_names],
                        axis=1) if face_names else np.zeros((n, 0), bool)
    n_faces = face_lit.sum(axis=1)
    axes_lit = np.zeros((n, 3), bool)
    for j, face in enumerate(face_names):
        axes_lit[:, axis_of[face]] |= face_lit[:, j]
    singular = ~np.all(np.isfinite(cov.reshape(n, -1)), axis=1)
    degenerate = (axes_lit.sum(axis=1) < 2) | singular | ambiguous
    cov = np.where(degenerate[:, None, None] & np.all(np.isfinite(s), axis=1)[:, None, None], np.inf, cov)
    zen, az = vector_angles(s)
    finite = np.all(np.isfinite(cov.reshape(n, -1)), axis=1)
    safe = np.where(finite[:, None, None], cov, 0.0)
    tr = safe[:, 0, 0] + safe[:, 1, 1]
    diff = safe[:, 0, 0] - safe[:, 1, 1]
    root = np.sqrt(np.maximum(diff**2 / 4.0 + safe[:, 0, 1] ** 2, 0.0))
    major = np.where(finite, np.sqrt(np.maximum(tr / 2.0 + root, 0.0)), np.inf)
    minor = np.where(finite, np.sqrt(np.maximum(tr / 2.0 - root, 0.0)), np.inf)
    angle = np.where(finite, np.degrees(0.5 * np.arctan2(2.0 * safe[:, 0, 1], diff)), np.nan)
    sigma = np.where(finite, np.sqrt(np.maximum(tr, 0.0)), np.inf)
    none = ~np.all(np.isfinite(s), axis=1)
    sigma = np.where(none, np.nan, sigma)
    return SunEstimate(model.channels, s, np.where(none, np.nan, zen), np.where(none, np.nan, az), sigma,
                       np.where(none, np.nan, major), np.where(none, np.nan, minor), angle, cov, chi2,
                       used.sum(axis=1), used, lit, n_faces, degenerate | none, converged, ambiguous)
