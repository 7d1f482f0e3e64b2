"""The horizon sensor driver against its simulator on a simulated bench (family "horizon", an alt-az fork with the
scan head at the axes' intersection, the IR Earth simulator as source): the reported crossings are where the scan
cones meet the disc, computed here from the geometry itself (S_k(δ)·n = cos ρ, the package's conventions) with the
sensor's build errors; the locator's threshold, the IFOV's profile and the bolometer's lag move the edges as their
physics says; faults show as typed errors or flagged scans; revolutions take their time on the simulated clock."""

import itertools
import math
import time

import numpy as np
import pytest
from framedtools import inject
from scipy.integrate import dblquad, quad
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation
from scipy.stats import norm

from calibration.horizon.ifov import covered_fraction_sphere, level_separation_deg
from drivers import horizon_protocol as wire
from drivers.errors import ChecksumError, DeviceTimeout
from drivers.horizon_sensor import HorizonSensorModule, MotorStalled
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.horizon_optics import cap_ifov_fraction, locate_edges
from drivers.sim.horizon_sensor import HorizonSensorConfig, horizon_fleet_truth
from drivers.transport import open_port

_names = itertools.count()
#: A build with cone-angle and phase errors but no threshold offset and no lag: the crossings are the geometry's
GEOMETRIC = {"gamma_1_deg": 70.04, "gamma_2_deg": 69.97, "phase_offset_1_deg": 0.12, "phase_offset_2_deg": -0.08,
             "threshold_offset": 0.0, "time_constant_ms": 0.0}


def _bench(time_scale=0.0, build=None, **horizon):
    config = HorizonSensorConfig(**({"build": build} if build else {}), **horizon)
    bench = SimBench(SimBenchConfig(family="horizon", time_scale=time_scale, seed=4, table="lx200",
                                    axis_order="zenith-on-azimuth", mount={"tilt_x_deg": 0.0, "tilt_y_deg": 0.0},
                                    geometry={"lever_arm_mm": 0.0, "source_distance_mm": 1000.0}, horizon=config))
    urls = bench.register(f"horizon-test-{next(_names)}")
    earth = bench.earth
    earth.set_heater(True)
    earth.move_cover(True)
    if bench.world.clock.instant:
        earth.observe_heater()
        earth.observe_cover()
    return bench, HorizonSensorModule(open_port(urls["sensor"], baudrate=115200, timeout_s=0.5))


@pytest.fixture
def horizon(request):
    bench, module = _bench(**getattr(request, "param", {}))
    yield bench, bench.devices["sensor"], module
    module.port.close()
    bench.unregister()


def set_disc(bench, radius_deg):
    bench.earth.move_iris(radius_deg)
    bench.earth.observe_iris()


def point(bench, azimuth_deg, zenith_deg):
    """Turn the fork; returns the disc centre's true direction in the body frame (the world's)."""
    world = bench.world
    world.azimuth.move_to(azimuth_deg)
    world.zenith.move_to(zenith_deg)
    zen, az = (math.radians(a) for a in world.sun_direction_body())
    return np.array([math.sin(zen) * math.cos(az), math.sin(zen) * math.sin(az), math.cos(zen)])


def expected_phases(n, rho_deg, gamma_deg, offset_deg, cone):
    """Where cone `cone` (half-angle γ, looking at δ + offset when the module says δ) leaves and re-enters a disc of
    radius ρ about `n`: S(δ)·n = cos ρ with S = (sin δ sin γ, ±cos γ, cos δ sin γ), solved here in closed form."""
    g, s = math.radians(gamma_deg), 1.0 if cone == 1 else -1.0
    a, b, c = n[0] * math.sin(g), n[2] * math.sin(g), s * n[1] * math.cos(g)
    centre = math.degrees(math.atan2(a, b))
    half = math.degrees(math.acos((math.cos(math.radians(rho_deg)) - c) / math.hypot(a, b)))
    return (centre + half - offset_deg) % 360.0, (centre - half - offset_deg) % 360.0


