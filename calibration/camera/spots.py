"""The Sun's spot in a camera frame: seed 001's detection pipeline (digest §2.1 A1–A6) and a cloud flag.

Pipeline (:func:`detect_spot`):

A1. luminance Y = 0.2989 R + 0.5870 G + 0.1140 B of an RGB frame (MATLAB's ``rgb2gray``; the thesis gives
    no formula), or the grey frame as it is;
A2. threshold, eq. (1): f(x_ij) = 1 if x_ij ≥ p else 0. The thesis gives no p; here p is a fraction (0.5)
    of the frame's robust maximum above the background, and never below background + 6σ of the noise;
A3. connected components (``cv2.connectedComponentsWithStats``, 8-connectivity like MATLAB's ``bwlabel``);
A4. the largest object is kept;
A5. the thesis's centroid, "the middle pixel" of the object's rows and columns (its bounding box's centre),
    and an intensity-weighted centroid (background-subtracted, over the object dilated by 2 px), the default
    result: the thesis blames the middle pixel's resolution for its azimuth errors near the zenith;
A6. the validity test, eqs. (2)–(3): p = x_{i+R,j} · x_{i−R,j} · x_{i,j+R} · x_{i,j−R}, R = √(S/π) · ε,
    on the binary object, ε = 0.95, R rounded to the nearest pixel; p = 1 means valid.

Shape metrics for a cloud flag (:func:`cloud_flag`): the blob's roundness (minor/major axis of its second
moments), its fill of the equal-moment ellipse, its area against the expected disc's, the spread of its
edge radii along 16 rays (a cloud edge shortens the rays toward it), the light in a ring outside the disc
(an aureole), and the thesis's validity test.

Pixel coordinates (project-wide): x to the right (columns), y down (rows), the centre of pixel (0, 0) at
(0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..centroid import InvalidFrameError, NoSpotError, SaturatedSpotError

__all__ = ["CLOUD_THRESHOLDS", "CameraSpot", "CloudThresholds", "cloud_flag", "detect_spot", "luminance"]

LUMA_WEIGHTS = (0.2989, 0.5870, 0.1140)
"""Weights of R, G, B in the luminance (MATLAB ``rgb2gray``; digest §2.1 A1, an assumption)."""

_N_RAYS = 16  # rays of the edge-radius profile
_DILATE = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))  # a disc of radius 2 px


@dataclass(frozen=True)
class CameraSpot:
    """One detected Sun spot.

    Attributes
    ----------
    x_px, y_px : float
        Intensity-weighted centroid [px] (the default result).
    x_mid_px, y_mid_px : float
        The thesis's "middle pixel" centroid: the centre of the object's bounding box [px] (seed 001 A5).
    area_px : int
        Pixels of the object S [px] (seed 001 eq. 3).
    peak_dn : float
        Brightest luminance in the object [DN].
    flux_dn : float
        Background-subtracted luminance summed over the object dilated by 2 px [DN].
    background_dn : float
        Local background, the median of a ring around the object [DN].
    noise_dn : float
        Noise sigma of the frame's background (robust, from a sparse sample) [DN].
    threshold_dn : float
        The threshold p of eq. (1) [DN].
    saturated : bool
        The object reaches the saturation level.
    valid : bool
        The thesis's validity test, eqs. (2)–(3).
    roundness : float
        Minor over major axis of the binary object's second moments [unitless]; 1 for a disc.
    fill : float
        Object area over the area 4π√(λ₁λ₂) of the ellipse with its second moments [unitless]; 1 for a
        filled ellipse.
    expected_area_ratio : float
        Object area over π r² of the expected disc (NaN when no radius was given) [unitless].
    halo_fraction : float
        Background-subtracted light in the ring 2–6 disc radii from the centre over `flux_dn` [unitless]
        (NaN when no radius was given); an aureole raises it.
    halo_noise : float
        One sigma of `halo_fraction` from the background noise, noise · √(ring pixels) / flux [unitless].
    validity_reach_px : int
        How far from the centre (i, j) of eq. (2) the object runs unbroken along all four directions [px]:
        the test passes for every R up to it (a convex object passes for exactly those R).
    edge_radius_px : float
        Median distance from the weighted centroid to where the luminance drops below p, over 16 rays [px].
    edge_min_ratio, edge_max_ratio : float
        Shortest and longest of those 16 edge radii over their median [unitless]; ~1 for a disc, a cloud
        edge across the disc shortens the rays toward it.
    n_objects : int
        Objects above the threshold (the largest was kept).
    """

    x_px: float
    y_px: float
    x_mid_px: float
    y_mid_px: float
    area_px: int
    peak_dn: float
    flux_dn: float
    background_dn: float
    noise_dn: float
    threshold_dn: float
    saturated: bool
    valid: bool
    roundness: float
    fill: float
    expected_area_ratio: float = math.nan
    halo_fraction: float = math.nan
    halo_noise: float = math.nan
    validity_reach_px: int = 0
    edge_radius_px: float = math.nan
    edge_min_ratio: float = math.nan
    edge_max_ratio: float = math.nan
    n_objects: int = 1

    @property
    def xy(self) -> tuple[float, float]:
        """``(x_px, y_px)``, the weighted centroid [px]."""
        return self.x_px, self.y_px

    @property
    def radius_px(self) -> float:
        """Radius √(S/π) of the circle of the object's area [px] (seed 001 eq. 3 without ε)."""
        return math.sqrt(self.area_px / math.pi)


