"""How well a physical calibration knows each direction: its parameter covariance propagated to pointing.

A fitted physical calibration (:class:`~calibration.models.physical.PhysicalCalibration`) carries the
covariance C of its parameters p̂ (σ² (JᵀJ)⁻¹ of the least-squares fit). For a sun direction d the sensor
sees the spot x = f(d; p) and the calibration reports g(x; p̂) = f⁻¹(x; p̂); to first order its error is

    δd = (∂g/∂p)|ₓ · δp,        cov_d = J C Jᵀ,        J = ∂g/∂p at x = f(d; p̂) held fixed,

with δd expressed in a 2-D tangent basis at d (toward larger zenith, and across it toward larger azimuth),
in degrees. The "1σ pointing uncertainty" of a direction is the RMS of the angle between the reported and
the true direction, σ = √(trace cov_d): the expected vector error of seed 003 eq. 13, not the semi-axis of
the error ellipse in one direction (:func:`error_ellipse_deg` gives those).

That is the uncertainty of the *calibration*, the same for every frame read through it. A frame read in
flight adds its own centroid noise, :func:`centroid_noise_sigma_deg`, reported separately.

References
----------
research note anchors-sunsensors §6 (report the parameter covariance of the joint physical fit); first-order
(linear) error propagation, the law of propagation of uncertainty (GUM, JCGM 100:2008 §5.1.2) in its
matrix form cov_y = J C Jᵀ (JCGM 102:2011).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .geometry import direction_vector
from .pinhole import PinholeBuild, direction_from_spot, spot_from_direction

#: The continuous fields of a sensor build, those a calibration may have fitted; other fitted names (bench
#: geometry fitted jointly, say) do not change how a spot is turned into a direction in flight.
BUILD_FIELDS = frozenset(f.name for f in dataclasses.fields(PinholeBuild)
                         if isinstance(f.default, float) and not isinstance(f.default, bool))

#: Finite-difference step as a fraction of the parameter's own 1σ: far inside the linear regime and far
#: from the build's bounds (gap > 0, glass ≥ 0, index ≥ 1), yet ~1e-8 rad of direction change, well above
#: the model's rounding (its Newton inversion reaches machine precision).
_STEP_PER_SIGMA = 1e-3

#: Finite-difference step of the spot position [px].
_STEP_PX = 1e-3


def build_covariance(calibration) -> tuple[tuple[str, ...], np.ndarray]:
    """Marginal covariance of the fitted build parameters of a physical calibration.

    C = diag(σ) · R · diag(σ) over the fitted names, restricted to the names that are fields of
    :class:`~calibration.pinhole.PinholeBuild`: the marginal covariance of a subset of jointly Gaussian
    estimates is exactly that sub-block, whatever else was fitted with them.

    Parameters
    ----------
    calibration : PhysicalCalibration
        With `fitted`, `uncertainties` (1σ by name, in the parameter's units) and `correlation` (in the
        order of `fitted`).

    Returns
    -------
    names : tuple of str
        The build parameters kept, in the order of `fitted`.
    cov : ndarray, shape (k, k)
        Their covariance [product of the parameters' units].

    References
    ----------
    research note anchors-sunsensors §6 (parameter covariance and correlation of the physical fit).
    """
    fitted = tuple(calibration.fitted)
    corr = np.asarray(calibration.correlation, dtype=float)
    if corr.shape != (len(fitted), len(fitted)):
        raise ValueError(f"the correlation matrix is {corr.shape}, the calibration fitted {len(fitted)} parameters")
    keep = [i for i, name in enumerate(fitted) if name in BUILD_FIELDS]
    sigma = np.array([calibration.uncertainties[fitted[i]] for i in keep], dtype=float)
    cov = corr[np.ix_(keep, keep)] * np.outer(sigma, sigma)
    return tuple(fitted[i] for i in keep), cov


def _tangent_basis(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit vectors toward larger zenith and toward larger azimuth at each direction, shape (..., 2, 3).

    At the boresight they follow the azimuth given, so each (zenith, azimuth) still has a basis.
    """
    th = np.radians(np.asarray(zenith_deg, dtype=float))
    ph = np.radians(np.asarray(azimuth_deg, dtype=float))
    e_zenith = np.stack([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)], axis=-1)
    e_azimuth = np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], axis=-1)
    return np.stack([e_zenith, e_azimuth], axis=-2)


