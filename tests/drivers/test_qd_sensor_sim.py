"""The QD module driver against its simulator through a sim:// port on a simulated bench (family "qd"):
the currents follow the table, the lamp and the TEC as the world says; the effects a calibration does not model
(the diaphragm's thickness, the housing's stray light, crosstalk between channels) act in the right sense."""

import dataclasses
import itertools
import math
import time

import numpy as np
import pytest
from framedtools import inject

from drivers import qd_protocol as wire
from drivers.errors import ChecksumError, DeviceDisconnected, DeviceTimeout, ProtocolError
from drivers.qd_sensor import QdSensorError, QdSunSensor
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.qd_optics import (
    QUADRANT_SIGNS,
    RING_PAIRS,
    QdOptics,
    QdTruth,
    lens_rect_area,
    qd_fleet_truth,
)
from drivers.sim.qd_sensor import QdSensorConfig
from drivers.transport import open_port

_names = itertools.count()


@pytest.fixture
def qd(request):
    time_scale = getattr(request, "param", 0.0)
    bench = SimBench(SimBenchConfig(family="qd", time_scale=time_scale, seed=3))
    urls = bench.register(f"qd-test-{next(_names)}")
    lamp = bench.world.lamp
    if bench.world.clock.instant:
        lamp.start()
        lamp.is_warm()
        lamp.shutter_open = True
    sensor = QdSunSensor(open_port(urls["sensor"], baudrate=115200, timeout_s=0.3))
    yield bench, bench.devices["sensor"], sensor
    sensor.port.close()
    bench.unregister()


def point(world, alpha_deg, beta_deg):
    """Turn the table so the Sun sits near projection angles (α, β) of the body frame: tan α = s_x/s_z,
    tan β = s_y/s_z (the world's truth then differs by the sensor's mount tilt and the bench geometry)."""
    tx, ty = math.tan(math.radians(alpha_deg)), math.tan(math.radians(beta_deg))
    world.azimuth.move_to(math.degrees(math.atan2(ty, tx)) if tx or ty else 0.0)
    world.zenith.move_to(math.degrees(math.atan(math.hypot(tx, ty))))
    return world.sun_direction_body()


def _direction(alpha_deg, beta_deg):
    """(zenith, azimuth) [°] of the direction of projection angles (α, β)."""
    s = np.array([math.tan(math.radians(alpha_deg)), math.tan(math.radians(beta_deg)), 1.0])
    return math.degrees(math.acos(s[2] / np.linalg.norm(s))), math.degrees(math.atan2(s[1], s[0]))


def _lens_area(r, delta):
    """Area of two discs of radius r whose centres are delta apart."""
    return 2 * r * r * math.acos(delta / (2 * r)) - 0.5 * delta * math.sqrt(4 * r * r - delta * delta)


def _segment_integral(x, r):
    """∫₀ˣ √(r² − t²) dt for |x| ≤ r."""
    x = np.clip(x, -r, r)
    return 0.5 * (x * np.sqrt(np.maximum(r * r - x * x, 0.0)) + r * r * np.arcsin(x / r))


def _disc_quarter_area(u, v, r):
    """Area of the disc of radius `r` centred at the origin inside the quarter-plane {x > u, y > v} (exact).

    ∫ over x > u of the chord length above y = v: where the chord lies wholly above (v ≤ −√(r² − x²)) it is
    2√(r² − x²), where it crosses, √(r² − x²) − v; with the breakpoints at ±√(r² − v²) the integrals are
    closed-form."""
    u = np.clip(u, -r, r)
    v = np.clip(v, -r, r)
    xv = np.sqrt(np.maximum(r * r - v * v, 0.0))
    lo = np.clip(u, -xv, xv)
    crossing = _segment_integral(xv, r) - _segment_integral(lo, r)
    above = crossing - v * (xv - lo)  # v ≥ 0: only the crossing chords count
    whole = 2.0 * (_segment_integral(r, r) - _segment_integral(u, r))
    below = whole - (crossing + v * (xv - lo))  # v < 0: full chords, less what y < v takes inside |x| < xv
    return np.where(v >= 0.0, above, below)


def _disc_rect_area(x1, x2, y1, y2, r):
    """Area of the disc of radius `r` at the origin inside the rectangle [x1, x2] × [y1, y2] (x1 ≤ x2, y1 ≤ y2),
    in closed form: the oracle of :func:`~drivers.sim.qd_optics.lens_rect_area` with coincident discs."""
    return (_disc_quarter_area(x1, y1, r) - _disc_quarter_area(x2, y1, r) - _disc_quarter_area(x1, y2, r)
            + _disc_quarter_area(x2, y2, r))