def luminance(frame) -> np.ndarray:
    """Luminance of a frame as float64 (seed 001 §2.1 A1).

    Parameters
    ----------
    frame : array_like, shape (H, W) or (H, W, 3)
        Grey frame, or RGB frame (channel order R, G, B; convert OpenCV's BGR first) [DN].

    Returns
    -------
    ndarray, shape (H, W)
        Y = 0.2989 R + 0.5870 G + 0.1140 B, or the grey frame [DN].

    Raises
    ------
    InvalidFrameError
        Not a numeric (integer or float) array of shape (H, W) or (H, W, 3), empty, or with NaN/inf.

    References
    ----------
    seed 001 §2.1 A1 (digest: the formula is MATLAB's ``rgb2gray``, an assumption).
    """
    arr = frame if isinstance(frame, np.ndarray) else np.asarray(frame)
    if arr.dtype.kind not in "uif":
        raise InvalidFrameError(f"frame must hold integer or float pixels, got dtype {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] == 3:
        y = arr.astype(np.float64) @ np.array(LUMA_WEIGHTS)  # seed 001 A1 ([A]: MATLAB rgb2gray)
    elif arr.ndim == 2:
        y = arr.astype(np.float64)
    else:
        raise InvalidFrameError(f"frame must be a grey (H, W) or RGB (H, W, 3) image, got shape {arr.shape}")
    if y.shape[0] < 3 or y.shape[1] < 3:
        raise InvalidFrameError(f"frame must be at least 3×3 px, got shape {arr.shape}")
    if arr.dtype.kind == "f" and not np.isfinite(y).all():
        raise InvalidFrameError("frame contains NaN/inf pixels")
    return y


def _background(y: np.ndarray) -> tuple[float, float]:
    """Level and robust sigma of the frame's background [DN].

    The sigma is IQR / 1.349 of a sparse ~2000-pixel sample (floored at 0.5 DN, about an integer ADC's
    quantisation); the level is the mean of every other pixel of every other row within 5 sigma of the
    sample's median — not the median itself, which for integer pixels with ~1 DN of noise sticks to an
    integer and would bias sums over many pixels (the halo ring), and from enough pixels (~1/4 of the frame)
    that its own noise does not matter there either.
    """
    h, w = y.shape
    step = max(1, int(math.sqrt(h * w / 2048.0)))
    sample = y[step // 2::step, step // 2::step].ravel()
    q1, q2, q3 = np.percentile(sample, (25, 50, 75))
    sigma = max(float(q3 - q1) / 1.349, 0.5)
    dense = y[::2, ::2]
    core = dense[np.abs(dense - q2) <= 5 * sigma]
    return (float(core.mean()) if core.size else float(q2)), sigma


def detect_spot(frame, *, threshold_fraction: float = 0.5, min_snr: float = 6.0, eps: float = 0.95,
                expected_radius_px: float | None = None, saturation_dn: float | None = None,
                reject_saturated: bool = False) -> CameraSpot:
    """Find the Sun's spot in a camera frame (seed 001 §2.1, A1–A6).

    Parameters
    ----------
    frame : array_like, shape (H, W) or (H, W, 3)
        Grey or RGB frame [DN]; any integer or float dtype.
    threshold_fraction : float
        Threshold p of eq. (1) as a fraction of the robust maximum above the background [unitless]: p =
        bg + f · (max − bg), with max the largest value that fills a 3×3 neighbourhood (hot pixels do not
        count); never below bg + `min_snr` σ.
    min_snr : float
        The robust maximum must exceed the background by this many noise sigmas, else :class:`NoSpotError`.
    eps : float
        ε of eq. (3), the validity test's tolerance [unitless] (thesis: 0.95).
    expected_radius_px : float, optional
        Radius of the clear disc's image [px], for `expected_area_ratio` and `halo_fraction`.
    saturation_dn : float, optional
        Saturation level [DN]; by default the dtype's maximum for integer frames and none for float ones.
    reject_saturated : bool
        Raise :class:`SaturatedSpotError` for a saturated spot instead of flagging it.

    Returns
    -------
    CameraSpot

    Raises
    ------
    InvalidFrameError
        Not a numeric 2-D (or RGB) image (also a ``ValueError``).
    NoSpotError
        Nothing significantly above the background (a dark or flat frame).
    SaturatedSpotError
        The spot reaches `saturation_dn` and `reject_saturated` is set.

    References
    ----------
    seed 001 §2.1 A1–A6, eqs. (1)–(3) (digest); MATLAB ``rgb2gray`` and ``bwlabel`` (8-connectivity).
    """
    if not 0.0 < threshold_fraction < 1.0:
        raise ValueError(f"`threshold_fraction` must lie in (0, 1), got {threshold_fraction}")
    if not 0.0 < eps <= 1.5:
        raise ValueError(f"`eps` must lie in (0, 1.5], got {eps}")
    arr = frame if isinstance(frame, np.ndarray) else np.asarray(frame)
    y = luminance(arr)  # A1
    if saturation_dn is None and arr.dtype.kind in "ui":
        saturation_dn = float(np.iinfo(arr.dtype).max)
    bg, noise = _background(y)
    robust_max = float(cv2.erode(y.astype(np.float32), None).max())
    if not robust_max - bg >= min_snr * noise:
        raise NoSpotError(f"no spot: the brightest 3×3 patch is {robust_max:.1f} DN, {(robust_max - bg) / noise:.1f}"
                          f" noise sigmas above the background {bg:.1f} DN (noise {noise:.2f} DN); need >= {min_snr}",
                          peak_dn=robust_max, background_dn=bg, noise_dn=noise,
                          snr=(robust_max - bg) / noise, min_peak_snr=min_snr)
    p = max(bg + threshold_fraction * (robust_max - bg), bg + min_snr * noise)
    binary = (y >= p).view(np.uint8)  # seed 001 eq. (1)
    # A3 on the bounding box of the pixels above p (the labels are the same; the full frame costs ~10× more),
    # by OpenCV's sequential SAUF algorithm (its parallel default is slower on such frames).
    rx, ry, rw, rh = cv2.boundingRect(binary)
    n, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
        np.ascontiguousarray(binary[ry:ry + rh, rx:rx + rw]), 8, cv2.CV_32S, cv2.CCL_SAUF)
    label = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))  # A4: the largest object
    left, top, width, height, area = (int(v) for v in stats[label])
    left, top = left + rx, top + ry

    # Work in a box around the object, large enough for the dilation, the background ring and the halo ring.
    h, w = y.shape
    r_halo = 6.0 * expected_radius_px if expected_radius_px else 0.0
    margin = int(math.ceil(max(8.0, r_halo + 2.0)))
    bx0, by0 = max(left - margin, 0), max(top - margin, 0)
    bx1, by1 = min(left + width + margin, w), min(top + height + margin, h)
    yy = y[by0:by1, bx0:bx1]
    obj = np.zeros(yy.shape, np.uint8)
    ly0, lx0 = max(by0 - ry, 0), max(bx0 - rx, 0)  # the labels' window inside the box
    sub = labels[ly0:min(by1 - ry, rh), lx0:min(bx1 - rx, rw)] == label
    oy, ox = ry + ly0 - by0, rx + lx0 - bx0
    obj[oy:oy + sub.shape[0], ox:ox + sub.shape[1]] = sub

    # A5: the thesis's "middle pixel" of the rows and of the columns (bounding-box centre)
    x_mid = left + (width - 1) / 2.0
    y_mid = top + (height - 1) / 2.0

    # A5': background-subtracted, intensity-weighted centroid over the object dilated by 2 px
    near = cv2.dilate(obj, _DILATE)
    ring = cv2.dilate(obj, _DILATE, iterations=3) & ~cv2.dilate(obj, _DILATE, iterations=2) & 1
    local_bg = float(np.median(yy[ring.astype(bool)])) if ring.any() else bg
    weights = (yy - local_bg) * near
    flux = float(weights.sum())
    rows, cols = np.indices(yy.shape, dtype=np.float64)
    if flux > 0:
        x_c = float((weights * cols).sum() / flux) + bx0
        y_c = float((weights * rows).sum() / flux) + by0
    else:
        x_c, y_c = x_mid, y_mid

    peak = float(yy[obj.astype(bool)].max())
    saturated = saturation_dn is not None and peak >= saturation_dn
    if saturated and reject_saturated:
        n_sat = int(np.count_nonzero((yy >= saturation_dn) & obj.astype(bool)))
        raise SaturatedSpotError(f"saturated spot: {n_sat} pixel(s) at >= {saturation_dn:g} DN near "
                                 f"(x={x_c:.1f}, y={y_c:.1f}); reduce the exposure",
                                 x_px=x_c, y_px=y_c, n_saturated=n_sat, saturation_dn=float(saturation_dn))

    # A6: validity test, eqs. (2)–(3), on the binary object, centre (i, j) = the middle pixel rounded
    big_r = int(round(math.sqrt(area / math.pi) * eps))  # seed 001 eq. (3), R rounded to the nearest pixel
    i, j = _nearest_pixel(y_mid, y_c), _nearest_pixel(x_mid, x_c)

    def on(r: int, c: int) -> bool:  # the object lies inside the box, so a point outside it is not on it
        r, c = r - by0, c - bx0
        return 0 <= r < obj.shape[0] and 0 <= c < obj.shape[1] and bool(obj[r, c])

    valid = on(i + big_r, j) and on(i - big_r, j) and on(i, j + big_r) and on(i, j - big_r)  # eq. (2)
    reach = 0  # the largest R for which the four points and every pixel between them and (i, j) are on
    while all(on(i + di * (reach + 1), j + dj * (reach + 1)) for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))):
        reach += 1

    # Shape: second moments of the binary object
    m = cv2.moments(obj, binaryImage=True)
    mu20, mu11, mu02 = m["mu20"] / area, m["mu11"] / area, m["mu02"] / area
    root = math.sqrt(max(((mu20 - mu02) / 2) ** 2 + mu11 * mu11, 0.0))
    lmax, lmin = (mu20 + mu02) / 2 + root, (mu20 + mu02) / 2 - root
    roundness = math.sqrt(max(lmin, 0.0) / lmax) if lmax > 0 else 1.0
    # a single pixel has zero moments; the pixels' own extent (1/12 px² per axis) keeps the ellipse finite
    ellipse_area = 4.0 * math.pi * math.sqrt((lmax + 1 / 12) * (lmin + 1 / 12))
    fill = area / ellipse_area

    # Edge radii: where the luminance first drops below p along 16 rays from the weighted centroid, found
    # by linear interpolation between bilinear samples 0.1 px apart (sub-pixel, so a clear disc's radii agree
    # to a few hundredths of a pixel where the blob's own outline is quantised to whole pixels).
    reach_px = 3.0 * max(math.sqrt(area / math.pi), expected_radius_px or 0.0) + 2.0
    steps = np.arange(0.0, reach_px, 0.1, dtype=np.float32)
    ang = np.arange(_N_RAYS, dtype=np.float32) * np.float32(2 * math.pi / _N_RAYS)
    map_x = (x_c - bx0) + np.cos(ang)[:, None] * steps[None, :]
    map_y = (y_c - by0) + np.sin(ang)[:, None] * steps[None, :]
    prof = cv2.remap(yy.astype(np.float32), map_x.astype(np.float32), map_y.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=float(bg))
    below = prof < p
    below[:, -1] = True
    first = np.argmax(below, axis=1)
    k = np.maximum(first, 1)
    hi, lo = prof[np.arange(_N_RAYS), k - 1], prof[np.arange(_N_RAYS), k]
    frac = np.where(hi > lo, (hi - p) / np.where(hi > lo, hi - lo, 1.0), 0.0)
    radii = np.where(first == 0, 0.0, (k - 1 + np.clip(frac, 0.0, 1.0)) * 0.1)
    edge_median = float(np.median(radii))
    edge_min = float(radii.min() / edge_median) if edge_median > 0 else 0.0
    edge_max = float(radii.max() / edge_median) if edge_median > 0 else math.inf

    area_ratio, halo, halo_noise = math.nan, math.nan, math.nan
    if expected_radius_px:
        area_ratio = area / (math.pi * expected_radius_px**2)
        dist = np.hypot(cols + bx0 - x_c, rows + by0 - y_c)
        annulus = (dist >= 2.0 * expected_radius_px) & (dist <= r_halo)
        if annulus.any() and flux > 0:
            # light above the frame's background spread over the ring (an aureole), per unit disc flux
            halo = float((yy[annulus] - bg).sum() / flux)
            halo_noise = noise * math.sqrt(float(annulus.sum())) / flux
    return CameraSpot(x_px=x_c, y_px=y_c, x_mid_px=x_mid, y_mid_px=y_mid, area_px=area, peak_dn=peak,
                      flux_dn=flux, background_dn=local_bg, noise_dn=noise, threshold_dn=p, saturated=saturated,
                      valid=valid, roundness=roundness, fill=fill, expected_area_ratio=area_ratio,
                      halo_fraction=halo, halo_noise=halo_noise, validity_reach_px=reach,
                      edge_radius_px=edge_median, edge_min_ratio=edge_min, edge_max_ratio=edge_max,
                      n_objects=n - 1)


