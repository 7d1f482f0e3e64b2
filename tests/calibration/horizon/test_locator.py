"""The thesis' locators (seed 004 eqs. 2.1–2.2) on synthetic pulses with known edges: the "first sample after the
change" bias (digest §5.3) and its removal by sub-sample interpolation, the pre-filter, the integrated locator."""

import numpy as np
import pytest

from calibration.horizon import ifov, locator, pulse, scan

RHO_DEG = float(scan.earth_angular_radius_deg(504.652))
NADIR = scan.nadir_in_body(0.8, -0.4)
# the 50 % obscuration crossings are known exactly: the boresight crossings of a disc of radius d_50
TRUE_OUT, TRUE_IN = (float(x) for x in scan.crossing_phases_for_nadir(NADIR, ifov.level_separation_deg(RHO_DEG),
                                                                      cone=1))


def _obscuration_pulse(step_s, start_s):
    phase = pulse.sample_phases_deg(step_s, start_s=start_s)
    return phase, ifov.covered_fraction_along_scan(phase, NADIR, RHO_DEG)


@pytest.mark.parametrize("step_s", [1e-5, 1e-4, 1e-3])
def test_first_sample_rule_is_late_by_up_to_a_sample_and_interpolation_removes_it(step_s):
    """Over random sampling offsets the thesis' rule reports both edges late by 0 to one step (mean ≈ half a step:
    0.0018° at 10⁻⁵ s, the size of Table 4-3's −0.003° pitch bias); linear interpolation is within 1e-3 of a step
    (the pulse's curvature over one step: 4e-4 of a step at 10⁻³ s, falling with the step)."""
    rng = np.random.default_rng(15)
    step_deg = 360.0 * step_s
    late, interp = [], []
    for start in rng.uniform(0, step_s, 8):
        phase, values = _obscuration_pulse(step_s, start)
        first = locator.constant_locator(phase, values, 0.5, rule="first-sample")
        fine = locator.constant_locator(phase, values, 0.5, rule="interpolate")
        for got, truth in zip(first, (TRUE_OUT, TRUE_IN)):
            late.append((got - truth + 180) % 360 - 180)
        for got, truth in zip(fine, (TRUE_OUT, TRUE_IN)):
            interp.append((got - truth + 180) % 360 - 180)
    late, interp = np.array(late), np.array(interp)
    assert np.all(late >= 0) and np.all(late <= step_deg)
    assert 0.2 * step_deg < late.mean() < 0.8 * step_deg
    assert np.max(np.abs(interp)) < 1e-3 * step_deg


def test_a_centred_moving_average_does_not_move_a_symmetric_edge_but_tames_noise():
    """A tanh edge (odd about its midpoint) keeps its 50 % phase under a centred moving average to 1e-9°; with
    noise (σ 0.05) the raw pulse crosses 50 % several times (a clear error), the filtered one (101 samples) once,
    within 0.05° of the edge (the filtered noise over the edge's slope is ~0.012°, so 4σ)."""
    phase = pulse.sample_phases_deg(1e-4)
    edge_out, edge_in = 70.0, 290.0
    clean = 0.5 * (np.tanh((edge_out - phase) / 1.2) + np.tanh((phase - edge_in) / 1.2)) + 0.5
    filtered = locator.moving_average(clean, 41)
    for rule_pulse in (clean, filtered):
        out, inn = locator.constant_locator(phase, rule_pulse, 0.5, reference="range")
        assert out == pytest.approx(edge_out, abs=1e-6) and inn == pytest.approx(edge_in, abs=1e-6)
    noisy = clean + np.random.default_rng(2).normal(0.0, 0.05, phase.size)
    with pytest.raises(ValueError, match="crosses the level"):
        locator.constant_locator(phase, noisy, 0.5, reference="range")
    out, inn = locator.constant_locator(phase, locator.moving_average(noisy, 101), 0.5, reference="range")
    assert out == pytest.approx(edge_out, abs=0.05) and inn == pytest.approx(edge_in, abs=0.05)


def test_integrated_locator_puts_the_boresight_on_a_straight_edge_at_c2_of_two_alpha_over_three_pi():
    """A top-hat disc of radius α swept square-on across a straight edge at unit phase rate: the covered fraction is
    ½ + (x√(α² − x²) + α² asin(x/α))/(πα²); eq. 2.2 with C2 = 2α/(3π) fires with the boresight on the edge."""
    alpha = 2.0
    phase = pulse.sample_phases_deg(1e-5)
    edge_in, edge_out = 100.0, 250.0
    x = np.minimum(phase - edge_in, edge_out - phase)  # depth into the Earth
    xc = np.clip(x, -alpha, alpha)
    covered = 0.5 + (xc * np.sqrt(alpha**2 - xc**2) + alpha**2 * np.arcsin(xc / alpha)) / (np.pi * alpha**2)
    out, inn = locator.integrated_locator(phase, covered, 2 * alpha / (3 * np.pi))
    assert out == pytest.approx(edge_out, abs=1e-4) and inn == pytest.approx(edge_in, abs=1e-4)
    # and the constant locator at 50 % agrees (a straight edge has no curvature bias)
    assert locator.constant_locator(phase, covered, 0.5) == pytest.approx((edge_out, edge_in), abs=1e-6)