def mean_phases(module, n=8):
    scans = module.read_scans(n)
    assert all(s.valid == (True, True) for s in scans)
    out = np.array([s.phase_out_deg for s in scans]).mean(axis=0)
    inn = np.array([s.phase_in_deg for s in scans]).mean(axis=0)
    return out, inn


def apparent_radius(n, phase_out, phase_in, gamma_deg, offset_deg, cone):
    """The disc radius the chord's width says (the crossing condition solved for ρ)."""
    g, s = math.radians(gamma_deg), 1.0 if cone == 1 else -1.0
    a, b, c = n[0] * math.sin(g), n[2] * math.sin(g), s * n[1] * math.cos(g)
    half = math.radians(((phase_out - phase_in) % 360.0) / 2.0)
    return math.degrees(math.acos(c + math.hypot(a, b) * math.cos(half)))


def wrap(x):
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


# -- identity and geometry ----------------------------------------------------------------------------------
def test_identify_reports_the_design(horizon):
    _, _, module = horizon
    ident = module.identify()
    assert (ident.model, ident.serial, ident.cones, ident.samples_per_revolution) == ("SB-HORIZON-DCS", "HZ-0001", 2,
                                                                                       3600)
    assert (ident.gamma_deg, ident.ifov_half_angle_deg, ident.threshold, ident.nominal_period_s) == (70.0, 2.0, 0.5,
                                                                                                      1.0)


@pytest.mark.parametrize("horizon", [{"build": {"gamma_1_deg": 70.0, "gamma_2_deg": 70.0, "phase_offset_1_deg": 0.0,
                                                "phase_offset_2_deg": 0.0, "threshold_offset": 0.0,
                                                "time_constant_ms": 0.0}}], indirect=True)
def test_a_nominal_sensor_at_zero_attitude_crosses_where_the_thesis_says(horizon):
    """Digest §2.5: zero attitude at 504.652 km (ρ = 67.923°, eq. 2.3 with R_e = 6378.137 km), γ = 70° gives
    δ = 66.423°, t = 0.18451 s; STK reports 0.18443–0.18452 s (Table 4-2)."""
    bench, _, module = horizon
    rho = math.degrees(math.asin(6378.137 / (6378.137 + 504.652)))
    assert rho == pytest.approx(67.923, abs=5e-4)
    set_disc(bench, rho)
    point(bench, 0.0, 0.0)
    scans = module.read_scans(32)
    t_out = np.mean([s.t_out_s for s in scans], axis=0)
    phase_out = np.mean([s.phase_out_deg for s in scans], axis=0)
    # the 50 % point of a 2° IFOV lies a few thousandths of a degree inside a curved limb (0.006° = 1.7e-5 s) and
    # the module counts whole microseconds: within 3e-5 s
    assert t_out == pytest.approx([0.18451, 0.18451], abs=3e-5)
    assert phase_out == pytest.approx([66.423, 66.423], abs=0.01)
    assert np.mean([s.phase_in_deg for s in scans], axis=0) == pytest.approx([293.577, 293.577], abs=0.01)


@pytest.mark.parametrize("horizon", [{"build": GEOMETRIC}], indirect=True)
def test_the_crossings_follow_the_disc_and_the_build(horizon):
    """Fork poses that put the disc centre up to 30° off nadir (roll and pitch alike), two disc radii: every edge
    within 0.015° of S_k(δ + o_k)·n = cos ρ with the build's own γ_k and o_k (the IFOV's limb-curvature bias, a few
    thousandths, and the noise of 8 scans are the difference)."""
    bench, sim, module = horizon
    gammas, offsets = sim.truth.gamma_deg, sim.truth.phase_offset_deg
    worst = 0.0
    for radius in (64.3, 70.2):
        set_disc(bench, radius)
        for azimuth, zenith in [(0, 0), (90, 15), (270, 30), (0, -12), (45, 20), (200, 8)]:
            n = point(bench, azimuth, zenith)
            out, inn = mean_phases(module)
            for k in (0, 1):
                want = expected_phases(n, radius, gammas[k], offsets[k], k + 1)
                worst = max(worst, abs(wrap(out[k] - want[0])), abs(wrap(inn[k] - want[1])))
    assert worst < 0.015
    # and the build matters: with the nominal 70° and no offsets the same edges miss by far more
    n = point(bench, 90, 15)
    out, _ = mean_phases(module)
    assert abs(wrap(out[0] - expected_phases(n, 70.2, 70.0, 0.0, 1)[0])) > 0.1