IDEAL = dict(diaphragm_thickness_um=0.0, wall_reflectance=0.0, crosstalk=(0.0, 0.0, 0.0, 0.0))


def ratios(i):
    """Seed 002 eq. 2.1's normalised differences (x, y) from Q1 … Q4."""
    i1, i2, i3, i4 = i
    s = i1 + i2 + i3 + i4
    return ((i2 + i3) - (i1 + i4)) / s, ((i2 + i4) - (i1 + i3)) / s


def dark_corrected(world, sensor, average=20):
    world.lamp.shutter_open = True
    lit = np.array(sensor.read(average).currents_a)
    world.lamp.shutter_open = False
    dark = np.array(sensor.read(average).currents_a)
    world.lamp.shutter_open = True
    return lit - dark


# -- identity and build -------------------------------------------------------------------------------------
def test_identify_reports_the_modules_conversion(qd):
    bench, sim, sensor = qd
    ident = sensor.identify()
    truth = sim.truth
    assert (ident.model, ident.serial, ident.adc_bits) == ("SB-QD-SUN", "QD-0001", 16)
    assert ident.amperes_per_count == pytest.approx(tuple(truth.amperes_per_count), rel=1e-6)
    assert (ident.detector_side_um, ident.gap_um, ident.integration_ms) == (1000.0, 5.0, 1.0)
    assert ident.full_scale_a[0] == pytest.approx(2.0e-6, rel=0.01)


def test_a_fleets_serials_are_built_reproducibly_from_the_serial(qd):
    bench, sim, sensor = qd
    fresh = {s: SimBench(SimBenchConfig(family="qd", time_scale=0.0)).mount_sensor(s) for s in ("QD-101", "QD-102")}
    for serial in ("QD-102", "QD-101", "QD-102"):
        assert bench.mount_sensor(serial) == fresh[serial] and sim.truth == fresh[serial]
        assert sensor.identify().serial == serial
    a, b = fresh["QD-101"], fresh["QD-102"]
    assert (a.x0_um, a.height_um, a.quadrant_response) != (b.x0_um, b.height_um, b.quadrant_response)
    assert (a.diaphragm_thickness_um, a.crosstalk, a.wall_reflectance, a.bore_radius_mm) != (
        b.diaphragm_thickness_um, b.crosstalk, b.wall_reflectance, b.bore_radius_mm)  # and so are the effects
    assert bench.mount_sensor("QD-0001") == SimBenchConfig().qd.truth()  # the configured module is its own
    for k in range(200):  # every fleet build keeps the spot over the centre across ±40° × ±40°
        truth = qd_fleet_truth(QdTruth(), f"FM-{k}")
        # (the thick diaphragm's top opening reaches 2.5·tan 50° µm farther than its mid-plane: ≥ 3.4 µm is left)
        assert truth.centre_margin_um() > 3.0 and abs(truth.height_um - 30.0) <= 1.5
        assert abs(truth.diaphragm_thickness_um - QdTruth().diaphragm_thickness_um) < 1.3
        assert 0 < min(truth.crosstalk) <= max(truth.crosstalk) < 0.01
        assert 0.3 < truth.wall_reflectance <= 1 and truth.window_radius_mm < truth.bore_radius_mm
        assert abs(truth.stray_cutoff_deg - QdTruth().stray_cutoff_deg) < 2.0


# -- optics ----------------------------------------------------------------------------------------------
def test_the_disc_rectangle_area_is_exact():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, (400_000, 2))
    pts = pts[(pts ** 2).sum(axis=1) < 1]
    for x1, x2, y1, y2 in [(-0.2, 0.6, 0.1, 2.0), (-2, 2, -2, 2), (0.05, 9, -9, -0.05), (-0.9, -0.4, -0.3, 0.3)]:
        inside = ((pts[:, 0] > x1) & (pts[:, 0] < x2) & (pts[:, 1] > y1) & (pts[:, 1] < y2)).mean() * math.pi
        assert _disc_rect_area(x1, x2, y1, y2, 1.0) == pytest.approx(inside, abs=0.006)
    assert _disc_rect_area(-5, 5, -5, 5, 3.0) == pytest.approx(9 * math.pi)


