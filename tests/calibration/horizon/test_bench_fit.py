"""The horizon sensor's bench calibration (calibration.horizon.bench_fit): known errors recovered from synthetic scans
made here with their own forward computation (rotations from scipy, crossings found by bisection on a sampled scan,
not the closed form the fit uses), within their stated 1σ; the stated 1σ honest over noise draws; identifiability
said in words; outliers named; the calibrated sensor's roll and pitch against the table."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from horizontools import NOISE_DEG, RADII, RECOVERABLE, TRUTH, crossings, half_cover_separation, synthetic
from scipy.spatial.transform import Rotation

from calibration.errors import BenchDataError, CalibrationFormatError, FitError, InsufficientDataError
from calibration.horizon.bench_document import (
    c_header,
    horizon_document,
    sensor_parameters_from_document,
    validate_horizon_document,
)
from calibration.horizon.bench_fit import (
    NOMINAL,
    PARAMETERS,
    HorizonBenchData,
    attitude_errors,
    fit_horizon_bench,
    model_disc_radius_deg,
    mount_offsets_from_tilts,
    predicted_phases,
    solve_roll_pitch,
)


@pytest.fixture(scope="module")
def data():
    return synthetic(check=[(-25.0, 12.0, RADII[1]), (17.0, -9.0, RADII[0]), (5.0, 4.0, RADII[2]),
                            (28.0, 14.0, RADII[1])])


@pytest.fixture(scope="module")
def fit(data):
    return fit_horizon_bench(data)


def test_the_closed_form_agrees_with_the_long_way_round():
    """The fit's forward model (scan.py's closed form with the mount and the offsets) against this file's."""
    for roll, pitch, rho, cone in [(0.0, 0.0, 68.0, 1), (30.0, -15.0, 64.5, 2), (-33.0, 17.0, 70.2, 1),
                                   (12.0, 8.0, 66.0, 2)]:
        want = crossings(roll, pitch, rho, cone, TRUTH)
        got = predicted_phases(roll, pitch, rho, cone, TRUTH)
        assert np.abs(np.array(got, float) - want).max() < 1e-8, (roll, pitch, cone)


def test_the_mount_pitch_is_a_phase_offset_of_both_cones():
    """A turn about the spin axis Y_s turns each cone's scan along itself: the folded sensor reports the same phases."""
    for roll, pitch, rho, cone in [(0.0, 0.0, 68.0, 1), (30.0, -15.0, 64.5, 2), (-20.0, 10.0, 70.2, 2)]:
        assert np.allclose(crossings(roll, pitch, rho, cone, TRUTH), crossings(roll, pitch, rho, cone, RECOVERABLE),
                           atol=1e-9)


def test_known_errors_are_recovered_within_their_stated_uncertainty(fit):
    truth = RECOVERABLE.vector()
    got = fit.parameters.vector()
    sd = np.array([fit.sd[n] for n in PARAMETERS])
    z = (got - truth) / sd
    print("\n" + "\n".join(f"{n}: {g:+.5f} ± {s:.5f} (truth {t:+.5f}, {zz:+.2f} σ)"
                           for n, g, s, t, zz in zip(PARAMETERS, got, sd, truth, z)))
    assert np.all(np.abs(z) < 3.5), z
    # the stated 1σ are small enough to mean something: every error recovered to a few millidegrees
    assert sd.max() < 0.01 and np.abs(got - truth).max() < 0.02
    # the noise is what the repeats show, the model explains the data to it
    assert all(s == pytest.approx(NOISE_DEG, rel=0.15) for s in fit.noise.sigma_deg.values())
    assert fit.noise.source == "repeats" and 0.8 < fit.chi2_dof < 1.25
    assert fit.uncertainty_scale == max(1.0, fit.chi2_dof)
    assert not fit.rejected and fit.n_missing == 0
    assert fit.free == PARAMETERS and fit.radii_deg == pytest.approx(sorted(RADII), abs=1e-3)


def test_a_plan_over_the_sensors_range_separates_every_parameter(fit):
    """Over ±30° of roll, ±15° of pitch and three radii no pair of parameters trades (|correlation| < 0.95)."""
    off_diagonal = np.abs(fit.correlation - np.eye(len(fit.free)))
    assert off_diagonal.max() < 0.95 and not fit.trades
    assert np.isfinite(fit.condition_number) and fit.condition_number < 1e3