def test_a_fleet_is_drawn_from_the_serial(horizon):
    bench, sim, module = horizon
    a, b = (SimBench(SimBenchConfig(family="horizon", time_scale=0.0)).mount_sensor(s) for s in ("HZ-7", "HZ-8"))
    for serial, truth in (("HZ-8", b), ("HZ-7", a), ("HZ-8", b)):
        assert bench.mount_sensor(serial) == truth and sim.truth == truth
        assert module.identify().serial == serial
    assert a.gamma_deg != b.gamma_deg and a.phase_offset_deg != b.phase_offset_deg
    assert abs(a.gamma_deg[0] - 70.0) < 3 * 0.03 + 1e-12 and abs(a.phase_offset_deg[1]) <= 0.3 + 1e-12
    assert horizon_fleet_truth(HorizonSensorConfig(), "HZ-7") == a
    assert bench.mount_sensor("HZ-0001") == HorizonSensorConfig().truth()


# -- the locator, the IFOV and the detector ---------------------------------------------------------------------
def straight_edge_offset(fraction, half_angle_deg, profile):
    """How far inside the disc [°] the IFOV's centre is when `fraction` of its response lies on a straight edge:
    a top hat's circular segment, a Gaussian's (half maximum at the half-angle) normal edge-spread function."""
    if profile == "gaussian":
        return half_angle_deg / math.sqrt(2 * math.log(2)) * norm.ppf(fraction)
    segment = lambda d: (math.acos(d) - d * math.sqrt(1 - d * d)) / math.pi  # noqa: E731 - area beyond d, radius 1
    return half_angle_deg * brentq(lambda d: 1.0 - segment(d) - fraction, -1.0, 1.0)


@pytest.mark.parametrize("profile", ["tophat", "gaussian"])
def test_a_higher_threshold_shrinks_the_disc_as_the_ifov_says(profile):
    """C1 = 0.7 instead of 0.5: the apparent disc radius shrinks by the distance at which 70 % of the IFOV's response
    lies on a straight edge (within 10 %: the limb's curvature and the sampling are the rest)."""
    bench, module = _bench(build=GEOMETRIC, ifov_profile=profile)
    sim = bench.devices["sensor"]
    set_disc(bench, 68.0)
    n = point(bench, 90, 10)
    radii = {}
    for c1 in (0.5, 0.7):
        module.set_threshold(c1)
        out, inn = mean_phases(module)
        radii[c1] = [apparent_radius(n, out[k], inn[k], sim.truth.gamma_deg[k], sim.truth.phase_offset_deg[k], k + 1)
                     for k in (0, 1)]
    assert np.abs(np.array(radii[0.5]) - 68.0).max() < 0.02
    shrink = np.array(radii[0.5]) - np.array(radii[0.7])
    assert shrink == pytest.approx([straight_edge_offset(0.7, 2.0, profile)] * 2, rel=0.1)
    module.port.close()
    bench.unregister()


def test_the_bolometer_lag_delays_both_edges_by_its_time_constant():
    """τ = 2 ms: every edge comes τ late (a ramp through a first-order lag), so the chord keeps its width and only
    its centre moves — the lag is a phase offset."""
    phases = {}
    for tau_ms in (0.0, 2.0):
        bench, module = _bench(build={**GEOMETRIC, "time_constant_ms": tau_ms})
        set_disc(bench, 68.0)
        point(bench, 30, 12)
        scans = module.read_scans(8)
        phases[tau_ms] = (np.mean([s.t_out_s for s in scans], axis=0), np.mean([s.t_in_s for s in scans], axis=0))
        module.port.close()
        bench.unregister()
    late_out = phases[2.0][0] - phases[0.0][0]
    late_in = phases[2.0][1] - phases[0.0][1]
    assert late_out == pytest.approx([0.002, 0.002], rel=0.05)
    assert late_in == pytest.approx([0.002, 0.002], rel=0.05)


