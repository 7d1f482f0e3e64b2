"""The calibration methods of seed 003: centre, 6th-order θ(r), linear azimuth, tilt and sector variants.

* ``seed003``: centre (x0, y0) from the normal-incidence frames, θ = Σ a_i r^i (eq. 9), φ = b1 φ_meas + b0
  (eqs. 10–11) — the basic method of §4.2–4.3 (Table 4.1).
* ``seed003-tilt``: plus the detector tilt α, β added to the zenith as θ*(φ) (eqs. 14–16, §4.4).
* ``seed003-sector``: one zenith polynomial per 45° azimuth sector, each from its two bounding bench
  azimuths (§4.5).

The polynomial is kept in the scaled variable u = r / r_s (r_s: the largest fitted radius) so that its
coefficients stay well conditioned (a_i r^i with r ~ 240 px reaches 1e14 otherwise); a_i of eq. 9 are
the stored coefficients divided by r_s^i.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..data import BenchData
from ..design import DEFAULT_SENSOR, SensorDesign
from ..errors import InsufficientDataError
from ..geometry import azimuth_measured_deg, combined_tilt, split_tilt, spot_radius_px, tilt_along_azimuth, wrap_deg
from .base import Calibration

ZENITH_ORDER = 6  # seed 003 eq. 9
SECTOR_DEG = 45.0  # seed 003 §4.5


def centre_from_normal_incidence(data: BenchData, method: str = "seed003") -> tuple[float, float]:
    """Centre (x0, y0) as the mean spot of the normal-incidence frames [px].

    References
    ----------
    seed 003, §4.2 stage 1 (8 azimuths × 5 frames, mean of the 40 centres).
    """
    mask = data.normal_incidence
    if not mask.any():
        raise InsufficientDataError(
            f"{method}: no normal-incidence points (zenith_deg = 0) to find the centre x0, y0 "
            "(seed 003 §4.2 stage 1)", column="zenith_deg")
    return float(data.x_px[mask].mean()), float(data.y_px[mask].mean())


def fit_azimuth_linear(azimuth_measured_deg_, azimuth_true_deg) -> tuple[float, float]:
    """Linear azimuth calibration φ = b1 φ_meas + b0 (eq. 11), with the 0°/360° wrap unwrapped.

    The thesis does not say how the wrap is handled ([ambiguous]). Here the sign of b1 (a mirrored read-out
    gives −1) and a first b0 come from the circular mean of φ − ±φ_meas; every true azimuth is then moved
    by whole turns to lie within 180° of that first guess, and b1, b0 are fitted by least squares.

    Returns
    -------
    b1 : float
        Slope [unitless].
    b0 : float
        Offset [°].

    References
    ----------
    seed 003, eq. 11 and Fig. 4.8.
    """
    meas = np.asarray(azimuth_measured_deg_, dtype=float)
    true = np.asarray(azimuth_true_deg, dtype=float)
    best = None
    for sign in (1.0, -1.0):
        d = np.radians(true - sign * meas)
        offset = np.degrees(np.arctan2(np.sin(d).mean(), np.cos(d).mean()))
        spread = np.sqrt(np.mean(wrap_deg(true - sign * meas - offset) ** 2))
        if best is None or spread < best[0]:
            best = (spread, sign, offset)
    _, sign, offset = best
    guess = sign * meas + offset
    unwrapped = guess + wrap_deg(true - guess)
    b1, b0 = np.polyfit(meas, unwrapped, 1)
    return float(b1), float(b0)


def _vandermonde(u: np.ndarray, order: int) -> np.ndarray:
    return u[:, None] ** np.arange(order + 1)


def fit_zenith_polynomial(radius_px, zenith_deg, *, radius_scale_px: float, order: int = ZENITH_ORDER,
                          extra_columns=None):
    """Least-squares θ(r) = Σ a_i (r / r_s)^i, optionally with extra linear terms (eq. 9, eq. 16).

    Returns
    -------
    coefficients : ndarray, shape (order + 1,)
        Polynomial coefficients in u = r / r_s [°].
    extra : ndarray, shape (k,)
        Coefficients of the extra columns.

    References
    ----------
    seed 003, eq. 9 (ordinary least squares is implied by the thesis).
    """
    a = _vandermonde(np.asarray(radius_px, dtype=float) / radius_scale_px, order)
    if extra_columns is not None:
        a = np.column_stack([a, extra_columns])
    coef, *_ = np.linalg.lstsq(a, np.asarray(zenith_deg, dtype=float), rcond=None)
    return coef[: order + 1], coef[order + 1:]


def zenith_polynomial(radius_px, coefficients, radius_scale_px: float) -> np.ndarray:
    """θ(r) = Σ a_i (r / r_s)^i [°] (seed 003 eq. 9)."""
    return np.polynomial.polynomial.polyval(np.asarray(radius_px, dtype=float) / radius_scale_px,
                                            np.asarray(coefficients))


def _direction(zenith, azimuth):
    """Fold a negative polynomial zenith (possible near the centre) onto the opposite azimuth."""
    flip = zenith < 0
    return np.abs(zenith), np.mod(np.where(flip, azimuth + 180.0, azimuth), 360.0)


@dataclass(frozen=True)
class Seed003Calibration(Calibration):
    """Basic method of seed 003 (§4.2–4.3).

    Attributes
    ----------
    x0_px, y0_px : float
        Normal-incidence centre [px].
    zenith_coefficients : tuple of float
        a_i of eq. 9 for u = r / radius_scale_px [°].
    radius_scale_px : float
        r_s [px].
    azimuth_slope : float
        b1 of eq. 11 [unitless].
    azimuth_offset_deg : float
        b0 of eq. 11 [°].
    """

    method: ClassVar[str] = "seed003"
    min_points: ClassVar[int] = 2 * (ZENITH_ORDER + 1)

    x0_px: float
    y0_px: float
    zenith_coefficients: tuple
    radius_scale_px: float
    azimuth_slope: float
    azimuth_offset_deg: float

    def __post_init__(self) -> None:
        if not self.radius_scale_px > 0:
            raise ValueError(f"`radius_scale_px` must be positive, got {self.radius_scale_px}")
        if len(self.zenith_coefficients) != ZENITH_ORDER + 1:
            raise ValueError(f"`zenith_coefficients` must hold {ZENITH_ORDER + 1} numbers (eq. 9), got "
                             f"{len(self.zenith_coefficients)}")

    #: Options of the leave-one-zenith-ring-out fits: a 6th-order θ(r) is still determined by 6 rings, since
    #: the radii of one ring spread with azimuth (pinhole offset, tilt), and that is the only way to score the
    #: method between rings on seed 003's 7-ring grid (calibration.evaluation).
    ring_out_options: ClassVar[dict] = {"min_zeniths": ZENITH_ORDER}

    @classmethod
    def _fit_common(cls, data: BenchData, min_zeniths: int = ZENITH_ORDER + 1):
        data.require_spread(min_points=cls.min_points, method=cls.method)
        x0, y0 = centre_from_normal_incidence(data, cls.method)
        r = spot_radius_px(data.x_px, data.y_px, x0, y0)  # seed 003 eq. 7
        meas = azimuth_measured_deg(data.x_px, data.y_px, x0, y0)  # seed 003 eq. 10
        off = ~data.normal_incidence
        b1, b0 = fit_azimuth_linear(meas[off], data.azimuth_deg[off])
        n_zenith = np.unique(np.round(data.zenith_deg, 3)).size
        if n_zenith < min_zeniths:
            raise InsufficientDataError(
                f"{cls.method}: the 6th-order θ(r) needs at least {ZENITH_ORDER + 1} distinct zenith angles, "
                f"the data have {n_zenith}", column="zenith_deg")
        scale = float(r.max()) or 1.0
        return x0, y0, r, meas, b1, b0, scale

    @classmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *,
            min_zeniths: int = ZENITH_ORDER + 1) -> Seed003Calibration:
        x0, y0, r, _, b1, b0, scale = cls._fit_common(data, min_zeniths)
        coef, _ = fit_zenith_polynomial(r, data.zenith_deg, radius_scale_px=scale)
        return cls(x0, y0, tuple(coef), scale, b1, b0)

    def _radius_and_azimuth(self, x_px, y_px):
        r = spot_radius_px(x_px, y_px, self.x0_px, self.y0_px)
        meas = azimuth_measured_deg(x_px, y_px, self.x0_px, self.y0_px)
        return r, np.mod(self.azimuth_slope * meas + self.azimuth_offset_deg, 360.0)  # seed 003 eq. 11

    def apply(self, x_px, y_px):
        r, azimuth = self._radius_and_azimuth(x_px, y_px)
        return _direction(zenith_polynomial(r, self.zenith_coefficients, self.radius_scale_px), azimuth)


@dataclass(frozen=True)
class Seed003TiltCalibration(Seed003Calibration):
    """Seed 003 with the detector tilt term θ*(φ) added to the zenith (eqs. 14–16, §4.4).

    The thesis measures α and β on the bench (the zenith turn that brings the spot back to x0, y0 along two
    azimuths). From grid data alone they are fitted here jointly with the polynomial: with small tilts
    θ*(φ) ≈ sin θ' cos(φ − φ') is linear in (cos φ, sin φ), and φ is the calibrated azimuth, as used at
    run time. The linearisation error is below (θ')³/6, 5e-5° for a 1° tilt.

    Attributes
    ----------
    tilt_x_deg, tilt_y_deg : float
        α (tilt along azimuth 0°) and β (along 90°) of eq. 14 [°].
    """

    method: ClassVar[str] = "seed003-tilt"

    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0

    @classmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *,
            min_zeniths: int = ZENITH_ORDER + 1) -> Seed003TiltCalibration:
        x0, y0, r, meas, b1, b0, scale = cls._fit_common(data, min_zeniths)
        azimuth = np.radians(np.mod(b1 * meas + b0, 360.0))
        coef, (c, s) = fit_zenith_polynomial(r, data.zenith_deg, radius_scale_px=scale,
                                             extra_columns=np.column_stack([np.cos(azimuth), np.sin(azimuth)]))
        tilt = np.degrees(np.arcsin(np.clip(np.radians(np.hypot(c, s)), 0.0, 1.0)))
        alpha, beta = split_tilt(tilt, np.degrees(np.arctan2(s, c)))  # seed 003 eq. 14 (inverted)
        return cls(x0, y0, tuple(coef), scale, b1, b0, float(alpha), float(beta))

    def apply(self, x_px, y_px):
        r, azimuth = self._radius_and_azimuth(x_px, y_px)
        tilt, tilt_azimuth = combined_tilt(self.tilt_x_deg, self.tilt_y_deg)  # seed 003 eq. 14
        zenith = zenith_polynomial(r, self.zenith_coefficients, self.radius_scale_px)
        return _direction(zenith + tilt_along_azimuth(azimuth, tilt, tilt_azimuth), azimuth)  # eqs. 15–16


def sector_of(azimuth_deg) -> np.ndarray:
    """Index 0…7 of the 45° sector an azimuth falls in (seed 003 §4.5)."""
    return (np.floor(np.mod(azimuth_deg, 360.0) / SECTOR_DEG).astype(int)) % 8


@dataclass(frozen=True)
class Seed003SectorCalibration(Seed003Calibration):
    """Seed 003 with one zenith polynomial per 45° sector (§4.5).

    Sector k covers calibrated azimuths [45k, 45k + 45)° and is fitted to the points at the bench azimuths
    that bound it (within 0.5°) plus the normal-incidence points. A sector with too few distinct zeniths for a
    6th-order fit keeps the pooled polynomial (its entry in `sector_coefficients` is empty).

    Attributes
    ----------
    sector_coefficients : tuple of tuple of float
        Eight coefficient sets in u = r / radius_scale_px [°], or () for "use the pooled polynomial".
    sector_radius_max_px : tuple of float
        Largest radius each sector was fitted to [px]; beyond it the pooled polynomial answers, since a
        6th-order polynomial must not extrapolate.
    """

    method: ClassVar[str] = "seed003-sector"

    sector_coefficients: tuple = ()
    sector_radius_max_px: tuple = ()

    @classmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *,
            min_zeniths: int = ZENITH_ORDER + 1) -> Seed003SectorCalibration:
        x0, y0, r, _, b1, b0, scale = cls._fit_common(data, min_zeniths)
        pooled, _ = fit_zenith_polynomial(r, data.zenith_deg, radius_scale_px=scale)
        sectors, reach = [], []
        for k in range(8):
            from_lo = np.mod(data.azimuth_deg - k * SECTOR_DEG, 360.0)
            inside = (from_lo <= SECTOR_DEG + 0.5) | (from_lo >= 360.0 - 0.5) | data.normal_incidence
            if np.unique(np.round(data.zenith_deg[inside], 3)).size < min_zeniths:
                sectors.append(())
                reach.append(0.0)
                continue
            coef, _ = fit_zenith_polynomial(r[inside], data.zenith_deg[inside], radius_scale_px=scale)
            sectors.append(tuple(coef))
            reach.append(float(r[inside].max()))
        return cls(x0, y0, tuple(pooled), scale, b1, b0, tuple(sectors), tuple(reach))

    def apply(self, x_px, y_px):
        r, azimuth = self._radius_and_azimuth(x_px, y_px)
        zenith = zenith_polynomial(r, self.zenith_coefficients, self.radius_scale_px)
        sector = sector_of(azimuth)
        reach = self.sector_radius_max_px or (np.inf,) * len(self.sector_coefficients)
        for k, coef in enumerate(self.sector_coefficients):
            pick = (sector == k) & (r <= reach[k] * 1.01)
            if len(coef) and np.any(pick):
                zenith = np.where(pick, zenith_polynomial(r, coef, self.radius_scale_px), zenith)
        return _direction(zenith, azimuth)
