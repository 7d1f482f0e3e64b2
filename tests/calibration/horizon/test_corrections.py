"""The thesis' ten windows with the IFOV (case C) and the atmosphere (case D): thesis-like errors before, and the
corrections of :mod:`calibration.horizon.corrections` after (below 0.02° for case C; for case D only when the
atmosphere is the climatology — a round trip).

The truth (seed 004 Tables 3-1, 4-1 through :mod:`calibration.horizon.orbit`): each window's satellite at zero roll
and pitch in the orbit frame (the thesis' truth), WGS84, a snapshot at the window's start.

* Case C: STK's obscuration computed exactly on WGS84 (:func:`pulse.ellipsoid_depth`), its 50 % crossing found to
  1e-9°. Thesis-like: the "first sample after the change" at 10⁻⁴ s and the spherical solution (eq. 2.7, ρ of eq.
  2.3 with R = a at Table 4-1's altitude). Corrected: linear interpolation at 10⁻⁴ s and the oblate solution
  (:func:`attitude.solve_oblate`, A1's) with the IFOV's effective horizon height (−0.21 km).
* Case D: the pulse is the top-hat IFOV's mean of the limb radiance over WGS84 (2-D quadrature, tangent heights from
  the ellipsoid); each crossing sees a horizontally uniform atmosphere with the climatological profile of its tangent
  point's latitude on 12 April (the pulse's maximum from the same profile); locator C1 = 0.5. Thesis-like: first
  sample at 10⁻³ s (§3-5's step) and the spherical solution with H_eq = 0. Corrected: interpolation at 10⁻³ s and
  :func:`corrections.corrected_roll_pitch` (per-crossing h* from latitude and season).

What this proves and what it does not: in case D the truth's atmosphere and the correction's are the same model
(the correction knows the climatology), so that test is a round trip — it shows the method removes the error when
the profile is right, and is named so. What is left with a truth that has weather, another band model and a polar
cold pool (0.024° / 0.008° mean roll / pitch for the best locator, not ≤ 0.02° per window) is measured in
test_atmosphere_robustness.py; the profile-mismatch test here shows the same from one fixed profile. The thesis'
PSG radiance (land/sea, day/night) is not modelled: a zonal climatology gives cone 1 and cone 2 (east/west of
track) the same horizon, so the thesis' large roll errors of case D cannot appear here (weather per crossing, in
test_atmosphere_robustness.py, does break that symmetry).
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from calibration.horizon import atmosphere, attitude, corrections, ifov, oblate, orbit, pulse, scan, thesis

STEP_C_S, STEP_D_S = 1e-4, 1e-3
DAY_OF_YEAR = 103  # 12 April 2020
THESIS_C = (0.0926, 0.0985)  # Table 4-6 means of |error| (roll, pitch)
THESIS_D = (0.2696, 0.1240)  # Table 4-8 / 5-1


def _first_sample(at_deg, step_deg):
    return np.ceil(at_deg / step_deg) * step_deg


def _interpolated(fn, at_deg, step_deg):
    lo = np.floor(at_deg / step_deg) * step_deg
    f_lo, f_hi = fn(lo), fn(lo + step_deg)
    return lo - f_lo / (f_hi - f_lo) * step_deg


def _window(w):
    state = orbit.thesis_window_state(w)
    p, frame, rot = state.position_km, state.orbit_frame(), state.body_to_frame(0.0, 0.0)
    depth = pulse.ellipsoid_depth(p)
    nadir_body = rot.T @ (-p / np.linalg.norm(p))
    c, d = {}, {}
    for cone in (1, 2):
        boresight = oblate.crossing_phases_oblate(p, rot, cone=cone)
        peak_phase = float(np.degrees(np.arctan2(nadir_body[0], nadir_body[2])))
        for k, edge in enumerate(("out", "in")):
            guess = float(boresight[k])

            def obscured(x, cone=cone):
                return ifov.covered_fraction(scan.scan_vector(x, cone=cone) @ rot.T, depth) - 0.5

            at = brentq(obscured, guess - 1.0, guess + 1.0, xtol=1e-9)
            step = 360.0 * STEP_C_S
            c[(cone, edge)] = (at, _first_sample(at, step), _interpolated(obscured, at, step))
            lat = corrections.tangent_latitudes_deg([guess], [cone], 0.0, 0.0, p, frame)[0]
            table = atmosphere.radiance_table(atmosphere.seasonal_profile(lat, DAY_OF_YEAR), step_km=0.25)
            peak = float(pulse.wgs84_pulse(peak_phase, p, rot, table, cone=cone))

            def radiance(x, cone=cone, table=table, peak=peak):
                return float(pulse.wgs84_pulse(x, p, rot, table, cone=cone)) - 0.5 * peak

            at = brentq(radiance, guess - 3.0, guess + 3.0, xtol=1e-9)
            step = 360.0 * STEP_D_S
            d[(cone, edge)] = (at, _first_sample(at, step), _interpolated(radiance, at, step))
    return state, c, d


def _pairs(crossings, i):
    return ([crossings[(1, "out")][i], crossings[(2, "out")][i]], [crossings[(1, "in")][i], crossings[(2, "in")][i]])


def _flat(crossings, i):
    out, inn = _pairs(crossings, i)
    return [out[0], inn[0], out[1], inn[1]], [1, 1, 2, 2]


@pytest.fixture(scope="module")
def windows():
    """Per window: the state, case C and case D crossings (exact, first-sample, interpolated), and the solutions."""
    rows = []
    for w in range(10):
        state, c, d = _window(w)
        p, frame = state.position_km, state.orbit_frame()
        distance_alt = float(np.linalg.norm(p) - scan.EQUATORIAL_RADIUS_KM)
        rho = float(scan.earth_angular_radius_deg(thesis.TABLE_4_1_ALTITUDE_KM[w]))
        c_before = attitude.solve_spherical(*_pairs(c, 1), rho_deg=rho)
        c_after = attitude.solve_oblate(*_pairs(c, 2), p, frame,
                                        emitting_height_km=float(corrections.ifov_horizon_height_km(distance_alt)))
        d_before = attitude.solve_spherical(*_pairs(d, 1), rho_deg=rho)
        d_exact_uncorrected = attitude.solve_spherical(*_pairs(d, 0), rho_deg=rho)
        model = corrections.HorizonHeightModel(distance_alt, DAY_OF_YEAR)
        d_after = corrections.corrected_roll_pitch(*_flat(d, 2), p, frame, model)
        us76 = corrections.HorizonHeightModel(distance_alt, DAY_OF_YEAR, profile_name="us-standard-1976")
        d_us76 = corrections.corrected_roll_pitch(*_flat(d, 2), p, frame, us76)
        rows.append({
            "c_before": (c_before.roll_deg, c_before.pitch_deg), "c_after": (c_after.roll_deg, c_after.pitch_deg),
            "d_before": (d_before.roll_deg, d_before.pitch_deg), "d_after": d_after,
            "d_exact_uncorrected": (d_exact_uncorrected.roll_deg, d_exact_uncorrected.pitch_deg),
            "d_us76": d_us76, "state": state, "c": c, "d": d,
        })
    return rows


def _errors(windows, key):
    return np.abs(np.array([row[key] for row in windows]))  # truth is roll = pitch = 0


def test_case_c_ifov_thesis_like_errors_then_corrected_below_0_02(windows):
    """Case C before (first sample at 10⁻⁴ s, spherical model): mean |error| roll ≈ 0.025°, pitch ≈ 0.096° against
    the thesis' 0.0926° / 0.0985° — pitch of the thesis' size (oblateness, N–S orbit), roll smaller (our zero-yaw
    truth in the orbit frame, the thesis' YPR321 in ICRF). After (interpolation, oblate solver, h* = −0.21 km):
    every window within 1e-4° (measured ~5e-6°), far below the issue's 0.02°."""
    before, after = _errors(windows, "c_before"), _errors(windows, "c_after")
    mean = before.mean(axis=0)
    assert 0.01 < mean[0] < THESIS_C[0] and 0.05 < mean[1] < 2 * THESIS_C[1], mean
    assert before.max() > 0.1
    assert after.max() < 1e-4, after


def test_case_d_thesis_like_errors_and_the_correction_is_exact_when_the_atmosphere_is_the_climatology(windows):
    """A round trip, not a calibration: truth and correction share the climatology (the honest figures are in
    test_atmosphere_robustness.py). Case D before: at 10⁻³ s the first-sample rule quantises phases to 0.36°, and
    the solution is dominated by it (pitch 0.18° in most windows, against the thesis' 0.124°; roll ~0 by the
    east/west symmetry of a zonal climatology, against the thesis' 0.27°). With exact crossings and no correction
    the spherical solution is off by up to 0.084° in pitch (mean 0.037°: the forward and backward horizons at
    different latitudes and heights; the sphere's missing oblateness partly cancels the atmosphere's latitude
    trend). After (interpolation at 10⁻³ s, per-crossing h* from the same latitude and season as the truth's, oblate
    solver): every window ≤ 0.02° (measured ≤ 0.005°) — the correction is exact when the atmosphere is the
    climatology."""
    before, exact, after = (_errors(windows, k) for k in ("d_before", "d_exact_uncorrected", "d_after"))
    assert before[:, 1].mean() > 0.1
    assert exact[:, 1].max() > 0.05
    assert after.max() <= 0.02, after
    assert after.mean(axis=0).max() < 0.005


def test_a_correction_without_climatology_leaves_the_latitude_error(windows):
    """The same correction with one profile (US 1976) for every crossing removes the mean horizon height but not its
    latitude dependence: the pitch error reaches 0.14° (mean 0.07°), worse than no correction at all on these
    windows (the spherical solution's missing oblateness happens to offset part of the latitude trend) — the
    correction is only as good as the profile it is given (h* spans 11–26 km across the climatologies)."""
    us76 = _errors(windows, "d_us76")
    assert us76.max() > 0.1
    assert us76.max() > 3 * _errors(windows, "d_after").max()
    assert us76[:, 1].max() > _errors(windows, "d_exact_uncorrected")[:, 1].max()


def test_the_tangent_height_solver_agrees_with_the_oblate_phase_solver(windows):
    """Two independent oblate solutions of the same corrected case C crossings — ours (tangent-height residuals,
    scaled-sphere heights) and A1's (phase residuals, exact crossing model) — agree to 1e-4°."""
    for row in windows[:3]:
        state, c = row["state"], row["c"]
        alt = float(np.linalg.norm(state.position_km) - scan.EQUATORIAL_RADIUS_KM)
        ours = corrections.fit_roll_pitch_wgs84(*_flat(c, 2), state.position_km, state.orbit_frame(),
                                                float(corrections.ifov_horizon_height_km(alt)))
        assert ours == pytest.approx(row["c_after"], abs=1e-4)
