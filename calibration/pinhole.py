"""Physical forward and inverse model of a pinhole sun sensor with a cover glass and a tilted detector.

The sun's light passes a point-like pinhole, crosses an air gap g, then a plane glass plate of
thickness t and index n lying on the detector, and lands on the pixels. The detector (with its glass)
may be tilted and rotated in-plane against the housing, which defines the body frame.

In the detector frame, for a ray at incidence θ_d and in-plane direction u (unit), the spot lies at

    spot = c − k(θ_d) · sin θ_d · u / p,      k(θ) = g / cos θ + t / (n cos θ_g),   sin θ_g = sin θ / n

where c = (x0, y0) is the foot of the perpendicular from the pinhole on the detector [px] and p the pixel
pitch. The radial distance is r = g tan θ + t tan θ_g (Snell refraction in the glass). With t = 0 this is
the ideal pinhole of seed 003 eq. 6, θ = arctan(r / L).

When the glass is bonded under the mask instead (``glass_on_mask``), the plate is parallel to the housing, not
to a tilted die: the chief ray is traced exactly — vector Snell refraction into the plate, out of it parallel
to its incoming direction, then on to the die plane — so the plate's shift is taken in the mask's frame and
the ray meets the die at the die's own tilt. The gap then runs from the glass's exit face to the die, and
gap + thickness is still the pinhole's perpendicular height above the die.

A slightly non-round pinhole (seed 003 §4.5, error source 13) stretches the spot's offset with its
azimuth φ_d in the detector frame: r → r (1 + a_c cos 2φ_d + a_s sin 2φ_d), an ellipse of the aperture's
effective shape; the two coefficients are linear and well conditioned, unlike an (amplitude, angle) pair.

The detector orientation in the body frame is M = R_y(α) · R_x(−β) · R_z(ψ): an in-plane rotation ψ,
then the tilt α that tips the detector normal toward azimuth 0° and β toward azimuth 90° (the α, β
convention of seed 003 eqs. 14–15). A body-frame direction s is seen in the detector frame as Mᵀ s.

References
----------
seed 003, eqs. 6–7 (ideal pinhole), eqs. 14–15 (tilt convention), §4.4 (detector tilt and rotation);
research note anchors-sunsensors §2.2 (refraction in glass between pinhole and pixels).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .geometry import direction_vector, zenith_azimuth_from_vector


@dataclass(frozen=True)
class PinholeBuild:
    """Build parameters of one pinhole sun sensor.

    Attributes
    ----------
    x0_px, y0_px : float
        Foot of the perpendicular from the pinhole on the detector [px].
    gap_mm : float
        Air gap between the pinhole and the glass (or the pixels when there is no glass) [mm].
    glass_mm : float
        Thickness of the glass between pinhole and pixels [mm]; 0 for none.
    glass_index : float
        Refractive index of that glass [unitless].
    tilt_x_deg, tilt_y_deg : float
        Detector tilt α toward azimuth 0° and β toward azimuth 90° [°].
    rotation_deg : float
        In-plane rotation ψ of the detector [°].
    mirrored : bool
        True when the detector rows run against the body +y axis (a mirrored read-out).
    aperture_c, aperture_s : float
        Non-round aperture: the offset stretches by 1 + a_c cos 2φ_d + a_s sin 2φ_d [unitless].
    glass_on_mask : bool
        True when the glass is bonded under the mask (parallel to the housing) rather than lying on the die.
    """

    x0_px: float = 319.5
    y0_px: float = 239.5
    gap_mm: float = 1.37
    glass_mm: float = 0.0
    glass_index: float = 1.52
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0
    rotation_deg: float = 0.0
    mirrored: bool = False
    aperture_c: float = 0.0
    aperture_s: float = 0.0
    glass_on_mask: bool = False

    def __post_init__(self) -> None:
        if not self.gap_mm > 0:
            raise ValueError(f"`gap_mm` must be positive, got {self.gap_mm}")
        if not self.glass_mm >= 0:
            raise ValueError(f"`glass_mm` must be >= 0, got {self.glass_mm}")
        if not self.glass_index >= 1:
            raise ValueError(f"`glass_index` must be >= 1, got {self.glass_index}")

    def to_dict(self) -> dict:
        return asdict(self)


def detector_rotation(tilt_x_deg: float, tilt_y_deg: float, rotation_deg: float) -> np.ndarray:
    """Orientation M of the detector in the body frame (columns: detector axes) [unitless, 3×3].

    References
    ----------
    seed 003, §4.4 and eqs. 14–15 (α along azimuth 0°, β along 90°, in-plane rotation φ0).
    """
    a, b, p = np.radians([tilt_x_deg, tilt_y_deg, rotation_deg])
    ry = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), np.sin(b)], [0.0, -np.sin(b), np.cos(b)]])  # R_x(−β)
    rz = np.array([[np.cos(p), -np.sin(p), 0.0], [np.sin(p), np.cos(p), 0.0], [0.0, 0.0, 1.0]])
    return ry @ rx @ rz


def radial_offset_mm(incidence_deg, gap_mm, glass_mm, glass_index) -> np.ndarray:
    """Distance r of the spot from the pinhole's foot for a ray at incidence θ_d [mm].

    .. math:: r = g \\tan θ + t \\tan(\\arcsin(\\sin θ / n))

    References
    ----------
    seed 003, eq. 6 (t = 0); Snell's law for the glass term (research note anchors-sunsensors §2.2).
    """
    th = np.radians(incidence_deg)
    s = np.sin(th)
    return gap_mm * np.tan(th) + glass_mm * s / np.sqrt(glass_index**2 - s**2)


def incidence_from_radial_offset(r_mm, gap_mm, glass_mm, glass_index, *, iterations: int = 8) -> np.ndarray:
    """Invert :func:`radial_offset_mm`: incidence θ_d for a radial distance r [°].

    Newton's method from the paraxial guess θ = arctan(r / (g + t/n)), which lies at or below the root;
    r(θ) is increasing and convex on [0°, 90°), so after the first step the iteration converges
    monotonically from above (8 steps reach machine precision for the sensors here).

    References
    ----------
    seed 003, eq. 6 (t = 0, where the first guess is already exact).
    """
    r = np.asarray(r_mm, dtype=float)
    n2 = glass_index**2
    th = np.arctan(r / (gap_mm + glass_mm / glass_index))
    for _ in range(iterations):
        s, c = np.sin(th), np.cos(th)
        root = np.sqrt(n2 - s**2)
        f = gap_mm * s / c + glass_mm * s / root - r
        df = gap_mm / c**2 + glass_mm * c * n2 / root**3
        th = np.clip(th - f / df, 0.0, np.radians(89.9))
    return np.degrees(th)


def _spot_scale_mm(cos_incidence, gap_mm, glass_mm, glass_index):
    """k(θ) = g / cos θ + t / (n cos θ_g): offset per unit of sin θ, finite at θ = 0 [mm]."""
    sin2 = 1.0 - cos_incidence**2
    cos_glass = np.sqrt(1.0 - sin2 / glass_index**2)
    return gap_mm / cos_incidence + glass_mm / (glass_index * cos_glass)


def _aperture_stretch(dx, dy, build: PinholeBuild):
    """1 + a_c cos 2φ + a_s sin 2φ for the in-plane direction (dx, dy) (1 where it is undefined)."""
    rho2 = dx * dx + dy * dy
    with np.errstate(invalid="ignore", divide="ignore"):
        cos2 = np.where(rho2 > 0, (dx * dx - dy * dy) / rho2, 0.0)
        sin2 = np.where(rho2 > 0, 2.0 * dx * dy / rho2, 0.0)
    return 1.0 + build.aperture_c * cos2 + build.aperture_s * sin2


def spot_from_direction(zenith_deg, azimuth_deg, build: PinholeBuild, pixel_pitch_mm: float):
    """Where the spot lands for a sun direction given in the body frame.

    Parameters
    ----------
    zenith_deg, azimuth_deg : numeric
        Sun direction in the body frame [°].
    build : PinholeBuild
        Build parameters of the sensor.
    pixel_pitch_mm : float
        Pixel pitch [mm].

    Returns
    -------
    x_px, y_px : ndarray
        Spot centre [px].

    References
    ----------
    seed 003, eqs. 6–7 and §4.4; see the module docstring for the model.
    """
    s = direction_vector(zenith_deg, azimuth_deg)
    return spot_from_vectors(s, build, pixel_pitch_mm)


def _die_offset_mask_glass_mm(s: np.ndarray, build: PinholeBuild, m: np.ndarray) -> np.ndarray:
    """Spot offset (dx, dy) in the die frame [mm] for glass bonded under the mask (module docstring).

    The light travels along u = −s. Snell's law in vector form for the plate's normal z (facing the light):
    t = η u + (η cos i − cos t) z with η = 1/n; the ray leaves the plate at depth T along t, then runs along
    u to the die plane m₃·X = −(g + T).
    """
    u = -s
    eta = 1.0 / build.glass_index
    cos_i = s[..., 2]
    cos_t = np.sqrt(1.0 - eta**2 * (1.0 - cos_i**2))
    t = eta * u + (eta * cos_i - cos_t)[..., None] * np.array([0.0, 0.0, 1.0])
    exit_point = t * (build.glass_mm / cos_t)[..., None]
    normal = m[:, 2]
    height = build.gap_mm + build.glass_mm
    lam = (-height - exit_point @ normal) / (u @ normal)
    hit = exit_point + lam[..., None] * u
    return (hit @ m)[..., :2]


def spot_from_vectors(s: np.ndarray, build: PinholeBuild, pixel_pitch_mm: float):
    """:func:`spot_from_direction` for unit vectors s of shape (..., 3) [px]."""
    m = detector_rotation(build.tilt_x_deg, build.tilt_y_deg, build.rotation_deg)
    handed = -1.0 if build.mirrored else 1.0
    if build.glass_on_mask and build.glass_mm > 0:
        d = _die_offset_mask_glass_mm(np.asarray(s, dtype=float), build, m) / pixel_pitch_mm
        if build.aperture_c or build.aperture_s:
            d = d * _aperture_stretch(d[..., 0], d[..., 1], build)[..., None]
        return build.x0_px + d[..., 0], build.y0_px + handed * d[..., 1]
    sd = s @ m  # rows: Mᵀ s
    k = _spot_scale_mm(sd[..., 2], build.gap_mm, build.glass_mm, build.glass_index) / pixel_pitch_mm
    if build.aperture_c or build.aperture_s:
        k = k * _aperture_stretch(sd[..., 0], sd[..., 1], build)
    # the pinhole inverts the image: the spot moves away from the sun's azimuth
    return build.x0_px - k * sd[..., 0], build.y0_px - handed * k * sd[..., 1]


def direction_from_spot(x_px, y_px, build: PinholeBuild, pixel_pitch_mm: float):
    """Sun direction in the body frame for a spot centre: the inverse of :func:`spot_from_direction`.

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray
        [°], azimuth in [0, 360).

    References
    ----------
    seed 003, eqs. 6–7 (ideal pinhole) and eq. 12; see the module docstring for the model.
    """
    if build.glass_on_mask and build.glass_mm > 0:
        return _direction_from_spot_mask_glass(x_px, y_px, build, pixel_pitch_mm)
    handed = -1.0 if build.mirrored else 1.0
    ux = -(np.asarray(x_px, dtype=float) - build.x0_px) * pixel_pitch_mm
    uy = -handed * (np.asarray(y_px, dtype=float) - build.y0_px) * pixel_pitch_mm
    r = np.hypot(ux, uy)
    radial = r / _aperture_stretch(ux, uy, build) if (build.aperture_c or build.aperture_s) else r
    th = np.radians(incidence_from_radial_offset(radial, build.gap_mm, build.glass_mm, build.glass_index))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(r > 0, np.sin(th) / r, 0.0)  # the stretch keeps the direction of (ux, uy)
    sd = np.stack([ux * scale, uy * scale, np.cos(th)], axis=-1)
    m = detector_rotation(build.tilt_x_deg, build.tilt_y_deg, build.rotation_deg)
    return zenith_azimuth_from_vector(sd @ m.T)


def _direction_from_spot_mask_glass(x_px, y_px, build: PinholeBuild, pixel_pitch_mm: float, *, iterations: int = 6):
    """Inverse of the glass-under-mask forward model by Newton's method in the tangent plane.

    The start is the inverse with the same plate lying on the die, which differs by the plate's tilt against
    the die only (a few hundredths of a degree for a 1–2° die tilt); each step solves the 2×2 system of the
    numerical Jacobian of the spot with respect to two tangent directions.
    """
    x = np.asarray(x_px, dtype=float)
    y = np.asarray(y_px, dtype=float)
    on_die = PinholeBuild(**{**build.to_dict(), "glass_on_mask": False})
    s = direction_vector(*direction_from_spot(x, y, on_die, pixel_pitch_mm))
    h = 1e-7
    for _ in range(iterations):
        # tangent basis at s: e1 ⟂ s in the plane of s and z (or x near the pole), e2 = s × e1
        ref = np.where(np.abs(s[..., 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
        e1 = ref - (ref * s).sum(-1, keepdims=True) * s
        e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
        e2 = np.cross(s, e1)
        fx, fy = spot_from_vectors(s, build, pixel_pitch_mm)
        cols = []
        for e in (e1, e2):
            sp = s + h * e
            sp /= np.linalg.norm(sp, axis=-1, keepdims=True)
            gx, gy = spot_from_vectors(sp, build, pixel_pitch_mm)
            cols.append(np.stack([(gx - fx) / h, (gy - fy) / h], axis=-1))
        jac = np.stack(cols, axis=-1)  # (..., 2 spot, 2 tangent)
        rhs = np.stack([x - fx, y - fy], axis=-1)
        step = np.linalg.solve(jac, rhs[..., None])[..., 0]
        s = s + step[..., 0:1] * e1 + step[..., 1:2] * e2
        s /= np.linalg.norm(s, axis=-1, keepdims=True)
    return zenith_azimuth_from_vector(s)
