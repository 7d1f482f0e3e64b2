"""From the table's stage angles to the sun direction in the sensor's body frame, with the bench's geometry.

Seed 003 eq. 8 converts the zenith stage's angle Ω to the incidence angle θ on a bench whose zenith axis is a
lever arm d behind the sensor, with the simulator L in front of it. Written as vectors (lab frame: zenith axis
along y through the origin, sensor d out along z at Ω = 0, source at distance D = L + d), the body direction
of the source is

    w = R_z(φ_s) · [ sin Ω' cos η,  sin η,  cos Ω' cos η − q ]ᵀ,      Ω' = Ω − Ω₀,   q = d / (L + d)

normalised, and seen through the sensor's misalignment on its fixture. Three things follow:

* only the ratio q can be learnt from spots: a bench scaled as a whole gives the same angles, so a lever
  arm and a source distance are each known only when one of them is measured (the other then follows);
* the zenith stage's zero Ω₀ and the source's elevation η out of the zenith stage's plane are seen in the
  body frame as a ring traced by the azimuth stage, so several azimuths determine them;
* the azimuth stage's zero is indistinguishable from the detector's in-plane rotation, and the sensor's tilt
  on its fixture from the detector's tilt: without an outside reference (an alignment cube) the bench
  defines them, so they are given (default 0), never fitted.

References
----------
seed 003, eq. 8 and Fig. 4.5 (offset zenith axis); §4.4–4.5 (bench non-parallelism, 0.47° found).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .design import BenchGeometry
from .errors import CalibrationError
from .geometry import incidence_from_stage_angle
from .pinhole import detector_rotation

#: Geometry parameters the joint fit can estimate, in the order of the parameter vector.
GEOMETRY_PARAMETERS = ("arm_ratio", "zenith_zero_deg", "source_elevation_deg")


class StageGeometryError(CalibrationError):
    """Stage angles whose bench geometry is neither given nor determined by the data."""


@dataclass(frozen=True)
class StageGeometry:
    """Bench geometry seen by the stage-angle conversion.

    Attributes
    ----------
    arm_ratio : float
        q = d / (L + d): lever arm over the axis-to-source distance [unitless].
    zenith_zero_deg : float
        Ω₀: the zenith stage reads Ω₀ when the azimuth axis points at the source [°].
    source_elevation_deg : float
        η: the source's direction out of the zenith stage's plane, seen from the axis [°].
    mount_tilt_x_deg, mount_tilt_y_deg : float
        The sensor's tilt on its fixture (toward body azimuth 0° and 90°) [°]; given, not fitted.
    """

    arm_ratio: float
    zenith_zero_deg: float = 0.0
    source_elevation_deg: float = 0.0
    mount_tilt_x_deg: float = 0.0
    mount_tilt_y_deg: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.arm_ratio < 1.0:
            raise ValueError(f"`arm_ratio` must lie in [0, 1), got {self.arm_ratio}")


def arm_ratio(lever_arm_mm: float, source_distance_mm: float) -> float:
    """q = d / (L + d) of seed 003 eq. 8's bench [unitless].

    References
    ----------
    seed 003, eq. 8 (its only length ratio).
    """
    return float(lever_arm_mm) / (float(source_distance_mm) + float(lever_arm_mm))


def body_direction_deg(stage_azimuth_deg, stage_zenith_deg, geometry: BenchGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Sun direction in the body frame that a bench of known geometry sets with its stage angles.

    .. math::

        θ' = 180° − \\arccos\\frac{d − (L + d)\\cos Ω}{\\sqrt{(L + d)^2 + d^2 − 2 (L + d) d \\cos Ω}},
        \\qquad θ = |θ'|, \\qquad φ = φ_s + 180° \\;(Ω < 0), \\; φ_s \\;(Ω ≥ 0)

    Parameters
    ----------
    stage_azimuth_deg : numeric
        Azimuth stage reading φ_s [°].
    stage_zenith_deg : numeric
        Zenith stage reading Ω [°]; negative tilts the sensor the other way.
    geometry : BenchGeometry
        Lever arm d and source distance L the bench believes [mm].

    Returns
    -------
    zenith_deg : ndarray
        Zenith θ of the source from the boresight [°], in [0, 180].
    azimuth_deg : ndarray
        Azimuth φ of the source in the body frame [°], in [0, 360).

    Notes
    -----
    Seed 003's azimuth-on-zenith bench with its stages at their zeros and the source in the zenith stage's
    plane (Ω₀ = η = 0 in the module docstring): θ' is eq. 8's incidence angle with the sign of Ω
    (:func:`calibration.geometry.incidence_from_stage_angle`). A negative stage angle tilts the sensor away
    from the azimuth stage's zero, so the source is seen at |θ'| on the opposite azimuth. The result equals
    the direction of :func:`body_vectors_from_stage` with ``StageGeometry(arm_ratio(d, L))``. The inputs
    broadcast against each other; a NaN stage angle gives a NaN direction. The thesis's L (710 mm at eq. 8,
    710 cm in §4.1) is [ambiguous]: always pass the bench's.

    References
    ----------
    seed 003, eq. 8 and Fig. 4.5 (offset zenith axis), eq. 12 (body frame).

    See Also
    --------
    body_vectors_from_stage : the same with the stages' zero offsets and the fixture's tilt, as fitted.
    """
    theta = incidence_from_stage_angle(stage_zenith_deg, geometry.lever_arm_mm, geometry.source_distance_mm)  # eq. 8
    theta, azimuth = np.broadcast_arrays(theta, np.asarray(stage_azimuth_deg, dtype=float))
    azimuth = np.where(np.isnan(theta), np.nan, azimuth + np.where(theta < 0, 180.0, 0.0))
    return np.abs(theta), np.mod(azimuth, 360.0)


