"""The simulator's own physics (drivers.sim.raytrace): the exact chief ray, Snell refraction, glass on the die
or under the mask, the bench's stage chain, and the rendered spot's shape and centroid."""

import dataclasses

import numpy as np
import pytest

from calibration.centroid import find_spot
from calibration.design import SensorDesign
from calibration.geometry import incidence_from_stage_angle
from calibration.pinhole import PinholeBuild, spot_from_direction
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.cmos_sensor import CmosSensorSimulator
from drivers.sim.motion import AxisSpec
from drivers.sim.raytrace import (
    SensorOptics,
    body_direction_from_stage,
    refract,
    spot_moments,
    spot_patch,
    sun_vector,
    trace_bench_frames,
    trace_chief_ray,
)
from drivers.sim.world import EXAMPLE_OPTICS, SensorTruth, SimWorld

PITCH = 0.0099  # mm, the default detector's


def _field(n=4000, seed=0, max_zenith=65.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, max_zenith, n), rng.uniform(0.0, 360.0, n)


# -- (a) two independent formulations of the same sensor ---------------------------------------------------
@pytest.mark.parametrize("build", [
    dict(x0_px=319.5, y0_px=239.5, gap_mm=1.37),
    dict(x0_px=325.8, y0_px=233.4, gap_mm=1.05, glass_mm=0.5, tilt_x_deg=0.22, tilt_y_deg=-0.21, rotation_deg=1.4),
    dict(x0_px=301.2, y0_px=255.9, gap_mm=0.9, glass_mm=0.7, glass_index=1.77, tilt_x_deg=-2.5, tilt_y_deg=3.0,
         rotation_deg=-40.0, mirrored=True),
    dict(x0_px=330.0, y0_px=220.0, gap_mm=1.2, glass_mm=0.3, tilt_x_deg=1.0, rotation_deg=175.0, mirrored=True),
])
def test_chief_ray_agrees_with_the_calibrations_closed_form(build):
    """Cross-check of two independent formulations: the simulator traces the ray through explicit planes with
    vector Snell refraction; calibration.pinhole scales sin θ_d by k(θ_d) = g / cos θ_d + t / (n cos θ_g) in the
    detector frame. For a thin round hole and glass on the die they describe the same sensor, so they must agree
    to rounding (1e-6 px) over the whole field, at any tilt, rotation and read-out handedness."""
    zenith, azimuth = _field()
    x, y = trace_chief_ray(zenith, azimuth, SensorOptics(**build, pixel_pitch_mm=PITCH))
    x_ref, y_ref = spot_from_direction(zenith, azimuth, PinholeBuild(**build), PITCH)
    assert np.max(np.hypot(x - x_ref, y - y_ref)) < 1e-6


@pytest.mark.parametrize("tilt", [(1.5, 0.0, 0.8), (-0.7, 2.0, -35.0)])
def test_glass_under_the_mask_agrees_with_the_calibrations_exact_trace(tilt):
    """The same cross-check for glass bonded under the mask: calibration.pinhole's ``glass_on_mask`` traces the
    chief ray its own way (Snell's vector form into a plate on the housing's normal, then a line-plane
    intersection with the die), so the two must agree to rounding."""
    tx, ty, rot = tilt
    build = dict(x0_px=325.8, y0_px=233.4, gap_mm=1.05, glass_mm=0.5, tilt_x_deg=tx, tilt_y_deg=ty, rotation_deg=rot)
    zenith, azimuth = _field()
    x, y = trace_chief_ray(zenith, azimuth, SensorOptics(**build, glass_position="mask", pixel_pitch_mm=PITCH))
    x_ref, y_ref = spot_from_direction(zenith, azimuth, PinholeBuild(**build, glass_on_mask=True), PITCH)
    assert np.max(np.hypot(x - x_ref, y - y_ref)) < 1e-6


def test_a_thick_mask_leaves_the_chief_ray_alone():
    # the gap runs from the hole's mid-plane, so the chief ray does not depend on the mask's thickness
    zenith, azimuth = _field(500)
    thin = trace_chief_ray(zenith, azimuth, EXAMPLE_OPTICS)
    thick = trace_chief_ray(zenith, azimuth, dataclasses.replace(EXAMPLE_OPTICS, mask_thickness_mm=0.05))
    assert np.max(np.abs(np.subtract(thin, thick))) < 1e-9