@pytest.mark.parametrize("alpha, beta, grow", [(20, 0, (1, 4)), (-20, 0, (2, 3)), (0, 20, (1, 3)), (0, -20, (2, 4))])
def test_the_spot_moves_opposite_to_the_sun(qd, alpha, beta, grow):
    """Sun towards +x → spot towards −x → Q1 (−x, −y) and Q4 (−x, +y) grow; towards +y → Q1 and Q3 (−y)."""
    bench, _, sensor = qd
    point(bench.world, alpha, beta)
    i = dark_corrected(bench.world, sensor)
    grown = i[grow[0] - 1] + i[grow[1] - 1]
    assert grown > 1.4 * (i.sum() - grown)


def test_the_ratios_are_monotonic_and_every_quadrant_stays_lit_over_the_field(qd):
    bench, sim, sensor = qd
    xs = []
    for alpha in range(-40, 41, 10):
        point(bench.world, alpha, 0)
        xs.append(ratios(dark_corrected(bench.world, sensor, 4))[0])
    assert np.all(np.diff(xs) < -0.05)  # Sun towards +x: spot towards −x, the x ratio falls
    optics = sim.optics
    for alpha in (-40, 40):
        for beta in (-40, 40):  # the field's corners, through the optics alone: the spot itself lights each
            zen, az = _direction(alpha, beta)
            spot = optics.spot_power_w(zen, az, 1000.0, 0.5)
            assert spot.min() > 0.002 * spot.sum()
            i = optics.photocurrents_a(zen, az, 1000.0, 0.5)
            assert i.min() > 0.005 * i.sum()  # with the stray light and the crosstalk on top
    assert sim.truth.centre_margin_um() > 4.0


def test_the_thesis_geometry_saturates_the_ratio():
    """d = 0.817 mm and y0 = +0.52 mm (seed 002 §5.2) with a 100 µm diaphragm: the spot straddles the x axis
    only for β near 32.5°, elsewhere eq. 2.1's y ratio is ±1 and carries no angle. (A 3 mm detector keeps the
    spot, which a ±40° sweep moves ±0.69 mm around y0, on the die.)"""
    thesis = QdTruth(height_um=817.0, x0_um=-51.7, y0_um=520.0, alpha0_deg=0.0086, beta0_deg=-0.15, phi0_deg=0.0005,
                     detector_side_mm=3.0)
    assert thesis.centre_margin_um() < -1000
    optics = QdOptics(thesis)
    saturated = 0
    for beta in range(-40, 41, 5):  # the spot's light (stray light and crosstalk reach the other side)
        y = ratios(optics.spot_power_w(abs(beta), 90.0 if beta >= 0 else 270.0, 1000.0, 0.53))[1]
        saturated += abs(abs(y) - 1.0) < 1e-9
    assert saturated >= 15  # all but the one or two points near 32.5°


def test_totals_follow_the_cosine_of_incidence_times_the_lens(qd):
    """The light through a diaphragm of thickness t is E·cos i over the lens of its two openings' shadows,
    t·tan i apart: 6 % less than the hole's area at 45° for t = 5 µm."""
    bench, sim, sensor = qd
    sim.mount(dataclasses.replace(sim.truth, diaphragm_thickness_um=5.0))  # a foil mask: the lens shows clearly
    t = sim.truth
    totals, lens = [], []
    for omega in (0, 15, 30, 45):
        point(bench.world, omega, 0)
        s = sim.optics.die_direction(*bench.world.sun_direction_body())
        totals.append(dark_corrected(bench.world, sensor).sum() / s[2])
        lens.append(_lens_area(50.0, t.diaphragm_thickness_um * math.hypot(s[0], s[1]) / s[2]) / (math.pi * 2500))
    assert lens[-1] < 0.95 and totals[-1] < 0.97 * totals[0]
    # within 2 % of the lens law: the dead cross takes a little less of the spot once it has moved off the
    # centre, the crosstalk adds ~0.6 % (45° is beyond the stray light's cut-off, which adds ~0.1 % there)
    flat = np.array(totals) / np.array(lens)
    assert np.ptp(flat) < 0.02 * np.mean(flat) and flat[-1] > flat[0]
    assert 2.0e-6 < np.mean(flat) < 3.0e-6  # 100 µm diaphragm, 1000 W/m², 0.35 A/W, less the dead cross
    for thickness in (0.0, 5.0):  # without the cross, exactly the lens' projected area (the hole's when t = 0)
        no_gap = QdOptics(QdTruth(gap_um=0.0, **{**IDEAL, "diaphragm_thickness_um": thickness}))
        for zenith, azimuth in [(0, 0), (20, 30), (45, 200), (55, 300)]:
            s = no_gap.die_direction(zenith, azimuth)
            power = no_gap.quadrant_power_w(zenith, azimuth, 1000.0, 0.5).sum()
            area = _lens_area(50e-6, thickness * 1e-6 * math.hypot(s[0], s[1]) / s[2])
            assert power / s[2] == pytest.approx(1000.0 * area, rel=1e-4)