def test_the_noise_scatters_the_edges_and_jitter_the_periods(horizon):
    bench, _, module = horizon
    set_disc(bench, 68.0)
    point(bench, 0, 10)
    scans = module.read_scans(32)
    periods = np.array([s.period_s for s in scans])
    assert [s.revolution for s in scans] == list(range(scans[0].revolution, scans[0].revolution + 32))
    assert 0.3e-4 < periods.std() < 2e-4 and abs(periods.mean() - 1.0) < 1e-4  # period_jitter 1e-4
    spread = np.array([s.phase_out_deg for s in scans]).std(axis=0)
    assert (spread > 1e-4).all() and (spread < 0.01).all()


def test_the_pulse_shows_earth_space_and_the_threshold(horizon):
    bench, _, module = horizon
    set_disc(bench, 68.0)
    point(bench, 0, 0)
    scan = module.read_scans(1)[0]
    pulse = module.pulse()
    assert pulse.samples.shape == (2, 900) and pulse.period_s == scan.period_s
    earth, space = pulse.samples[:, 0], pulse.samples[:, 450]  # phase 0 looks at the disc's centre side, 180 away
    assert (earth > 20000).all() and (space < 2200).all()
    assert pulse.threshold == pytest.approx(np.array(scan.level_space) + 0.518 * (np.array(scan.level_earth)
                                                                                 - np.array(scan.level_space)), abs=2)


def _noise_free_edges(sensor, roll, pitch):
    """Both cones' (out, in) phases [°] the module's locator finds on the noise-free, unquantised pulses with the
    table turning the disc centre to n = (−sin θ, sin φ cos θ, cos φ cos θ) in the body (the pose given to the optics
    directly: the wire's whole microseconds would hide a tenth of a millidegree)."""
    rotation = Rotation.from_euler("YX", [pitch, roll], degrees=True).as_matrix()
    clean = sensor.clean_signal(pose=(rotation, np.zeros(3)))
    n = sensor.config.samples_per_revolution
    level = sensor.threshold + sensor.truth.threshold_offset
    found = [locate_edges(clean[k], level, min_contrast=500.0, full_scale=1e9,
                          plateau_margin=sensor.plateau_margin_samples) for k in (0, 1)]
    return [(e.out_index * 360.0 / n, e.in_index * 360.0 / n) for e in found]


@pytest.mark.parametrize("horizon", [{"build": GEOMETRIC}], indirect=True)
def test_an_edge_lies_where_half_the_ifov_covers_the_disc_whatever_its_orientation(horizon):
    """Without noise, lag or comparator offset the locator's edges lie where half of the 2° top hat covers the disc —
    the exact overlap of two caps (calibration.horizon.ifov, the seed 004 §2-4-2 obscuration) — within 0.2 mdeg for
    crossings from square-on (zero attitude) to the most oblique of the sensor's range (roll ±33°, pitch ±17°, the
    short chords included), at three disc radii."""
    bench, sensor, _ = horizon
    worst = 0.0
    for radius in (64.304, 68.019, 70.218):
        set_disc(bench, radius)
        half = float(level_separation_deg(radius, 2.0, 0.5))
        for roll, pitch in [(0, 0), (33, 17), (-33, -17), (33, -17), (-33, 0), (15, 8), (0, 17)]:
            n = np.array([-math.sin(math.radians(pitch)), math.sin(math.radians(roll)) * math.cos(math.radians(pitch)),
                          math.cos(math.radians(roll)) * math.cos(math.radians(pitch))])
            got = _noise_free_edges(sensor, roll, pitch)
            for k in (0, 1):
                want = expected_phases(n, half, sensor.truth.gamma_deg[k], sensor.truth.phase_offset_deg[k], k + 1)
                worst = max(worst, *np.abs(wrap(np.array(got[k]) - want)))
    assert worst < 2e-4, worst