# -- (b) Snell's law ---------------------------------------------------------------------------------------
def test_refract_obeys_snells_law_and_refuses_total_internal_reflection():
    rng = np.random.default_rng(1)
    normal = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    incoming = -sun_vector(rng.uniform(0, 80, 200), rng.uniform(0, 360, 200))
    incoming = incoming[incoming @ normal < 0]
    out = refract(incoming, normal, 1.0 / 1.52)
    sin_in = np.linalg.norm(np.cross(incoming, normal), axis=-1)
    sin_out = np.linalg.norm(np.cross(out, normal), axis=-1)
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(1.0 * sin_in, 1.52 * sin_out, atol=1e-12)  # n₁ sin θ₁ = n₂ sin θ₂
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(incoming, normal), out), 0.0, atol=1e-12)  # coplanar
    back = refract(out, normal, 1.52)
    np.testing.assert_allclose(back, incoming, atol=1e-12)  # a plane-parallel plate keeps the direction
    with pytest.raises(ValueError, match="total internal reflection"):
        refract(sun_vector(60.0, 0.0) * [1, 1, -1], [0, 0, 1], 1.52)  # sin 60° × 1.52 > 1


def test_no_shift_at_normal_incidence_and_the_plate_formula_at_oblique_incidence():
    with_glass = SensorOptics(x0_px=320.0, y0_px=240.0, gap_mm=0.9, glass_mm=0.5, glass_index=1.52)
    no_glass = dataclasses.replace(with_glass, gap_mm=1.4, glass_mm=0.0)  # the same height, all air
    x, y = trace_chief_ray(0.0, 37.0, with_glass)
    assert (x, y) == pytest.approx((320.0, 240.0), abs=1e-12)
    zenith, azimuth = np.linspace(1.0, 70.0, 50), np.linspace(0.0, 350.0, 50)
    xg, yg = trace_chief_ray(zenith, azimuth, with_glass)
    xa, ya = trace_chief_ray(zenith, azimuth, no_glass)
    # the glass pulls the spot back toward the foot; the ray's lateral shift (perpendicular to itself) is the
    # textbook plate formula d = t sin(θ − θ_g) / cos θ_g (the spot's shift on the die times cos θ)
    th = np.radians(zenith)
    th_g = np.arcsin(np.sin(th) / 1.52)
    plate = 0.5 * np.sin(th - th_g) / np.cos(th_g)
    shift_mm = np.hypot(xg - xa, yg - ya) * PITCH
    np.testing.assert_allclose(shift_mm * np.cos(th), plate, rtol=1e-9, atol=1e-12)
    # and toward the foot: along −(direction of the spot from the foot)
    assert np.all((xa - 320.0) * (xg - xa) + (ya - 240.0) * (yg - ya) < 0)


# -- (c) glass under the mask against a tilted die ---------------------------------------------------------
def test_glass_under_the_mask_differs_from_glass_on_a_tilted_die():
    die = SensorOptics(x0_px=320.0, y0_px=240.0, gap_mm=1.05, glass_mm=0.5, tilt_x_deg=0.3, tilt_y_deg=-0.2)
    mask = dataclasses.replace(die, glass_position="mask")
    azimuth = np.arange(0.0, 360.0, 45.0)
    xd, yd = trace_chief_ray(50.0, azimuth, die)
    xm, ym = trace_chief_ray(50.0, azimuth, mask)
    assert np.min(np.hypot(xd - xm, yd - ym)) > 0.05  # px, at every azimuth
    # with the die parallel to the mask the two placements are the same plane-parallel stack
    flat_die, flat_mask = (dataclasses.replace(o, tilt_x_deg=0.0, tilt_y_deg=0.0) for o in (die, mask))
    zenith, az = _field(300)
    np.testing.assert_allclose(trace_chief_ray(zenith, az, flat_die), trace_chief_ray(zenith, az, flat_mask),
                               atol=1e-9)


