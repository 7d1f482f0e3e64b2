"""The physical model (spot overlap with the quadrants, gap, gains, offsets) against a brute-force sensor."""

import dataclasses

import numpy as np
import pytest
from qd_simulation import SENSOR, grid, measure

from calibration.qd.angles import angle_between_projections_deg
from calibration.qd.design import QdDesign, quadrant_layout
from calibration.qd.evaluation import heldout_schemes
from calibration.qd.geometric import fit_geometric
from calibration.qd.overlap import corner_area, corner_area_gradient, quadrant_areas
from calibration.qd.physical import (
    FIXED_NOTES,
    PhysicalParameters,
    fit_physical,
    invert_physical,
    predict_currents,
    predict_shares,
)
from calibration.qd.polynomial import select_polynomial
from calibration.qd.spot import spot_position, spot_ratios

DESIGN = QdDesign(diaphragm_diameter_m=2 * SENSOR.radius_m, pinhole_height_m=SENSOR.d_m, gap_m=5e-6)
TRUE = PhysicalParameters(x0_m=SENSOR.x0_m, y0_m=SENSOR.y0_m, alpha0_deg=SENSOR.alpha0_deg,
                          beta0_deg=SENSOR.beta0_deg, phi0_deg=SENSOR.phi0_deg, d_m=SENSOR.d_m, gap_m=SENSOR.gap_m,
                          gain2=SENSOR.gains[1], gain3=SENSOR.gains[2], gain4=SENSOR.gains[3], radius_m=SENSOR.radius_m)


def test_corner_area_against_an_independent_monte_carlo_count():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1.0, 1.0, (2_000_000, 2))
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < 1.0]
    for a, b in [(0.0, 0.0), (0.3, -0.2), (-0.5, -0.7), (-1.5, 0.4), (0.6, 0.6), (0.95, 0.95), (-0.3, 0.95)]:
        share = np.mean((pts[:, 0] > a) & (pts[:, 1] > b))
        sigma = np.pi * np.sqrt(max(share * (1 - share), 1e-6) / pts.shape[0])
        assert corner_area(a, b, 1.0) == pytest.approx(share * np.pi, abs=5 * sigma)
    a, b = rng.uniform(-1.2, 1.2, (2, 500))
    ga, gb = corner_area_gradient(a, b, 1.0)
    h = 1e-6
    np.testing.assert_allclose((corner_area(a + h, b, 1.0) - corner_area(a - h, b, 1.0)) / (2 * h), ga, atol=1e-6)
    np.testing.assert_allclose((corner_area(a, b + h, 1.0) - corner_area(a, b - h, 1.0)) / (2 * h), gb, atol=1e-6)
    # the four quadrants and the dead cross share the disc exactly
    signs = quadrant_layout("thesis")
    g = 0.1
    total = quadrant_areas(0.0, 0.0, 1.0, g, signs).sum()
    strip = 2 * (np.arcsin(g / 2) + (g / 2) * np.sqrt(1 - (g / 2) ** 2))  # area of |x| < g/2 in the unit disc
    assert total == pytest.approx(np.pi - 2 * strip + g * g, rel=1e-12)  # two strips, overlapping in a g × g square


def test_inversion_round_trips_the_model():
    a, b = grid(40.0, 2.5)
    currents = predict_currents(a, b, TRUE, 600.0)
    alpha, beta, ok = invert_physical(currents, TRUE)
    assert ok.all()
    assert np.abs(alpha - a).max() < 1e-9 and np.abs(beta - b).max() < 1e-9
    for offsets in ("additive",):
        p = dataclasses.replace(TRUE, offsets=offsets)
        alpha, beta, ok = invert_physical(predict_currents(a, b, p, 600.0), p)
        assert ok.all() and np.abs(alpha - a).max() < 1e-9


def test_a_spot_off_the_centre_gives_no_direction():
    alpha, beta, ok = invert_physical(predict_currents([0.0, 75.0], [0.0, 70.0], TRUE, 600.0), TRUE)
    assert ok.tolist() == [True, False] and np.isnan(alpha[1]) and np.isnan(beta[1])


def test_only_length_ratios_reach_the_currents():
    """Why the radius is fixed: scaling every length leaves every current's share unchanged."""
    a, b = grid(40.0, 10.0)
    k = 1.7
    scaled = dataclasses.replace(TRUE, x0_m=k * TRUE.x0_m, y0_m=k * TRUE.y0_m, d_m=k * TRUE.d_m,
                                 gap_m=k * TRUE.gap_m, radius_m=k * TRUE.radius_m)
    np.testing.assert_allclose(predict_shares(a, b, scaled), predict_shares(a, b, TRUE), atol=1e-14)
    assert any("radius_m is fixed" in n for n in FIXED_NOTES)


