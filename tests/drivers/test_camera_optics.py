"""The simulated camera sun sensor's renderer (drivers.sim.camera_optics): its own lens, radiometry and noise."""

import math
import time

import numpy as np
import pytest
from scipy.integrate import quad

from calibration.geometry import direction_vector
from drivers.sim.camera_optics import (
    DEFAULT_LENS,
    LIMB_DARKENING_U,
    CameraDetector,
    CameraLens,
    CameraRenderer,
)
from drivers.sim.sky import SUN_DIAMETER_DEG, CloudState


@pytest.fixture
def renderer():
    return CameraRenderer(rng=np.random.default_rng(11))


def _moments(image: np.ndarray) -> np.ndarray:
    rows, cols = np.indices(image.shape)
    total = image.sum()
    return np.array([(image * cols).sum() / total, (image * rows).sum() / total])


def _tangent_basis(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """CloudState's basis at the Sun: e1 = x̂ − (x̂·s)s normalised, e2 = s × e1 (body frame)."""
    e1 = np.array([1.0, 0.0, 0.0]) - s[0] * s
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(s, e1)


def _frame_positions(renderer, n, margin_px, seed):
    """Directions whose true image lands uniformly over the frame, `margin_px` inside its border."""
    rng = np.random.default_rng(seed)
    det = renderer.detector
    xs = rng.uniform(margin_px, det.width_px - 1 - margin_px, n)
    ys = rng.uniform(margin_px, det.height_px - 1 - margin_px, n)
    return [renderer.pixel_direction(x, y) for x, y in zip(xs, ys)]


def test_noiseless_clear_disc_centroid_is_the_true_pixel_over_the_whole_frame(renderer):
    suns = _frame_positions(renderer, 60, 12, seed=1)
    corners = [renderer.pixel_direction(x, y) for x, y in [(12, 12), (627, 12), (12, 467), (627, 467)]]
    worst = 0.0
    for s in suns + corners:
        centre = np.array(renderer.true_pixel(s))
        worst = max(worst, float(np.hypot(*(_moments(renderer.signal(s, exposure_ms=1.0)) - centre))))
    print(f"noiseless centroid − true pixel: max {worst:.4f} px")
    assert worst < 0.01


def test_true_pixel_and_pixel_direction_invert_each_other_and_the_field_ends(renderer):
    for s in _frame_positions(renderer, 20, 0, seed=2):
        x, y = renderer.true_pixel(s)
        back = renderer.pixel_direction(x, y)
        assert np.degrees(np.linalg.norm(np.cross(back, s))) < 1e-9
    assert renderer.true_pixel(np.array([0.0, 0.0, -1.0])) is None  # behind the camera
    assert renderer.true_pixel(direction_vector(40.0, 0.0)) is None  # beyond the frame's edge
    assert renderer.true_pixel(direction_vector(20.0, 0.0)) is not None
    with pytest.raises(ValueError):
        renderer.true_pixel(np.zeros(3))


def test_the_lens_is_a_realistic_webcam_with_a_few_percent_barrel_and_an_off_centre_axis(renderer):
    f = DEFAULT_LENS.focal_px
    assert f == pytest.approx(800.0)
    # the boresight lands off the frame's centre (principal point + mount rotation)
    x0, y0 = renderer.true_pixel(np.array([0.0, 0.0, 1.0]))
    assert 1.0 < math.hypot(x0 - 319.5, y0 - 239.5) < 20.0
    # image height against a distortion-free pinhole, about the optical axis (no tilts, no mount)
    ideal = CameraRenderer(CameraLens(detector_tilt_x_deg=0, detector_tilt_y_deg=0, mount_tilt_x_deg=0,
                                      mount_tilt_y_deg=0, mount_twist_deg=0, principal_x_px=319.5,
                                      principal_y_px=239.5), rng=np.random.default_rng(0))
    corner = ideal.pixel_direction(0.0, 0.0)
    theta = math.acos(corner[2])
    r_true = math.hypot(319.5, 239.5)
    barrel = r_true / (f * math.tan(theta)) - 1.0
    print(f"distortion at the corner: {100 * barrel:.2f} %")
    assert -0.05 < barrel < -0.01


def test_exposure_scales_the_signal_and_saturation_clips_at_255(renderer):
    s = direction_vector(8.0, 40.0)
    one = renderer.signal(s, exposure_ms=1.0)
    np.testing.assert_allclose(renderer.signal(s, exposure_ms=3.0), 3.0 * one, rtol=1e-12)
    np.testing.assert_allclose(renderer.signal(s, exposure_ms=2.0, irradiance=0.5), one, rtol=1e-12)
    bias = renderer.detector.bias_dn
    box = np.s_[:, :]
    x, y = (int(round(v)) for v in renderer.true_pixel(s))
    box = np.s_[y - 8:y + 9, x - 8:x + 9]
    sums = [float((renderer.render(s, exposure_ms=e)[box].astype(float) - bias).sum()) for e in (2.0, 4.0)]
    assert sums[1] / sums[0] == pytest.approx(2.0, rel=0.03)
    frame = renderer.render(s, exposure_ms=40.0)
    assert frame.dtype == np.uint8 and frame.shape == (480, 640)
    assert frame.max() == 255 and np.count_nonzero(frame == 255) >= 20
    assert np.count_nonzero(renderer.render(s, exposure_ms=4.0) == 255) == 0


def test_noise_is_shot_plus_read_noise_and_the_background_sits_at_the_bias(renderer):
    det = renderer.detector
    s = direction_vector(5.0, 120.0)
    x, y = (int(round(v)) for v in renderer.true_pixel(s))
    exposure = 4.0
    mean = renderer.signal(s, exposure_ms=exposure)[y, x]
    values = np.array([renderer.render(s, exposure_ms=exposure)[y, x] for _ in range(360)], dtype=float)
    # the read noise comes from a pool of `pool_size` frames, so its mean over the pool is itself random
    assert values.mean() - det.bias_dn == pytest.approx(mean, abs=3 * det.read_noise_dn / math.sqrt(det.pool_size))
    # frames `pool_size` apart share their read noise: their difference is shot noise (and rounding) alone
    diff = values[det.pool_size:] - values[:-det.pool_size]
    assert diff.var() / 2 == pytest.approx(mean / det.electrons_per_dn + 1 / 12, rel=0.2)
    dark = renderer.render(s, exposure_ms=0.0)
    assert dark.mean() == pytest.approx(det.bias_dn, abs=0.05)
    assert dark.std() == pytest.approx(math.sqrt(det.read_noise_dn**2 + 1 / 12), rel=0.1)


def test_the_same_seed_gives_the_same_frames():
    s = direction_vector(12.0, 250.0)
    a = CameraRenderer(rng=np.random.default_rng(3))
    b = CameraRenderer(rng=np.random.default_rng(3))
    for _ in range(3):
        np.testing.assert_array_equal(a.render(s, exposure_ms=4.0), b.render(s, exposure_ms=4.0))


def test_a_half_covered_disc_moves_away_from_the_cloud_by_the_limb_darkened_half_disc_centroid(renderer):
    u = LIMB_DARKENING_U

    def intensity(r):
        return 1.0 - u * (1.0 - math.sqrt(1.0 - r * r))

    # centroid of the uncovered half of a limb-darkened disc, in disc radii (4/(3π) = 0.424 when uniform)
    xbar = 2 * quad(lambda r: r * r * intensity(r), 0, 1)[0] / (math.pi * quad(lambda r: r * intensity(r), 0, 1)[0])
    assert abs(xbar - 4 / (3 * math.pi)) > 0.02  # the limb darkening matters at the tolerance below
    rho = math.radians(SUN_DIAMETER_DEG / 2)
    for zenith, azimuth, angle in [(0.0, 0.0, 0.0), (10.0, 30.0, 90.0), (18.0, 200.0, 200.0), (14.0, 300.0, 45.0)]:
        s = direction_vector(zenith, azimuth)
        e1, e2 = _tangent_basis(s)
        toward = math.cos(math.radians(angle)) * e1 + math.sin(math.radians(angle)) * e2
        centre = np.array(renderer.true_pixel(s))
        # one disc radius toward the covered side, in pixels, through the renderer's own lens
        radius_vec = np.array(renderer.true_pixel(s * math.cos(rho) + toward * math.sin(rho))) - centre
        half = CloudState(edge_offset_deg=0.0, edge_angle_deg=angle)
        shift = _moments(renderer.signal(s, exposure_ms=1.0, clouds=half)) - centre
        expected = -xbar * radius_vec
        print(f"θ={zenith} φ={azimuth} edge {angle}°: shift {shift.round(4)} px, expected {expected.round(4)} px")
        assert np.hypot(*(shift - expected)) < 0.02
        # the covered half is dark: about half the clear flux is left
        ratio = renderer.signal(s, exposure_ms=1.0, clouds=half).sum() / renderer.signal(s, exposure_ms=1.0).sum()
        assert ratio == pytest.approx(0.5, abs=0.01)


def test_haze_thin_clouds_and_the_aureole_carry_the_light_they_should(renderer):
    s = direction_vector(6.0, 70.0)
    clear = renderer.signal(s, exposure_ms=1.0)
    np.testing.assert_allclose(renderer.signal(s, exposure_ms=1.0, clouds=CloudState(transmission=0.6)),
                               0.6 * clear, rtol=1e-6, atol=1e-9)
    thin = CloudState(edge_offset_deg=-math.inf, cloud_transmission=0.3)
    np.testing.assert_allclose(renderer.signal(s, exposure_ms=1.0, clouds=thin), 0.3 * clear, rtol=1e-6, atol=1e-9)
    halo = renderer.signal(s, exposure_ms=1.0, clouds=CloudState(aureole=0.2)) - clear
    assert halo.sum() / clear.sum() == pytest.approx(0.2, rel=0.03)
    # a broad halo: most of its light lies more than 0.5° from the Sun, little of it on the disc
    centre = np.array(renderer.true_pixel(s))
    rows, cols = np.indices(halo.shape)
    dist_px = np.hypot(cols - centre[0], rows - centre[1])
    assert halo[dist_px > 7.0].sum() > 0.8 * halo.sum()
    assert halo.max() < 0.01 * clear.max()


def test_charge_beyond_the_full_well_blooms_along_the_column():
    s = direction_vector(3.0, 10.0)
    blooming = CameraRenderer(rng=np.random.default_rng(4))
    plain = CameraRenderer(detector=CameraDetector(bloom=False), rng=np.random.default_rng(4))
    heavy = 300.0  # ms: ~30× the full well at the disc's centre
    sat_b = blooming.render(s, exposure_ms=heavy) == 255
    sat_p = plain.render(s, exposure_ms=heavy) == 255
    rows_b, cols_b = np.nonzero(sat_b)
    rows_p, cols_p = np.nonzero(sat_p)
    assert np.ptp(rows_b) > np.ptp(rows_p) + 4  # taller
    assert np.ptp(cols_b) == np.ptp(cols_p)  # not wider


def test_a_new_position_renders_in_a_few_ms_and_a_repeat_in_about_one(renderer):
    suns = _frame_positions(renderer, 40, 20, seed=5)
    renderer.render(suns[0], exposure_ms=4.0)
    t0 = time.perf_counter()
    for s in suns:
        renderer.render(s, exposure_ms=4.0)
    new_ms = (time.perf_counter() - t0) / len(suns) * 1e3
    t0 = time.perf_counter()
    for _ in range(40):
        renderer.render(suns[0], exposure_ms=4.0)
    repeat_ms = (time.perf_counter() - t0) / 40 * 1e3
    print(f"render 640×480: new position {new_ms:.2f} ms, same position {repeat_ms:.2f} ms")
    assert new_ms < 25.0 and repeat_ms < 10.0  # loose: a busy CI machine
