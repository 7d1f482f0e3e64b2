"""A sensor's readings against the real Sun (seed 003 §5): per-sample errors and clear-sky statistics.

Each reading (θ, φ) in the sensor frame (:mod:`calibration.geometry`, seed 003 eq. 12) is turned into the sky
by the mount (:class:`calibration.field.sky.Mount`: d = M · n) and compared with the Sun's apparent position
from NREL SPA (:func:`calibration.field.sky.sun_position`) at the site:

- zenith error Δz = z_meas − z_sun; azimuth error ΔA = wrap(A_meas − A_sun) to ±180°, and its horizontal arc
  ΔA · sin z_sun (the part of the vector error it makes);
- vector error: the great-circle angle between the two directions (seed 003 eq. 13);
- the Sun in the sensor frame (θ_sun, φ_sun) = what the sensor should have read; in the field of view when
  θ_sun ≤ `fov_half_deg` (seed 003's CMOS sensor: 60°).

Seed 003 §5 set its heading with a household compass and removed the constant azimuth offset over the clear
interval before 12:00; ``heading="fit"`` does that by least squares over a chosen interval and reports the
heading with its standard uncertainty; the azimuth error is then relative, not absolute. ``level="fit"`` also
fits roll and pitch (the zenith error is then relative to the fitted level). The fit minimises the two
tangent-plane components of the direction error in the sensor frame, as :func:`calibration.field.locate.locate`
does, with covariance σ² (JᵀJ)⁻¹ and σ from the residuals.

Seed 003 §5 reported, for the clear sky: zenith RMS 0.12°, vector standard deviation 0.13°.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import FieldDataError
from ..geometry import angular_error_deg, direction_vector, wrap_deg, zenith_azimuth_from_vector
from .locate import _closed_form_heading, _level_matrix, tangent_basis
from .sky import Atmosphere, Mount, Site, mount_matrix, sun_position, track_arrays, zenith_azimuth_enu

MODES = ("given", "fit")


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of one error over a set of samples [°] (NaN when the set is empty).

    Attributes
    ----------
    count : int
    rms : float
        Root mean square.
    mean, std : float
        Mean and standard deviation (population, ddof=0).
    max_abs : float
        Largest magnitude.
    """

    count: int
    rms: float
    mean: float
    std: float
    max_abs: float

    @classmethod
    def of(cls, values) -> ErrorStats:
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return cls(0, math.nan, math.nan, math.nan, math.nan)
        return cls(int(v.size), float(np.sqrt(np.mean(v**2))), float(np.mean(v)), float(np.std(v)),
                   float(np.max(np.abs(v))))


@dataclass(frozen=True)
class FieldSummary:
    """Clear-sky statistics: samples that are valid, not cloud-flagged and with the Sun in the field of view.

    Attributes
    ----------
    count : int
        Samples summarised.
    zenith, azimuth, azimuth_arc, vector : ErrorStats
        Of the zenith error, the azimuth error (only where the Sun is ≥ `boresight_deg` from the sky's zenith,
        so its azimuth is defined), its horizontal arc, and the vector error (a magnitude: its `std` is seed 003
        §5's "standard deviation of the vector", its `rms` the RMS angle).
    """

    count: int
    zenith: ErrorStats
    azimuth: ErrorStats
    azimuth_arc: ErrorStats
    vector: ErrorStats


@dataclass(frozen=True)
class MountFit:
    """The heading (and level) fitted to the Sun by least squares.

    Attributes
    ----------
    heading_deg, roll_deg, pitch_deg : float
        The fitted (or given) mount [°].
    parameters : tuple of str
        Fitted parameters, the order of `covariance`.
    sigma_deg : dict
        1-σ standard uncertainty of each fitted parameter [°].
    covariance : ndarray
        σ² (JᵀJ)⁻¹ [°²].
    n_samples : int
        Samples in the fit.
    residual_rms_deg : float
        RMS of the residual components (two per sample) [°].
    """

    heading_deg: float
    roll_deg: float
    pitch_deg: float
    parameters: tuple[str, ...]
    sigma_deg: dict
    covariance: np.ndarray
    n_samples: int
    residual_rms_deg: float

    @property
    def heading_sigma_deg(self) -> float:
        return float(self.sigma_deg.get("heading", 0.0))


