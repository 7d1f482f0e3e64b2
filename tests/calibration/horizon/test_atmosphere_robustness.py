"""The atmosphere case (seed 004 case D: WGS84, the 2° top-hat IFOV, the 14–16 µm limb, sampled every 10⁻³ s) with
a truth that is NOT the correction's atmosphere — what a climatological correction and better locators leave on
the thesis' ten windows.

The truth (one world per draw, seeded; every method sees the same pulses):

* Each window's satellite at Table 4-1's position (:mod:`calibration.horizon.orbit`) with a roll and pitch drawn
  once per window in ±0.5° (the same in every scenario), so the solver does not start at the truth.
* Each of the four crossings sees its own horizontally uniform atmosphere, and the disc below the satellite (the
  pulse's brightest part, which the thesis' locator normalises by) a fifth: the climatology of its latitude on 12
  April (:func:`atmosphere.seasonal_profile`) plus, per scenario, the day's weather
  (:class:`atmosphere.WeatherModel`: a height-correlated anomaly of 2 K in the troposphere, 5 K in the
  stratosphere, 8 K in the mesosphere, 6 km correlation; ±1 % surface pressure; drawn independently per crossing —
  the tangent points lie 1800–4500 km apart, beyond a synoptic correlation length — and optionally the polar cold
  pool, 20–30 K colder from 12 to 40 km in half the crossings poleward of 60°).
* The truth's band is a different k-distribution (:data:`atmosphere.CO2_BAND_SEVEN`) with a strength factor drawn
  once per draw, log-normal 5 % (line strengths and the CO2 amount; 5 % is assumed, generous for the 15 µm band's
  strong lines, small against the grey-band approximation itself).

The correction knows the geometry, the sensor and a climatology (latitude + day of year, the 5-sub-band model): it
predicts each edge from the climatology at a first estimate (:meth:`corrections.ClimatologyPulseModel.edge_windows`),
runs the same locator on the prediction, and solves with the boresight's tangent heights there
(:func:`corrections.locator_horizon_heights_km`, :func:`corrections.fit_roll_pitch_wgs84`). "None" is the thesis' H_eq
= 0 on WGS84. The locators (:func:`locator.locate_edge`): the thesis' eq. 2.1 normalised by the whole pulse's peak,
eq. 2.1 normalised by the edge's own level, eq. 2.2 likewise (C2 = 1° of phase), the steepest slope, and the foot of
a two-level (30 %/70 %) line.

Scale: from 505 km the horizon is ~2560 km away, so 1 km of horizon height is 0.022° of arc; the issue's 0.02° is
~0.9 km of height difference between opposite crossings.
"""

import numpy as np
import pytest

from calibration.horizon import atmosphere as A
from calibration.horizon import corrections as C
from calibration.horizon import orbit
from calibration.horizon.pulse import tangent_height_scaled_km
from calibration.horizon.scan import body_to_orbit, scan_vector

DAY_OF_YEAR = 103  # 12 April (seed 004 §3-5)
SEED = 20240412
CONES = [c for c, _ in C.CROSSINGS]
METHODS = {"peak-threshold": {}, "local-threshold": {}, "local-integrated": {"c2_deg": 1.0}, "inflection": {},
           "two-level": {}}
LOCAL_METHODS = [m for m in METHODS if m != "peak-threshold"]
#: scenario → (weather or None, band differs from the correction's, number of draws)
SCENARIOS = {"climatology": (None, False, 1), "band": (None, True, 1), "weather": (A.ORDINARY_WEATHER, True, 3),
             "cold-pool": (A.POLAR_COLD_POOL_WEATHER, True, 2)}
BAR_DEG = 0.02  # issue 15


#: The correction's knowledge, shared by every scenario (its radiance tables are cached per degree of latitude).
_MODEL = C.ClimatologyPulseModel(DAY_OF_YEAR)


def _truth_attitudes():
    return np.random.default_rng(SEED).uniform(-0.5, 0.5, (10, 2))