def test_closed_shutter_leaves_the_dark_current(qd):
    bench, sim, sensor = qd
    bench.world.lamp.shutter_open = False
    dark = np.array(sensor.read(200).currents_a)
    expected = sim.optics.dark_current_a(sim.tec.true_c())
    # the pedestal's error (a few counts, 30 pA each) and the noise are all that is left
    assert dark == pytest.approx(expected, abs=0.15e-9)


# -- what a real module adds (effects the calibration does not model) -----------------------------------------
def test_the_lens_rectangle_area_is_exact():
    rng = np.random.default_rng(2)
    for _ in range(300):  # coincident discs: the disc's closed form
        c = rng.uniform(-1.5, 1.5, 2)
        (x1, x2), (y1, y2) = np.sort(rng.uniform(-2, 2, 2)), np.sort(rng.uniform(-2, 2, 2))
        assert lens_rect_area(*c, *c, 1.0, x1, x2, y1, y2) == pytest.approx(
            _disc_rect_area(x1 - c[0], x2 - c[0], y1 - c[1], y2 - c[1], 1.0), abs=1e-12)
    for delta in (0.0, 0.3, 1.0, 1.9, 2.0, 2.5):  # a rectangle around everything: the two discs' lens
        lens = lens_rect_area(0.3, 0.1, 0.3 + 0.6 * delta, 0.1 + 0.8 * delta, 1.0, -5, 5, -5, 5)
        assert lens == pytest.approx(_lens_area(1.0, min(delta, 2.0)), abs=1e-12)
    pts = rng.uniform(-2, 2, (2_000_000, 2))  # Monte Carlo: 1σ ≈ 0.002
    for a, b, (x1, x2, y1, y2) in [((0.1, -0.2), (0.5, 0.3), (-0.3, 0.9, -2, 0.05)),
                                   ((-0.4, 0.2), (-0.4, -0.6), (-2, -0.1, -0.8, 2)),
                                   ((0.0, 0.0), (0.9, -0.1), (0.2, 0.6, -0.5, 0.5))]:
        inside = ((((pts - a) ** 2).sum(1) < 1) & (((pts - b) ** 2).sum(1) < 1) & (pts[:, 0] > x1)
                  & (pts[:, 0] < x2) & (pts[:, 1] > y1) & (pts[:, 1] < y2))
        assert lens_rect_area(*a, *b, 1.0, x1, x2, y1, y2) == pytest.approx(inside.mean() * 16, abs=0.01)


def test_a_thick_diaphragm_passes_the_lens_of_its_two_openings():
    """Sun towards +x at incidence i: the spot is the lens t·tan i narrower along x than the hole, centred on the
    mid-plane's shadow (t·tan i / 2 beyond the bottom opening's), so the x split sees a narrower, shifted spot."""
    i = 40.0
    tan_i = math.tan(math.radians(i))
    thick = dict(gap_um=0.0, alpha0_deg=0.0, beta0_deg=0.0, phi0_deg=0.0, y0_um=0.0, wall_reflectance=0.0,
                 crosstalk=(0.0,) * 4, diaphragm_thickness_um=5.0)
    delta = 5.0 * tan_i

    def plus_x_share(x0_um, **over):  # share of the +x quadrants (Q2, Q3) for the Sun at i towards +x
        power = QdOptics(QdTruth(**{**thick, "x0_um": x0_um, **over})).spot_power_w(i, 0.0, 1000.0, 0.0)
        return (power[1] + power[2]) / power.sum()

    # the split through the mid-plane's shadow halves the lens: its centre is (x0 − d·tan i)
    assert plus_x_share(30.0 * tan_i) == pytest.approx(0.5, abs=1e-9)
    # … not the bottom opening's shadow's (a thin mask at d − t/2 would put it there)
    assert plus_x_share(27.5 * tan_i, diaphragm_thickness_um=0.0, height_um=27.5) == pytest.approx(0.5, abs=1e-9)
    assert plus_x_share(27.5 * tan_i) < 0.5 - 0.02
    # the lens' +x edge is r − δ/2 from its centre, where the disc's would be r
    edge = 30.0 * tan_i - (50.0 - delta / 2)  # x0 that puts the split line on the lens' +x edge
    assert plus_x_share(edge + 0.05) > 0 and plus_x_share(edge - 0.05) == 0.0
    assert plus_x_share(edge - 0.05, diaphragm_thickness_um=0.0) > 0.002  # a thin mask's disc still crosses
    # and the spot's light is the lens' area (the test above checks it against the closed form)