def _rot_z(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)


def body_vectors_from_stage(stage_azimuth_deg, stage_zenith_deg, geometry: StageGeometry) -> np.ndarray:
    """Unit sun vectors in the body frame for stage angles, on an azimuth-on-zenith bench (seed 003).

    Parameters
    ----------
    stage_azimuth_deg, stage_zenith_deg : array_like
        Azimuth stage φ_s and zenith stage Ω readings [°].
    geometry : StageGeometry

    Returns
    -------
    s : ndarray, shape (..., 3)

    References
    ----------
    seed 003, eq. 8 (with η = Ω₀ = 0 the zenith of s is eq. 8's θ, and its azimuth φ_s, or φ_s + 180° for
    Ω < 0); module docstring for the offsets.
    """
    omega = np.radians(np.asarray(stage_zenith_deg, dtype=float) - geometry.zenith_zero_deg)
    eta = np.radians(geometry.source_elevation_deg)
    w = np.stack([np.sin(omega) * np.cos(eta), np.full_like(omega, np.sin(eta)),
                  np.cos(omega) * np.cos(eta) - geometry.arm_ratio], axis=-1)
    w = np.einsum("...ij,...j->...i", _rot_z(np.asarray(stage_azimuth_deg, dtype=float)), w)
    if geometry.mount_tilt_x_deg or geometry.mount_tilt_y_deg:
        # the fixture tilts the body as the detector's tilt does (no in-plane turn); rows: Rᵀ w
        w = w @ detector_rotation(geometry.mount_tilt_x_deg, geometry.mount_tilt_y_deg, 0.0)
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