def _reported_vector(x_px, y_px, build: PinholeBuild, pixel_pitch_mm: float) -> np.ndarray:
    """Unit vector the calibration reports for a spot; vectors stay smooth at the boresight, angles do not."""
    return direction_vector(*direction_from_spot(x_px, y_px, build, pixel_pitch_mm))


def _derivative(vector_at, value: float, step: float, valid=lambda v: True) -> np.ndarray:
    """d(vector)/d(value) by central differences, or one-sided where the step would leave the domain."""
    lo, hi = (value - step, value + step) if valid(value - step) else (value, value + step)
    return (vector_at(hi) - vector_at(lo)) / np.asarray(hi - lo, dtype=float)[..., None]


def direction_jacobian(calibration, zenith_deg, azimuth_deg) -> tuple[tuple[str, ...], np.ndarray]:
    """∂g/∂p: how the reported direction moves with each fitted build parameter, the spot held fixed.

    The spot is the one the calibration itself predicts for (zenith, azimuth), so g(x; p̂) is that
    direction; the derivatives are central differences of :func:`calibration.pinhole.direction_from_spot`.

    Parameters
    ----------
    calibration : PhysicalCalibration
    zenith_deg, azimuth_deg : array_like
        Directions in the body frame [°], broadcast together to shape S.

    Returns
    -------
    names : tuple of str
        The build parameters, as :func:`build_covariance` orders them.
    jacobian : ndarray, shape S + (2, k)
        Rows: the angle toward larger zenith and the angle across it toward larger azimuth [°]; columns:
        per unit of each parameter ([° per px], [° per mm], [° per °], [° per unit]).

    References
    ----------
    First-order error propagation (JCGM 100:2008 §5.1.2); research note anchors-sunsensors §6.
    """
    names, cov = build_covariance(calibration)
    zenith_deg, azimuth_deg = np.broadcast_arrays(np.asarray(zenith_deg, float), np.asarray(azimuth_deg, float))
    build, pitch = calibration.build, calibration.pixel_pitch_mm
    x, y = spot_from_direction(zenith_deg, azimuth_deg, build, pitch)
    basis = _tangent_basis(zenith_deg, azimuth_deg)
    columns = []
    for name, var in zip(names, np.diag(cov)):
        value = getattr(build, name)
        step = _STEP_PER_SIGMA * np.sqrt(var) if var > 0 else 1e-9 * max(abs(value), 1.0)

        def vector_at(v, name=name):
            return _reported_vector(x, y, dataclasses.replace(build, **{name: v}), pitch)

        def valid(v, name=name):
            try:
                dataclasses.replace(build, **{name: v})
            except ValueError:  # the build refuses it (negative glass, index below 1, ...)
                return False
            return True

        dn = _derivative(vector_at, value, step, valid)
        columns.append(np.einsum("...ij,...j->...i", basis, dn))
    jacobian = np.degrees(np.stack(columns, axis=-1)) if columns else np.zeros(zenith_deg.shape + (2, 0))
    return names, jacobian


def pointing_covariance(calibration, zenith_deg, azimuth_deg) -> np.ndarray:
    """Covariance of the pointing error the calibration's parameter uncertainty causes, cov_d = J C Jᵀ.

    Parameters
    ----------
    calibration : PhysicalCalibration
    zenith_deg, azimuth_deg : array_like
        Directions in the body frame [°], broadcast to shape S.

    Returns
    -------
    cov : ndarray, shape S + (2, 2)
        In the tangent basis (toward larger zenith, across toward larger azimuth) [deg²].

    References
    ----------
    First-order error propagation, cov_y = J C Jᵀ (JCGM 102:2011); research note anchors-sunsensors §6.
    """
    _, cov = build_covariance(calibration)
    _, jacobian = direction_jacobian(calibration, zenith_deg, azimuth_deg)
    return jacobian @ cov @ np.swapaxes(jacobian, -1, -2)


