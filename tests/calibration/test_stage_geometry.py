"""Stage angles to body directions on seed 003's bench (eq. 8), and the bench geometry the fits start from."""

import numpy as np
import pytest
from test_geometry import EQ8_TABLE  # seed 003 digest §2.6, [derived] from eq. 8 with d = 136.2 mm

from calibration.design import DEFAULT_BENCH, BenchGeometry
from calibration.geometry import zenith_azimuth_from_vector
from calibration.stage_geometry import (
    GeometryPrior,
    StageGeometry,
    arm_ratio,
    body_direction_deg,
    body_vectors_from_stage,
)


@pytest.mark.parametrize("source_mm", sorted(EQ8_TABLE))
def test_body_direction_reproduces_the_eq8_table(source_mm):
    geometry = BenchGeometry(lever_arm_mm=136.2, source_distance_mm=source_mm)
    zenith, azimuth = body_direction_deg(np.full(7, 45.0), np.arange(0, 61, 10), geometry)
    np.testing.assert_allclose(zenith, EQ8_TABLE[source_mm], atol=1e-3)
    np.testing.assert_allclose(azimuth, 45.0)


def test_a_negative_stage_angle_is_the_opposite_azimuth():
    zenith, azimuth = body_direction_deg(45.0, -10.0, DEFAULT_BENCH)
    assert float(zenith) == pytest.approx(11.902, abs=1e-3) and float(azimuth) == pytest.approx(225.0)
    zenith, azimuth = body_direction_deg(270.0, -30.0, DEFAULT_BENCH)  # wrapped to [0, 360)
    assert float(zenith) == pytest.approx(35.342, abs=1e-3) and float(azimuth) == pytest.approx(90.0)
    assert body_direction_deg(-45.0, 0.0, DEFAULT_BENCH) == (0.0, 315.0)


def test_body_direction_scalar_array_and_nan():
    zenith, azimuth = body_direction_deg(0.0, 10.0, DEFAULT_BENCH)
    assert np.ndim(zenith) == np.ndim(azimuth) == 0
    zenith, azimuth = body_direction_deg([0.0, 90.0], [[10.0], [np.nan]], DEFAULT_BENCH)  # broadcast
    assert zenith.shape == azimuth.shape == (2, 2)
    assert np.isnan(zenith[1]).all() and np.isnan(azimuth[1]).all() and np.isfinite(zenith[0]).all()
    np.testing.assert_allclose(azimuth[0], [0.0, 90.0])


def test_body_direction_is_the_stage_vector_model_without_offsets():
    rng = np.random.default_rng(3)
    az, omega = rng.uniform(-180, 360, 200), rng.uniform(-70, 70, 200)
    geometry = BenchGeometry(lever_arm_mm=136.2, source_distance_mm=710.0)
    zenith, azimuth = body_direction_deg(az, omega, geometry)
    q = arm_ratio(geometry.lever_arm_mm, geometry.source_distance_mm)
    z2, a2 = zenith_azimuth_from_vector(body_vectors_from_stage(az, omega, StageGeometry(q)))
    np.testing.assert_allclose(zenith, z2, atol=1e-9)
    near_axis = zenith < 1e-6  # the azimuth of the boresight is arbitrary
    np.testing.assert_allclose(np.mod(azimuth - a2 + 180.0, 360.0)[~near_axis] - 180.0, 0.0, atol=1e-9)


def test_bench_geometry_carries_the_measured_uncertainties():
    assert DEFAULT_BENCH.lever_arm_sd_mm is None and DEFAULT_BENCH.source_distance_sd_mm is None
    with pytest.raises(ValueError, match="lever_arm_sd_mm"):
        BenchGeometry(lever_arm_sd_mm=0.0)
    with pytest.raises(ValueError, match="source_distance_sd_mm"):
        BenchGeometry(source_distance_sd_mm=-1.0)


def test_the_prior_is_built_from_the_bench_geometry():
    geometry = BenchGeometry(lever_arm_mm=134.5, source_distance_mm=7080.0, lever_arm_sd_mm=2.0,
                             source_distance_sd_mm=20.0)
    prior = GeometryPrior.from_bench(geometry, mount_tilt_x_deg=0.1)
    assert (prior.lever_arm_mm, prior.lever_arm_sd_mm, prior.source_distance_mm, prior.source_distance_sd_mm) == \
        (134.5, 2.0, 7080.0, 20.0)
    assert prior.mount_tilt_x_deg == 0.1 and prior.mount_tilt_y_deg == 0.0
    assert prior.ratio[0] == pytest.approx(arm_ratio(134.5, 7080.0))
    # a sensor on the zenith axis states no lever arm the fit could use (its logarithm is undefined)
    on_axis = GeometryPrior.from_bench(BenchGeometry(lever_arm_mm=0.0))
    assert on_axis.lever_arm_mm is None and on_axis.ratio is None