def _nearest_pixel(mid: float, weighted: float) -> int:
    """The pixel nearest to the middle-pixel coordinate; a half-integer (an even-sized object) goes toward the
    weighted centroid (the thesis does not say how it rounds)."""
    lo = math.floor(mid)
    if mid - lo != 0.5:
        return int(round(mid))
    return lo + 1 if weighted > mid else lo


@dataclass(frozen=True)
class CloudThresholds:
    """Limits of :func:`cloud_flag`; a spot beyond any of them is flagged.

    Attributes
    ----------
    validity_eps : float
        ε of the thesis's validity test (seed 001 eqs. 2–3) as applied here [unitless]. The thesis's 0.95
        fails ~16 % of clear discs of ~3.6 px radius: R = round(0.95 √(S/π)) and the rounded centre leave
        no room for the outline's pixel quantisation (±0.5 px) on so small a disc; 0.6 keeps the test's
        meaning (the object reaches out about its centre in all four directions) without that.
    min_roundness : float
        Minor/major axis ratio of the blob [unitless].
    min_area_ratio, max_area_ratio : float
        Blob area over the expected disc's π r² [unitless].
    min_edge_ratio, max_edge_ratio : float
        Shortest and longest of the 16 edge radii over their median [unitless].
    min_edge_radius_ratio : float
        Median edge radius over the expected disc radius [unitless].
    min_flux_ratio : float
        Flux over the expected clear flux, when that is given [unitless].
    max_halo_fraction, halo_sigmas : float
        The ring's light over the disc's must exceed both `max_halo_fraction` and `halo_sigmas` times its
        noise to count as an aureole [unitless].
    """

    validity_eps: float = 0.6
    min_roundness: float = 0.8
    min_area_ratio: float = 0.65
    max_area_ratio: float = 1.5
    min_edge_ratio: float = 0.95
    max_edge_ratio: float = 1.06
    min_edge_radius_ratio: float = 0.85
    min_flux_ratio: float = 0.5
    max_halo_fraction: float = 0.03
    halo_sigmas: float = 4.0