@dataclass(frozen=True)
class FieldComparison:
    """A sensor's field run against the Sun (see the module docstring). Arrays have one entry per sample.

    Attributes
    ----------
    times_s : ndarray
        Unix seconds (UTC).
    sun_zenith_deg, sun_azimuth_deg : ndarray
        The Sun's apparent zenith and azimuth east of north (SPA) [°].
    measured_zenith_deg, measured_azimuth_deg : ndarray
        The reading turned into the sky by `mount` [°] (NaN for invalid samples).
    sun_sensor_zenith_deg, sun_sensor_azimuth_deg : ndarray
        The Sun in the sensor frame through `mount`: what the sensor should have read [°].
    zenith_error_deg, azimuth_error_deg, azimuth_arc_error_deg, vector_error_deg : ndarray
        Measured minus Sun: zenith, azimuth wrapped to ±180°, azimuth × sin z_sun, great-circle angle [°].
    sensor_zenith_error_deg, sensor_azimuth_error_deg : ndarray
        The same in the sensor's own frame (θ − θ_sun, wrap(φ − φ_sun)) [°].
    in_fov, valid, cloudy, used : ndarray of bool
        Sun within `fov_half_deg` of the boresight; a finite, not-invalid reading; cloud-flagged; and the
        samples the summary is over (valid, clear, in the FOV).
    mount : Mount
        The mount the comparison used (given, or with the fitted heading/level).
    mount_fit : MountFit or None
        The fit, when ``heading="fit"`` or ``level="fit"``.
    summary : FieldSummary
    fov_half_deg : float
    notes, warnings : tuple of str
        What the numbers mean, and what to look at, in words.
    """

    times_s: np.ndarray
    sun_zenith_deg: np.ndarray
    sun_azimuth_deg: np.ndarray
    measured_zenith_deg: np.ndarray
    measured_azimuth_deg: np.ndarray
    sun_sensor_zenith_deg: np.ndarray
    sun_sensor_azimuth_deg: np.ndarray
    zenith_error_deg: np.ndarray
    azimuth_error_deg: np.ndarray
    azimuth_arc_error_deg: np.ndarray
    vector_error_deg: np.ndarray
    sensor_zenith_error_deg: np.ndarray
    sensor_azimuth_error_deg: np.ndarray
    in_fov: np.ndarray
    valid: np.ndarray
    cloudy: np.ndarray
    used: np.ndarray
    mount: Mount
    mount_fit: MountFit | None
    summary: FieldSummary
    fov_half_deg: float
    notes: tuple[str, ...] = field(default=())
    warnings: tuple[str, ...] = field(default=())


def _flags(flags, size: int, name: str) -> np.ndarray:
    if flags is None:
        return np.zeros(size, dtype=bool)
    out = np.asarray(flags, dtype=bool)
    if out.shape != (size,):
        raise FieldDataError(f"{name} must have one flag per sample ({size}), got shape {out.shape}", column=name)
    return out


