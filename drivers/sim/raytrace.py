"""The simulated sensor's own physics: an exact ray trace of a pinhole sun sensor on its bench.

The simulator must not share its forward model with the calibration it is used to test, or a test on the
simulated bench measures a round trip instead of a calibration. So this module knows nothing of
``calibration.pinhole``: it traces rays through explicit planes in the body frame with the vector form of
Snell's law, where the calibration's model uses a closed-form radial scale k(θ). The two agree where they
describe the same sensor (thin round hole, glass on the die), which ``tests/drivers/test_raytrace.py``
checks to 1e-6 px; beyond that the ray trace has what the calibration model lacks: a hole of finite
diameter and thickness and a slightly non-round shape, cover glass bonded under the mask instead of on the
die, an extended (0.5°) source and diffraction blur.

Geometry (body frame: +z is the boresight, out of the sensor face; the sun is at
n = (sin θ cos φ, sin θ sin φ, cos θ), its light travels along −n):

- the **pinhole** is the centre of the hole at the mask's mid-plane, at the origin; the mask is the plane
  z = 0 (the housing defines the body frame). A hole of thickness T is a short cylinder from z = −T/2 to
  +T/2; the chief ray is the ray through its centre, which is also the centroid of the beam it lets
  through (the overlap of its two faces is centrally symmetric about that point);
- the **die** has the orientation M = R_y(α) · R_x(−β) · R_z(ψ) (columns: the detector's x and y axes and
  its normal N in the body frame; α tips the normal toward azimuth 0°, β toward 90°, ψ turns it in its
  plane — the convention of seed 003 eqs. 14–15 as written in ``calibration/pinhole.py``), and lies at
  the perpendicular distance h = gap + glass from the pinhole; (x0, y0) is the foot of that perpendicular
  [px]. Pixel x runs along M's first column, y along its second (against it for a mirrored read-out),
  origin at the centre of pixel (0, 0);
- the **glass** (thickness t, index n) lies either on the die, parallel to it (``"die"``, a package cover
  glass: its top at N·X = −gap), or bonded under the mask, parallel to the housing (``"mask"``: from
  z = −T/2 to z = −T/2 − t), which tilts it against a tilted die. Everything else is air; the gap is the
  air path along the normal from the pinhole's mid-plane, so at zero tilt both placements give the same
  spot.

Because every interface is a plane, all rays of one direction are refracted alike, so the map from the
mask plane to the die is affine for a given direction: the spot is the hole's shadow mapped by it, blurred
by the image of the extended source (a disc of directions around n, mapped through the trace's
Jacobian) and by diffraction.

References
----------
seed 003, eqs. 6–7 (ideal pinhole: θ = arctan(r / L)), eq. 8 (offset zenith axis), eqs. 14–15 (tilt
convention); research note anchors-sunsensors §2.2 (glass between pinhole and pixels: r = L_air tan θ +
t tan θ_g); Snell's law in vector form, t = η i + (η cos θ_i − cos θ_t) n (e.g. Glassner, *An
Introduction to Ray Tracing*, 1989, §6.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import cv2
import numpy as np

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR

GLASS_POSITIONS = ("die", "mask")
AXIS_ORDERS = ("azimuth-on-zenith", "zenith-on-azimuth")


@dataclass(frozen=True)
class SensorOptics:
    """The true optics of a pinhole sun sensor, in physical terms.

    Attributes
    ----------
    x0_px, y0_px : float
        Foot of the perpendicular from the pinhole (its mid-plane centre) on the die [px].
    gap_mm : float
        Air path from the pinhole's mid-plane to the glass along the normal (to the die without glass) [mm].
    glass_mm : float
        Thickness of the plane-parallel glass between pinhole and pixels [mm]; 0 for none.
    glass_index : float
        Refractive index of that glass [unitless].
    tilt_x_deg, tilt_y_deg : float
        Die tilt α toward body azimuth 0° and β toward azimuth 90° [°].
    rotation_deg : float
        In-plane rotation ψ of the die [°].
    mirrored : bool
        True when the detector rows run against the die's y axis (a mirrored read-out).
    glass_position : {"die", "mask"}
        Glass on the die, parallel to it, or bonded under the mask, parallel to the housing.
    pixel_pitch_mm : float
        Pixel pitch [mm].
    width_px, height_px : int
        Detector size [px].
    hole_diameter_mm : float
        Pinhole diameter [mm] (of a circle of the same area when the hole is not round).
    mask_thickness_mm : float
        Thickness of the mask, the length of the hole [mm]; 0 for a thin mask.
    hole_axis_ratio : float
        Ratio of the hole's long to short axis [unitless]; 1 for a round hole.
    hole_axis_deg : float
        Direction of the long axis in the mask plane, from body +x toward +y [°].
    wavelength_mm : float
        Effective wavelength of the light the pixels see, for the diffraction blur [mm]; 0 for none.
    """

    x0_px: float = DEFAULT_SENSOR.centre_px[0]
    y0_px: float = DEFAULT_SENSOR.centre_px[1]
    gap_mm: float = DEFAULT_SENSOR.pinhole_height_mm
    glass_mm: float = 0.0
    glass_index: float = 1.52
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0
    rotation_deg: float = 0.0
    mirrored: bool = False
    glass_position: str = "die"
    pixel_pitch_mm: float = DEFAULT_SENSOR.pixel_pitch_mm
    width_px: int = DEFAULT_SENSOR.width_px
    height_px: int = DEFAULT_SENSOR.height_px
    hole_diameter_mm: float = DEFAULT_SENSOR.hole_diameter_mm
    mask_thickness_mm: float = 0.0
    hole_axis_ratio: float = 1.0
    hole_axis_deg: float = 0.0
    wavelength_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.glass_position not in GLASS_POSITIONS:
            raise ValueError(f"`glass_position` must be one of {GLASS_POSITIONS}, got {self.glass_position!r}")
        for name in ("gap_mm", "pixel_pitch_mm", "hole_diameter_mm", "hole_axis_ratio"):
            if not getattr(self, name) > 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        for name in ("glass_mm", "mask_thickness_mm", "wavelength_mm"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"`{name}` must be >= 0, got {getattr(self, name)}")
        if not self.glass_index >= 1:
            raise ValueError(f"`glass_index` must be >= 1, got {self.glass_index}")
        if not self.gap_mm > self.mask_thickness_mm / 2:
            raise ValueError(f"`gap_mm` ({self.gap_mm}) must exceed half the mask thickness: the hole ends in air")
        if self.width_px <= 0 or self.height_px <= 0:
            raise ValueError(f"detector size must be positive, got {self.width_px}×{self.height_px}")

    @property
    def height_mm(self) -> float:
        """Perpendicular distance h from the pinhole to the die [mm]."""
        return self.gap_mm + self.glass_mm

    # The calibration's pinhole model reads the next three, so these optics can stand for the nearest such
    # model (duck-typed: this module does not import it). A non-round hole changes the shape of the spot, not
    # where its centroid lands (the shadow stays centrally symmetric), so that model's stretch is zero.
    @property
    def glass_on_mask(self) -> bool:
        return self.glass_position == "mask"

    @property
    def aperture_c(self) -> float:
        return 0.0

    @property
    def aperture_s(self) -> float:
        return 0.0


# -- vector helpers ---------------------------------------------------------------------------------------
def _rotation(axis: int, angle_deg) -> np.ndarray:
    """Right-handed rotation matrices about body axis 0/1/2 by `angle_deg`, stacked as (..., 3, 3)."""
    a = np.radians(np.asarray(angle_deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane the rotation turns
    out = np.zeros(a.shape + (3, 3))
    out[..., axis, axis] = 1.0
    out[..., i, i] = out[..., j, j] = c
    out[..., i, j], out[..., j, i] = -s, s
    return out


def tilt_rotation(tilt_x_deg, tilt_y_deg, rotation_deg=0.0) -> np.ndarray:
    """R_y(α) · R_x(−β) · R_z(ψ): a frame tipped toward azimuth 0° by α, toward 90° by β, turned by ψ.

    Columns are the tilted frame's axes in the body frame [unitless, (..., 3, 3)].

    References
    ----------
    seed 003, eqs. 14–15 and §4.4 (α along azimuth 0°, β along 90°, in-plane rotation).
    """
    return _rotation(1, tilt_x_deg) @ _rotation(0, -np.asarray(tilt_y_deg, dtype=float)) @ _rotation(2, rotation_deg)


def sun_vector(zenith_deg, azimuth_deg) -> np.ndarray:
    """n = (sin θ cos φ, sin θ sin φ, cos θ), shape (..., 3) [unitless] (seed 003 eq. 12)."""
    th = np.radians(np.asarray(zenith_deg, dtype=float))
    ph = np.radians(np.asarray(azimuth_deg, dtype=float))
    return np.stack(np.broadcast_arrays(np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)), axis=-1)


def _zenith_azimuth(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zenith from +z and azimuth in [0, 360) of vectors (..., 3) [°]."""
    zenith = np.degrees(np.arctan2(np.hypot(v[..., 0], v[..., 1]), v[..., 2]))
    return zenith, np.mod(np.degrees(np.arctan2(v[..., 1], v[..., 0])), 360.0)


