"""What the simulated camera sun sensor (seed 001) sees: a webcam frame of the solar disc.

This is the simulator's own physics. It shares no code with the calibration's camera model
(``calibration.camera``, OpenCV's pinhole + Brown–Conrady polynomial in r²): here the lens maps the field
angle θ to an image height with a polynomial in θ, the detector plane is tilted, and the camera sits on its
fixture with a small rotation. A calibration tested on these frames therefore measures how well OpenCV's
model represents a real lens, not a round trip.

Geometry
--------
- **Mount.** The camera frame (OpenCV's: x right, y down, z along the optical axis) is turned against the
  sensor body frame (+z boresight) by M = R_y(α) · R_x(−β) · R_z(ψ): the optical axis tipped toward body
  +x by α (``mount_tilt_x_deg``), toward +y by β (``mount_tilt_y_deg``), the camera turned about it by ψ
  (``mount_twist_deg``). M's columns are the camera axes in the body frame; cam = Mᵀ · body.
- **Lens.** A ray at field angle θ (from the optical axis) and azimuth φ leaves the exit pupil toward the
  point (u, v) = r(θ) (cos φ, sin φ) of the nominal focal plane at distance f (all in pixels), with

  .. math:: r(θ) = f \\tan θ \\, (1 + a θ^2 + b θ^4)

  (θ in radians): a barrel distortion of a few per cent at the corners, in powers of θ rather than of
  tan θ as in OpenCV's model.
- **Detector.** Its plane passes through the foot F = (0, 0, f) of the optical axis, its normal tipped by
  the detector tilt (same convention as the mount) — a fraction of a degree, which gives the decentring
  (tangential) distortion of a real, imperfectly assembled module. The pixel of F is the principal point
  (``principal_x_px``, ``principal_y_px``), a few pixels off the frame's centre. Pixel x runs along the
  tilted plane's first axis, y along its second; pixel (0, 0) is centred on (0, 0) (project convention).

Radiometry
----------
The source (the Sun, 0.533°, or a bench simulator's own ~0.5° disc) has the limb darkening
I(μ) = 1 − u (1 − μ), μ = cos of the angle on the solar surface (u = 0.6). A pixel collects
L · cos θ · dΩ/dA (the entrance pupil seen obliquely and the lens's solid angle per image area, which for a
distortion-free lens is the cos⁴ law), normalised to 1 on the axis; `signal_dn_per_ms` is the DN of the
clear disc's centre on the axis per ms of exposure at unit irradiance. Haze (``CloudState.transmission``)
dims the disc; an opaque or thin cloud's straight edge, defined in the tangent plane at the Sun exactly as
in :class:`drivers.sim.sky.CloudState` (e1 = x̂ − (x̂·s)s normalised in the body frame, e2 = s × e1),
covers one side with the cloud's own transmission; the cloud's aureole is a broad halo, a fraction
``aureole`` of the clear disc's flux, with the profile (1 + (d/w)²)^(−3/2), w = 1°, cut at 4°.

The disc and the cloud edge are sampled on a supersampled grid (antialiased edges: each sample's
coverage ramps over one sample), blurred by the lens's Gaussian PSF and averaged over each pixel, which
puts the noiseless weighted centroid of a clear disc within 0.01 px of :meth:`CameraRenderer.true_pixel`
(the centre's image) over the whole frame.

Detector: shot noise (Poisson in electrons), read noise, a bias (black level), 8-bit output clipped at
255; charge beyond the full well blooms along the column. For speed the background is taken from a small
pool of noise frames drawn once; only the spot's neighbourhood is drawn per frame, and its noiseless image
is kept while the sun and the clouds stay put. A 640×480 frame takes ~0.1 ms at a repeated position, ~2 ms
at a new one and ~5 ms with an aureole (which spreads over ±4°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .sky import CLEAR, SUN_DIAMETER_DEG, CloudState

LIMB_DARKENING_U = 0.6
"""Linear limb-darkening coefficient u of the visible solar disc [unitless]."""
AUREOLE_WIDTH_DEG = 1.0
"""Half width w of the aureole's profile (1 + (d/w)²)^(−3/2) [°]."""
AUREOLE_EXTENT_DEG = 4.0
"""The aureole is cut at this distance from the Sun's centre [°]."""
MAX_FIELD_DEG = 55.0
"""Largest field angle the lens passes [°]; beyond it nothing reaches the detector."""