def sigma_from_covariance(cov) -> np.ndarray:
    """RMS vector error of a 2-D angular error of covariance `cov`: √(trace cov) [°] from [deg²].

    References
    ----------
    seed 003, eq. 13 (the vector error whose expected square this is); E|δ|² = trace cov.
    """
    cov = np.asarray(cov, dtype=float)
    return np.sqrt(np.maximum(cov[..., 0, 0] + cov[..., 1, 1], 0.0))


def error_ellipse_deg(cov) -> tuple[np.ndarray, np.ndarray]:
    """Semi-axes of the 1σ error ellipse of a 2-D angular error: √ of the eigenvalues of `cov`.

    Returns
    -------
    semi_major_deg, semi_minor_deg : ndarray
        [°]; semi_major² + semi_minor² = σ² of :func:`sigma_from_covariance`.

    References
    ----------
    Standard first-order error propagation (the covariance ellipse of a 2-D output, JCGM 102:2011).
    """
    eig = np.linalg.eigvalsh(np.asarray(cov, dtype=float))  # ascending
    eig = np.maximum(eig, 0.0)
    return np.sqrt(eig[..., 1]), np.sqrt(eig[..., 0])


def pointing_sigma_deg(calibration, zenith_deg, azimuth_deg) -> np.ndarray:
    """1σ pointing uncertainty of a physical calibration at each direction: the RMS vector error [°].

    σ = √(trace J C Jᵀ), the RMS over the calibration's parameter errors of the angle between the
    direction it reports and the true one (seed 003 eq. 13), to first order. Centroid noise of the frame
    read through it is not included (:func:`centroid_noise_sigma_deg`).

    Parameters
    ----------
    calibration : PhysicalCalibration
    zenith_deg, azimuth_deg : array_like
        Directions in the body frame [°].

    Returns
    -------
    sigma_deg : ndarray
        [°], of the broadcast shape of the directions.

    References
    ----------
    research note anchors-sunsensors §6; first-order error propagation (JCGM 100:2008 §5.1.2).
    """
    return sigma_from_covariance(pointing_covariance(calibration, zenith_deg, azimuth_deg))


def centroid_noise_sigma_deg(calibration, zenith_deg, azimuth_deg, noise_px: float) -> np.ndarray:
    """RMS vector error that the centroid noise of one frame adds at each direction, the calibration exact.

    cov = σ_px² (∂g/∂x)(∂g/∂x)ᵀ with ∂g/∂x the 2×2 derivative of the direction in the tangent basis
    with respect to the spot (x_px, y_px); σ = √(trace cov).

    Parameters
    ----------
    calibration : PhysicalCalibration
    zenith_deg, azimuth_deg : array_like
        Directions in the body frame [°].
    noise_px : float
        Standard deviation of the spot centre of one frame, on each axis, independent [px].

    Returns
    -------
    sigma_deg : ndarray
        [°].

    References
    ----------
    research note anchors-sunsensors §2.5 and §6 item 4 (a per-frame centroid noise estimate next to the
    calibration's); first-order error propagation (JCGM 100:2008 §5.1.2).
    """
    zenith_deg, azimuth_deg = np.broadcast_arrays(np.asarray(zenith_deg, float), np.asarray(azimuth_deg, float))
    build, pitch = calibration.build, calibration.pixel_pitch_mm
    x, y = spot_from_direction(zenith_deg, azimuth_deg, build, pitch)
    basis = _tangent_basis(zenith_deg, azimuth_deg)
    columns = [_derivative(lambda v: _reported_vector(v, y, build, pitch), x, _STEP_PX),
               _derivative(lambda v: _reported_vector(x, v, build, pitch), y, _STEP_PX)]
    jacobian = np.degrees(np.stack([np.einsum("...ij,...j->...i", basis, c) for c in columns], axis=-1))
    return float(noise_px) * np.sqrt(np.sum(jacobian**2, axis=(-2, -1)))


def _grid(zenith_max_deg: float, zenith_step_deg: float, azimuth_step_deg: float):
    if not (zenith_step_deg > 0 and azimuth_step_deg > 0 and 0 <= zenith_max_deg < 90):
        raise ValueError("the steps must be positive and `zenith_max_deg` in [0, 90)")
    zenith = np.arange(0.0, zenith_max_deg + 1e-9, zenith_step_deg)
    azimuth = np.arange(0.0, 360.0 - 1e-9, azimuth_step_deg)
    return zenith, azimuth