def _world(scenario, draw):
    """Per window: errors (roll, pitch) per method and mode, and each crossing's h* truth − prediction [km]."""
    weather, other_band, _ = SCENARIOS[scenario]
    rng = np.random.default_rng([SEED, list(SCENARIOS).index(scenario), draw])
    band = A.CO2_BAND
    if other_band:
        band = A.BandModel(A.CO2_BAND_SEVEN.weights, A.CO2_BAND_SEVEN.unit_depth_heights_km,
                           strength=float(np.exp(0.05 * rng.standard_normal())))
    model = _MODEL

    def truth_radiance(latitude):
        if weather is None and not other_band:
            return model.radiance(latitude)
        base = A.seasonal_profile(latitude, DAY_OF_YEAR)
        prof = base if weather is None else A.weather_profile(base, latitude, rng, weather)
        return A.radiance_table(prof, band, step_km=0.5, layer_km=1.0)  # its own numerics: 1-km layers

    errors = {(m, mode): [] for m in METHODS for mode in ("none", "climatology")}
    height_misses = {m: [] for m in METHODS}
    for w, truth in enumerate(_truth_attitudes()):
        state = orbit.thesis_window_state(w)
        p, frame = state.position_km, state.orbit_frame()
        rot = frame @ body_to_orbit(*truth)
        _, latitudes = C.crossing_tangent_latitudes_deg(p, rot)
        crossing_atmospheres = [truth_radiance(lat) for lat in latitudes]
        windows, peaks = C.simulate_edge_windows(p, rot, crossing_atmospheres,
                                                 truth_radiance(C.sub_satellite_latitude_deg(p)))
        measured = {m: C.locate_windows(m, windows, peaks, **o) for m, o in METHODS.items()}
        # one prediction for all locators, at the first estimate of one of them (h* hardly moves with attitude:
        # test_the_shared_first_estimate_costs_nothing)
        first = C.fit_roll_pitch_wgs84(measured["local-threshold"], CONES, p, frame, 0.0)
        first_rot = frame @ body_to_orbit(*first)
        predicted, predicted_peaks = model.edge_windows(p, first_rot)
        for m, options in METHODS.items():
            none = C.fit_roll_pitch_wgs84(measured[m], CONES, p, frame, 0.0, initial=first)
            heights = C.locator_horizon_heights_km(m, predicted, predicted_peaks, p, first_rot, **options)
            corrected = C.fit_roll_pitch_wgs84(measured[m], CONES, p, frame, heights, initial=first)
            errors[(m, "none")].append(np.subtract(none, truth))
            errors[(m, "climatology")].append(np.subtract(corrected, truth))
            dirs = np.stack([scan_vector(ph, cone=c) for ph, c in zip(measured[m], CONES)]) @ rot.T
            height_misses[m].extend(tangent_height_scaled_km(p, dirs) - heights)
    return errors, height_misses


@pytest.fixture(scope="module")
def figures():
    """scenario → {"errors": {(method, mode): (windows × draws, 2) [°]}, "misses": {method: (crossings,) [km]}}."""
    out = {}
    for scenario, (_, _, draws) in SCENARIOS.items():
        errors, misses = {}, {}
        for draw in range(draws):
            e, h = _world(scenario, draw)
            for key, rows in e.items():
                errors.setdefault(key, []).extend(rows)
            for key, rows in h.items():
                misses.setdefault(key, []).extend(rows)
        out[scenario] = {"errors": {k: np.abs(np.array(v)) for k, v in errors.items()},
                         "misses": {k: np.array(v) for k, v in misses.items()}}
    return out


def _table(figures, scenario):
    """(method, mode) → (mean roll, mean pitch, max roll, max pitch) of |error| [°]."""
    return {key: (*e.mean(axis=0), *e.max(axis=0)) for key, e in figures[scenario]["errors"].items()}


def test_every_locator_is_exact_when_the_atmosphere_is_the_climatology(figures):
    """The round trip, kept only to show the machinery: truth = the correction's climatology and band. Every
    locator's correction leaves ≤ 0.006° (the thresholds ≤ 0.001°; the slope-based locators' jitter with the sample
    clock, ±0.25 km of h*, up to 0.0045°), while without it the thesis' locator is off by up to 0.06° in pitch (the
    latitude trend of the horizon)."""
    table = _table(figures, "climatology")
    for m in METHODS:
        assert max(table[(m, "climatology")][2:]) < (0.006 if m in ("inflection", "two-level") else 0.001), m
    assert table[("peak-threshold", "none")][3] > 0.04


def test_a_different_band_model_is_mostly_a_common_shift_the_solver_ignores(figures):
    """Truth with the 7-sub-band model and a 5 % strength error, no weather: the thesis' locator's h* moves by 4–6 km
    but nearly alike at all four crossings, which roll and pitch do not see — every locator with the correction
    stays ≤ 0.015° (measured ≤ 0.010°, the inflection and two-level locators 0.012–0.013° in pitch)."""
    table = _table(figures, "band")
    for m in METHODS:
        assert max(table[(m, "climatology")][2:]) < 0.015, (m, table[(m, "climatology")])
    misses = figures["band"]["misses"]
    assert np.mean(np.abs(misses["peak-threshold"])) > 2.0  # the band does move the horizon


def test_ordinary_weather_defeats_the_thesis_locator_and_the_climatology_cannot_help_it(figures):
    """Ordinary weather (30 window solutions): the thesis' locator (eq. 2.1 normalised by the pulse's peak, which
    comes from the disc under the satellite, another atmosphere than the crossing's) leaves a mean |roll error| of
    ~0.1° corrected or not (measured 0.094°, max 0.36°; 0.08–0.16° over other seeds tried) — the peak's weather
    sets each cone's threshold, and its h* misses by 3.8 ± 3.8 km. Every locator normalised on its own edge does
    better by ≥ 2.5× in roll."""
    table = _table(figures, "weather")
    none, clim = table[("peak-threshold", "none")], table[("peak-threshold", "climatology")]
    assert clim[0] > 0.05 and clim[2] > 0.1, clim
    assert abs(clim[0] - none[0]) < 0.5 * none[0]  # the climatology does not touch the roll error
    for m in LOCAL_METHODS:  # every locator normalised on its own edge does far better
        assert table[(m, "climatology")][0] < 0.6 * clim[0], m