def _dot(a, b):
    return np.sum(a * b, axis=-1, keepdims=True)


def refract(direction, normal, eta) -> np.ndarray:
    """Direction of a ray after a plane interface (vector Snell's law).

    .. math:: t = η\\,i + (η \\cos θ_i − \\cos θ_t)\\,\\hat n, \\qquad
              \\cos θ_t = \\sqrt{1 − η^2 (1 − \\cos^2 θ_i)}

    Parameters
    ----------
    direction : array_like, shape (..., 3)
        Unit direction i of the incident ray.
    normal : array_like, shape (3,) or (..., 3)
        Unit normal of the interface, either orientation (it is turned to face the incoming ray).
    eta : float
        n₁ / n₂, the index of the medium the ray leaves over the one it enters [unitless].

    Returns
    -------
    ndarray, shape (..., 3)
        Unit direction of the refracted ray. Total internal reflection raises ValueError.

    References
    ----------
    Snell's law, n₁ sin θ_i = n₂ sin θ_t, in vector form.
    """
    i = np.asarray(direction, dtype=float)
    n = np.broadcast_to(np.asarray(normal, dtype=float), i.shape)
    cos_i = -_dot(i, n)
    n = np.where(cos_i < 0, -n, n)  # the normal must face the incoming ray
    cos_i = np.abs(cos_i)
    sin2_t = eta**2 * (1.0 - cos_i**2)
    if np.any(sin2_t > 1.0):
        raise ValueError("total internal reflection: the ray does not leave the medium")
    return eta * i + (eta * cos_i - np.sqrt(1.0 - sin2_t)) * n