def test_a_poor_plan_is_said_in_words():
    """One cone at one disc radius and no pitch: a cone angle, the threshold bias and the mount's roll all move that
    cone's chord alike; the warnings name the pairs and say what to measure."""
    poor = synthetic(radii=(RADII[1],), pitches=np.array([0.0]), repeats=2, seed=3)
    fit = fit_horizon_bench(poor.subset(poor.cone == 1), heldout=False)
    text = " ".join(fit.warnings)
    assert "gamma1_deg and radius_bias_deg trade" in text and "disc radii further apart" in text, fit.warnings
    assert "radius_bias_deg and mount_roll_deg trade" in text and "measure both cones" in text
    assert "a single disc radius" in text and "no scans of cone 2" in text
    # roll spanned alone, without pitch: the fit still converges; without roll it does not, and says why
    with pytest.raises(FitError, match="hardly separates .*radius_bias_deg"):
        flat = synthetic(radii=(RADII[1],), rolls=np.array([0.0]), repeats=2, seed=3)
        fit_horizon_bench(flat.subset(flat.cone == 1), heldout=False)


def test_one_radius_and_one_cone_are_said_in_words():
    one = synthetic(radii=(RADII[1],), repeats=2, seed=4)
    fit = fit_horizon_bench(one.subset(one.cone == 1), heldout=False)
    assert fit.free == ("gamma1_deg", "phase_offset1_deg", "radius_bias_deg", "mount_roll_deg", "mount_yaw_deg")
    assert fit.parameters.gamma2_deg == NOMINAL.gamma2_deg
    text = " ".join(fit.warnings)
    assert "no scans of cone 2" in text and "a single disc radius" in text


def test_held_out_radius_and_check_points_score_roll_and_pitch_against_the_table(fit):
    held = fit.heldout
    assert [round(e["disc_radius_deg"], 3) for e in held["radius_out"]] == [round(r, 3) for r in sorted(RADII)]
    for entry in held["radius_out"]:
        # refitted without that radius, its phases are predicted to about the noise
        assert entry["phase_rms_sigma"] < 2.0, entry
        assert entry["calibrated"]["roll_rms_deg"] < 0.02 and entry["calibrated"]["pitch_rms_deg"] < 0.02
    check = held["check"]
    assert check["calibrated"]["n_scans"] == 12 and check["calibrated"]["n_failed"] == 0
    # the calibrated sensor reads the table's roll and pitch to the noise; the nominal one is off by its errors
    # (one scan's four edges of 0.01° noise give its roll to ≈ 0.01°, its pitch to ≈ 0.005°)
    assert check["calibrated"]["roll_rms_deg"] < 0.02 and check["calibrated"]["pitch_rms_deg"] < 0.01
    assert check["calibrated"]["roll_max_deg"] < 0.04 and check["calibrated"]["pitch_max_deg"] < 0.02
    assert check["nominal"]["roll_rms_deg"] > 0.1 and check["nominal"]["pitch_rms_deg"] > 0.1
    assert not any("left out" in w for w in fit.warnings)


def test_roll_and_pitch_are_solved_from_thecrossings():
    exact = synthetic(noise=0.0, repeats=1, radii=(RADII[0],))
    scans, roll, pitch = solve_roll_pitch(exact, TRUTH)
    first = np.unique(exact.scan, return_index=True)[1]
    # the sensor's own roll and pitch: the table's turned by the mount (nearly the table's plus its roll and pitch)
    assert np.abs(roll - (exact.roll_deg[first] + TRUTH.mount_roll_deg)).max() < 0.2
    assert np.abs(pitch - (exact.pitch_deg[first] + TRUTH.mount_pitch_deg)).max() < 0.2
    for sensor in (TRUTH, RECOVERABLE):  # the folded sensor reads the table's angles as well
        errors = attitude_errors(exact, sensor)
        assert errors.n_scans == len(scans) and errors.roll_max_deg < 1e-6 and errors.pitch_max_deg < 1e-6
    errors = attitude_errors(exact, TRUTH)
    assert errors.n_scans == len(scans) and errors.roll_max_deg < 1e-6 and errors.pitch_max_deg < 1e-6