CLOUD_THRESHOLDS = CloudThresholds()
"""Tuned on the simulator's frames (``drivers.sim.camera_optics``: r ≈ 3.7 px disc, 0.5 px PSF, 8 bits,
peak 60–240 DN): 0–2 of 300 clear frames (haze 0.7–1) flagged, 299–300 of 300 cloudy ones (a cloud edge over
10–90 % of the disc, opaque or passing ≤ 50 %; a thin cloud over the whole disc, with the clear flux given;
an aureole of ≥ 15 % of the disc's flux) over four seeds; ``tests/calibration/camera/test_fit.py`` prints
the confusion matrix."""


def cloud_flag(spot: CameraSpot, *, expected_radius_px: float, expected_flux_dn: float | None = None,
               thresholds: CloudThresholds = CLOUD_THRESHOLDS) -> tuple[bool, str]:
    """Whether the spot's shape shows a cloud in front of the Sun, and why.

    Parameters
    ----------
    spot : CameraSpot
        From :func:`detect_spot` (called with the same `expected_radius_px`, for the halo metric).
    expected_radius_px : float
        Radius of the clear disc's image where the spot lies [px].
    expected_flux_dn : float, optional
        The clear Sun's flux at this exposure and place in the frame [DN]; enables the flux test (a thin
        cloud over the whole disc keeps its shape and only dims it).
    thresholds : CloudThresholds

    Returns
    -------
    flagged : bool
    reason : str
        The failed tests in words, "; "-separated ("" when clear).

    Notes
    -----
    Tests: the thesis's validity test (seed 001 eqs. 2–3, with ``thresholds.validity_eps``), roundness,
    area against the expected disc, the spread of the edge radii and their size against the expected radius,
    flux against the clear flux, aureole. The edge radii do most of the work: a clear disc's 16 radii
    stay within −4 %/+7 % of their median, an edge over 10 % of the disc shortens the rays toward it by
    ~25 %. A cloud edge over
    less than ~10 % of the disc lies in the darkened limb and is not reliably seen; a thin cloud passing
    more than ~50 % of the light looks like haze.

    References
    ----------
    seed 001 §2.1 A6 (validity test), §4.3 and digest §7 item 7 (samples failing the test are warned of).
    """
    if not expected_radius_px > 0:
        raise ValueError(f"`expected_radius_px` must be positive, got {expected_radius_px}")
    t = thresholds
    reasons = []
    big_r = int(round(t.validity_eps * spot.radius_px))  # seed 001 eq. (3) with ε = validity_eps
    if spot.validity_reach_px < big_r:
        reasons.append(f"validity test (eqs. 2–3, ε = {t.validity_eps}) fails: the blob reaches "
                       f"{spot.validity_reach_px} px about its centre, not R = {big_r} px")
    if spot.roundness < t.min_roundness:
        reasons.append(f"blob not round (axis ratio {spot.roundness:.2f} < {t.min_roundness})")
    ratio = spot.area_px / (math.pi * expected_radius_px**2)
    if not t.min_area_ratio <= ratio <= t.max_area_ratio:
        reasons.append(f"blob area {ratio:.2f}× the clear disc's (allowed {t.min_area_ratio}–{t.max_area_ratio})")
    if spot.edge_min_ratio < t.min_edge_ratio or spot.edge_max_ratio > t.max_edge_ratio:
        reasons.append(f"outline not a circle (edge radii {spot.edge_min_ratio:.2f}–{spot.edge_max_ratio:.2f}× "
                       f"their median, allowed {t.min_edge_ratio}–{t.max_edge_ratio})")
    if spot.edge_radius_px / expected_radius_px < t.min_edge_radius_ratio:
        reasons.append(f"disc too small (edge radius {spot.edge_radius_px:.2f} px, "
                       f"{spot.edge_radius_px / expected_radius_px:.2f}× the expected)")
    if expected_flux_dn is not None and expected_flux_dn > 0:
        fr = spot.flux_dn / expected_flux_dn
        if fr < t.min_flux_ratio:
            reasons.append(f"flux {fr:.2f}× the clear Sun's (< {t.min_flux_ratio})")
    if spot.halo_fraction > max(t.max_halo_fraction, t.halo_sigmas * spot.halo_noise):
        reasons.append(f"aureole: {spot.halo_fraction:.3f} of the disc's light in a ring outside it "
                       f"(noise {spot.halo_noise:.3f})")
    return bool(reasons), "; ".join(reasons)
