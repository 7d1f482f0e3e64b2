"""What the simulated CMOS pinhole sensor sees: a frame rendered from the world's truth.

The spot lands where the sensor's true build puts the sun direction the table set (calibration.pinhole,
the same forward model the physical calibration fits), including the slight stretch with azimuth of a
non-round pinhole. Its shape is the pinhole's shadow (a disk of the hole's diameter: the mask is parallel to the
pixels, so the shadow keeps its size at any incidence) blurred by the image of the 0.5° source, which
stretches radially with incidence. Its brightness follows the lamp through the shutter, the exposure,
the aperture's projected area (cos θ) and the pixels' angular response. The detector adds a bias, dark
current, shot and read noise, hot and dead pixels, and clips at its 10-bit full scale.

Speed: the background noise comes from a small pool of full frames drawn once per bench (shot noise of the
dark level approximated by a Gaussian); only the spot's neighbourhood is drawn per frame, with Poisson
noise. A 640×480 frame renders in about a millisecond.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calibration.pinhole import detector_rotation, spot_from_direction

from .world import SimWorld


@dataclass(frozen=True)
class DetectorSpec:
    """Detector and electronics of the simulated module.

    Attributes
    ----------
    bias_dn : float
        Offset of a dark pixel [DN].
    read_noise_dn : float
        Read noise, one sigma [DN].
    dark_dn_per_ms : float
        Dark signal per ms of exposure [DN/ms].
    signal_dn_per_ms : float
        Peak signal of the spot at normal incidence, warm lamp, open shutter, per ms of exposure [DN/ms].
    electrons_per_dn : float
        Conversion gain, for shot noise [e⁻/DN].
    pixel_response_power : float
        Pixels' angular response cos^k(incidence in the detector).
    hot_pixels, dead_pixels : int
        Number of hot (dark current ×`hot_factor`) and dead (0 DN) pixels.
    hot_factor : float
    pool_size : int
        Background noise frames drawn once and reused.
    readout_ms : float
        Time to read out a frame [ms].
    """

    bias_dn: float = 16.0
    read_noise_dn: float = 3.0
    dark_dn_per_ms: float = 0.5
    signal_dn_per_ms: float = 200.0
    electrons_per_dn: float = 1.0
    pixel_response_power: float = 1.0
    hot_pixels: int = 20
    dead_pixels: int = 5
    hot_factor: float = 400.0
    pool_size: int = 6
    readout_ms: float = 8.0


class SpotRenderer:
    """Renders frames of one simulated sensor from its world (see the module docstring)."""

    PATCH = 32  # px, side of the patch the spot is drawn in
    SUPER = 4  # supersampling of the patch

    def __init__(self, world: SimWorld, spec: DetectorSpec = DetectorSpec()):
        self.world = world
        self.spec = spec
        design = world.sensor.design
        self.shape = (design.height_px, design.width_px)
        self.full_scale = design.saturation_dn
        rng = world.rng("detector")
        self._pool = [rng.normal(0.0, 1.0, self.shape).astype(np.float32) for _ in range(spec.pool_size)]
        n = self.shape[0] * self.shape[1]
        picks = rng.choice(n, spec.hot_pixels + spec.dead_pixels, replace=False)
        self.hot = picks[: spec.hot_pixels]
        self.dead = picks[spec.hot_pixels:]
        self._rng = world.rng("shot-noise")
        self.counter = 0

    # -- geometry of the spot -----------------------------------------------------------------------------
    def spot_centre(self) -> tuple[float, float, float, float, float]:
        """Spot centre [px], the sun's body zenith and azimuth, and its incidence on the detector [°]."""
        truth = self.world.sensor
        zenith, azimuth = self.world.sun_direction_body()
        x, y = spot_from_direction(zenith, azimuth, truth.optics, truth.design.pixel_pitch_mm)
        m = detector_rotation(truth.build.tilt_x_deg, truth.build.tilt_y_deg, truth.build.rotation_deg)
        s = np.array([np.sin(np.radians(zenith)) * np.cos(np.radians(azimuth)),
                      np.sin(np.radians(zenith)) * np.sin(np.radians(azimuth)), np.cos(np.radians(zenith))])
        incidence_det = np.degrees(np.arccos(np.clip((s @ m)[2], -1, 1)))
        return float(x), float(y), float(zenith), float(azimuth), float(incidence_det)

    def _spot_patch(self, x: float, y: float, zenith_deg: float, azimuth_deg: float) -> tuple[np.ndarray, int, int]:
        """Unit-peak spot image on a PATCH×PATCH grid whose top-left pixel is (x0, y0)."""
        truth = self.world.sensor
        pitch = truth.design.pixel_pitch_mm
        half = self.PATCH // 2
        x0, y0 = int(np.floor(x)) - half, int(np.floor(y)) - half
        n = self.PATCH * self.SUPER
        coords = (np.arange(n) + 0.5) / self.SUPER - 0.5  # pixel-centre convention: pixel i spans i ± 0.5
        gx = x0 + coords[None, :] - x
        gy = y0 + coords[:, None] - y
        radius = truth.design.hole_diameter_mm / 2 / pitch
        disk = ((gx * gx + gy * gy) <= radius * radius).astype(np.float32)
        # the 0.5° source blurs the shadow; the blur stretches radially as 1/cos²θ
        height = truth.build.gap_mm + truth.build.glass_mm / truth.build.glass_index
        sigma = 0.5 * np.radians(self.world.bench.source_diameter_deg / 2) * height / pitch
        cos2 = np.cos(np.radians(zenith_deg)) ** 2
        s_par, s_perp = sigma / cos2 * self.SUPER, sigma * self.SUPER
        ang = np.radians(azimuth_deg)
        blurred = cv2.GaussianBlur(disk, (0, 0), sigmaX=max(s_par * abs(np.cos(ang)) + s_perp * abs(np.sin(ang)), 0.3),
                                   sigmaY=max(s_par * abs(np.sin(ang)) + s_perp * abs(np.cos(ang)), 0.3))
        patch = blurred.reshape(self.PATCH, self.SUPER, self.PATCH, self.SUPER).mean(axis=(1, 3))
        peak = patch.max()
        return (patch / peak if peak > 0 else patch), x0, y0

    # -- one frame ------------------------------------------------------------------------------------------
    def render(self, exposure_ms: float) -> np.ndarray:
        """One 10-bit frame (uint16) for the world's present state."""
        spec = self.spec
        h, w = self.shape
        self.counter += 1
        dark = spec.bias_dn + spec.dark_dn_per_ms * exposure_ms
        sigma = np.sqrt(spec.read_noise_dn**2 + spec.dark_dn_per_ms * exposure_ms / spec.electrons_per_dn)
        img = self._pool[self.counter % len(self._pool)] * np.float32(sigma) + np.float32(dark)
        img.ravel()[self.hot] += spec.hot_factor * spec.dark_dn_per_ms * exposure_ms
        irradiance = self.world.irradiance()
        x, y, zenith, azimuth, incidence = self.spot_centre()
        if irradiance > 0 and incidence < 89:
            patch, x0, y0 = self._spot_patch(x, y, zenith, azimuth)
            response = np.cos(np.radians(zenith)) * np.cos(np.radians(incidence)) ** spec.pixel_response_power
            signal = patch * (spec.signal_dn_per_ms * exposure_ms * irradiance * response)
            electrons = self._rng.poisson(np.maximum(signal, 0) * spec.electrons_per_dn) / spec.electrons_per_dn
            ys, xs = slice(max(y0, 0), min(y0 + self.PATCH, h)), slice(max(x0, 0), min(x0 + self.PATCH, w))
            if ys.start < ys.stop and xs.start < xs.stop:
                img[ys, xs] += electrons[ys.start - y0: ys.stop - y0, xs.start - x0: xs.stop - x0]
        img.ravel()[self.dead] = 0.0
        np.clip(img, 0, self.full_scale, out=img)
        return np.rint(img).astype(np.uint16)