def fit_mount(sun_enu, zenith_deg, azimuth_deg, mount: Mount = Mount(), *, heading: str = "fit",
              level: str = "given") -> MountFit:
    """Least-squares heading (and roll, pitch) of the mount that turns the readings onto the Sun.

    Parameters
    ----------
    sun_enu : array (N, 3)
        Unit vectors to the Sun's apparent centre in east-north-up.
    zenith_deg, azimuth_deg : array (N,)
        The sensor's readings θ, φ [°].
    mount : Mount
        The given heading and level (used where not fitted; the level is the fit's start).
    heading, level : {"given", "fit"}
        What to fit.

    Returns
    -------
    MountFit
        With 1-σ uncertainties from σ² (JᵀJ)⁻¹, σ² = Σ r² / (2N − p).

    Raises
    ------
    FieldDataError
        Nothing to fit, or fewer samples than needed (one for the heading, two with the level).
    """
    from scipy.optimize import least_squares

    if heading not in MODES or level not in MODES:
        raise FieldDataError(f"heading and level must be one of {MODES}, got {heading!r}, {level!r}")
    fit_heading, fit_level = heading == "fit", level == "fit"
    s = np.asarray(sun_enu, dtype=float).reshape(-1, 3)
    n = direction_vector(zenith_deg, azimuth_deg).reshape(-1, 3)
    p_count = int(fit_heading) + 2 * int(fit_level)
    if p_count == 0:
        raise FieldDataError("nothing to fit: heading and level are both given")
    if 2 * s.shape[0] < p_count + 1:
        raise FieldDataError(f"{s.shape[0]} sample(s) cannot fit {p_count} mount angle(s) with an uncertainty")
    e1, e2 = tangent_basis(n)
    psi0 = float(mount.heading_deg)
    if fit_heading:
        psi0 = float(_closed_form_heading(s, n @ _level_matrix(mount.roll_deg, mount.pitch_deg).T)[0])
    x0 = np.array(([psi0] if fit_heading else []) + ([mount.roll_deg, mount.pitch_deg] if fit_level else []),
                  dtype=float)

    def unpack(x):
        psi = x[0] if fit_heading else mount.heading_deg
        rp = x[int(fit_heading):] if fit_level else (mount.roll_deg, mount.pitch_deg)
        return psi, rp[0], rp[1]

    def residuals(x):
        p = s @ mount_matrix(*unpack(x))
        return np.degrees(np.concatenate([np.sum(p * e1, axis=1), np.sum(p * e2, axis=1)]))

    sol = least_squares(residuals, x0, method="lm", xtol=1e-12, ftol=1e-12)
    r, jac = sol.fun, sol.jac
    dof = max(r.size - x0.size, 1)
    cov = (np.sum(r**2) / dof) * np.linalg.pinv(jac.T @ jac)
    names = (("heading",) if fit_heading else ()) + (("roll", "pitch") if fit_level else ())
    psi, roll, pitch = unpack(sol.x)
    return MountFit(heading_deg=float(psi % 360.0), roll_deg=float(roll), pitch_deg=float(pitch),
                    parameters=names, sigma_deg={k: float(v) for k, v in zip(names, np.sqrt(np.diag(cov)))},
                    covariance=cov, n_samples=int(s.shape[0]), residual_rms_deg=float(np.sqrt(np.mean(r**2))))