# the stray-light tests' build: a 5 µm foil mask (the figures below are for it; the default mask is 1 µm)
FOIL = dataclasses.replace(QdTruth(), diaphragm_thickness_um=5.0)


def test_the_housing_scatters_light_beyond_its_cut_off_onto_the_suns_side():
    truth = FOIL
    optics = QdOptics(truth)
    cut = truth.stray_cutoff_deg
    assert cut == pytest.approx(math.degrees(math.atan2(1.9 - 1.3, 1.0)))
    assert optics.die_direction(cut - 0.6, 45.0)[2] > 0
    assert not optics.stray_power_w(cut - 0.6, 45.0 - truth.phi0_deg, 1000.0).any()  # below: none
    fractions = []
    for alpha in (32, 35, 40):  # beyond it the stray light grows with the incidence
        zen, az = _direction(alpha, alpha)
        fractions.append(optics.stray_power_w(zen, az, 1000.0).sum() / optics.spot_power_w(zen, az, 1000.0).sum())
    assert 0 < fractions[0] < fractions[1] < fractions[2]
    assert 0.003 < fractions[-1] < 0.0045  # 0.74 %·ρ at the field's corner (module docstring), ρ = 0.5
    # it lands on the side the Sun is on: opposite the direct spot, in the diagonally opposite quadrant
    for (alpha, beta), spot_q, stray_q in [((40, 40), 1, 2), ((-40, -40), 2, 1), ((40, -40), 4, 3), ((-40, 40), 3, 4)]:
        zen, az = _direction(alpha, beta)
        spot, stray = optics.spot_power_w(zen, az, 1000.0), optics.stray_power_w(zen, az, 1000.0)
        assert np.argmax(spot) == spot_q - 1 and stray[stray_q - 1] > 0.9 * stray.sum()
    zen, az = _direction(40, 0)  # Sun towards +x: the spot on Q1, Q4, the stray light on Q2, Q3
    stray = optics.stray_power_w(zen, az, 1000.0)
    assert stray[1] + stray[2] > 0.99 * stray.sum()
    # proportional to the wall's reflectance, off at zero
    darker = QdOptics(dataclasses.replace(truth, wall_reflectance=0.1)).stray_power_w(zen, az, 1000.0)
    assert darker == pytest.approx(0.2 * stray, rel=1e-9)
    assert not QdOptics(dataclasses.replace(truth, wall_reflectance=0.0)).stray_power_w(zen, az, 1000.0).any()


def test_the_stray_light_integral_matches_brute_force_ray_tracing():
    """The wall integral (Gauss–Legendre over the lit band, bounded in closed form) against the same physics by
    brute force: rays through a lattice over the window, traced to the wall, each hit a Lambertian source."""
    truth = FOIL
    optics = QdOptics(truth)
    rh, h, rw = truth.bore_radius_mm, truth.bore_height_mm, truth.window_radius_mm
    for alpha, beta in [(40, 40), (-38, 15), (10, -40), (50, 45), (-62, 10)]:  # the last two beyond i = 54°
        zen, az = _direction(alpha, beta)
        s = optics.die_direction(zen, az)
        tx, ty = s[0] / s[2], s[1] / s[2]
        n = 400
        g = (np.arange(n) + 0.5) / n * 2 - 1
        px, py = (a.ravel() * rw for a in np.meshgrid(g, g))
        keep = px * px + py * py < rw * rw
        px, py = px[keep], py[keep]
        cell = (2 * rw / n) ** 2 * s[2]  # beam cross-section of one ray's cell [mm²] (E·cos i on the window)
        # a ray from (p, H) goes down as p − u·T; it meets the wall where |p − u·T| = R_h with u ≤ H
        tt = tx * tx + ty * ty
        pt = px * tx + py * ty
        u = (pt + np.sqrt(pt * pt - tt * (px * px + py * py - rh * rh))) / tt
        hit = u < h
        wx, wy, z = px[hit] - u[hit] * tx, py[hit] - u[hit] * ty, h - u[hit]
        power = 1000.0 * cell * 1e-6  # [W] per ray
        dist2 = rh * rh + z * z
        # Lambertian: intensity ρ P cos(emission)/π towards the diaphragm; irradiance there I/|w|², die-plane ·cos
        irradiance = truth.wall_reflectance * power / math.pi * (rh / np.sqrt(dist2)) / dist2 * (z / np.sqrt(dist2))
        irradiance *= 1e6  # per mm² → per m²
        areas = optics._footprint_areas_um2(wx / z, wy / z)
        brute = 1e-12 * (areas * irradiance).sum(axis=1)
        fast = optics.stray_power_w(zen, az, 1000.0)
        assert fast.sum() > 0 and fast == pytest.approx(brute, abs=0.01 * brute.sum()), (alpha, beta, fast, brute)