@dataclass(frozen=True)
class GeometryPrior:
    """What the bench's operator knows of its geometry: each length with its 1σ, or None when unknown.

    Attributes
    ----------
    lever_arm_mm, lever_arm_sd_mm : float or None
        d and its uncertainty [mm].
    source_distance_mm, source_distance_sd_mm : float or None
        L and its uncertainty [mm].
    mount_tilt_x_deg, mount_tilt_y_deg : float
        The sensor's tilt on its fixture, if measured [°] (module docstring: not separable from the detector's).
    """

    lever_arm_mm: float | None = None
    lever_arm_sd_mm: float | None = None
    source_distance_mm: float | None = None
    source_distance_sd_mm: float | None = None
    mount_tilt_x_deg: float = 0.0
    mount_tilt_y_deg: float = 0.0

    @classmethod
    def from_bench(cls, geometry: BenchGeometry, *, mount_tilt_x_deg: float = 0.0,
                   mount_tilt_y_deg: float = 0.0) -> GeometryPrior:
        """What a bench's stated geometry tells the fit: its two lengths with their 1σ.

        A zero lever arm (the sensor on the zenith axis) is no prior on the lever arm: the fit works with the
        lengths' logarithms (:func:`split_arm_ratio`).

        References
        ----------
        seed 003, eq. 8 (d and L, of which only d / (L + d) enters).
        """
        return cls(lever_arm_mm=geometry.lever_arm_mm or None, lever_arm_sd_mm=geometry.lever_arm_sd_mm,
                   source_distance_mm=geometry.source_distance_mm,
                   source_distance_sd_mm=geometry.source_distance_sd_mm,
                   mount_tilt_x_deg=mount_tilt_x_deg, mount_tilt_y_deg=mount_tilt_y_deg)

    def __post_init__(self) -> None:
        for name in ("lever_arm", "source_distance"):
            value, sd = getattr(self, f"{name}_mm"), getattr(self, f"{name}_sd_mm")
            if value is not None and not value > 0:
                raise StageGeometryError(f"`{name}_mm` must be positive, got {value}")
            if sd is not None and not sd > 0:
                raise StageGeometryError(f"`{name}_sd_mm` must be positive, got {sd}")

    @property
    def ratio(self) -> tuple[float, float] | None:
        """q and its 1σ when both lengths are given (an unknown σ counts as 0.5 % of the length)."""
        if self.lever_arm_mm is None or self.source_distance_mm is None:
            return None
        d, L = self.lever_arm_mm, self.source_distance_mm
        sd_d = self.lever_arm_sd_mm or 0.005 * d
        sd_l = self.source_distance_sd_mm or 0.005 * L
        total = (L + d) ** 2
        return arm_ratio(d, L), float(np.hypot(L / total * sd_d, d / total * sd_l))


def split_arm_ratio(q: float, sd_q: float, prior: GeometryPrior) -> dict:
    """Lever arm and source distance from the fitted ratio q and what was given of them.

    Works in logarithms: log d − log L = log(q / (1 − q)) from the fit, plus log d and log L from the prior,
    each with its relative uncertainty; a linear least squares gives both lengths and their 1σ. A length that
    is not given has no prior, so with neither given only the ratio is known.

    Returns
    -------
    dict
        ``{"lever_arm_mm": (value, sd) or None, "source_distance_mm": (value, sd) or None}``.

    References
    ----------
    seed 003, eq. 8 (only d / (L + d) enters it); first-order propagation of the ratio's uncertainty.
    """
    r = q / (1.0 - q)
    sd_log_r = sd_q / (q * (1.0 - q)) if q > 0 else np.inf
    rows, values, sigmas = [[1.0, -1.0]], [np.log(r) if r > 0 else -np.inf], [sd_log_r]
    for j, name in enumerate(("lever_arm", "source_distance")):
        value = getattr(prior, f"{name}_mm")
        if value is not None:
            sd = getattr(prior, f"{name}_sd_mm") or 0.005 * value
            rows.append([1.0 if j == 0 else 0.0, 1.0 if j == 1 else 0.0])
            values.append(np.log(value))
            sigmas.append(sd / value)
    if len(rows) < 2 or not np.isfinite(values[0]) or not np.isfinite(sd_log_r):
        return {"lever_arm_mm": None, "source_distance_mm": None}
    a = np.array(rows) / np.array(sigmas)[:, None]
    b = np.array(values) / np.array(sigmas)
    est, *_ = np.linalg.lstsq(a, b, rcond=None)
    cov = np.linalg.inv(a.T @ a)
    d, L = np.exp(est)
    return {"lever_arm_mm": (float(d), float(d * np.sqrt(cov[0, 0]))),
            "source_distance_mm": (float(L), float(L * np.sqrt(cov[1, 1])))}
