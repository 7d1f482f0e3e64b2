"""Table angles → the Sun's (α, β) on the sensor, and back (digest §7 item 9)."""

import numpy as np
import pytest

from calibration.errors import CalibrationError
from calibration.geometry import direction_vector
from calibration.mount import (
    ForkMount,
    fork_vectors,
    mount_for_projection,
    mount_projection,
    projection_grid,
    table_vectors,
)
from calibration.qd.angles import angle_between_projections_deg, projection_angles_from_vector
from calibration.stage_geometry import StageGeometry


def test_naive_table_angles_are_7_6_degrees_off_at_the_corner_and_the_mapping_is_exact():
    fork = ForkMount()
    alpha, beta = mount_projection(40.0, 40.0, fork)  # the naive plan: table angles = (α, β) = (40°, 40°)
    expected = np.degrees(np.arctan(np.tan(np.radians(40.0)) / np.cos(np.radians(40.0))))  # digest: 47.6°
    assert alpha == pytest.approx(expected, abs=1e-12) and beta == pytest.approx(40.0, abs=1e-12)
    assert alpha - 40.0 == pytest.approx(7.6, abs=0.05)
    miss = angle_between_projections_deg(40.0, 40.0, alpha, beta)
    print(f"\nnaive fork angles (40°, 40°): α = {float(alpha):.3f}°, β = {float(beta):.3f}°, "
          f"{float(miss):.3f}° from the wanted direction")
    # the mapping's readings put the Sun exactly there
    az, alt = mount_for_projection(40.0, 40.0, fork)
    a2, b2 = mount_projection(az, alt, fork)
    assert a2 == pytest.approx(40.0, abs=1e-12) and b2 == pytest.approx(40.0, abs=1e-12)
    t = np.tan(np.radians(40.0))
    assert az == pytest.approx(np.degrees(np.arcsin(t / np.sqrt(1 + 2 * t * t))), abs=1e-9)  # asin(s_x), 33.3°
    assert alt == pytest.approx(40.0, abs=1e-12)  # β is the inner axis' angle itself


def test_fork_kinematics_is_the_digests_with_its_sign():
    a, b = np.radians(25.0), np.radians(-15.0)
    s = fork_vectors(25.0, -15.0, ForkMount(azimuth_sign=-1.0))
    np.testing.assert_allclose(s, [-np.sin(a), np.sin(b) * np.cos(a), np.cos(a) * np.cos(b)], atol=1e-15)


@pytest.mark.parametrize("mount", [ForkMount(), ForkMount(-1.0, 1.0, 181.5, -0.7, 12.0),
                                   StageGeometry(0.0), StageGeometry(0.16, 0.3, 0.0, 0.1, -0.05)],
                         ids=["fork", "fork-offsets", "seed003-ideal", "seed003-bench"])
def test_round_trip_over_the_field(mount):
    plan = projection_grid(40.0, 5.0)  # the nodes and the check points between them
    a, b = plan["alpha_deg"], plan["beta_deg"]
    first, second = mount_for_projection(a, b, mount)
    a2, b2 = mount_projection(first, second, mount)
    np.testing.assert_allclose(a2, a, atol=1e-9)
    np.testing.assert_allclose(b2, b, atol=1e-9)


def test_seed003_table_puts_the_sun_at_its_stage_angles():
    phi, omega = np.meshgrid(np.arange(0.0, 360.0, 45.0), [10.0, 30.0, 50.0])
    np.testing.assert_allclose(table_vectors(phi, omega), direction_vector(omega, phi), atol=1e-15)
    # and the inverse finds them
    a, b = projection_angles_from_vector(direction_vector(omega, phi))
    p2, o2 = mount_for_projection(a, b, StageGeometry(0.0))
    np.testing.assert_allclose(o2, omega, atol=1e-9)
    np.testing.assert_allclose(np.mod(p2 - phi + 180, 360) - 180, 0.0, atol=1e-9)


def test_an_unreachable_direction_is_named():
    bench = StageGeometry(0.16, 0.0, -0.2)  # the source 0.2° out of the zenith stage's plane
    with pytest.raises(CalibrationError, match="cannot be set"):
        mount_for_projection([0.0, 10.0], [0.0, 5.0], bench)
    first, _ = mount_for_projection([0.0, 10.0], [0.0, 5.0], bench, unreachable="nan")
    assert np.isnan(first[0]) and np.isfinite(first[1])


def test_grid_plan_has_nodes_and_checkpoints_between_them():
    plan = projection_grid(40.0, 5.0)
    nodes, check = ~plan["check"], plan["check"]
    assert nodes.sum() == 17 * 17 and check.sum() == 16 * 16
    assert np.all(np.mod(plan["alpha_deg"][check], 5.0) == 2.5)
    assert plan["alpha_deg"].max() == 40.0 and plan["beta_deg"].min() == -40.0