def test_crosstalk_couples_geometric_neighbours_only():
    """Q1 (−,−) is next to Q3 (+,−) and Q4 (−,+), diagonal to Q2 (+,+): with the spot wholly on Q1, Q3 and Q4
    read their pair's fraction of it and Q2 nothing."""
    assert all(np.abs(QUADRANT_SIGNS[i] - QUADRANT_SIGNS[j]).sum() == 2 for i, j in RING_PAIRS)  # one axis differs
    assert {frozenset(p) for p in RING_PAIRS} == {frozenset((i, j)) for i in range(4) for j in range(4)
                                                 if np.abs(QUADRANT_SIGNS[i] - QUADRANT_SIGNS[j]).sum() == 2}
    truth = QdTruth(x0_um=-200.0, y0_um=-200.0, quadrant_response=(1.0, 1.0, 1.0, 1.0))  # the spot on Q1 alone
    k13, k32, k24, k41 = truth.crosstalk
    i = QdOptics(truth).photocurrents_a(0.0, 0.0, 1000.0, 0.5)
    assert i[0] > 2e-6 and i[1] == 0.0
    assert i[2] == pytest.approx(k13 * i[0], rel=1e-12) and i[3] == pytest.approx(k41 * i[0], rel=1e-12)
    # everywhere: the channels are C · the quadrants' photocurrents
    optics = QdOptics(QdTruth())
    own = optics._response_a_w * optics.quadrant_power_w(30.0, 70.0, 1000.0, 0.5)
    mixed = optics.photocurrents_a(30.0, 70.0, 1000.0, 0.5)
    assert mixed[0] == pytest.approx(own[0] + k13 * own[2] + k41 * own[3], rel=1e-12)
    assert mixed[1] == pytest.approx(own[1] + k32 * own[2] + k24 * own[3], rel=1e-12)
    off = QdOptics(QdTruth(crosstalk=(0.0,) * 4)).photocurrents_a(30.0, 70.0, 1000.0, 0.5)
    assert off == pytest.approx(own, rel=1e-12)


def test_the_effects_pull_a_reading_at_the_edge_of_the_field(qd):
    """Through the wire at α = 40°: the stray light and the crosstalk put light on the Sun's side (+x), so the x
    ratio is less negative than the ideal module's; each is there only when its field is nonzero."""
    bench, sim, sensor = qd
    point(bench.world, 40, 0)
    x = {}
    for name, over in [("real", {}), ("no stray light", dict(wall_reflectance=0.0)),
                       ("ideal", dict(wall_reflectance=0.0, crosstalk=(0.0,) * 4))]:
        sim.mount(dataclasses.replace(QdTruth(), **over))
        x[name] = ratios(dark_corrected(bench.world, sensor, 100))[0]
    # x ≈ −0.65; the crosstalk adds ≈ 2k·0.65 ≈ +0.004, the stray light (0.035 % of the light at 40° for ρ = 0.5,
    # all on +x) ≈ +0.0007; the ratio's noise here is ~2e-5
    assert x["ideal"] + 0.003 < x["no stray light"] < x["real"] - 0.0004
    ideal_truth = sim.truth
    zen, az = bench.world.sun_direction_body()
    assert np.allclose(sim.photocurrents_a(), QdOptics(ideal_truth).photocurrents_a(
        zen, az, sim.truth.irradiance_w_m2 * bench.world.irradiance(), bench.world.bench.source_diameter_deg))