def test_bad_input_is_named():
    phase = pulse.sample_phases_deg(1e-3)
    values = ifov.covered_fraction_along_scan(phase, NADIR, RHO_DEG)
    with pytest.raises(ValueError, match="C1"):
        locator.constant_locator(phase, values, 1.5)
    with pytest.raises(ValueError, match="uniformly"):
        locator.constant_locator(np.r_[phase[:10], phase[11:]], np.r_[values[:10], values[11:]])
    with pytest.raises(ValueError, match="odd"):
        locator.moving_average(values, 4)
    with pytest.raises(ValueError, match="flat"):
        locator.constant_locator(phase, np.zeros_like(phase))
    with pytest.raises(ValueError, match="rule"):
        locator.level_crossings(phase, values, 0.5, rule="nearest")


def _limb_edge(phase, edge_at, scale=1.0, width=1.5, darkening=0.02):
    """A rising edge (sky below `edge_at`, disc above) with a plateau that darkens towards the horizon."""
    plateau = 1.0 + darkening * (phase - edge_at)
    return scale * plateau * 0.5 * (1.0 + np.tanh((phase - edge_at) / width))


def test_edge_locators_blind_to_the_radiance_scale_and_the_thesis_one_is_not():
    """Scaling the pulse by 0.8 (a crossing 4 K colder, ~2 %/K in this band) leaves the edge-normalised threshold,
    integrated, inflection and two-level locators where they were (to 1e-9°), while eq. 2.1 normalised by a fixed
    peak moves by ~0.3° — the thesis' locator's weakness when its peak comes from another atmosphere."""
    phase = np.arange(80.0, 100.0, 0.36)
    bright, dim = _limb_edge(phase, 90.0), _limb_edge(phase, 90.0, scale=0.8)
    for method, options in [("local-threshold", {}), ("local-integrated", {"c2_deg": 1.0}), ("inflection", {}),
                            ("two-level", {})]:
        a = locator.locate_edge(method, phase, bright, "in", **options)
        b = locator.locate_edge(method, phase, dim, "in", **options)
        assert a == pytest.approx(b, abs=1e-9), method
    a = locator.locate_edge("peak-threshold", phase, bright, "in", peak=1.0)
    b = locator.locate_edge("peak-threshold", phase, dim, "in", peak=1.0)
    assert 0.2 < b - a < 0.5


def test_edge_locators_find_a_symmetric_edge_and_mirror_for_the_falling_one():
    """On a tanh edge without darkening the local 50 % threshold and the steepest slope sit on the edge's centre
    (to 3e-3° at a 0.36° step: the parabola's residual on a sech² slope, and the plateau 5° in is 0.9987 of 1,
    each ~0.0016°); the same edge run
    backwards as an "out" edge gives the mirrored phase to 1e-9°; the local reference is the plateau within
    `depth_deg` of the edge."""
    phase = np.arange(80.0, 100.0, 0.36)
    edge = _limb_edge(phase, 90.1, darkening=0.0)
    assert locator.threshold_edge_locator(phase, edge, "in") == pytest.approx(90.1, abs=3e-3)
    assert locator.inflection_locator(phase, edge, "in") == pytest.approx(90.1, abs=3e-3)
    reference, at = locator.local_reference(phase, edge, "in", depth_deg=5.0)
    assert reference == pytest.approx(1.0, abs=0.01) and at == pytest.approx(90.1, abs=3e-3)
    mirrored_phase = -phase[::-1]
    for method in ("local-threshold", "inflection", "two-level"):
        rising = locator.locate_edge(method, phase, edge, "in")
        falling = locator.locate_edge(method, mirrored_phase, edge[::-1], "out")
        assert falling == pytest.approx(-rising, abs=1e-9), method


def test_edge_locators_name_bad_input():
    phase = np.arange(80.0, 100.0, 0.36)
    edge = _limb_edge(phase, 90.0)
    with pytest.raises(ValueError, match="edge must be"):
        locator.inflection_locator(phase, edge, "up")
    with pytest.raises(ValueError, match="unknown edge locator"):
        locator.locate_edge("median", phase, edge)
    with pytest.raises(ValueError, match="peak"):
        locator.locate_edge("peak-threshold", phase, edge)
    with pytest.raises(ValueError, match="does not hold the edge"):
        locator.threshold_edge_locator(phase, edge, "out")  # a rising window read as a falling edge
    with pytest.raises(ValueError, match="into the Earth"):
        locator.local_reference(phase, edge, "in", depth_deg=15.0)
    with pytest.raises(ValueError, match="levels"):
        locator.two_level_locator(phase, edge, levels=(0.7, 0.3))