def test_glass_under_the_mask_matches_a_hand_calculation():
    """One ray in the plane of the tilt, worked by hand in 2-D: a die tipped by α toward azimuth 0°, the sun at
    azimuth 0°, zenith θ. In the plate (z from 0 to −t) the ray runs at θ_g = asin(sin θ / n), leaving it at
    x = −t tan θ_g; then along (−sin θ, −cos θ) to the die plane N·X = −h, N = (sin α, 0, cos α), which it
    meets after λ = (h − t cos α − t sin α tan θ_g) / cos(θ − α); the die's x axis is (cos α, 0, −sin α)."""
    alpha, theta, g, t, n = np.radians(0.8), np.radians(50.0), 1.05, 0.5, 1.52
    h = g + t
    theta_g = np.arcsin(np.sin(theta) / n)
    lam = (h - t * np.cos(alpha) - t * np.sin(alpha) * np.tan(theta_g)) / np.cos(theta - alpha)
    x_mm = -t * (np.cos(alpha) * np.tan(theta_g) - np.sin(alpha)) - lam * np.sin(theta - alpha)
    optics = SensorOptics(x0_px=320.0, y0_px=240.0, gap_mm=g, glass_mm=t, glass_index=n, tilt_x_deg=0.8,
                          glass_position="mask")
    x, y = trace_chief_ray(50.0, 0.0, optics)
    assert x == pytest.approx(320.0 + x_mm / PITCH, abs=1e-9) and y == pytest.approx(240.0, abs=1e-9)
    # the same ray with the glass on the die: the plate formula at the die incidence θ − α
    theta_d = theta - alpha
    x_die_mm = -(g * np.tan(theta_d) + t * np.tan(np.arcsin(np.sin(theta_d) / n)))
    x_die, _ = trace_chief_ray(50.0, 0.0, dataclasses.replace(optics, glass_position="die"))
    assert x_die == pytest.approx(320.0 + x_die_mm / PITCH, abs=1e-9)
    assert abs(x - x_die) > 0.1  # px


# -- (d) the bench's stage chain ---------------------------------------------------------------------------
@pytest.mark.parametrize("source_mm", [710.0, 7100.0])
def test_stage_chain_reduces_to_seed003_eq8(source_mm):
    omega = np.array([-30.0, -5.0, 0.0, 10.0, 20.0, 40.0, 60.0])
    stage_azimuth = np.array([10.0, 45.0, 90.0, 135.0, 200.0, 270.0, 315.0])
    zenith, azimuth = body_direction_from_stage(stage_azimuth, omega, lever_arm_mm=136.2, source_distance_mm=source_mm)
    np.testing.assert_allclose(zenith, np.abs(incidence_from_stage_angle(omega, 136.2, source_mm)), atol=1e-9)
    expected = np.where(omega < 0, stage_azimuth + 180.0, stage_azimuth) % 360.0
    lit = omega != 0  # the azimuth of the boresight is 0 by convention
    np.testing.assert_allclose(azimuth[lit], expected[lit], atol=1e-9)


def test_zero_offsets_are_the_true_angle_where_a_stage_reads_zero():
    kw = dict(lever_arm_mm=136.2, source_distance_mm=7100.0)
    # true = reading + zero: a zenith stage whose zero lies at 0.5° true puts the sun at eq. 8's 0.5° at 0
    zenith, azimuth = body_direction_from_stage(30.0, 0.0, zenith_zero_deg=0.5, **kw)
    assert zenith == pytest.approx(incidence_from_stage_angle(0.5, 136.2, 7100.0), abs=1e-12)
    assert azimuth == pytest.approx(30.0, abs=1e-9)
    readings = (np.array([0.0, 45.0, 300.0]), np.array([5.0, 20.0, 55.0]))
    offset = body_direction_from_stage(*readings, azimuth_zero_deg=-0.7, zenith_zero_deg=0.3, **kw)
    shifted = body_direction_from_stage(readings[0] - 0.7, readings[1] + 0.3, **kw)
    np.testing.assert_allclose(offset, shifted, atol=1e-12)
    _, flipped = body_direction_from_stage(120.0, 20.0, azimuth_sign=-1.0, **kw)
    assert flipped == pytest.approx(240.0, abs=1e-9)


def test_mount_tilt_tips_the_boresight_as_documented():
    kw = dict(lever_arm_mm=136.2, source_distance_mm=7100.0)
    assert body_direction_from_stage(0.0, 0.0, mount_tilt_x_deg=0.5, **kw) == (pytest.approx(0.5, abs=1e-9),
                                                                              pytest.approx(180.0, abs=1e-9))
    assert body_direction_from_stage(0.0, 0.0, mount_tilt_y_deg=0.5, **kw) == (pytest.approx(0.5, abs=1e-9),
                                                                              pytest.approx(270.0, abs=1e-9))
    # tilted toward azimuth 0°, the sun at stage azimuth 0° is seen 0.5° nearer the boresight
    tilted, _ = body_direction_from_stage(0.0, 20.0, mount_tilt_x_deg=0.5, **kw)
    straight, _ = body_direction_from_stage(0.0, 20.0, **kw)
    assert tilted == pytest.approx(straight - 0.5, abs=1e-9)


