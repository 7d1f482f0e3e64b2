"""The physical model: pinhole offset, air gap, cover glass, detector tilt and rotation, fitted jointly.

The forward model (:mod:`calibration.pinhole`) predicts the spot of every bench direction; the build
parameters are fitted with ``scipy.optimize.least_squares`` to the measured centres, in pixels — the
space in which the measurement noise lives — so the fit is the maximum-likelihood one for Gaussian
centroid noise and its covariance, σ² (JᵀJ)⁻¹, gives each build error an uncertainty.

Why: a plain tan model leaves degrees of error when there is glass between pinhole and pixels, and the
published routes below 0.05° are physical models fitted jointly (research note anchors-sunsensors §0, §2.2,
§6). Seven parameters also extrapolate where a 7-coefficient polynomial per azimuth does not.

Robust to outliers: the fit minimises a soft-L1 loss of the residuals scaled by the centroid noise (the repeat
scatter when the data have repeats, else a robust scale of the residuals), so a glint pulls it like a
few-sigma point, not like a 10 px one. A point farther than ``OUTLIER_SIGMAS`` times that scale from the model
is an outlier; the final fit is plain least squares on the rest, whose covariance gives the uncertainties and
whose χ²/dof compares the residual with the repeat scatter.

From stage angles the bench geometry (:mod:`calibration.stage_geometry`: q = d / (L + d), the zenith stage's
zero, the source's elevation) can be fitted jointly with the sensor (:func:`fit_physical` with ``stage``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.optimize import least_squares

from ..data import BenchData
from ..design import DEFAULT_SENSOR, SensorDesign
from ..errors import CalibrationError, FitError
from ..geometry import direction_vector, wrap_deg, zenith_azimuth_from_vector
from ..pinhole import PinholeBuild, direction_from_spot, spot_from_vectors
from ..repeats import RAYLEIGH_MEDIAN
from ..stage_geometry import (
    StageGeometry,
    StageGeometryError,
    body_vectors_from_stage,
)
from .base import Calibration

#: Parameters fitted, in the order of the parameter vector (``glass_index`` only when asked).
FITTED = ("x0_px", "y0_px", "gap_mm", "glass_mm", "tilt_x_deg", "tilt_y_deg", "rotation_deg", "aperture_c",
          "aperture_s")


#: A point farther than this many noise sigmas from the model is an outlier.
OUTLIER_SIGMAS = 6.0


def _initial_build(data: BenchData, design: SensorDesign, glass_index: float) -> PinholeBuild:
    """A start close enough for the fit: centre, focal distance, handedness and rotation from the data."""
    normal = data.normal_incidence
    if normal.any():
        x0, y0 = data.x_px[normal].mean(), data.y_px[normal].mean()
    else:  # the spot nearest to the boresight, moved back along its ray by the nominal focal distance
        i = int(np.argmin(data.zenith_deg))
        x0, y0 = data.x_px[i], data.y_px[i]
    dx, dy = data.x_px - x0, data.y_px - y0
    use = (data.zenith_deg > 1.0) & (data.zenith_deg < 35.0)
    if not use.any():
        use = data.zenith_deg > 1.0
    tan_th = np.tan(np.radians(data.zenith_deg[use]))
    focal_mm = float(np.median(np.hypot(dx, dy)[use] / tan_th)) * design.pixel_pitch_mm
    if not np.isfinite(focal_mm) or focal_mm <= 0:
        focal_mm = design.pinhole_height_mm
    best = None
    for mirrored in (False, True):
        spot_az = np.degrees(np.arctan2(-(-1.0 if mirrored else 1.0) * dy[use], -dx[use]))
        d = np.radians(data.azimuth_deg[use] - spot_az)
        rotation = np.degrees(np.arctan2(np.sin(d).mean(), np.cos(d).mean()))
        spread = np.sqrt(np.mean(wrap_deg(data.azimuth_deg[use] - spot_az - rotation) ** 2))
        if best is None or spread < best[0]:
            # the in-plane rotation ψ turns the detector, so the spot azimuth lags the sun's by ψ
            best = (spread, mirrored, rotation)
    _, mirrored, rotation = best
    glass = 0.3 * focal_mm * glass_index  # a start inside the bounds; the fit splits gap and glass
    return PinholeBuild(x0_px=float(x0), y0_px=float(y0), gap_mm=0.7 * focal_mm, glass_mm=glass,
                        glass_index=glass_index, rotation_deg=float(rotation), mirrored=mirrored)


@dataclass(frozen=True)
class PhysicalCalibration(Calibration):
    """Joint physical calibration of a pinhole sensor (see :mod:`calibration.pinhole` for the model).

    Attributes
    ----------
    x0_px, y0_px, gap_mm, glass_mm, glass_index, tilt_x_deg, tilt_y_deg, rotation_deg, mirrored,
    aperture_c, aperture_s
        The fitted build (:class:`~calibration.pinhole.PinholeBuild`); units in the names.
    pixel_pitch_mm : float
        Pixel pitch the model was fitted with [mm] (given, not fitted: it sets the length scale).
    uncertainties : dict of str to float
        One-sigma standard error of each fitted parameter, same units.
    correlation : tuple of tuple of float
        Correlation matrix of the fitted parameters, in the order of `fitted`.
    fitted : tuple of str
        Names of the fitted parameters (bench-geometry ones too when they were fitted jointly).
    residual_rms_px : float
        RMS of the centre residuals at the fitted points, per axis [px].
    """

    method: ClassVar[str] = "physical"
    min_points: ClassVar[int] = 10
    glass_on_mask: ClassVar[bool] = False

    x0_px: float
    y0_px: float
    gap_mm: float
    glass_mm: float
    glass_index: float
    tilt_x_deg: float
    tilt_y_deg: float
    rotation_deg: float
    mirrored: bool
    pixel_pitch_mm: float
    aperture_c: float = 0.0
    aperture_s: float = 0.0
    uncertainties: dict = dataclasses.field(default_factory=dict)
    correlation: tuple = ()
    fitted: tuple = FITTED
    residual_rms_px: float = float("nan")

    def __post_init__(self) -> None:
        if not self.pixel_pitch_mm > 0:
            raise ValueError(f"`pixel_pitch_mm` must be positive, got {self.pixel_pitch_mm}")
        self.build  # noqa: B018 - the build checks its own fields (positive gap, index >= 1 ...)

    @property
    def build(self) -> PinholeBuild:
        return PinholeBuild(self.x0_px, self.y0_px, self.gap_mm, self.glass_mm, self.glass_index,
                            self.tilt_x_deg, self.tilt_y_deg, self.rotation_deg, self.mirrored,
                            self.aperture_c, self.aperture_s, self.glass_on_mask)

    @classmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *, glass_index: float = 1.52,
            fit_index: bool = False, noise_px=None) -> PhysicalCalibration:
        """Fit the build of the sensor to bench data (robustly; see :func:`fit_physical`).

        Parameters
        ----------
        data : BenchData
            Spot centres at known directions; no normal-incidence frames are needed.
        design : SensorDesign
            Pixel pitch and nominal pinhole height (the start of the fit).
        glass_index : float
            Refractive index of the glass between pinhole and pixels [unitless]; the start value when
            `fit_index`. Thickness and index are strongly correlated, so by default the index is given
            (BK7/D263 cover glass ≈ 1.52, sapphire ≈ 1.77) and the thickness fitted.
        fit_index : bool
            Fit the index as well.
        noise_px : float or array, optional
            Centroid noise of each point per axis [px] (the repeat scatter / √frames); estimated from the
            residuals when not given.
        """
        return fit_physical(data, design, glass_index=glass_index, fit_index=fit_index, noise_px=noise_px,
                            model=cls).calibration

    def apply(self, x_px, y_px):
        return direction_from_spot(x_px, y_px, self.build, self.pixel_pitch_mm)


@dataclass(frozen=True)
class PhysicalMaskCalibration(PhysicalCalibration):
    """The physical model with the cover glass bonded under the mask (parallel to the housing, so tilted
    against a tilted die) instead of lying on the die; chosen over ``physical`` by the held-out figure only."""

    method: ClassVar[str] = "physical-mask"
    glass_on_mask: ClassVar[bool] = True


@dataclass(frozen=True)
class PhysicalFit:
    """A physical fit with what it found beyond the calibration.

    Attributes
    ----------
    calibration : PhysicalCalibration
    outliers : ndarray of bool
        Points the robust fit rejected (left out of the final fit).
    offsets_px : ndarray
        Distance of every point from the final model [px].
    noise_px : ndarray
        Noise scale of every point per axis [px] that residuals were judged against.
    chi2_dof : float or None
        Σ (residual / noise)² / dof of the final fit, when the noise came from repeats; else None.
    geometry : StageGeometry or None
        The bench geometry the directions came from (fitted or given), for stage-angle data.
    geometry_sd : dict
        1σ of each fitted geometry parameter.
    vectors : ndarray, shape (n, 3)
        Body-frame sun vectors of the points under that geometry.
    model_px : ndarray, shape (n, 2)
        Where the final model puts each point's spot [px].
    """

    calibration: PhysicalCalibration
    outliers: np.ndarray
    offsets_px: np.ndarray
    noise_px: np.ndarray
    chi2_dof: float | None
    geometry: StageGeometry | None = None
    geometry_sd: dict = dataclasses.field(default_factory=dict)
    vectors: np.ndarray | None = None
    model_px: np.ndarray | None = None


def _robust_scale(distance_px: np.ndarray) -> float:
    """Per-axis sigma from 2-D residual distances, robust to a minority of outliers [px]."""
    return float(np.median(distance_px) / RAYLEIGH_MEDIAN)


def fit_physical(data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *, glass_index: float = 1.52,
                 fit_index: bool = False, noise_px=None, model: type = PhysicalCalibration,
                 stage: tuple | None = None, geometry: StageGeometry | None = None,
                 fit_geometry: tuple[str, ...] = (), ratio_prior: tuple[float, float] | None = None) -> PhysicalFit:
    """Robust joint fit of the physical model (module docstring), optionally with the bench geometry.

    Parameters
    ----------
    data : BenchData
        Spot centres; their (zenith_deg, azimuth_deg) are used unless `stage` is given.
    design, glass_index, fit_index, noise_px
        As in :meth:`PhysicalCalibration.fit`.
    model : type
        :class:`PhysicalCalibration` or :class:`PhysicalMaskCalibration`.
    stage : (stage_azimuth_deg, stage_zenith_deg), optional
        Stage angles of the points; the directions then come from
        :func:`~calibration.stage_geometry.body_vectors_from_stage`.
    geometry : StageGeometry, optional
        The start (and, for what is not in `fit_geometry`, the value) of the bench geometry.
    fit_geometry : tuple of str
        Names of :data:`~calibration.stage_geometry.GEOMETRY_PARAMETERS` to fit jointly with the sensor.
    ratio_prior : (q, sd), optional
        A measured arm ratio added to the fit as one more observation.

    References
    ----------
    research note anchors-sunsensors §2.2 and §6 (joint physical fit; robust loss); seed 003 eq. 8.
    """
    if not 1.0 <= glass_index <= 3.0:
        raise CalibrationError(f"{model.method}: `glass_index` must lie in [1, 3], got {glass_index}")
    data.require_spread(min_points=model.min_points, method=model.method)
    if stage is not None and geometry is None:
        raise StageGeometryError(f"{model.method}: stage angles need a bench geometry to start from")
    if stage is not None:
        # the directions the start is estimated from: the given geometry's
        zen, az = zenith_azimuth_from_vector(body_vectors_from_stage(*stage, geometry))
        data = BenchData(zen, az, data.x_px, data.y_px, sensor_id=data.sensor_id, frame_id=data.frame_id)
    start = dataclasses.replace(_initial_build(data, design, glass_index), glass_on_mask=model.glass_on_mask)
    names = FITTED + (("glass_index",) if fit_index else ())
    off = ~data.normal_incidence
    if np.unique(np.round(np.mod(data.azimuth_deg[off], 180.0), 1)).size < 3:
        # cos 2φ and sin 2φ need three azimuths modulo 180° to be told apart: assume a round pinhole
        names = tuple(n for n in names if not n.startswith("aperture_"))
    n_build = len(names)
    names = names + tuple(fit_geometry)
    fixed_s = direction_vector(data.zenith_deg, data.azimuth_deg) if stage is None else None
    measured = np.concatenate([data.x_px, data.y_px])
    pitch = design.pixel_pitch_mm
    given_noise = noise_px is not None
    # residuals are always in noise sigmas; without repeats the noise is a guess, then the residuals' own scale
    noise = np.broadcast_to(np.asarray(noise_px if given_noise else 0.2, dtype=float), data.x_px.shape).copy()

    def unpack(p):
        build = dataclasses.replace(start, **dict(zip(names[:n_build], p[:n_build])))
        geo = dataclasses.replace(geometry, **dict(zip(names[n_build:], p[n_build:]))) if stage is not None else None
        return build, geo

    def spots(p):
        build, geo = unpack(p)
        s = fixed_s if geo is None else body_vectors_from_stage(*stage, geo)
        return spot_from_vectors(s, build, pitch)

    def residuals(p, weight):
        x, y = spots(p)
        r = (np.concatenate([x, y]) - measured) / np.concatenate([noise, noise])
        r = r * np.concatenate([weight, weight])
        if ratio_prior is not None and "arm_ratio" in names:
            r = np.append(r, (p[names.index("arm_ratio")] - ratio_prior[0]) / ratio_prior[1])
        return r

    bounds = {"gap_mm": (1e-3, 10.0), "glass_mm": (0.0, 10.0), "tilt_x_deg": (-10.0, 10.0),
              "tilt_y_deg": (-10.0, 10.0), "aperture_c": (-0.1, 0.1), "aperture_s": (-0.1, 0.1),
              "glass_index": (1.0, 3.0), "arm_ratio": (0.0, 0.9), "zenith_zero_deg": (-10.0, 10.0),
              "source_elevation_deg": (-10.0, 10.0)}
    lower = np.array([bounds.get(n, (-np.inf, np.inf))[0] for n in names])
    upper = np.array([bounds.get(n, (-np.inf, np.inf))[1] for n in names])
    p0 = np.array([getattr(start, n) for n in names[:n_build]] + [getattr(geometry, n) for n in names[n_build:]],
                  dtype=float)
    p0 = np.clip(p0, lower, upper)
    keep = np.ones(len(data), dtype=bool)
    options = dict(bounds=(lower, upper), x_scale="jac", method="trf", max_nfev=2000)

    def distances(p):
        x, y = spots(p)
        return np.hypot(x - data.x_px, y - data.y_px)

    # 1. robust pass: soft-L1 at one noise sigma (without repeats: at the guess, then at the residuals' scale)
    result = least_squares(residuals, p0, args=(keep.astype(float),), loss="soft_l1", **options)
    if not given_noise:
        noise[:] = max(_robust_scale(distances(result.x)), 1e-4)
        result = least_squares(residuals, result.x, args=(keep.astype(float),), loss="soft_l1", **options)
    # 2. outliers: judged against the noise, or the residuals' own scale when the model misses by more
    dist = distances(result.x)
    keep = dist <= OUTLIER_SIGMAS * np.maximum(noise, _robust_scale(dist))
    if keep.sum() < model.min_points:
        keep[:] = True
    # 3. plain least squares on the rest: the estimate, its covariance and χ²
    result = least_squares(residuals, result.x, args=(keep.astype(float),), xtol=1e-12, ftol=1e-12, gtol=1e-12,
                           **options)
    if not result.success:
        raise FitError(f"{model.method}: the fit did not converge ({result.message})")
    n_obs = 2 * int(keep.sum()) + (1 if ratio_prior is not None and "arm_ratio" in names else 0)
    dof = max(n_obs - len(names), 1)
    jac = result.jac
    chi2 = 2.0 * result.cost
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    null = vt[singular <= singular.max() * 1e-9]
    if null.size:  # name what the data cannot see (e.g. the glass index once the glass thickness is 0)
        free = [n for n, w in zip(names, np.abs(null).max(axis=0)) if w > 1e-3]
        raise FitError(f"{model.method}: the data do not constrain {', '.join(free) or 'every parameter'}; "
                       "fix it (e.g. do not fit the glass index) or add zeniths and azimuths")
    # covariance scaled by the residual (σ² from the fit, as when the noise is unknown; χ²/dof otherwise)
    cov = np.linalg.inv(jac.T @ jac) * (chi2 / dof)
    std = np.sqrt(np.diag(cov))
    corr = cov / np.outer(std, std)
    build, geo = unpack(result.x)
    values = {n: float(getattr(build, n)) for n in names[:n_build]}
    values["rotation_deg"] = float(wrap_deg(values["rotation_deg"]))
    dist = distances(result.x)
    calibration = model(**{**{k: v for k, v in dataclasses.asdict(start).items() if k != "glass_on_mask"},
                           **values},
                        pixel_pitch_mm=pitch,
                        uncertainties={n: float(v) for n, v in zip(names, std)},
                        correlation=tuple(tuple(float(c) for c in row) for row in corr),
                        fitted=names,
                        residual_rms_px=float(np.sqrt(np.mean(dist[keep] ** 2) / 2.0)))
    vectors = (direction_vector(data.zenith_deg, data.azimuth_deg) if geo is None
               else body_vectors_from_stage(*stage, geo))
    return PhysicalFit(calibration, ~keep, dist, noise, chi2 / dof if given_noise else None, geo,
                       {n: float(v) for n, v in zip(names[n_build:], std[n_build:])}, vectors,
                       np.column_stack(spots(result.x)))