# -- temperature -----------------------------------------------------------------------------------------------
def test_the_tec_setpoint_is_approached_first_order(qd):
    bench, sim, sensor = qd
    clock = bench.world.clock
    start = sensor.read().temperature_c
    assert start == pytest.approx(bench.world.temperature_c + sim.truth.thermometer_offset_c, abs=0.1)
    status = sensor.set_temperature_setpoint_c(40.0)
    assert status.enabled and status.setpoint_c == 40.0 and not status.settled
    tau = sim.truth.tec_tau_s
    clock.advance(tau)
    assert sensor.read(10).temperature_c == pytest.approx(40.0 - (40.0 - start) / math.e, abs=0.15)
    clock.advance(9 * tau)
    assert sensor.read(10).temperature_c == pytest.approx(40.0, abs=0.1)
    settled = sensor.wait_until_settled()
    assert settled.settled and settled.temperature_c == pytest.approx(40.0, abs=0.1)
    # switched off, the die drifts back to ambient; at time scale 0 asking completes the settling
    assert not sensor.set_temperature_setpoint_c(None).enabled
    t0 = clock.now()
    back = sensor.temperature_status()
    assert back.settled and back.setpoint_c is None and clock.now() - t0 > 5 * tau
    assert back.temperature_c == pytest.approx(bench.world.temperature_c + sim.truth.thermometer_offset_c, abs=0.1)


def test_the_dark_current_rises_with_temperature(qd):
    bench, sim, sensor = qd
    bench.world.lamp.shutter_open = False
    dark = {}
    for setpoint in (0.0, 20.0, 40.0, 60.0):
        sensor.set_temperature_setpoint_c(setpoint)
        sensor.wait_until_settled()
        dark[setpoint] = np.array(sensor.read(500).currents_a)
    for low, high in [(0.0, 20.0), (20.0, 40.0), (40.0, 60.0)]:
        assert np.all(dark[high] > dark[low])
    ratio = dark[60.0] / dark[40.0]  # doubling every ~9 °C: 20 °C is a factor of ~4.7
    assert np.all((ratio > 3.5) & (ratio < 6.5))
    assert np.all((dark[40.0] > 1e-9) & (dark[40.0] < 10e-9))  # nA level
    assert len(set(np.round(dark[60.0] * 1e11))) == 4  # every quadrant its own


# -- timing and noise --------------------------------------------------------------------------------------------
def test_a_read_takes_its_integration_time_on_the_simulated_clock(qd):
    bench, sim, sensor = qd
    sensor.identify()
    t0 = bench.world.clock.now()
    reading = sensor.read(100)
    assert bench.world.clock.now() - t0 == pytest.approx((100 * 1.0 + sim.truth.overhead_ms) / 1000.0)
    assert reading.sample_counter == 100 and sensor.read(5).sample_counter == 105


@pytest.mark.parametrize("qd", [1.0], indirect=True)
def test_a_read_waits_for_its_samples_in_real_time_and_the_module_is_busy_meanwhile(qd):
    bench, sim, sensor = qd
    sensor.identify()
    start = time.monotonic()
    reading = sensor.read(60)
    assert time.monotonic() - start >= 0.06 and reading.n_samples == 60
    assert sim.receive(wire.encode_frame(wire.READ, 9, wire.READ_REQUEST.pack(100))) == b""  # held back
    frame, _ = wire.decode_frame(sim.receive(wire.encode_frame(wire.GET_TEMPERATURE, 10)))
    assert frame.code == wire.ERROR and frame.payload[0] == wire.NOT_READY


def test_a_read_is_quiet(qd):
    # (how fast a READ is: tests/perf/bench_qd.py measures it, beside the ideal module's)
    bench, _, sensor = qd
    point(bench.world, 10, -5)
    sensor.read()
    xs = [ratios(sensor.read().currents_a)[0] for _ in range(50)]
    # near the centre d(ratio)/dα ≈ (4/π)(d/R) per radian = 0.013 per degree: the angle noise of one sample
    assert np.std(xs) / 0.0133 < 0.01


def test_a_bright_source_saturates_and_the_driver_flags_it(qd):
    bench, _, sensor = qd
    point(bench.world, 30, 30)
    assert not sensor.read().any_saturated
    bench.world.lamp.current_a = 3 * bench.world.lamp.spec.nominal_current_a
    reading = sensor.read(10)
    full = sensor.identity.full_scale_counts
    assert reading.saturated == tuple(c == full for c in reading.counts) and reading.any_saturated


