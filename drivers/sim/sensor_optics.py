"""What the simulated CMOS pinhole sensor sees: a frame rendered from the world's truth.

The spot is the simulator's own physics (:mod:`drivers.sim.raytrace`, which shares no code with the
calibration models): the chief ray traced through the cover glass onto the tilted die, and around it the
shadow of the finite, slightly non-round hole in a mask of some thickness, cast by the 0.5° source and
blurred by diffraction. Its brightness follows the lamp through the shutter, the exposure, the aperture's
projected area (cos θ) and the pixels' angular response (the hole's vignetting at oblique incidence is in
the shadow itself). The detector adds a bias, dark current, shot and read noise, hot and dead pixels, and
clips at its full scale; its size and pitch are the sensor design's.

Speed: the background noise comes from a small pool of full frames drawn once per bench (shot noise of the
dark level approximated by a Gaussian); only the spot's neighbourhood is drawn per frame, with Poisson
noise, and the noiseless spot is kept while the sun does not move (the repeated frames of one bench point).
A 640×480 frame renders in about a millisecond.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .raytrace import SpotPatch, spot_patch
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

    SUPER = 2  # supersampling of the spot (antialiased: its centroid is within 0.002 px of the exact one)

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
        self._last: tuple[tuple, SpotPatch] | None = None

    # -- geometry of the spot -----------------------------------------------------------------------------
    def spot(self) -> tuple[SpotPatch | None, float, float]:
        """The noiseless spot for the world's present state (None when the sun is behind the mask), with the
        sun's body zenith and azimuth [°]."""
        zenith, azimuth = self.world.sun_direction_body()
        if zenith >= 89:
            return None, zenith, azimuth
        optics = self.world.sensor.optics
        key = (zenith, azimuth, optics, self.world.bench.source_diameter_deg, self.world.occlusion())
        if self._last is None or self._last[0] != key:
            patch = spot_patch(zenith, azimuth, optics, source_diameter_deg=key[3], supersample=self.SUPER,
                               occlusion=key[4])
            self._last = (key, patch)
        return self._last[1], zenith, azimuth

    def spot_centre(self) -> tuple[float, float, float, float, float]:
        """Chief ray's spot [px], the sun's body zenith and azimuth, and its incidence on the die [°] (NaN for
        the position and incidence when the sun is behind the mask)."""
        patch, zenith, azimuth = self.spot()
        if patch is None:
            return np.nan, np.nan, zenith, azimuth, np.nan
        return patch.chief_x_px, patch.chief_y_px, zenith, azimuth, patch.incidence_deg

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
        if irradiance > 0:
            patch, zenith, _ = self.spot()
            if patch is not None and patch.incidence_deg < 89:
                self._add_spot(img, patch, zenith, exposure_ms * irradiance)
        img.ravel()[self.dead] = 0.0
        np.clip(img, 0, self.full_scale, out=img)
        return np.rint(img).astype(np.uint16)

    def _add_spot(self, img: np.ndarray, patch: SpotPatch, zenith_deg: float, dose: float) -> None:
        """Add the spot's photo-electrons (Poisson) to the frame, where it overlaps the frame."""
        spec = self.spec
        h, w = self.shape
        side_y, side_x = patch.image.shape
        x0, y0 = patch.x_origin_px, patch.y_origin_px
        ys, xs = slice(max(y0, 0), min(y0 + side_y, h)), slice(max(x0, 0), min(x0 + side_x, w))
        if ys.start >= ys.stop or xs.start >= xs.stop:
            return
        # the aperture's projected area (cos θ) and the pixels' angular response
        response = np.cos(np.radians(zenith_deg)) * np.cos(np.radians(patch.incidence_deg)) ** spec.pixel_response_power
        signal = patch.image[ys.start - y0: ys.stop - y0, xs.start - x0: xs.stop - x0] * (
            spec.signal_dn_per_ms * dose * response)
        electrons = self._rng.poisson(np.maximum(signal, 0) * spec.electrons_per_dn) / spec.electrons_per_dn
        img[ys, xs] += electrons