def _plain(value, digits: int = 7):
    """A float with `digits` significant digits (a map need not carry 17), None where it is not finite
    (JSON has no NaN)."""
    return float(f"{value:.{digits}g}") if np.isfinite(value) else None


def _rounded(values, digits: int = 7) -> list:
    """:func:`_plain` over nested lists."""
    return [_rounded(v, digits) for v in values] if np.ndim(values) else _plain(values, digits)


def uncertainty_map(calibration, zenith_max_deg: float = 60.0, zenith_step_deg: float = 5.0,
                    azimuth_step_deg: float = 15.0, *, noise_px: float | None = None) -> dict:
    """The calibration's 1σ pointing uncertainty on a zenith × azimuth grid, as a JSON-able dict.

    Parameters
    ----------
    calibration : PhysicalCalibration
    zenith_max_deg : float
        Largest zenith of the grid [°]; the grid runs from 0 in `zenith_step_deg` steps.
    zenith_step_deg, azimuth_step_deg : float
        Grid steps [°]; azimuths cover [0, 360).
    noise_px : float, optional
        Centroid noise of one frame [px]; when given, the map carries that contribution too, apart.

    Returns
    -------
    dict
        ``zenith_deg`` (n), ``azimuth_deg`` (m): the grid [°]; ``sigma_deg`` (n × m, rows by zenith): the
        RMS vector error from the parameter uncertainty [°]; ``semi_major_deg``, ``semi_minor_deg`` (n × m):
        its 1σ error ellipse [°]; ``max_deg`` and ``rms_deg``: the largest σ and the RMS of σ over the field,
        each direction weighted by its solid angle (sin θ) [°]; ``kind``: what σ means. With `noise_px`:
        ``noise_px`` and ``noise_sigma_deg`` (n × m), the RMS vector error one frame's centroid noise adds.

    References
    ----------
    research note anchors-sunsensors §6; first-order error propagation (JCGM 100:2008 §5.1.2).
    """
    zenith, azimuth = _grid(zenith_max_deg, zenith_step_deg, azimuth_step_deg)
    zz, aa = np.meshgrid(zenith, azimuth, indexing="ij")
    cov = pointing_covariance(calibration, zz, aa)
    sigma = sigma_from_covariance(cov)
    major, minor = error_ellipse_deg(cov)
    # the field's RMS per unit solid angle: a cell at zenith θ covers ∝ sin θ; the boresight row then
    # weighs nothing, which is right for a 5° grid (its cell is a sliver)
    weight = np.broadcast_to(np.sin(np.radians(zenith))[:, None], sigma.shape)
    if weight.sum() == 0:  # a grid of the boresight alone
        weight = np.ones_like(sigma)
    rms = np.sqrt(np.sum(weight * sigma**2) / np.sum(weight))
    out = {"kind": "1-sigma RMS vector error from the calibration's parameter covariance (first order)",
           "zenith_deg": zenith.tolist(), "azimuth_deg": azimuth.tolist(),
           "sigma_deg": _rounded(sigma), "semi_major_deg": _rounded(major), "semi_minor_deg": _rounded(minor),
           "max_deg": _plain(sigma.max()), "rms_deg": _plain(rms)}
    if noise_px is not None:
        out["noise_px"] = float(noise_px)
        out["noise_sigma_deg"] = _rounded(centroid_noise_sigma_deg(calibration, zz, aa, noise_px))
    return out


def uncertainty_document(calibration, **map_options) -> dict | None:
    """The ``uncertainty_map`` entry of a calibration document, or None when the method has no covariance.

    Only the physical model carries a parameter covariance (seed 003's polynomial fits do not); a physical
    calibration restored from an older document without one gets None too.

    References
    ----------
    research note anchors-sunsensors §6.
    """
    if not (hasattr(calibration, "build") and getattr(calibration, "correlation", None)
            and getattr(calibration, "uncertainties", None)):
        return None
    return uncertainty_map(calibration, **map_options)