# -- faults ----------------------------------------------------------------------------------------------------
def test_channel_faults(qd):
    bench, sim, sensor = qd
    full = sensor.identify().full_scale_counts
    sim.stick_channel(2, 12345)
    sim.kill_channel(3)
    sim.saturate_channel(4)
    reading = sensor.read(50)
    assert reading.counts[1] == 12345.0
    assert abs(reading.currents_a[2]) < 0.2e-9  # pedestal and amplifier noise only
    assert reading.counts[3] == full and reading.saturated == (False, False, False, True)
    assert reading.currents_a[0] > 0.3e-6  # Q1 untouched
    with pytest.raises(ValueError):
        sim.kill_channel(5)
    sim.clear_faults()
    reading = sensor.read(50)
    assert min(reading.currents_a) > 0.3e-6 and not reading.any_saturated


@pytest.mark.parametrize("fault", ["garble", "truncate", "corrupt_crc"])
def test_one_bad_reply_is_a_counted_retry(qd, fault):
    _, sim, sensor = qd
    sensor.identify()
    inject(sim, fault, 1)
    assert sensor.read(3).n_samples == 3  # asked again: a fresh read
    assert sensor.retry_count == 1


@pytest.mark.parametrize("fault, error", [("no_reply", DeviceTimeout), ("garble", ProtocolError),
                                          ("truncate", DeviceTimeout), ("corrupt_crc", ChecksumError)])
def test_faults_give_typed_errors_then_a_clean_exchange(qd, fault, error):
    bench, sim, sensor = qd
    sensor.port.timeout_s = 0.05
    inject(sim, fault, sensor.retries + 1)
    with pytest.raises(error, match=sensor.name) as info:
        sensor.temperature_status()
    assert info.value.attempts == sensor.retries + 1
    sim.faults.clear()
    assert sensor.temperature_status().temperature_c == pytest.approx(bench.world.temperature_c + 0.3, abs=0.1)


def test_disconnect(qd):
    _, sim, sensor = qd
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        sensor.identify()


def test_the_module_answers_bad_commands_with_error_frames(qd):
    _, sim, sensor = qd

    def ask(raw):
        frame, _ = wire.decode_frame(sim.receive(raw))
        assert frame.code == wire.ERROR
        return frame.sequence, frame.payload[0]

    bad_crc = bytearray(wire.encode_frame(wire.GET_TEMPERATURE, 5))
    bad_crc[-1] ^= 0xFF
    assert ask(bytes(bad_crc)) == (5, wire.BAD_CRC)
    assert ask(wire.encode_frame(0x7E, 6)) == (6, wire.UNKNOWN_COMMAND)
    assert ask(wire.encode_frame(wire.READ, 7, b"\x01\x00\x00")) == (7, wire.BAD_LENGTH)
    assert ask(wire.encode_frame(wire.READ, 8, wire.READ_REQUEST.pack(0))) == (8, wire.OUT_OF_RANGE)
    assert ask(wire.encode_frame(wire.SET_TEMPERATURE, 9, wire.TEC_REQUEST.pack(1, 9000))) == (9, wire.OUT_OF_RANGE)
    assert ask(wire.encode_frame(wire.SET_TEMPERATURE, 10, wire.TEC_REQUEST.pack(2, 0))) == (10, wire.OUT_OF_RANGE)
    frame, _ = wire.decode_frame(sim.receive(wire.encode_frame(wire.READ, 11)))  # no payload: one sample
    assert frame.code == wire.READ | wire.REPLY and wire.READ_REPLY.unpack(frame.payload)[0] == 1
    with pytest.raises(QdSensorError, match="value out of range"):
        QdSunSensor(sensor.port, setpoint_range_c=(-100, 100)).set_temperature_setpoint_c(90.0)


def test_the_bench_config_section():
    config = SimBenchConfig(family="qd", qd=QdSensorConfig(height_um=25.0, aperture_diameter_um=80.0,
                                                           diaphragm_thickness_um=2.0, wall_reflectance=0.05))
    bench = SimBench(config, time_scale=0.0)
    truth = bench.devices["sensor"].truth
    assert (truth.height_um, truth.diaphragm_thickness_um, truth.wall_reflectance) == (25.0, 2.0, 0.05)
    for bad in [dict(window_radius_mm=2.0), dict(crosstalk=(0.003, -0.001, 0.003, 0.003)),
                dict(diaphragm_thickness_um=61.0), dict(wall_reflectance=1.5)]:
        with pytest.raises(ValueError):
            QdSensorConfig(**bad)
    assert SimBench(time_scale=0.0).devices["sensor"].name == "cmos-sensor"  # the default family is unchanged
    with pytest.raises(ValueError):
        QdSensorConfig(quadrant_response=(1.0, 1.0, 1.0, -1.0))
