"""Seed 001's spot detection (A1–A6) on frames of the simulated camera, and its typed errors."""

import math

import numpy as np
import pytest

from calibration.camera.spots import CLOUD_THRESHOLDS, cloud_flag, detect_spot, luminance
from calibration.centroid import InvalidFrameError, NoSpotError, SaturatedSpotError
from calibration.errors import CalibrationError
from drivers.sim.camera_optics import DEFAULT_LENS, CameraRenderer
from drivers.sim.sky import SUN_DIAMETER_DEG, CloudState

RADIUS_PX = DEFAULT_LENS.focal_px * math.tan(math.radians(SUN_DIAMETER_DEG / 2))


@pytest.fixture(scope="module")
def renderer():
    return CameraRenderer(rng=np.random.default_rng(21))


def _random_suns(renderer, n, seed, margin_px=15):
    rng = np.random.default_rng(seed)
    return [renderer.pixel_direction(rng.uniform(margin_px, 639 - margin_px), rng.uniform(margin_px, 479 - margin_px))
            for _ in range(n)]


def test_weighted_centroid_beats_the_thesis_middle_pixel_on_rendered_frames(renderer):
    errors_w, errors_mid = [], []
    for s in _random_suns(renderer, 150, seed=1):
        spot = detect_spot(renderer.render(s, exposure_ms=4.0), expected_radius_px=RADIUS_PX)
        x, y = renderer.true_pixel(s)
        errors_w.append(math.hypot(spot.x_px - x, spot.y_px - y))
        errors_mid.append(math.hypot(spot.x_mid_px - x, spot.y_mid_px - y))
    rms_w, rms_mid = (float(np.sqrt(np.mean(np.square(e)))) for e in (errors_w, errors_mid))
    print(f"centroid error RMS: weighted {rms_w:.4f} px, thesis middle pixel {rms_mid:.4f} px")
    assert rms_w < 0.03
    assert 0.1 < rms_mid < 0.6  # the bounding box's centre moves in half-pixel steps
    assert rms_mid > 5 * rms_w


def test_noiseless_weighted_centroid_is_within_a_hundredth_of_a_pixel(renderer):
    for s in _random_suns(renderer, 30, seed=2):
        frame = renderer.signal(s, exposure_ms=4.0) + renderer.detector.bias_dn
        spot = detect_spot(frame, expected_radius_px=RADIUS_PX)
        x, y = renderer.true_pixel(s)
        assert math.hypot(spot.x_px - x, spot.y_px - y) < 0.01
        assert not spot.saturated  # a float frame has no saturation level unless given


def test_an_rgb_frame_gives_the_luminance_and_the_same_spot(renderer):
    s = _random_suns(renderer, 1, seed=3)[0]
    grey = renderer.render(s, exposure_ms=4.0)
    rgb = np.stack([grey, grey, grey], axis=-1)
    assert luminance(rgb)[0, 0] == pytest.approx(grey[0, 0] * (0.2989 + 0.5870 + 0.1140))
    pixel = np.array([[[100, 50, 10]]] * 3 * 3, dtype=np.uint8).reshape(3, 3, 3)
    assert luminance(pixel)[1, 1] == pytest.approx(0.2989 * 100 + 0.5870 * 50 + 0.1140 * 10)
    a, b = detect_spot(grey), detect_spot(rgb)
    assert b.x_px == pytest.approx(a.x_px, abs=1e-3) and b.y_px == pytest.approx(a.y_px, abs=1e-3)


def test_the_largest_object_is_kept(renderer):
    s = renderer.pixel_direction(200.0, 200.0)
    frame = renderer.render(s, exposure_ms=4.0)
    frame[50:53, 500:503] = 250  # a small bright glint
    spot = detect_spot(frame)
    assert spot.n_objects == 2
    assert math.hypot(spot.x_px - 200.0, spot.y_px - 200.0) < 0.1


def test_dark_flat_and_noise_frames_have_no_spot(renderer):
    dark = renderer.render(np.array([0.0, 0.0, 1.0]), exposure_ms=0.0)
    for frame in (dark, np.zeros((480, 640), np.uint8), np.full((100, 100), 77.0)):
        with pytest.raises(NoSpotError) as info:
            detect_spot(frame)
        assert isinstance(info.value, CalibrationError)
    hot = dark.copy()
    hot[10, 10] = 255  # one hot pixel is not a spot
    with pytest.raises(NoSpotError):
        detect_spot(hot)