def test_outliers_are_named_and_left_out(data):
    phases = data.phase_out_deg.copy()
    phases[[10, 200]] += [0.5, -0.3]
    spoilt = HorizonBenchData(data.roll_deg, data.pitch_deg, data.cone, phases, data.phase_in_deg,
                              data.disc_radius_deg, scan=data.scan, repeat=data.repeat, check=data.check,
                              row_id=np.arange(len(data)) + 1)
    fit = fit_horizon_bench(spoilt, heldout=False)
    assert sorted(r.row_id for r in fit.rejected) == [11, 201]
    assert all(r.edge == "out" for r in fit.rejected) and "σ" in fit.rejected[0].reason
    z = (fit.parameters.vector() - RECOVERABLE.vector()) / np.array([fit.sd[n] for n in PARAMETERS])
    assert np.all(np.abs(z) < 3.5)
    assert any("rejected as outliers" in w for w in fit.warnings)


def test_missing_edges_are_left_out():
    data = synthetic(repeats=2, seed=5)
    phases = data.phase_in_deg.copy()
    phases[::7] = np.nan
    gappy = HorizonBenchData(data.roll_deg, data.pitch_deg, data.cone, data.phase_out_deg, phases,
                             data.disc_radius_deg, scan=data.scan, repeat=data.repeat)
    fit = fit_horizon_bench(gappy, heldout=False)
    assert fit.n_missing == np.isnan(phases).sum()
    sd = np.array([fit.sd[n] for n in PARAMETERS])
    assert np.all(np.abs(fit.parameters.vector() - RECOVERABLE.vector()) < 5 * sd)


def test_the_stated_uncertainty_covers_the_truth_over_noise_draws():
    """Eight noise draws on a small plan: the parameters' errors in units of their stated 1σ have an RMS near 1 (the
    covariance is honest), within the scatter of 56 samples."""
    z = []
    for seed in range(8):
        fit = fit_horizon_bench(synthetic(rolls=np.arange(-30.0, 30.1, 15.0), pitches=np.array([-15.0, 0.0, 15.0]),
                                          repeats=3, seed=100 + seed), heldout=False)
        z.append((fit.parameters.vector() - RECOVERABLE.vector()) / np.array([fit.sd[n] for n in PARAMETERS]))
    z = np.array(z)
    rms = float(np.sqrt(np.mean(z ** 2)))
    inside = float(np.mean(np.abs(z) < 1.0))
    print(f"\nz RMS {rms:.2f}, {inside:.0%} within 1σ")
    assert 0.7 < rms < 1.35 and 0.5 < inside < 0.85


def test_no_repeats_takes_the_noise_from_the_residuals():
    fit = fit_horizon_bench(synthetic(repeats=1, seed=6), heldout=False)
    assert fit.noise.source == "residuals" and any("no repeated scans" in w for w in fit.warnings)
    assert fit.noise.sigma_deg[(1, "out")] == pytest.approx(NOISE_DEG, rel=0.2)
    sd = np.array([fit.sd[n] for n in PARAMETERS])
    assert np.all(np.abs(fit.parameters.vector() - RECOVERABLE.vector()) < 4 * sd)


def test_the_mount_of_a_seed_003_tilt():
    """A boresight tipped toward +x by α and toward +y by β (seed 003's R_y(α)·R_x(−β)) is the mount roll −β, pitch α
    and a yaw of order αβ, the same rotation."""
    alpha, beta = 0.4, -0.25
    tilt = Rotation.from_euler("YX", [alpha, -beta], degrees=True).as_matrix()
    roll, yaw, pitch = mount_offsets_from_tilts(alpha, beta)
    assert roll == pytest.approx(-beta, abs=1e-4) and pitch == pytest.approx(alpha, abs=1e-4) and abs(yaw) < 3e-3
    mount = Rotation.from_euler("XZY", [roll, yaw, pitch], degrees=True).as_matrix()
    assert np.allclose(tilt, mount, atol=1e-15)


@pytest.mark.parametrize("change, column", [
    ({"cone": [1, 3]}, "cone"),
    ({"disc_radius_deg": [68.0, 95.0]}, "disc_radius_deg"),
    ({"roll_deg": [0.0, np.nan]}, "roll_deg"),
    ({"phase_out_deg": [10.0, np.inf]}, "phase_out_deg"),
    ({"scan": [4, 4], "cone": [2, 2]}, "cone"),
])
def test_bad_data_are_refused_naming_the_row_and_column(change, column):
    fields = {"roll_deg": [0.0, 1.0], "pitch_deg": [0.0, 1.0], "cone": [1, 2], "phase_out_deg": [66.0, 66.0],
              "phase_in_deg": [294.0, 294.0], "disc_radius_deg": [68.0, 68.0]}
    fields.update(change)
    with pytest.raises(BenchDataError) as info:
        HorizonBenchData(**fields)
    assert info.value.column == column and info.value.row == 1