@pytest.fixture(scope="module")
def measured(physical_grid):
    rng = np.random.default_rng(7)
    t = rng.uniform(18.0, 32.0, physical_grid["alpha_deg"].size)
    raw = measure(physical_grid["photocurrents_a"], t, SENSOR, rng)
    return {**physical_grid, "photo": raw - SENSOR.dark(t)}  # the dark current known here; dark fits elsewhere


def test_physical_model_held_out_between_the_nodes_within_a_tenth_of_a_degree(measured):
    nodes, check = ~measured["check"], measured["check"]
    a, b, photo = measured["alpha_deg"], measured["beta_deg"], measured["photo"]
    fit = fit_physical(a[nodes], b[nodes], photo[nodes], design=DESIGN, offsets="auto")
    alpha, beta, ok = invert_physical(photo[check], fit.parameters)
    assert ok.all()
    err = angle_between_projections_deg(a[check], b[check], alpha, beta)
    # for comparison: eq. 2.1 + eq. 2.2, and eq. 2.1 + the eq. 2.3 polynomial of held-out order
    xc, yc = spot_position(photo, DESIGN.eq21_length_m)
    geo = fit_geometric(xc[nodes], yc[nodes], a[nodes], b[nodes])
    g_err = angle_between_projections_deg(a[check], b[check], *geo.apply(xc[check], yc[check]))
    u, v = spot_ratios(photo)
    poly = select_polynomial(u[nodes], v[nodes], a[nodes], b[nodes],
                             list(heldout_schemes(a[nodes], b[nodes]).values())).model
    p_err = angle_between_projections_deg(a[check], b[check], *poly.evaluate(u[check], v[check]))
    print(f"\nheld out at {check.sum()} cell centres of the ±40° grid (max / RMS):"
          f"\n  physical   {err.max():.4f}° / {np.sqrt(np.mean(err**2)):.4f}°  ({fit.parameters.offsets} offsets)"
          f"\n  polynomial {p_err.max():.4f}° / {np.sqrt(np.mean(p_err**2)):.4f}°  ({poly.kind} {poly.degree})"
          f"\n  geometric  {g_err.max():.4f}° / {np.sqrt(np.mean(g_err**2)):.4f}°")
    assert err.max() <= 0.1
    assert np.sqrt(np.mean(err**2)) <= 0.03
    assert g_err.max() > 5 * err.max()  # eq. 2.1's linear reading of the QD costs the geometric model


def test_physical_fit_recovers_the_build(measured):
    nodes = ~measured["check"]
    fit = fit_physical(measured["alpha_deg"][nodes], measured["beta_deg"][nodes], measured["photo"][nodes],
                       design=DESIGN, offsets="auto")
    p = fit.parameters
    # The brute-force sensor's own integration error (≈5e-5 of a share, not white) exceeds the fit's formal 1σ,
    # so the build is checked against tolerances of the integration's size, not against 3σ.
    assert p.offsets == "rotation"  # the simulated die is rotated, not shifted in angle
    assert p.d_m == pytest.approx(SENSOR.d_m, rel=5e-3)
    assert p.x0_m == pytest.approx(SENSOR.x0_m, abs=0.1e-6) and p.y0_m == pytest.approx(SENSOR.y0_m, abs=0.1e-6)
    assert p.phi0_deg == pytest.approx(SENSOR.phi0_deg, abs=0.05)
    assert p.alpha0_deg == pytest.approx(SENSOR.alpha0_deg, abs=0.05)
    assert p.beta0_deg == pytest.approx(SENSOR.beta0_deg, abs=0.05)
    assert p.gap_m == pytest.approx(SENSOR.gap_m, abs=0.3e-6)
    np.testing.assert_allclose(p.gains, SENSOR.gains, rtol=3e-3)
    assert fit.responsivity_a_per_m2 == pytest.approx(SENSOR.k_a_per_m2, rel=2e-3)
    assert fit.cos_law_rms < 2e-3  # the sums follow cos(incidence)
    assert set(fit.sd) == set(fit.free) and all(np.isfinite(list(fit.sd.values())))
    assert fit.correlation.shape == (10, 10)


def test_fixed_parameters_of_the_physical_fit(measured):
    nodes = ~measured["check"]
    fit = fit_physical(measured["alpha_deg"][nodes], measured["beta_deg"][nodes], measured["photo"][nodes],
                       design=DESIGN, fixed={"gap_m": SENSOR.gap_m, "alpha0_deg": SENSOR.alpha0_deg})
    assert "gap_m" not in fit.free and fit.parameters.gap_m == SENSOR.gap_m
    assert fit.fixed == {"gap_m": SENSOR.gap_m, "alpha0_deg": SENSOR.alpha0_deg}
    assert len(fit.free) == 8