def _to_plane(origin, direction, normal, offset):
    """Where rays origin + λ·direction meet the plane normal·X = offset."""
    lam = (offset - _dot(origin, normal)) / _dot(direction, normal)
    return origin + lam * direction


@lru_cache(maxsize=64)
def _die_frame(optics: SensorOptics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Image x axis, image y axis, die normal N (toward the pinhole) and the pinhole's foot F, body frame."""
    m = tilt_rotation(optics.tilt_x_deg, optics.tilt_y_deg, optics.rotation_deg)
    normal = m[:, 2]
    y_axis = -m[:, 1] if optics.mirrored else m[:, 1]
    return m[:, 0], y_axis, normal, -optics.height_mm * normal


# -- the ray trace ----------------------------------------------------------------------------------------
def trace_rays(origin_mm, sun, optics: SensorOptics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Trace rays of sunlight from points of the mask's mid-plane to the die.

    Parameters
    ----------
    origin_mm : array_like, shape (..., 3)
        Where each ray crosses the mask's mid-plane (z = 0), body frame [mm]; (0, 0, 0) is the chief ray.
    sun : array_like, shape (..., 3)
        Unit sun direction n in the body frame (the light travels along −n).
    optics : SensorOptics

    Returns
    -------
    x_px, y_px : ndarray
        Where the rays land on the die [px].
    final : ndarray, shape (..., 3)
        Direction of each ray as it reaches the die [unitless].

    References
    ----------
    Snell's law (:func:`refract`) at each glass face; plane intersections. See the module docstring.
    """
    x_axis, y_axis, normal, foot = _die_frame(optics)
    sun = np.asarray(sun, dtype=float)
    point = np.broadcast_to(np.asarray(origin_mm, dtype=float), np.broadcast_shapes(np.shape(origin_mm), sun.shape))
    ray = -sun
    t, n = optics.glass_mm, optics.glass_index
    if t > 0 and optics.glass_position == "die":
        point = _to_plane(point, ray, normal, -optics.gap_mm)
        ray = refract(ray, normal, 1.0 / n)  # into the cover glass; the die is its lower face
    elif t > 0:
        z = np.array([0.0, 0.0, 1.0])
        top = -optics.mask_thickness_mm / 2  # the glass is bonded to the mask's underside
        point = _to_plane(point, ray, z, top)
        ray = refract(ray, z, 1.0 / n)
        point = _to_plane(point, ray, z, top - t)
        ray = refract(ray, z, n)  # out into the air gap above the tilted die
    point = _to_plane(point, ray, normal, -optics.height_mm)
    offset = point - foot
    return (optics.x0_px + offset @ x_axis / optics.pixel_pitch_mm,
            optics.y0_px + offset @ y_axis / optics.pixel_pitch_mm, ray)


def trace_chief_ray(zenith_deg, azimuth_deg, optics: SensorOptics) -> tuple[np.ndarray, np.ndarray]:
    """Where the chief ray (through the pinhole's centre) from a sun direction lands on the die.

    Parameters
    ----------
    zenith_deg, azimuth_deg : array_like
        Sun direction in the body frame [°], zenith below 90°.
    optics : SensorOptics

    Returns
    -------
    x_px, y_px : ndarray
        Spot centre [px]: x to the right (columns), y down (rows), origin at the centre of pixel (0, 0).

    References
    ----------
    seed 003 eqs. 6–7 (the ideal pinhole this reduces to without glass or tilt); research note
    anchors-sunsensors §2.2 and Snell's law (the glass).
    """
    x, y, _ = trace_rays(np.zeros(3), sun_vector(zenith_deg, azimuth_deg), optics)
    return x, y


def die_incidence_deg(zenith_deg, azimuth_deg, optics: SensorOptics) -> np.ndarray:
    """Angle between the incoming sunlight and the die's normal, outside any glass [°]."""
    _, _, normal, _ = _die_frame(optics)
    cos = sun_vector(zenith_deg, azimuth_deg) @ normal
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def trace_bench_frames(zenith_deg, azimuth_deg, optics: SensorOptics, *, noise_px: float,
                       rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Spot centres a sensor of these optics gives at bench directions, with Gaussian centroid noise.

    The centre is the chief ray's (the spot's centroid within ~0.01 px for a realistic hole; see
    :func:`spot_patch`); spots off the detector are returned as they are, for the caller to drop.

    Parameters
    ----------
    zenith_deg, azimuth_deg : array_like
        True sun directions in the body frame [°].
    optics : SensorOptics
    noise_px : float
        Standard deviation of the centroid noise on each axis [px].
    rng : numpy.random.Generator

    Returns
    -------
    x_px, y_px : ndarray
        Noisy spot centres [px].
    """
    x, y = trace_chief_ray(zenith_deg, azimuth_deg, optics)
    return x + rng.normal(0.0, noise_px, np.shape(x)), y + rng.normal(0.0, noise_px, np.shape(y))


# -- the spot ---------------------------------------------------------------------------------------------
class SpotPatch(NamedTuple):
    """A rendered spot: `image[i, j]` is pixel (x_origin_px + j, y_origin_px + i).

    Attributes
    ----------
    image : ndarray (float32)
        Fraction of the source's disc each pixel sees through the hole, averaged over the pixel and blurred by
        diffraction [unitless, 0–1].
    x_origin_px, y_origin_px : int
        Pixel of `image[0, 0]`.
    chief_x_px, chief_y_px : float
        Where the chief ray lands [px].
    incidence_deg : float
        Angle of the light on the die, outside the glass [°].
    """

    image: np.ndarray
    x_origin_px: int
    y_origin_px: int
    chief_x_px: float
    chief_y_px: float
    incidence_deg: float


@lru_cache(maxsize=64)
def _hole_quadric(optics: SensorOptics) -> np.ndarray:
    """Q with pᵀ Q p ≤ 1 inside the hole, p in the mask plane [mm⁻²] (an ellipse of the round hole's area)."""
    radius = optics.hole_diameter_mm / 2
    a, b = radius * np.sqrt(optics.hole_axis_ratio), radius / np.sqrt(optics.hole_axis_ratio)
    c, s = np.cos(np.radians(optics.hole_axis_deg)), np.sin(np.radians(optics.hole_axis_deg))
    r = np.array([[c, -s], [s, c]])
    return r @ np.diag([1 / a**2, 1 / b**2]) @ r.T


def _inv2(m: np.ndarray) -> np.ndarray:
    return np.array([[m[1, 1], -m[0, 1]], [-m[1, 0], m[0, 0]]]) / (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0])


def _ellipse_coverage(dx, dy, linear, shift, quad, supersample: int) -> np.ndarray:
    """Fraction of each sub-pixel (side 1/`supersample` px, centred at offsets dx, dy [px]) inside the ellipse
    uᵀ Q u ≤ 1, u = linear · (dx, dy) + shift; `shift` may stack several ellipses on a leading axis.

    The edge is taken as straight across a sub-pixel, at the signed distance (ρ − 1) / |∇ρ|, ρ = √(uᵀQu)
    (exact for a circle), and the covered fraction of the sub-pixel computed exactly for such an edge; this
    antialiasing keeps the sampled shape's area and centroid on the true ones.
    """
    ux = linear[0, 0] * dx + linear[0, 1] * dy + shift[..., 0, None, None]
    uy = linear[1, 0] * dx + linear[1, 1] * dy + shift[..., 1, None, None]
    qx, qy = quad[0, 0] * ux + quad[0, 1] * uy, quad[1, 0] * ux + quad[1, 1] * uy  # Q u
    rho = np.sqrt(ux * qx + uy * qy)
    gx, gy = np.abs(linear[0, 0] * qx + linear[1, 0] * qy), np.abs(linear[0, 1] * qx + linear[1, 1] * qy)
    grad = np.maximum(np.hypot(gx, gy), np.float32(1e-12))  # |Lᵀ Q u| = ρ |∇ρ|
    t = -(rho - 1) * rho / grad * np.float32(supersample)  # signed distance to the edge, inside > 0 [sub-px]
    # the fraction of a unit square on the inner side of a straight edge: the CDF of the square's projection
    # on the edge's normal, a trapezoid of widths a = |n_x|, b = |n_y| (b floored: the formula is 0/0 at 0)
    nx, ny = gx / grad, gy / grad
    a = np.maximum(np.maximum(nx, ny), np.float32(0.7))  # ≥ 1/√2 for a unit normal; the floor is for ∇ρ = 0
    b = np.maximum(np.minimum(nx, ny), np.float32(0.02))
    half_sum, half_diff = (a + b) / 2, (a - b) / 2
    t = np.clip(t, -half_sum, half_sum)  # beyond, the square is all out or all in (and float32 keeps its digits)
    ramp2 = lambda v: np.square(np.maximum(v, 0))  # noqa: E731
    cdf = (ramp2(t + half_sum) - ramp2(t + half_diff) - ramp2(t - half_diff) + ramp2(t - half_sum)) / (2 * a * b)
    return np.clip(cdf, 0, 1)


def spot_patch(zenith_deg: float, azimuth_deg: float, optics: SensorOptics, *,
               source_diameter_deg: float = DEFAULT_BENCH.source_diameter_deg, supersample: int = 4,
               patch_px: int | None = None, occlusion: tuple[float, float, float] | None = None) -> SpotPatch:
    """The spot on a patch of pixels: the hole's shadow cast by a disc source through the glass.

    A die point is lit by a direction of the source when the ray through it, traced back up, passes both
    faces of the hole. For one direction the mid-plane → die map is affine (planar interfaces), so the
    shadow is computed exactly, antialiased on a supersampled grid; the other directions of the disc shift
    it by the trace's Jacobian (linear over 0.5°), which is a convolution with the source's image, an
    ellipse stretched radially at oblique incidence. Diffraction adds a Gaussian edge blur of
    σ = 0.33 √(λ z) (the 10–90 % width of a Fresnel knife edge, z the reduced path to the die) — an
    approximation for the mid-range Fresnel numbers (~2) of such sensors. Every blur is centrally
    symmetric, so none moves the centroid; the thick hole's vignetting, weighted across the source, moves
    it by about a thousandth of a pixel at 60° (10–30 µm masks).

    Parameters
    ----------
    zenith_deg, azimuth_deg : float
        Sun direction (the source's centre) in the body frame [°], zenith below 90°.
    optics : SensorOptics
    source_diameter_deg : float
        Angular diameter of the source [°].
    supersample : int
        Samples per pixel along each axis (the antialiased spot's centroid is within ~0.002 px of the exact
        one at 2, ~0.0005 px at 4).
    patch_px : int, optional
        Side of the patch [px]; by default large enough for the spot and its blur.
    occlusion : (edge_offset_deg, edge_angle_deg, transmission), optional
        A cloud's straight edge across the source (the real Sun in the field, :class:`drivers.sim.sky.CloudState`):
        the part of the disc whose offset from the centre along `edge_angle_deg` (0 along the body's +x as seen
        at the source, 90 along s × that) exceeds `edge_offset_deg` passes only `transmission` of its light.
        The patch then holds the visible fraction of the disc (less than 1 at the plateau).

    Returns
    -------
    SpotPatch

    References
    ----------
    Snell's law and the ray trace of :func:`trace_rays`; Born & Wolf, *Principles of Optics*, §8.7
    (Fresnel diffraction at a straight edge) for the blur width.
    """
    th, ph = np.radians(zenith_deg), np.radians(azimuth_deg)
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    sun = np.array([st * cp, st * sp, ct])
    e_zenith, e_azimuth = np.array([ct * cp, ct * sp, -st]), np.array([-sp, cp, 0.0])
    eps, step = 1e-6, 0.01  # rad, mm: the maps are affine/smooth, so any small step will do
    origins = np.zeros((7, 3))
    origins[1, 0] = origins[2, 1] = step
    suns = np.array([sun, sun, sun, sun + eps * e_zenith, sun - eps * e_zenith,
                     sun + eps * e_azimuth, sun - eps * e_azimuth])
    suns /= np.sqrt(1 + eps**2)  # e_zenith, e_azimuth are unit and orthogonal to sun
    xs, ys, _ = trace_rays(origins, suns, optics)
    cx, cy = float(xs[0]), float(ys[0])
    to_die = np.array([[xs[1] - cx, xs[2] - cx], [ys[1] - cy, ys[2] - cy]]) / step  # px per mm of mid-plane
    jac = np.array([[xs[3] - xs[4], xs[5] - xs[6]], [ys[3] - ys[4], ys[5] - ys[6]]]) / (2 * eps)  # px per rad
    s = supersample

    # the source's image (its disc of directions mapped by the Jacobian) and the diffraction blur
    radius_rad = np.radians(source_diameter_deg / 2)
    cos_die = max(float(sun @ _die_frame(optics)[2]), 1e-6)
    path_mm = (optics.gap_mm + optics.glass_mm / optics.glass_index) / cos_die  # glass counts as its reduced depth
    sigma_px = 0.33 * np.sqrt(optics.wavelength_mm * path_mm) / optics.pixel_pitch_mm
    source_px = radius_rad * np.sqrt((jac * jac).sum())  # px, the image's half-length (Frobenius ≥ spectral norm)
    k = int(np.ceil(source_px * s)) + 1
    grid = (np.arange(-k, k + 1, dtype=np.float32) / s)
    to_angle = _inv2(jac).astype(np.float32)  # px → rad along (e_zenith, e_azimuth)
    kernel = _ellipse_coverage(grid[None, :], grid[:, None], to_angle, np.zeros(2, np.float32),
                               np.eye(2, dtype=np.float32) / np.float32(radius_rad**2), s)
    kernel /= kernel.sum()
    if occlusion is not None:
        kernel *= _cloud_mask(grid, to_angle, sun, e_zenith, e_azimuth, *occlusion)
    reach = source_px + 3 * sigma_px

    # the shadow of the hole's faces for the source's centre: a die point is lit when its ray passes both
    half_t = optics.mask_thickness_mm / 2 * sun[:2] / sun[2]  # the faces seen along the ray, from mid-plane
    faces = np.array([half_t, -half_t] if optics.mask_thickness_mm > 0 else [half_t], dtype=np.float32)
    shadow_px = np.sqrt((to_die * to_die).sum()) * optics.hole_diameter_mm / 2 * np.sqrt(optics.hole_axis_ratio)
    if patch_px is None:
        patch_px = max(16, int(8 * np.ceil((2 * (shadow_px + reach) + 4) / 8)))
    x0, y0 = int(np.floor(cx)) - patch_px // 2, int(np.floor(cy)) - patch_px // 2
    sub = (np.arange(patch_px * s) + 0.5) / s - 0.5  # pixel i spans i ± 0.5
    dx, dy = (x0 + sub - cx).astype(np.float32)[None, :], (y0 + sub - cy).astype(np.float32)[:, None]
    lit = _ellipse_coverage(dx, dy, _inv2(to_die).astype(np.float32), faces,
                            _hole_quadric(optics).astype(np.float32), s).min(axis=0)
    image = cv2.filter2D(lit, -1, kernel, borderType=cv2.BORDER_CONSTANT)
    if sigma_px > 0:  # separable, so after the (small) source kernel rather than inside it
        image = cv2.GaussianBlur(image, (0, 0), sigma_px * s, borderType=cv2.BORDER_CONSTANT)
    image = cv2.resize(image, (patch_px, patch_px), interpolation=cv2.INTER_AREA)  # the mean of each pixel
    return SpotPatch(image, x0, y0, cx, cy, float(np.degrees(np.arccos(min(cos_die, 1.0)))))


def _cloud_mask(grid, to_angle, sun, e_zenith, e_azimuth, edge_offset_deg: float, edge_angle_deg: float,
                transmission: float) -> np.ndarray:
    """Transmission (1 clear, `transmission` behind the cloud) over the source kernel's grid [px offsets]."""
    x_axis = np.array([1.0, 0.0, 0.0])
    e1 = x_axis - (x_axis @ sun) * sun
    if np.linalg.norm(e1) < 1e-9:  # the source along +x: any perpendicular will do
        e1 = np.array([0.0, 1.0, 0.0]) - sun[1] * sun
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(sun, e1)
    a = np.radians(edge_angle_deg)
    towards = np.cos(a) * e1 + np.sin(a) * e2  # unit, towards the covered side
    along = to_angle.T @ np.array([towards @ e_zenith, towards @ e_azimuth])  # rad of offset per px of (dx, dy)
    # cv2.filter2D correlates: the kernel's weight at offset d moves the spot by −d, so it is the source at −d
    offset = -(along[0] * grid[None, :] + along[1] * grid[:, None])
    return np.where(offset > np.radians(edge_offset_deg), np.float32(transmission), np.float32(1.0))


def spot_moments(patch: SpotPatch) -> tuple[float, float, np.ndarray]:
    """Intensity-weighted centroid [px] and covariance [px²] of a rendered spot (no threshold, no noise)."""
    img = patch.image.astype(float)
    rows, cols = np.indices(img.shape)
    total = img.sum()
    x = patch.x_origin_px + (img * cols).sum() / total
    y = patch.y_origin_px + (img * rows).sum() / total
    dx, dy = patch.x_origin_px + cols - x, patch.y_origin_px + rows - y
    cov = np.array([[(img * dx * dx).sum(), (img * dx * dy).sum()],
                    [(img * dx * dy).sum(), (img * dy * dy).sum()]]) / total
    return float(x), float(y), cov


# -- the bench --------------------------------------------------------------------------------------------
def stage_pose(stage_azimuth_deg, stage_zenith_deg, *, lever_arm_mm: float,
               axis_order: str = "azimuth-on-zenith", mount_tilt_x_deg: float = 0.0,
               mount_tilt_y_deg: float = 0.0, azimuth_sign: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Orientation R (columns: body axes in the lab, (..., 3, 3)) and position P [mm] of the sensor.

    Lab frame: the table's axes meet at the origin; at zero stage angles the sensor sits `lever_arm_mm` out
    along +z facing the source, which lies further along +z. ``azimuth-on-zenith`` (seed 003): the zenith
    stage turns about lab y and carries the azimuth stage, which turns the sensor about its boresight.
    ``zenith-on-azimuth`` (an alt-az mount, seed 002): the azimuth axis is the lab y axis and carries the altitude
    axis (x). The mount tilt is a rigid misalignment of the sensor on its fixture, in the convention of
    :func:`tilt_rotation` (about the sensor, so it leaves the position alone). Angles are true ones.
    """
    if axis_order not in AXIS_ORDERS:
        raise ValueError(f"`axis_order` must be one of {AXIS_ORDERS}, got {axis_order!r}")
    az = azimuth_sign * np.asarray(stage_azimuth_deg, dtype=float)
    omega = np.asarray(stage_zenith_deg, dtype=float)
    az, omega = np.broadcast_arrays(az, omega)
    arm = np.array([0.0, 0.0, lever_arm_mm])
    if axis_order == "azimuth-on-zenith":
        zenith_stage = _rotation(1, -omega)
        rotation = zenith_stage @ _rotation(2, -az)
        position = zenith_stage @ arm
    else:
        rotation = _rotation(1, -az) @ _rotation(0, omega)
        position = rotation @ arm
    if mount_tilt_x_deg or mount_tilt_y_deg:
        rotation = rotation @ tilt_rotation(mount_tilt_x_deg, mount_tilt_y_deg)
    return rotation, position


def body_direction_from_stage(stage_azimuth_deg, stage_zenith_deg, *, lever_arm_mm: float,
                              source_distance_mm: float, axis_order: str = "azimuth-on-zenith",
                              azimuth_zero_deg: float = 0.0, zenith_zero_deg: float = 0.0,
                              mount_tilt_x_deg: float = 0.0, mount_tilt_y_deg: float = 0.0,
                              azimuth_sign: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The true sun direction in the sensor's body frame from the table's stage angles.

    The direction from the sensor to the centre of the source, expressed in the body frame, along the chain
    of :func:`stage_pose`. For seed 003's axis order, with no offsets or tilt, its zenith is eq. 8's
    incidence angle (|θ|; a negative Ω puts the sun at the opposite azimuth) and its azimuth the stage's.

    Parameters
    ----------
    stage_azimuth_deg, stage_zenith_deg : array_like
        What the azimuth stage and the zenith stage (Ω) read [°].
    lever_arm_mm : float
        Zenith axis to sensor, d of eq. 8 [mm].
    source_distance_mm : float
        Sensor (at Ω = 0) to source, L of eq. 8 [mm].
    axis_order : {"azimuth-on-zenith", "zenith-on-azimuth"}
    azimuth_zero_deg, zenith_zero_deg : float
        The stages' zero offsets: the true angle where a stage reads zero, so that
        true = reading + zero (the ``home_switch_true_deg`` of a simulated axis homed to read 0) [°].
    mount_tilt_x_deg, mount_tilt_y_deg : float
        Misalignment of the sensor on its fixture: its boresight tipped toward body azimuth 0° and 90° [°].
    azimuth_sign : float
        +1 when a positive azimuth-stage angle is a positive sun azimuth in the body frame, −1 otherwise.

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray
        [°], azimuth in [0, 360) (0 at the boresight).

    References
    ----------
    seed 003, eq. 8 and Fig. 4.5 (offset zenith axis, finite source distance), eq. 12 (direction vector).
    """
    rotation, position = stage_pose(np.asarray(stage_azimuth_deg, dtype=float) + azimuth_zero_deg,
                                    np.asarray(stage_zenith_deg, dtype=float) + zenith_zero_deg,
                                    lever_arm_mm=lever_arm_mm, axis_order=axis_order,
                                    mount_tilt_x_deg=mount_tilt_x_deg, mount_tilt_y_deg=mount_tilt_y_deg,
                                    azimuth_sign=azimuth_sign)
    to_source = np.array([0.0, 0.0, lever_arm_mm + source_distance_mm]) - position
    body = np.einsum("...ji,...j->...i", rotation, to_source)  # Rᵀ · (source − P)
    return _zenith_azimuth(body)