def compare_with_sun(times_s, zenith_deg, azimuth_deg, site: Site, mount: Mount = Mount(),
                     atmosphere: Atmosphere = Atmosphere(), *, heading: str = "given", level: str = "given",
                     cloudy=None, invalid=None, fov_half_deg: float = 60.0, fit_mask=None,
                     boresight_deg: float = 1.0, min_clear: int = 10, scatter_warn_deg: float = 0.5
                     ) -> FieldComparison:
    """Compare a sensor's readings with the Sun (seed 003 §5).

    Parameters
    ----------
    times_s : array (N,) of Unix seconds, or ISO 8601 strings / datetimes
        Sample times, UTC (:func:`~calibration.field.sky.utc_seconds`).
    zenith_deg, azimuth_deg : array (N,)
        The sensor's measured direction θ, φ in its own frame [°].
    site : Site
    mount : Mount
        Heading (azimuth of the sensor's +x, east of north) and level (roll, pitch from an inclinometer,
        :func:`~calibration.field.sky.mount_from_gravity`) [°]; the start of a fit.
    atmosphere : Atmosphere
    heading : {"given", "fit"}
        ``"fit"``: the heading is unknown (a compass), fitted over `fit_mask`; the azimuth error is then
        relative.
    level : {"given", "fit"}
        ``"fit"``: roll and pitch fitted as well.
    cloudy, invalid : array of bool (N,) or None
        Per-sample flags: cloud over the Sun (operator's note or a detector), and readings to drop (no spot,
        saturated, ...). Non-finite readings count as invalid.
    fov_half_deg : float
        Half field of view of the sensor [°] (seed 003's CMOS sensor: 60°).
    fit_mask : array of bool (N,) or None
        Samples to fit the heading/level over (seed 003: the clear interval before 12:00); default the valid,
        clear samples with the Sun in the field of view (of the given mount, before the fit).
    boresight_deg : float
        Within this angle of a pole (the sensor's boresight, or the sky's zenith) an azimuth is ill-defined [°].
    min_clear : int
        Fewer clear samples in the field of view than this: a warning.
    scatter_warn_deg : float
        A clear-sky vector RMS above this: a warning [°].

    Returns
    -------
    FieldComparison

    Raises
    ------
    FieldDataError
        Arrays of different lengths, an unknown mode, or a fit with no samples to fit.

    References
    ----------
    seed 003 §5 (Figs. 5.1–5.5), eq. 13; digest 003 §9.5; Reda & Andreas (2004).
    """
    if heading not in MODES or level not in MODES:
        raise FieldDataError(f"heading and level must be one of {MODES}, got {heading!r}, {level!r}")
    t, th, ph = track_arrays(times_s, zenith_deg, azimuth_deg)
    size = t.size
    cloudy_f = _flags(cloudy, size, "cloudy")
    valid = ~_flags(invalid, size, "invalid") & np.isfinite(th) & np.isfinite(ph) & np.isfinite(t)
    clear = valid & ~cloudy_f
    sun = sun_position(np.where(np.isfinite(t), t, 0.0), site, atmosphere)
    s_enu = sun.enu()
    notes: list[str] = []
    warnings: list[str] = []

    def sun_in_sensor(m: Mount):
        return zenith_azimuth_from_vector(s_enu @ m.matrix())

    mount_fit = None
    if heading == "fit" or level == "fit":
        if fit_mask is None:
            mask = clear & (sun_in_sensor(mount)[0] <= fov_half_deg)
            what = "the clear samples with the Sun in the field of view"
        else:
            mask = _flags(fit_mask, size, "fit_mask") & valid
            what = "the chosen interval"
        if not mask.any():
            raise FieldDataError(f"no valid sample to fit the mount over ({what})")
        mount_fit = fit_mount(s_enu[mask], th[mask], ph[mask], mount, heading=heading, level=level)
        mount = Mount(mount_fit.heading_deg, mount_fit.roll_deg, mount_fit.pitch_deg)
        parts = [f"{k} {getattr(mount_fit, k + '_deg'):.4f}° ± {v:.4f}° (1σ)" for k, v in mount_fit.sigma_deg.items()]
        notes.append(f"mount fitted by least squares over {mount_fit.n_samples} samples ({what}): "
                     + ", ".join(parts) + f"; residual RMS {mount_fit.residual_rms_deg:.4f}° per component")
        if heading == "fit":
            notes.append("the heading was fitted, so the azimuth errors are relative, not absolute: a constant "
                         "azimuth offset of the sensor is absorbed into the heading (seed 003 §5 removed it over "
                         "the clear interval before 12:00)")
        if level == "fit":
            notes.append("the level was fitted, so the zenith errors are relative to the fitted level: a tilt of "
                         "the sensor's face (and part of any constant zenith bias) is absorbed into roll and pitch")
        if mount_fit.n_samples < min_clear:
            warnings.append(f"the mount was fitted over only {mount_fit.n_samples} samples")
    else:
        notes.append(f"mount as given: heading {mount.heading_deg:.4f}°, roll {mount.roll_deg:.4f}°, pitch "
                     f"{mount.pitch_deg:.4f}°; the errors are absolute (they include the mount's own errors)")

    sun_th, sun_ph = sun_in_sensor(mount)
    in_fov = sun_th <= fov_half_deg
    n_meas = direction_vector(np.where(valid, th, 0.0), np.where(valid, ph, 0.0))
    mz, ma = zenith_azimuth_enu(n_meas @ mount.matrix().T)
    nan = np.where(valid, 1.0, np.nan)
    mz, ma = mz * nan, ma * nan
    z_err = mz - sun.apparent_zenith_deg
    a_err = wrap_deg(ma - sun.azimuth_deg)
    arc = a_err * np.sin(np.radians(sun.apparent_zenith_deg))
    vec = angular_error_deg(sun.apparent_zenith_deg, 90.0 - sun.azimuth_deg, mz, 90.0 - ma)
    # (the azimuth east of north A maps onto the mathematical angle 90° − A; the great-circle angle is the same)
    used = clear & in_fov
    az_ok = used & (sun.apparent_zenith_deg >= boresight_deg)
    summary = FieldSummary(count=int(used.sum()), zenith=ErrorStats.of(z_err[used]),
                           azimuth=ErrorStats.of(a_err[az_ok]), azimuth_arc=ErrorStats.of(arc[used]),
                           vector=ErrorStats.of(vec[used]))

    out_fov = int((valid & ~in_fov).sum())
    if out_fov:
        warnings.append(f"{out_fov} valid sample(s) with the Sun outside the {fov_half_deg:g}° half field of view "
                        "(excluded from the summary)")
    near_bore = valid & (np.minimum(sun_th, np.where(valid, th, 180.0)) < boresight_deg)
    if near_bore.any():
        warnings.append(f"{int(near_bore.sum())} sample(s) with the Sun within {boresight_deg:g}° of the sensor's "
                        "boresight: its azimuth φ is ill-defined there (use the vector error, not the azimuth error)")
    near_zen = used & (sun.apparent_zenith_deg < boresight_deg)
    if near_zen.any():
        warnings.append(f"{int(near_zen.sum())} sample(s) with the Sun within {boresight_deg:g}° of the sky's zenith: "
                        "their azimuth errors are left out of the azimuth statistics")
    if summary.count < min_clear:
        warnings.append(f"only {summary.count} clear sample(s) with the Sun in the field of view (fewer than "
                        f"{min_clear}): the statistics are not meaningful")
    if summary.count and summary.vector.rms > scatter_warn_deg:
        warnings.append(f"large scatter: the clear-sky vector error RMS is {summary.vector.rms:.3f}° "
                        f"(> {scatter_warn_deg:g}°): unflagged cloud, a wrong mount, site or clock?")
    if cloudy_f.any():
        notes.append(f"{int((cloudy_f & valid).sum())} cloud-flagged sample(s) are compared but left out of the "
                     "clear-sky summary")
    return FieldComparison(
        times_s=t, sun_zenith_deg=sun.apparent_zenith_deg, sun_azimuth_deg=sun.azimuth_deg,
        measured_zenith_deg=mz, measured_azimuth_deg=ma, sun_sensor_zenith_deg=sun_th, sun_sensor_azimuth_deg=sun_ph,
        zenith_error_deg=z_err, azimuth_error_deg=a_err, azimuth_arc_error_deg=arc, vector_error_deg=vec,
        sensor_zenith_error_deg=(th - sun_th) * nan, sensor_azimuth_error_deg=wrap_deg(ph - sun_ph) * nan,
        in_fov=in_fov, valid=valid, cloudy=cloudy_f, used=used, mount=mount, mount_fit=mount_fit,
        summary=summary, fov_half_deg=float(fov_half_deg), notes=tuple(notes), warnings=tuple(warnings))