@pytest.mark.parametrize("frame", [
    np.zeros(100),  # 1-D
    np.zeros((10, 10, 4)),  # 4 channels
    np.array([["a", "b", "c"]] * 3),  # strings
    np.array([[object()] * 3] * 3),  # objects
    np.zeros((2, 50)),  # too small
    np.full((10, 10), np.nan),  # NaN
])
def test_garbage_frames_raise_a_typed_error(frame):
    with pytest.raises(InvalidFrameError):
        detect_spot(frame)


def test_saturation_is_flagged_or_rejected(renderer):
    s = renderer.pixel_direction(300.0, 250.0)
    frame = renderer.render(s, exposure_ms=20.0)
    spot = detect_spot(frame)
    assert spot.saturated and spot.peak_dn == 255
    with pytest.raises(SaturatedSpotError):
        detect_spot(frame, reject_saturated=True)
    assert not detect_spot(renderer.render(s, exposure_ms=4.0)).saturated


def _disc(radius, centre=(60.3, 50.6), shape=(120, 140)):
    rows, cols = np.indices(shape)
    return ((cols - centre[0]) ** 2 + (rows - centre[1]) ** 2 <= radius**2).astype(float) * 200 + 10


def test_thesis_validity_test_accepts_a_disc_and_rejects_a_cut_or_stretched_one():
    assert detect_spot(_disc(20)).valid
    half = _disc(20)
    half[:, 61:] = 10  # a straight edge through the centre
    cut = detect_spot(half)
    assert not cut.valid
    rows, cols = np.indices((120, 140))
    ellipse = (((cols - 70) / 30) ** 2 + ((rows - 60) / 10) ** 2 <= 1).astype(float) * 200 + 10
    stretched = detect_spot(ellipse)
    assert not stretched.valid
    assert stretched.roundness == pytest.approx(1 / 3, abs=0.02)
    assert detect_spot(_disc(20)).roundness > 0.98
    # eq. (3): R = round(√(S/π)·ε); a large ε reaches past the disc's own edge
    assert not detect_spot(_disc(20), eps=1.2).valid


def test_cloud_flag_passes_a_clear_disc_and_names_a_cut_one(renderer):
    s = renderer.pixel_direction(420.0, 130.0)
    clear = detect_spot(renderer.render(s, exposure_ms=4.0), expected_radius_px=RADIUS_PX)
    flagged, reason = cloud_flag(clear, expected_radius_px=RADIUS_PX)
    assert not flagged and reason == ""
    half = CloudState(edge_offset_deg=0.0, edge_angle_deg=30.0)
    cut = detect_spot(renderer.render(s, exposure_ms=4.0, clouds=half), expected_radius_px=RADIUS_PX)
    flagged, reason = cloud_flag(cut, expected_radius_px=RADIUS_PX)
    assert flagged and "outline" in reason
    thin = CloudState(edge_offset_deg=-math.inf, cloud_transmission=0.3)
    dim = detect_spot(renderer.render(s, exposure_ms=4.0, clouds=thin), expected_radius_px=RADIUS_PX)
    clear_flux = clear.flux_dn
    assert not cloud_flag(dim, expected_radius_px=RADIUS_PX)[0]  # a uniformly dimmed disc keeps its shape ...
    flagged, reason = cloud_flag(dim, expected_radius_px=RADIUS_PX, expected_flux_dn=clear_flux)
    assert flagged and "flux" in reason  # ... but not its flux
    halo = detect_spot(renderer.render(s, exposure_ms=4.0, clouds=CloudState(aureole=0.4)),
                       expected_radius_px=RADIUS_PX)
    flagged, reason = cloud_flag(halo, expected_radius_px=RADIUS_PX)
    assert flagged and "aureole" in reason
    assert CLOUD_THRESHOLDS.validity_eps < 0.95
    with pytest.raises(ValueError):
        cloud_flag(clear, expected_radius_px=0.0)