def test_the_ifov_integral_matches_the_cap_overlap_and_a_gaussian_quadrature():
    """The simulator's ring integral against the closed-form cap overlap (top hat) to 1e-10 of the IFOV across the
    edge, and against scipy's dblquad over a Gaussian IFOV (half maximum at α, cut at 2.5 α) to 1e-8."""
    separation = np.linspace(64.0, 72.0, 801)
    for radius in (64.3, 68.0, 70.2):
        exact = covered_fraction_sphere(separation, radius, 2.0)
        assert np.abs(cap_ifov_fraction(separation, radius, 2.0) - exact).max() < 1e-10
    alpha, reach, rho = math.radians(2.0), math.radians(5.0), math.radians(68.0)

    def weight(r):
        return math.exp(-math.log(2.0) * (r / alpha) ** 2) * math.sin(r)

    total = quad(weight, 0.0, reach, epsabs=1e-14)[0]
    for d_deg in (66.5, 67.9, 68.0, 69.3):
        d = math.radians(d_deg)

        def inside(phi, r, d=d):
            return weight(r) * (math.cos(d) * math.cos(r) + math.sin(d) * math.sin(r) * math.cos(phi) >= math.cos(rho))

        def ring(r, d=d):  # the azimuths of ring r inside the disc, in closed form: smooth apart from one kink
            c = (math.cos(rho) - math.cos(d) * math.cos(r)) / (math.sin(d) * math.sin(r))
            return weight(r) * math.acos(min(1.0, max(-1.0, c))) / math.pi

        share = quad(ring, 0.0, reach, points=[abs(rho - d)], epsabs=1e-14, limit=200)[0] / total
        brute = dblquad(inside, 0.0, reach, 0.0, 2.0 * math.pi, epsabs=1e-6)[0] / (2.0 * math.pi * total)
        got = float(cap_ifov_fraction(d_deg, 68.0, 2.0, "gaussian"))
        assert got == pytest.approx(share, abs=1e-8) and got == pytest.approx(brute, abs=2e-4)


@pytest.mark.parametrize("horizon", [{"build": GEOMETRIC, "noise_counts": 0.0}], indirect=True)
def test_the_locator_takes_its_levels_from_the_plateaus(horizon):
    """Roll −33° at the smallest disc: cone 1's chord is 76° long, cone 2's 143°. The highest quarter of the short
    pulse's range reaches down its shoulders and sits well below the disc's level; the module's Earth level is the
    plateau's, the same for both cones (and the space level the shroud's pedestal), so the short chord's threshold —
    and its edges — do not sink."""
    bench, sensor, module = horizon
    set_disc(bench, 64.304)
    n = point(bench, 0, -33)  # the fork's altitude axis about lab x: the disc centre at body roll −33°
    assert math.degrees(math.atan2(n[1], n[2])) == pytest.approx(-33.0, abs=0.01)
    scan = module.read_scans(1)[0]
    samples = sensor.last.samples
    top_quarter = [samples[k][samples[k] >= samples[k].max() - (samples[k].max() - samples[k].min()) / 4].mean()
                   for k in (0, 1)]
    chords = [(scan.phase_out_deg[k] - scan.phase_in_deg[k]) % 360.0 for k in (0, 1)]
    assert chords[0] == pytest.approx(76.3, abs=0.5) and chords[1] == pytest.approx(143.4, abs=0.5)
    assert top_quarter[1] - top_quarter[0] > 20.0  # the rough level of the short chord sinks
    assert abs(scan.level_earth[0] - scan.level_earth[1]) <= 1.0 and scan.level_earth[0] >= max(top_quarter)
    assert scan.level_space == (2000.0, 2000.0)
    half = float(level_separation_deg(64.304, 2.0, 0.5))
    for k in (0, 1):
        want = expected_phases(n, half, sensor.truth.gamma_deg[k], sensor.truth.phase_offset_deg[k], k + 1)
        got = (scan.phase_out_deg[k], scan.phase_in_deg[k])
        assert np.abs(wrap(np.array(got) - want)).max() < 5e-4  # the wire's whole µs: ±0.18 mdeg


