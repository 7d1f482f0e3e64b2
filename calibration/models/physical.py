"""The physical model: pinhole offset, air gap, cover glass, detector tilt and rotation, fitted jointly.

The forward model (:mod:`calibration.pinhole`) predicts the spot of every bench direction; the build
parameters are fitted with ``scipy.optimize.least_squares`` to the measured centres, in pixels — the
space in which the measurement noise lives — so the fit is the maximum-likelihood one for Gaussian
centroid noise and its covariance, σ² (JᵀJ)⁻¹, gives each build error an uncertainty.

Why: a plain tan model leaves degrees of error when there is glass between pinhole and pixels, and the
published routes below 0.05° are physical models fitted jointly (research note anchors-sunsensors §0, §2.2,
§6). Seven parameters also extrapolate where a 7-coefficient polynomial per azimuth does not.
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
from ..geometry import direction_vector, wrap_deg
from ..pinhole import PinholeBuild, direction_from_spot, spot_from_vectors
from .base import Calibration

#: Parameters fitted, in the order of the parameter vector (``glass_index`` only when asked).
FITTED = ("x0_px", "y0_px", "gap_mm", "glass_mm", "tilt_x_deg", "tilt_y_deg", "rotation_deg", "aperture_c",
          "aperture_s")


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
        Names of the fitted parameters.
    residual_rms_px : float
        RMS of the centre residuals at the fitted points, per axis [px].
    """

    method: ClassVar[str] = "physical"
    min_points: ClassVar[int] = 10

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

    @property
    def build(self) -> PinholeBuild:
        return PinholeBuild(self.x0_px, self.y0_px, self.gap_mm, self.glass_mm, self.glass_index,
                            self.tilt_x_deg, self.tilt_y_deg, self.rotation_deg, self.mirrored,
                            self.aperture_c, self.aperture_s)

    @classmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *, glass_index: float = 1.52,
            fit_index: bool = False) -> "PhysicalCalibration":
        """Fit the build of the sensor to bench data.

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
        """
        if not 1.0 <= glass_index <= 3.0:
            raise CalibrationError(f"physical: `glass_index` must lie in [1, 3], got {glass_index}")
        data.require_spread(min_points=cls.min_points, method=cls.method)
        start = _initial_build(data, design, glass_index)
        names = FITTED + (("glass_index",) if fit_index else ())
        off = ~data.normal_incidence
        if np.unique(np.round(np.mod(data.azimuth_deg[off], 180.0), 1)).size < 3:
            # cos 2φ and sin 2φ need three azimuths modulo 180° to be told apart: assume a round pinhole
            names = tuple(n for n in names if not n.startswith("aperture_"))
        s = direction_vector(data.zenith_deg, data.azimuth_deg)
        measured = np.concatenate([data.x_px, data.y_px])
        pitch = design.pixel_pitch_mm

        def residuals(p):
            build = dataclasses.replace(start, **dict(zip(names, p)))
            x, y = spot_from_vectors(s, build, pitch)
            return np.concatenate([x, y]) - measured

        p0 = np.array([getattr(start, n) for n in names], dtype=float)
        bounds = {"gap_mm": (1e-3, 10.0), "glass_mm": (0.0, 10.0), "tilt_x_deg": (-10.0, 10.0),
                  "tilt_y_deg": (-10.0, 10.0), "aperture_c": (-0.1, 0.1), "aperture_s": (-0.1, 0.1),
                  "glass_index": (1.0, 3.0)}
        lower = np.array([bounds.get(n, (-np.inf, np.inf))[0] for n in names])
        upper = np.array([bounds.get(n, (-np.inf, np.inf))[1] for n in names])
        result = least_squares(residuals, p0, bounds=(lower, upper), x_scale="jac", method="trf",
                               xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
        if not result.success:
            raise FitError(f"physical: the fit did not converge ({result.message})")
        dof = max(result.fun.size - len(names), 1)
        sigma2 = 2.0 * result.cost / dof
        _, singular, vt = np.linalg.svd(result.jac, full_matrices=False)
        null = vt[singular <= singular.max() * 1e-9]
        if null.size:  # name what the data cannot see (e.g. the glass index once the glass thickness is 0)
            free = [n for n, w in zip(names, np.abs(null).max(axis=0)) if w > 1e-3]
            raise FitError(f"physical: the data do not constrain {', '.join(free) or 'every parameter'}; "
                           "fix it (e.g. do not fit the glass index) or add zeniths and azimuths")
        cov = np.linalg.inv(result.jac.T @ result.jac) * sigma2
        std = np.sqrt(np.diag(cov))
        corr = cov / np.outer(std, std)
        fitted = dict(zip(names, result.x))
        fitted["rotation_deg"] = float(wrap_deg(fitted["rotation_deg"]))
        return cls(**{**dataclasses.asdict(start), **{k: float(v) for k, v in fitted.items()}},
                   pixel_pitch_mm=pitch,
                   uncertainties={n: float(v) for n, v in zip(names, std)},
                   correlation=tuple(tuple(float(c) for c in row) for row in corr),
                   fitted=names,
                   residual_rms_px=float(np.sqrt(np.mean(result.fun**2))))

    def apply(self, x_px, y_px):
        return direction_from_spot(x_px, y_px, self.build, self.pixel_pitch_mm)