def test_the_world_uses_the_same_chain():
    world = SimWorld(mount_tilt_x_deg=0.33, mount_tilt_y_deg=-0.33, azimuth_sign=-1.0)
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.azimuth.move_to(135.0)
    world.zenith.move_to(40.0)
    expected = body_direction_from_stage(*world.stage_true_deg(), lever_arm_mm=world.bench.lever_arm_mm,
                                         source_distance_mm=world.bench.source_distance_mm, mount_tilt_x_deg=0.33,
                                         mount_tilt_y_deg=-0.33, azimuth_sign=-1.0)
    assert world.sun_direction_body() == (pytest.approx(float(expected[0]), abs=1e-12),
                                          pytest.approx(float(expected[1]), abs=1e-12))


def test_alt_az_order_is_a_gimbal():
    zenith, azimuth = body_direction_from_stage([30.0, 0.0, 30.0], [0.0, 20.0, 20.0], lever_arm_mm=0.0,
                                                source_distance_mm=1e9, axis_order="zenith-on-azimuth")
    assert zenith[:2] == pytest.approx([30.0, 20.0], abs=1e-6) and azimuth[:2] == pytest.approx([0.0, 90.0], abs=1e-6)
    assert np.cos(np.radians(zenith[2])) == pytest.approx(np.cos(np.radians(30)) * np.cos(np.radians(20)), abs=1e-9)
    with pytest.raises(ValueError, match="axis_order"):
        body_direction_from_stage(0.0, 0.0, lever_arm_mm=0.0, source_distance_mm=1.0, axis_order="sideways")


def test_trace_bench_frames_adds_the_stated_noise_to_the_chief_ray():
    zenith, azimuth = _field(20000)
    x, y = trace_bench_frames(zenith, azimuth, EXAMPLE_OPTICS, noise_px=0.02, rng=np.random.default_rng(5))
    x0, y0 = trace_chief_ray(zenith, azimuth, EXAMPLE_OPTICS)
    assert np.std(x - x0) == pytest.approx(0.02, rel=0.03) and np.std(y - y0) == pytest.approx(0.02, rel=0.03)
    assert abs(np.mean(x - x0)) < 0.001 and abs(np.mean(y - y0)) < 0.001


# -- the spot ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mask_mm", [0.0, 0.01, 0.03])
def test_the_spot_centroid_is_the_chief_ray(mask_mm):
    # every blur is centrally symmetric; a thick hole's vignetting weighted across the 0.5° source moves the
    # centroid by ~1e-3 px at 60°, and the antialiased supersampling adds less than that
    optics = dataclasses.replace(EXAMPLE_OPTICS, mask_thickness_mm=mask_mm, hole_axis_ratio=1.05,
                                 hole_axis_deg=20.0)
    worst = 0.0
    for zenith in (0.0, 20.0, 40.0, 60.0):
        for azimuth in (0.0, 70.0, 135.0, 250.0):
            patch = spot_patch(zenith + 0.37, azimuth, optics, supersample=4)
            x, y, _ = spot_moments(patch)
            worst = max(worst, np.hypot(x - patch.chief_x_px, y - patch.chief_y_px))
    assert worst < 0.003  # px