def _rotation(axis: int, angle_deg: float) -> np.ndarray:
    """Right-handed rotation matrix about axis 0/1/2 by `angle_deg`."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.eye(3)
    out[i, i] = out[j, j] = c
    out[i, j], out[j, i] = -s, s
    return out


def _tipped(toward_x_deg: float, toward_y_deg: float, twist_deg: float = 0.0) -> np.ndarray:
    """R_y(α) · R_x(−β) · R_z(ψ): columns of a frame whose z axis is tipped toward +x by α, +y by β."""
    return _rotation(1, toward_x_deg) @ _rotation(0, -toward_y_deg) @ _rotation(2, twist_deg)


@dataclass(frozen=True)
class CameraLens:
    """The true optics of the simulated camera and its mounting.

    Attributes
    ----------
    focal_mm : float
        Focal length f [mm].
    pixel_pitch_mm : float
        Pixel pitch [mm] (square pixels).
    distortion_a, distortion_b : float
        Coefficients of r(θ) = f tan θ (1 + a θ² + b θ⁴), θ in radians [unitless].
    principal_x_px, principal_y_px : float
        Pixel where the optical axis meets the detector [px].
    detector_tilt_x_deg, detector_tilt_y_deg : float
        Detector normal tipped toward the camera's +x and +y axes [°].
    mount_tilt_x_deg, mount_tilt_y_deg : float
        Optical axis tipped toward the body's +x and +y axes [°].
    mount_twist_deg : float
        Camera turned about its optical axis [°].
    psf_sigma_px : float
        Gaussian blur of the lens (one sigma) [px].
    """

    focal_mm: float = 2.4
    pixel_pitch_mm: float = 0.003
    distortion_a: float = -0.14
    distortion_b: float = 0.03
    principal_x_px: float = 322.6
    principal_y_px: float = 237.3
    detector_tilt_x_deg: float = 0.35
    detector_tilt_y_deg: float = -0.25
    mount_tilt_x_deg: float = 0.45
    mount_tilt_y_deg: float = -0.3
    mount_twist_deg: float = 0.6
    psf_sigma_px: float = 0.5

    def __post_init__(self) -> None:
        for name in ("focal_mm", "pixel_pitch_mm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        if not self.psf_sigma_px >= 0:
            raise ValueError(f"`psf_sigma_px` must be >= 0, got {self.psf_sigma_px}")
        theta = np.radians(np.linspace(0.0, MAX_FIELD_DEG, 200))
        if not np.all(_radius_slope(theta, 1.0, self.distortion_a, self.distortion_b) > 0):
            raise ValueError("the lens's r(θ) must grow with θ over the field (distortion too strong)")

    @property
    def focal_px(self) -> float:
        """Focal length in pixels [px]."""
        return self.focal_mm / self.pixel_pitch_mm


@dataclass(frozen=True)
class CameraDetector:
    """Detector and electronics of the simulated webcam.

    Attributes
    ----------
    width_px, height_px : int
        Frame size [px].
    bias_dn : float
        Black level of a dark pixel [DN].
    read_noise_dn : float
        Read noise, one sigma [DN].
    electrons_per_dn : float
        Conversion gain [e⁻/DN], for the shot noise.
    full_well_e : float
        Charge a pixel holds [e⁻]; beyond it the charge blooms along the column.
    signal_dn_per_ms : float
        DN of the clear disc's centre on the optical axis per ms of exposure at unit irradiance [DN/ms].
    full_scale_dn : int
        Largest output value [DN] (8 bits).
    bloom : bool
        Spill charge beyond the full well into the column's neighbours.
    pool_size : int
        Background noise frames drawn once and reused.
    """

    width_px: int = 640
    height_px: int = 480
    bias_dn: float = 12.0
    read_noise_dn: float = 1.2
    electrons_per_dn: float = 25.0
    full_well_e: float = 9000.0
    signal_dn_per_ms: float = 40.0
    full_scale_dn: int = 255
    bloom: bool = True
    pool_size: int = 6

    def __post_init__(self) -> None:
        if self.width_px < 16 or self.height_px < 16:
            raise ValueError(f"detector must be at least 16×16 px, got {self.width_px}×{self.height_px}")
        for name in ("electrons_per_dn", "full_well_e", "signal_dn_per_ms"):
            if not getattr(self, name) > 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        if self.read_noise_dn < 0 or self.pool_size < 1:
            raise ValueError("`read_noise_dn` must be >= 0 and `pool_size` >= 1")


# -- the lens ---------------------------------------------------------------------------------------------
def _radius(theta, f: float, a: float, b: float):
    """r(θ) = f tan θ (1 + a θ² + b θ⁴) [px]."""
    t2 = theta * theta
    return f * np.tan(theta) * (1.0 + a * t2 + b * t2 * t2)


def _radius_slope(theta, f: float, a: float, b: float):
    """dr/dθ [px/rad]."""
    t2 = theta * theta
    tan = np.tan(theta)
    return f * ((1.0 + tan * tan) * (1.0 + a * t2 + b * t2 * t2) + tan * (2.0 * a * theta + 4.0 * b * theta * t2))


DEFAULT_LENS = CameraLens()
"""The simulated webcam: f = 2.4 mm on 3 µm pixels (800 px), ~3 % barrel at the corners, detector tilted
0.35°/−0.25°, principal point (322.6, 237.3) px, mounted 0.45°/−0.3° tipped and 0.6° twisted."""


class _Optics:
    """The lens's maps between body-frame directions and pixels (vectorised)."""

    def __init__(self, lens: CameraLens):
        self.lens = lens
        self.f = lens.focal_px
        self.a, self.b = lens.distortion_a, lens.distortion_b
        self.mount = _tipped(lens.mount_tilt_x_deg, lens.mount_tilt_y_deg, lens.mount_twist_deg)
        det = _tipped(lens.detector_tilt_x_deg, lens.detector_tilt_y_deg)
        self.ex, self.ey, self.normal = det[:, 0], det[:, 1], det[:, 2]
        self.foot = np.array([0.0, 0.0, self.f])
        self.nf = float(self.normal @ self.foot)
        self.max_theta = math.radians(MAX_FIELD_DEG)

    def to_pixel(self, body: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixels (x, y) of body-frame directions (..., 3), and whether the lens passes them."""
        cam = body @ self.mount
        rho = np.hypot(cam[..., 0], cam[..., 1])
        theta = np.arctan2(rho, cam[..., 2])
        ok = theta < self.max_theta
        r = _radius(np.minimum(theta, self.max_theta), self.f, self.a, self.b)
        scale = np.where(rho > 0, r / np.where(rho > 0, rho, 1.0), 0.0)
        ray = np.stack([cam[..., 0] * scale, cam[..., 1] * scale, np.full(theta.shape, self.f)], axis=-1)
        lam = self.nf / (ray @ self.normal)  # where the image-side ray meets the tilted detector
        point = ray * lam[..., None] - self.foot
        return (self.lens.principal_x_px + point @ self.ex, self.lens.principal_y_px + point @ self.ey, ok)

    def to_body(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit body-frame directions (..., 3) seen by pixels (x, y), and the camera's field angle θ [rad]."""
        dx = np.asarray(x, dtype=float) - self.lens.principal_x_px
        dy = np.asarray(y, dtype=float) - self.lens.principal_y_px
        point = self.foot + dx[..., None] * self.ex + dy[..., None] * self.ey
        u = self.f * point[..., 0] / point[..., 2]
        v = self.f * point[..., 1] / point[..., 2]
        r = np.hypot(u, v)
        theta = np.arctan(r / self.f)  # the distortion-free guess, then Newton on r(θ) = r
        for _ in range(6):
            theta = theta - (_radius(theta, self.f, self.a, self.b) - r) / _radius_slope(theta, self.f, self.a, self.b)
        s = np.where(r > 0, np.sin(theta) / np.where(r > 0, r, 1.0), 0.0)
        cam = np.stack([u * s, v * s, np.cos(theta)], axis=-1)
        return cam @ self.mount.T, theta

    def area_per_solid_angle(self, theta: np.ndarray) -> np.ndarray:
        """dA/dΩ = r r′ / sin θ, relative to its value f² on the axis [unitless]."""
        t = np.maximum(theta, 1e-9)
        return (_radius(t, self.f, self.a, self.b) * _radius_slope(t, self.f, self.a, self.b)
                / np.sin(t) / self.f**2)


# -- the renderer -----------------------------------------------------------------------------------------
def _ramp(distance_samples):
    """Coverage of a sample whose centre lies `distance_samples` (in sample widths) inside an edge."""
    return np.clip(distance_samples + 0.5, 0.0, 1.0)


class CameraRenderer:
    """Renders 8-bit frames of the simulated camera sun sensor (see the module docstring).

    Parameters
    ----------
    lens : CameraLens
        The true optics and mounting.
    detector : CameraDetector
    rng : numpy.random.Generator
        Source of every random draw (the background pool and the shot noise).
    source_diameter_deg : float
        Angular diameter of the source [°]: the Sun's by default, a bench simulator's own disc otherwise.
    """

    SUPER = 4
    """Samples per pixel along each axis in the spot's neighbourhood."""

    def __init__(self, lens: CameraLens = DEFAULT_LENS, detector: CameraDetector = CameraDetector(), *,
                 rng: np.random.Generator, source_diameter_deg: float = SUN_DIAMETER_DEG):
        if not 0 < source_diameter_deg < 5:
            raise ValueError(f"`source_diameter_deg` must lie in (0, 5), got {source_diameter_deg}")
        self.lens = lens
        self.detector = detector
        self.source_diameter_deg = float(source_diameter_deg)
        self._optics = _Optics(lens)
        self._rng = rng
        shape = (detector.height_px, detector.width_px)
        self._noise = [rng.standard_normal(shape).astype(np.float32) for _ in range(detector.pool_size)]
        self._background = [np.clip(np.rint(n * detector.read_noise_dn + detector.bias_dn), 0,
                                    detector.full_scale_dn).astype(np.uint8) for n in self._noise]
        self._counter = 0
        self._cache: tuple[tuple, tuple[np.ndarray, int, int] | None] | None = None

    # -- geometry ----------------------------------------------------------------------------------------
    @staticmethod
    def _unit(sun_body) -> np.ndarray:
        s = np.asarray(sun_body, dtype=float).reshape(3)
        norm = float(np.linalg.norm(s))
        if not np.isfinite(norm) or norm == 0:
            raise ValueError(f"`sun_body` must be a finite non-zero 3-vector, got {sun_body!r}")
        return s / norm

    def true_pixel(self, sun_body: np.ndarray) -> tuple[float, float] | None:
        """Where the image of the source's centre lands [px], or None when it misses the detector.

        Parameters
        ----------
        sun_body : array_like, shape (3,)
            Direction of the Sun (the source) in the sensor body frame (+z boresight).
        """
        x, y, ok = self._optics.to_pixel(self._unit(sun_body))
        w, h = self.detector.width_px, self.detector.height_px
        if not ok or not (-0.5 <= x < w - 0.5 and -0.5 <= y < h - 0.5):
            return None
        return float(x), float(y)

    def pixel_direction(self, x_px, y_px) -> np.ndarray:
        """The body-frame unit direction whose image lands on pixel (x, y) (the true lens, inverted) (..., 3)."""
        return self._optics.to_body(np.asarray(x_px, dtype=float), np.asarray(y_px, dtype=float))[0]

    # -- noiseless images --------------------------------------------------------------------------------
    def _patch(self, s: np.ndarray, clouds: CloudState) -> tuple[np.ndarray, int, int] | None:
        """Noiseless image of the disc (+ aureole) in units of the axis's clear disc-centre DN, and its origin."""
        key = (tuple(s), clouds)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = self._render_patch(s, clouds)
        self._cache = (key, out)
        return out

    def _render_patch(self, s: np.ndarray, clouds: CloudState) -> tuple[np.ndarray, int, int] | None:
        opt = self._optics
        xc, yc, ok = opt.to_pixel(s)
        if not ok:
            return None
        xc, yc = float(xc), float(yc)
        w, h = self.detector.width_px, self.detector.height_px
        # tangent basis at the Sun, in the body frame (drivers.sim.sky.CloudState's definition)
        xhat = np.array([1.0, 0.0, 0.0])
        e1 = xhat - (xhat @ s) * s
        if np.linalg.norm(e1) < 1e-9:  # the Sun along ±x: any perpendicular will do
            e1 = np.array([0.0, 1.0, 0.0]) - s[1] * s
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        # local scale [px/rad] from the images of two small offsets
        eps = 1e-5
        px = np.array(opt.to_pixel(np.stack([s + eps * e1, s + eps * e2]) / math.sqrt(1 + eps * eps))[:2])
        jac = (px - np.array([[xc, xc], [yc, yc]])) / eps
        scale = float(np.sqrt(np.abs(np.linalg.det(jac))))
        max_scale = float(np.linalg.norm(jac, 2))
        rho = math.radians(self.source_diameter_deg / 2)
        half = int(math.ceil(rho * max_scale + 4 * self.lens.psf_sigma_px + 3))
        aureole = clouds.aureole > 0
        if aureole:
            half = max(half, int(math.ceil(math.radians(AUREOLE_EXTENT_DEG) * max_scale)) + 2)
        x0, y0 = int(math.floor(xc)) - half, int(math.floor(yc)) - half
        side = 2 * half + 2
        if x0 + side <= 0 or y0 + side <= 0 or x0 >= w or y0 >= h:
            return None

        # the disc on the supersampled grid around the spot
        n = self.SUPER
        dhalf = int(math.ceil(rho * max_scale + 4 * self.lens.psf_sigma_px + 3))
        dx0, dy0 = int(math.floor(xc)) - dhalf, int(math.floor(yc)) - dhalf
        dside = 2 * dhalf + 2
        sub = (np.arange(dside * n) + 0.5) / n - 0.5
        gx, gy = np.meshgrid(dx0 + sub, dy0 + sub)
        d, theta = opt.to_body(gx, gy)
        c0, c1, c2 = d @ s, d @ e1, d @ e2
        dist = np.arctan2(np.hypot(c1, c2), c0)  # angle from the Sun's centre [rad]
        sample = 1.0 / (scale * n)  # one sample's angular width [rad]
        mu = np.sqrt(np.clip(1.0 - (dist / rho) ** 2, 0.0, 1.0))
        disc = (1.0 - LIMB_DARKENING_U * (1.0 - mu)) * _ramp((rho - dist) / sample)
        if clouds.edge_offset_deg < math.inf:  # a cloud edge: it covers offsets beyond edge_offset_deg
            if clouds.edge_offset_deg == -math.inf:
                covered = 1.0
            else:
                ang = math.radians(clouds.edge_angle_deg)
                offset = np.arctan2(c1 * math.cos(ang) + c2 * math.sin(ang), c0)  # along the edge's normal [rad]
                covered = _ramp((offset - math.radians(clouds.edge_offset_deg)) / sample)
            disc = disc * (1.0 - covered * (1.0 - clouds.cloud_transmission))
        # radiometry: L cos θ dΩ/dA, 1 on the axis (the cos⁴ law without distortion)
        disc *= clouds.transmission * np.cos(theta) / opt.area_per_solid_angle(theta)
        if self.lens.psf_sigma_px > 0:
            disc = cv2.GaussianBlur(disc.astype(np.float32), (0, 0), self.lens.psf_sigma_px * n,
                                    borderType=cv2.BORDER_CONSTANT)
        disc = disc.reshape(dside, n, dside, n).mean(axis=(1, 3), dtype=np.float64)

        image = np.zeros((side, side))
        oy, ox = dy0 - y0, dx0 - x0
        image[oy:oy + dside, ox:ox + dside] += disc
        if aureole:
            image += self._aureole(s, x0, y0, side, clouds)
        return image, x0, y0

    def _aureole(self, s: np.ndarray, x0: int, y0: int, side: int, clouds: CloudState) -> np.ndarray:
        """The cloud's halo on the patch (one sample per pixel: it is smooth), its flux `clouds.aureole` of the
        clear disc's."""
        opt = self._optics
        gx, gy = np.meshgrid(x0 + np.arange(side, dtype=float), y0 + np.arange(side, dtype=float))
        d, theta = opt.to_body(gx, gy)
        dist = np.degrees(np.arccos(np.clip(d @ s, -1.0, 1.0)))
        profile = np.where(dist < AUREOLE_EXTENT_DEG, (1.0 + (dist / AUREOLE_WIDTH_DEG) ** 2) ** -1.5, 0.0)
        profile *= np.cos(theta) / opt.area_per_solid_angle(theta)
        # the profile's flux per steradian: ∫ 2π d (1 + (d/w)²)^(−3/2) dd over [0, D]
        w, big_d = math.radians(AUREOLE_WIDTH_DEG), math.radians(AUREOLE_EXTENT_DEG)
        profile_sr = 2 * math.pi * w * w * (1.0 - 1.0 / math.sqrt(1.0 + (big_d / w) ** 2))
        rho = math.radians(self.source_diameter_deg / 2)
        disc_sr = math.pi * rho * rho * (1.0 - LIMB_DARKENING_U / 3.0)  # ∫ I(μ) dΩ of the limb-darkened disc
        # a pixel's value is (sky radiance) × cos θ / (dA/dΩ relative to f²), so the image of either sums to
        # f² cos θ × (its integral over the sky): the ratio of the integrals is the ratio of the fluxes
        return profile * (clouds.aureole * disc_sr / profile_sr)

    def signal(self, sun_body: np.ndarray, *, exposure_ms: float, irradiance: float = 1.0,
               clouds: CloudState = CLEAR) -> np.ndarray:
        """The noiseless mean signal of every pixel above the black level [DN, float64, (H, W)], unclipped.

        Parameters as :meth:`render`.
        """
        h, w = self.detector.height_px, self.detector.width_px
        out = np.zeros((h, w))
        patch = self._patch(self._unit(sun_body), clouds)
        if patch is not None:
            image, x0, y0 = patch
            ys, xs, sub = self._overlap(image, x0, y0)
            out[ys, xs] = sub * (self.detector.signal_dn_per_ms * exposure_ms * irradiance)
        return out

    def _overlap(self, image: np.ndarray, x0: int, y0: int):
        h, w = self.detector.height_px, self.detector.width_px
        side_y, side_x = image.shape
        ys = slice(max(y0, 0), min(y0 + side_y, h))
        xs = slice(max(x0, 0), min(x0 + side_x, w))
        return ys, xs, image[ys.start - y0: ys.stop - y0, xs.start - x0: xs.stop - x0]

    # -- one frame ---------------------------------------------------------------------------------------
    def render(self, sun_body: np.ndarray, *, exposure_ms: float, irradiance: float = 1.0,
               clouds: CloudState = CLEAR) -> np.ndarray:
        """One 8-bit frame (uint8, (H, W)).

        Parameters
        ----------
        sun_body : array_like, shape (3,)
            Direction of the Sun in the sensor body frame (+z boresight).
        exposure_ms : float
            Exposure [ms].
        irradiance : float
            The source's irradiance relative to the nominal one [unitless] (the lamp, the sky's clarity).
        clouds : CloudState
            Haze, cloud edge, cloud transmission and aureole in front of the Sun.
        """
        if not exposure_ms >= 0 or not irradiance >= 0:
            raise ValueError("`exposure_ms` and `irradiance` must be >= 0")
        det = self.detector
        self._counter += 1
        k = self._counter % det.pool_size
        frame = self._background[k].copy()
        patch = self._patch(self._unit(sun_body), clouds)
        if patch is None or exposure_ms * irradiance == 0:
            return frame
        image, x0, y0 = patch
        ys, xs, sub = self._overlap(image, x0, y0)
        electrons = self._rng.poisson(np.maximum(sub, 0.0) * (det.signal_dn_per_ms * exposure_ms * irradiance
                                                              * det.electrons_per_dn)).astype(float)
        if det.bloom and electrons.max() > det.full_well_e:
            electrons = self._bloom(electrons, det.full_well_e)
        dn = electrons / det.electrons_per_dn + self._noise[k][ys, xs] * det.read_noise_dn + det.bias_dn
        frame[ys, xs] = np.clip(np.rint(dn), 0, det.full_scale_dn).astype(np.uint8)
        return frame

    @staticmethod
    def _bloom(electrons: np.ndarray, full_well: float) -> np.ndarray:
        """Charge beyond the full well spills half up, half down the column until every pixel holds it."""
        e = electrons.copy()
        for _ in range(e.shape[0]):
            excess = np.maximum(e - full_well, 0.0)
            if not excess.any():
                break
            e -= excess
            e[:-1] += excess[1:] / 2
            e[1:] += excess[:-1] / 2
        return e