def test_too_little_data_is_refused():
    one_pose = synthetic(rolls=np.array([0.0]), pitches=np.array([0.0]), repeats=2)
    with pytest.raises(InsufficientDataError, match="one pose"):
        fit_horizon_bench(one_pose)
    with pytest.raises(InsufficientDataError, match="check row"):
        fit_horizon_bench(one_pose.subset(np.zeros(len(one_pose), bool)))


# --- the IFOV's curvature bias in the crossing model -----------------------------------------------------------------

def test_the_model_fires_where_half_the_ifov_covers_the_disc():
    """The crossing model's disc radius is ρ − b(ρ, α) + Δρ: b is 0.00472° at ρ = 67.9°, α = 2° (the 50 % locator on
    a curved limb, seed 004 §2-4-2), ≈ cot ρ · α²/6, shrinking as the disc grows; α = 0 is the bare boresight."""
    b = 67.9 - model_disc_radius_deg(67.9)
    assert b == pytest.approx(0.00472, abs=1e-5)
    radii = np.array(RADII)
    small_ifov = np.degrees(1.0 / np.tan(np.radians(radii)) * np.radians(2.0) ** 2 / 6.0)
    assert radii - model_disc_radius_deg(radii) == pytest.approx(small_ifov, rel=0.01)
    ascending = np.sort(radii)
    assert np.all(np.diff(ascending - model_disc_radius_deg(ascending)) < -5e-4)  # 5.6 → 4.2 mdeg over 64 → 70°
    bare = replace(NOMINAL, ifov_half_angle_deg=0.0, radius_bias_deg=0.03)
    assert np.all(model_disc_radius_deg(radii, bare) == radii + 0.03)
    # Δρ adds on top; the 50 % separation as horizontools finds it (scipy's quad over rings, brentq)
    assert model_disc_radius_deg(68.0, replace(NOMINAL, radius_bias_deg=0.03)) == pytest.approx(
        half_cover_separation(68.0, 2.0) + 0.03, abs=1e-10)


def test_without_the_curvature_bias_the_threshold_bias_is_wrong_and_the_model_misses():
    """Scans of a 2° IFOV at three disc radii with 0.5 mdeg of noise. Fitted with the bare boresight model (α = 0),
    Δρ takes the curvature bias's mean (≈ −4.8 mdeg, hundreds of σ: it is no longer the threshold's bias) and the
    bias's change with ρ (5.6 mdeg at 64.3°, 4.2 at 70.2°), which no parameter takes up, leaves χ²/dof ≈ 3; with
    the design's α every parameter comes back within its 1σ's few and χ²/dof ≈ 1. (The cone angles move by only
    ~0.2 mdeg: over this plan the bias trades with Δρ, hardly with γ.)"""
    data = synthetic(noise=0.0005, repeats=3, seed=21)
    right = fit_horizon_bench(data, heldout=False)
    wrong = fit_horizon_bench(replace(data, ifov_half_angle_deg=0.0), heldout=False)
    sd = np.array([right.sd[n] for n in PARAMETERS])
    assert np.all(np.abs((right.parameters.vector() - RECOVERABLE.vector()) / sd) < 3.5) and right.chi2_dof < 1.25
    bias = float(np.mean(np.array(RADII) - model_disc_radius_deg(np.array(RADII))))
    missed = wrong.parameters.radius_bias_deg - RECOVERABLE.radius_bias_deg
    print(f"\nα = 0: Δρ off by {missed * 1000:+.2f} mdeg ({missed / wrong.sd['radius_bias_deg']:+.0f} σ), χ²/dof "
          f"{wrong.chi2_dof:.2f} (α = 2°: {right.chi2_dof:.2f})")
    assert missed == pytest.approx(-bias, abs=3e-4) and abs(missed) > 50 * wrong.sd["radius_bias_deg"]
    assert wrong.chi2_dof > 2.0
    assert wrong.parameters.ifov_half_angle_deg == 0.0 and right.parameters.ifov_half_angle_deg == 2.0