# -- faults -----------------------------------------------------------------------------------------------------
def test_a_closed_cover_leaves_no_edges(horizon):
    bench, _, module = horizon
    bench.earth.move_cover(False)
    bench.earth.observe_cover()
    scan = module.read_scans(1)[0]
    assert scan.valid == (False, False) and all(math.isnan(t) for t in scan.t_out_s + scan.t_in_s)


def test_a_dead_detector_has_no_edges_on_its_cone(horizon):
    _, sim, module = horizon
    sim.kill_detector(2)
    scan = module.read_scans(1)[0]
    assert scan.valid == (True, False) and math.isnan(scan.t_out_s[1]) and scan.level_earth[1] < 2100


def test_a_blinding_source_saturates_and_invalidates_its_cone(horizon):
    _, sim, module = horizon
    sim.blind()
    scan = module.read_scans(1)[0]
    assert scan.saturated == (True, False) and scan.valid == (False, True) and scan.level_earth[0] > 60000
    sim.clear_faults()
    assert module.read_scans(1)[0].valid == (True, True)


def test_a_stalled_motor_is_a_typed_error_after_two_periods(horizon):
    bench, sim, module = horizon
    sim.stall_motor()
    start = bench.clock.now()
    with pytest.raises(MotorStalled, match="no index mark"):
        module.read_scans(1)
    assert bench.clock.now() - start == pytest.approx(2.0)


@pytest.mark.parametrize("fault", ["garble", "truncate", "corrupt_crc"])
def test_link_faults_are_asked_again(horizon, fault):
    _, sim, module = horizon
    module.identify()
    inject(sim, fault, 1)
    if fault == "corrupt_crc":  # a whole frame with a bad CRC is seen at once, without waiting for the timeout
        assert module.read_scans(1)[0].valid == (True, True)
    else:
        assert module.status().motor_turning
    assert module.retry_count == 1


def test_silence_and_persistent_corruption_are_typed_errors(horizon):
    _, sim, module = horizon
    inject(sim, "corrupt_crc", 10)
    with pytest.raises(ChecksumError):
        module.status()
    sim.clear_faults()
    inject(sim, "no_reply", 1)
    with pytest.raises(DeviceTimeout, match="no reply"):
        HorizonSensorModule(module.port, retries=0).status()


# -- time ---------------------------------------------------------------------------------------------------------
def test_a_read_waits_for_the_next_index_and_its_revolutions(horizon):
    bench, _, module = horizon
    bench.mount_sensor("HZ-0001")  # powered up now: index marks every second from here
    bench.clock.advance(0.3)  # between index marks
    start = bench.clock.now()
    scans = module.read_scans(3)
    assert bench.clock.now() - start == pytest.approx(0.7 + sum(s.period_s for s in scans), abs=2e-6)  # whole µs
    again = module.read_scans(1)[0]
    assert again.revolution == scans[-1].revolution + 1


def test_a_read_in_progress_makes_the_module_busy():
    bench, module = _bench(time_scale=20.0)  # 1 s revolutions take 50 ms of wall time
    sim = bench.devices["sensor"]
    try:
        assert sim.receive(wire.encode_frame(wire.READ_SCANS, 9, b"\x02")) == b""  # held back: the reply is not ready
        busy, _ = wire.decode_frame(sim.receive(wire.encode_frame(wire.GET_STATUS, 10)))
        assert busy.code == wire.ERROR and busy.payload[0] == wire.NOT_READY
        deadline = time.monotonic() + 2.0
        reply = b""
        while not reply and time.monotonic() < deadline:
            time.sleep(0.01)
            reply = sim.poll()
        done, _ = wire.decode_frame(reply)
        assert done.code == wire.READ_SCANS | wire.REPLY and done.sequence == 9 and done.payload[0] == 2
    finally:
        module.port.close()
        bench.unregister()