def test_the_spot_is_the_holes_shadow():
    flat = SensorOptics(x0_px=320.0, y0_px=240.0, gap_mm=1.05, glass_mm=0.5, wavelength_mm=0.0)
    area_px = np.pi * (flat.hole_diameter_mm / 2 / PITCH) ** 2
    # a flat die sees the hole's shadow at its true size at any incidence: its integral is the hole's area
    for zenith in (0.0, 45.0):
        assert spot_patch(zenith, 30.0, flat).image.sum() == pytest.approx(area_px, rel=2e-3)
    # a thick hole passes the overlap of its two faces, offset by T tan θ (the lens of two equal circles)
    thick = dataclasses.replace(flat, mask_thickness_mm=0.03)
    u = 0.03 * np.tan(np.radians(45.0)) / flat.hole_diameter_mm
    lens = 2 / np.pi * (np.arccos(u) - u * np.sqrt(1 - u * u))
    assert spot_patch(45.0, 30.0, thick).image.sum() == pytest.approx(lens * area_px, rel=3e-3)
    # a non-round hole: the spot's long axis lies along the hole's (no rotation, tilt or mirror here)
    oval = dataclasses.replace(flat, hole_axis_ratio=1.3, hole_axis_deg=25.0)
    _, _, cov = spot_moments(spot_patch(0.0, 0.0, oval))
    values, vectors = np.linalg.eigh(cov)
    assert np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])) % 180.0 == pytest.approx(25.0, abs=0.5)
    # the 0.5° source stretches the spot radially at oblique incidence (along azimuth 0°: along x)
    _, _, cov = spot_moments(spot_patch(60.0, 0.0, flat))
    assert cov[0, 0] > cov[1, 1] * 1.1


def _world(truth: SensorTruth, zenith_stage_deg: float, azimuth_deg: float) -> SimWorld:
    world = SimWorld(sensor=truth, seed=2)
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.lamp.start(), world.lamp.is_warm()
    world.lamp.shutter_open = True
    world.azimuth.move_to(azimuth_deg)
    world.zenith.move_to(zenith_stage_deg)
    return world


# -- (e) and (f) rendered frames ---------------------------------------------------------------------------
@pytest.mark.parametrize("zenith_stage, azimuth", [(20.0, 30.0), (35.0, 200.0)])
def test_rendered_spot_centroid_lands_on_the_chief_ray(zenith_stage, azimuth):
    truth = SensorTruth(build=dataclasses.replace(EXAMPLE_OPTICS, mask_thickness_mm=0.0))
    world = _world(truth, zenith_stage, azimuth)
    renderer = CmosSensorSimulator(world).renderer
    zenith, az = world.sun_direction_body()
    x, y = trace_chief_ray(zenith, az, world.sensor.optics)
    spots = [find_spot(renderer.render(4.0), saturation_dn=1023) for _ in range(8)]
    mean_x, mean_y = np.mean([s.x_px for s in spots]), np.mean([s.y_px for s in spots])
    assert np.hypot(mean_x - x, mean_y - y) < 0.05  # px (the noise of one frame is ~0.015 px)


def test_a_large_detector_renders_its_own_frame_with_the_spot_where_the_trace_says():
    design = SensorDesign(width_px=1280, height_px=1024, pixel_pitch_mm=0.0053)
    truth = SensorTruth(build=dataclasses.replace(EXAMPLE_OPTICS, x0_px=641.3, y0_px=508.6), design=design)
    world = _world(truth, 30.0, 120.0)
    sim = CmosSensorSimulator(world)
    frame = sim.renderer.render(4.0)
    assert frame.shape == (1024, 1280)
    zenith, azimuth = world.sun_direction_body()
    x, y = trace_chief_ray(zenith, azimuth, world.sensor.optics)
    assert np.hypot(x - 641.3, y - 508.6) > 140  # px: 0.78 mm from the foot at 5.3 µm (79 px at 9.9 µm)
    spot = find_spot(frame, saturation_dn=1023)
    assert np.hypot(spot.x_px - x, spot.y_px - y) < 0.05


def test_the_bench_file_sensor_section_sets_the_optics_and_the_detector():
    config = SimBenchConfig(sensor={"build": {"glass_position": "mask", "mask_thickness_mm": 0.02},
                                    "detector": {"width_px": 1280, "height_px": 1024, "pixel_pitch_mm": 0.0053},
                                    "hole_diameter_mm": 0.05})
    optics = SimBench(config, time_scale=0.0).world.sensor.optics
    assert optics.glass_position == "mask" and optics.mask_thickness_mm == 0.02
    assert (optics.width_px, optics.height_px, optics.pixel_pitch_mm) == (1280, 1024, 0.0053)
    assert optics.hole_diameter_mm == 0.05 and optics.hole_axis_ratio == pytest.approx(1.002)
    with pytest.raises(ValueError, match="half the mask thickness"):
        SimBenchConfig(sensor={"build": {"gap_mm": 0.01, "mask_thickness_mm": 0.05}})