def test_locators_blind_to_the_radiance_scale_with_the_climatology_reach_the_bar_on_average_not_per_window(figures):
    """The honest figure. With ordinary weather and the climatological correction, the best locator (the two-level
    foot) gives mean |error| 0.024° roll and 0.008° pitch, max 0.078° roll and 0.023° pitch; the inflection and
    integrated locators 0.032° / 0.009–0.010° (means), the edge-normalised threshold 0.038° / 0.011°. The pitch mean
    meets the issue's 0.02°; the roll mean and the per-window maxima do not (asserted: the measured figures with
    margin).

    Why no single-band locator can: the day's weather moves each crossing's own horizon — h* truth − prediction has
    a standard deviation of 0.9–1.5 km per crossing (asserted below), i.e. 0.02–0.03° of arc at the horizon's 2560
    km, independently at four tangent points 1800–4500 km apart. Roll is the difference of the two cones' (east and
    west) horizons, which a zonal climatology cannot predict at all; pitch is fore against aft, whose mean latitude
    trend the climatology does remove (pitch improves 1.5–2.5× with it; roll only where h* = 0 was far from the
    locator's own horizon, the two-level foot's ~110 km). The misses also have a mean of −0.8 to −1.5 km (the limb's
    response to a zero-mean anomaly is not linear): common to all crossings, so nearly harmless. Removing the rest
    needs the day's atmosphere (a second band, or assimilated temperatures), not a better threshold."""
    table = _table(figures, "weather")
    best = min(LOCAL_METHODS, key=lambda m: sum(table[(m, "climatology")]))
    mean_roll, mean_pitch, max_roll, max_pitch = table[(best, "climatology")]
    assert mean_pitch <= BAR_DEG, table[(best, "climatology")]
    assert 0.015 < mean_roll < 0.04 and 0.04 < max_roll < 0.12, table[(best, "climatology")]
    assert max_pitch < 0.04
    for m in LOCAL_METHODS:  # the climatology's share is in pitch
        assert table[(m, "climatology")][1] < 0.85 * table[(m, "none")][1], m
    spread = {m: float(np.std(figures["weather"]["misses"][m])) for m in LOCAL_METHODS}
    assert all(0.5 < s < 2.5 for s in spread.values()), spread


def test_a_polar_cold_pool_is_a_horizon_tens_of_km_lower_that_no_climatology_predicts(figures):
    """The stress case: ordinary weather plus a cold pool (20–30 K colder lower stratosphere) in half the crossings
    poleward of 60°. The thesis' locator's horizon drops by up to 28 km there (h* miss), putting its errors at a
    mean of 0.18° roll / 0.10° pitch (max 0.49°) with the climatology; the edge-normalised locators are hurt far
    less (their horizon sits near 35 km, above most of the pool; misses down to −6 to −10 km) — the two-level foot
    0.031° / 0.017° mean, max 0.083° — but exceed 0.02° where a pool lies under one crossing and not the opposite."""
    table = _table(figures, "cold-pool")
    misses = figures["cold-pool"]["misses"]
    assert np.min(misses["peak-threshold"]) < -15.0
    assert max(table[("peak-threshold", "climatology")][2:]) > 0.25
    best = min(LOCAL_METHODS, key=lambda m: sum(table[(m, "climatology")]))
    assert max(table[(best, "climatology")][2:]) > BAR_DEG
    assert max(table[(best, "climatology")][2:]) < 0.5 * max(table[("peak-threshold", "climatology")][2:])


def test_the_shared_first_estimate_costs_nothing():
    """The fixture predicts the edges once per window, at the first estimate of one locator; the full iteration
    (:func:`corrections.locator_corrected_roll_pitch`, two rounds from each locator's own estimate) gives the same
    answer within 0.002° on the round trip."""
    model = _MODEL
    truth = _truth_attitudes()[3]
    state = orbit.thesis_window_state(3)
    p, frame = state.position_km, state.orbit_frame()
    rot = frame @ body_to_orbit(*truth)
    _, lats = C.crossing_tangent_latitudes_deg(p, rot)
    windows, peaks = C.simulate_edge_windows(p, rot, [model.radiance(lat) for lat in lats],
                                             model.radiance(C.sub_satellite_latitude_deg(p)))
    for m in ("peak-threshold", "two-level"):
        measured = C.locate_windows(m, windows, peaks, **METHODS[m])
        full = C.locator_corrected_roll_pitch(measured, p, frame, m, model, iterations=2, **METHODS[m])
        assert full == pytest.approx(tuple(truth), abs=0.002), m