def test_the_document_carries_the_ifov_and_reads_it_back(fit):
    doc = horizon_document(fit)
    assert doc["design"] == {"ifov_half_angle_deg": 2.0, "locator_level": 0.5}
    assert "b(ρ, α)" in doc["model"]["crossing"] and "seed 004 §2-4-2" in doc["model"]["ifov"]
    back = sensor_parameters_from_document(doc)
    assert back == fit.parameters.folded() or back == fit.parameters
    assert "#define SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG (2)" in c_header(doc)
    old = {k: v for k, v in doc.items() if k != "design"}  # fitted before the model had the bias: α = 0
    assert sensor_parameters_from_document(old).ifov_half_angle_deg == 0.0
    for design, words in (({"ifov_half_angle_deg": -1.0}, "not in \\[0, 10\\)"),
                          ({"ifov_half_angle_deg": None}, "finite number"),
                          ({"ifov_half_angle_deg": 2.0, "locator_level": 0.7}, "locator level")):
        with pytest.raises(CalibrationFormatError, match=words):
            validate_horizon_document({**doc, "design": design})


@pytest.mark.parametrize("alpha", [-0.5, 12.0, float("nan"), "2"])
def test_a_bad_ifov_half_angle_is_refused(alpha):
    with pytest.raises(BenchDataError) as info:
        HorizonBenchData([0.0], [0.0], [1], [66.0], [294.0], [68.0], ifov_half_angle_deg=alpha)
    assert info.value.column == "ifov_half_angle_deg"


# --- a cone that never found an edge ---------------------------------------------------------------------------------

def test_a_cone_that_found_no_edge_is_not_fitted_and_the_document_says_so():
    """Cone 2's rows are there but every phase is NaN (a dead detector, or its pulse saturated all run, as the bench's
    data records them): its γ2 and o2 are not fitted — the fit no longer stops on their zero Jacobian columns ("the
    data do not constrain gamma2_deg, phase_offset2_deg") —, the other five come back within their stated 1σ's few,
    each radius left out is refitted on cone 1 alone, and the document keeps γ2, o2 nominal with a note saying why."""
    data = synthetic(rolls=np.arange(-30.0, 30.1, 15.0), pitches=np.array([-15.0, 0.0, 15.0]), repeats=2, seed=8,
                     check=[(-25.0, 12.0, RADII[1]), (17.0, -9.0, RADII[0])])
    dead = data.cone == 2
    blind = replace(data, phase_out_deg=np.where(dead, np.nan, data.phase_out_deg),
                    phase_in_deg=np.where(dead, np.nan, data.phase_in_deg))
    fit = fit_horizon_bench(blind)
    assert fit.free == ("gamma1_deg", "phase_offset1_deg", "radius_bias_deg", "mount_roll_deg", "mount_yaw_deg")
    z = {n: (getattr(fit.parameters, n) - getattr(RECOVERABLE, n)) / fit.sd[n] for n in fit.free}
    assert all(abs(v) < 3.5 for v in z.values()), z
    assert fit.parameters.gamma2_deg == NOMINAL.gamma2_deg and fit.parameters.phase_offset2_deg == 0.0
    text = " ".join(fit.warnings)
    assert "cone 2 found no edge in any of its" in text and "gamma2_deg and phase offset phase_offset2_deg are " \
        "not fitted" in text, fit.warnings
    assert "not found by the module" not in text and fit.n_missing == 2 * int(dead[~data.check].sum())
    assert all(e.get("parameters") is not None for e in fit.heldout["radius_out"])
    check = fit.heldout["check"]["calibrated"]
    assert check["n_scans"] == 2 * 2 and check["n_failed"] == 0
    doc = horizon_document(fit)
    for name in ("gamma2_deg", "phase_offset2_deg"):
        entry = doc["parameters"][name]
        assert not entry["fitted"] and entry["sd"] is None and entry["value"] == entry["nominal"]
        assert "no edge of cone 2" in entry["note"], entry
    assert doc["parameters"]["gamma1_deg"]["fitted"] and "note" not in doc["parameters"]["gamma1_deg"]
    assert "given, never fitted" in doc["parameters"]["mount_pitch_deg"]["note"]
    assert doc["covariance"]["names"] == list(fit.free) and any("cone 2 found no edge" in w for w in doc["warnings"])
    assert "SUNBENCH_HORIZON_GAMMA2_DEG (70)  /* nominal, not fitted */" in c_header(doc)
    # a cone absent altogether is said as before
    assert any("no scans of cone 2" in w for w in fit_horizon_bench(data.subset(~dead), heldout=False).warnings)
