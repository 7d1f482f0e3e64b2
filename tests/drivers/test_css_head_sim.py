"""The CSS head driver against its simulator through a sim:// port on a simulated bench (family "css"): the lit
face follows the table, signals follow the response law in amperes and volts, averaging N samples cuts the noise
by √N, faults show as documented, the thermal plate settles, a READ takes its time on the simulated clock; and a
bench file with a CSS head connects."""

import itertools
import math
import time

import numpy as np
import pytest
from framedtools import inject

from bench.benchfile import BenchFileError, parse_bench_file
from bench.hardware import connect_bench
from drivers import css_protocol as wire
from drivers.css_sensor import CssHead, CssHeadError
from drivers.errors import ChecksumError, DeviceTimeout, ProtocolError
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.css_head import CssHeadConfig, css_fleet_truth
from drivers.sim.css_optics import CHANNELS, CssChannels
from drivers.transport import open_port

_names = itertools.count()
FACES = ("px", "py", "mx", "my", "pz", "mz")


def _bench(time_scale=0.0, **config):
    bench = SimBench(SimBenchConfig(family="css", time_scale=time_scale, seed=3, **config))
    urls = bench.register(f"css-test-{next(_names)}")
    lamp = bench.world.lamp
    if bench.world.clock.instant:
        lamp.start()
        lamp.is_warm()
        lamp.shutter_open = True
    return bench, CssHead(open_port(urls["sensor"], baudrate=115200, timeout_s=0.3))


@pytest.fixture
def css(request):
    bench, head = _bench(getattr(request, "param", 0.0))
    yield bench, bench.devices["sensor"], head
    head.port.close()
    bench.unregister()


def point(world, zenith_deg, azimuth_deg):
    """Turn the table to (azimuth, zenith stage); returns the world's true sun vector in the head's body frame."""
    world.azimuth.move_to(azimuth_deg)
    world.zenith.move_to(zenith_deg)
    zen, az = (math.radians(a) for a in world.sun_direction_body())
    return np.array([math.sin(zen) * math.cos(az), math.sin(zen) * math.sin(az), math.cos(zen)])


def dark_corrected(world, head, average=64):
    world.lamp.shutter_open = True
    lit = np.array(head.read(average).signals)
    world.lamp.shutter_open = False
    dark = np.array(head.read(average).signals)
    world.lamp.shutter_open = True
    return lit - dark


def by_face(signals, kind):
    return {face: signals[CHANNELS.index(f"{face}_{kind}")] for face in FACES}


# -- identity and build -------------------------------------------------------------------------------------
def test_identify_reports_the_heads_channels_and_conversion(css):
    _, sim, head = css
    ident = head.identify()
    assert (ident.model, ident.serial, ident.adc_bits, ident.max_average) == ("SB-CSS-HEAD", "CSS-0001", 16, 1024)
    assert ident.channels == CHANNELS and ident.sample_ms == 1.0
    channels = CssChannels(16)
    assert ident.pedestal_counts == tuple(int(p) for p in channels.pedestals())
    assert ident.units_per_count == pytest.approx(tuple(channels.units_per_count()), rel=1e-7)
    # the ranges are css_optics' FRONT_ENDS: 12 µA (uv), 2 mA (vis), ±5 mV (ir)
    assert [ident.range[i][1] for i in range(3)] == pytest.approx([12e-6, 2e-3, 5e-3], rel=1e-4)
    assert ident.range[2][0] == pytest.approx(-5e-3)


def test_a_fleets_heads_are_built_reproducibly_from_the_serial(css):
    bench, sim, head = css
    fresh = {s: SimBench(SimBenchConfig(family="css", time_scale=0.0)).mount_sensor(s) for s in ("CSS-101", "CSS-102")}
    for serial in ("CSS-102", "CSS-101", "CSS-102"):
        assert bench.mount_sensor(serial) == fresh[serial] and sim.truth == fresh[serial]
        assert head.identify().serial == serial
    a, b = fresh["CSS-101"], fresh["CSS-102"]
    assert a.diode("pz_vis").scale != b.diode("pz_vis").scale
    assert a.diode("px_uv").normal_zenith_deg != b.diode("px_uv").normal_zenith_deg
    assert css_fleet_truth(CssHeadConfig(), "CSS-101") == a
    assert bench.mount_sensor("CSS-0001") == SimBenchConfig().css.truth()  # the configured head is its own


# -- light ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("zenith, azimuth, face", [(0, 0, "pz"), (90, 0, "px"), (90, 90, "py"), (90, 180, "mx"),
                                                   (90, 270, "my")])
def test_the_lit_face_follows_the_table(css, zenith, azimuth, face):
    bench, _, head = css
    point(bench.world, zenith, azimuth)
    light = dark_corrected(bench.world, head)
    for kind, contrast in (("uv", 1000), ("vis", 1000), ("ir", 20)):  # the others: noise (ir: ~0.3 µV at N = 64)
        faces = by_face(light, kind)
        others = max(abs(v) for f, v in faces.items() if f != face)
        assert faces[face] > contrast * others, (kind, faces)
    assert by_face(light, "vis")[face] > 0.5e-3  # ≈ 1.17 mA × 1000/1366 × 0.95 (xenon) at normal incidence: [A]
    assert 20e-6 < by_face(light, "ir")[face] < 40e-6  # ≈ 0.13 mV × 0.73 × 0.30: [V]


def test_between_two_faces_both_follow_the_response_law(css):
    """A nominal head (no build errors) with the ``power`` law γ^1.2: the dark-corrected signals of px and pz, lit
    from zenith θ between them, are scale · E/E_ref · K · (1 + c_T ΔT) · (n·s)^1.2, each on its own face's cosine —
    computed here from the law as DiodeTruth documents it and the world's true sun vector."""
    bench, sim, head = css
    sim.mount(CssHeadConfig(build_seed=None, response="power").truth())
    ambient = bench.world.temperature_c
    for zenith in (0, 20, 40, 60, 75):
        s = point(bench.world, zenith, 0)
        light = dark_corrected(bench.world, head)
        relative = bench.world.irradiance() * 1000.0 / 1366.0 * 0.95  # the xenon's mismatch for the BPW 21
        gain = 1.17e-3 * (1 - 0.5e-3 * (ambient - 25.0))
        for face, cosine in (("pz", s[2]), ("px", s[0])):
            expected = gain * relative * max(cosine, 0.0) ** 1.2 if math.degrees(math.acos(cosine)) < 79 else 0.0
            assert by_face(light, "vis")[face] == pytest.approx(expected, rel=0.002, abs=2e-8), (zenith, face)


def test_a_closed_shutter_gives_offsets_only(css):
    bench, sim, head = css
    point(bench.world, 30, 40)
    bench.world.lamp.shutter_open = False
    reading = head.read(1024)
    t = sim.tec.true_c()
    expected = [d.bias + d.bias_temp_coeff * (t - 25.0) for d in sim.truth.diodes]
    upc = np.array(head.identity.units_per_count)
    assert np.all(np.abs(np.array(reading.signals) - expected) < 2 * upc)  # the noise of 1024 samples, a count at most
    bench.world.lamp.shutter_open = True
    assert head.read(1024).signal("pz_vis") > 1000 * abs(reading.signal("pz_vis"))


def test_an_led_source_has_no_uv_or_thermal_ir(css):
    led, head = _bench(source="led")
    try:
        light = dark_corrected(led.world, head)
        xenon_bench, _, xenon_head = css
        xenon = dark_corrected(xenon_bench.world, xenon_head)
        pz = CHANNELS.index("pz_uv")
        assert light[pz + 1] == pytest.approx(xenon[pz + 1] / 0.95, rel=0.02)  # vis: mismatch 1.0 vs 0.95
        assert light[pz] == pytest.approx(xenon[pz] * 0.02 / 0.85, rel=0.05)  # uv: 0.02 vs 0.85
        assert abs(light[pz + 2]) < 0.5e-6  # ir: nothing beyond 5.5 µm (the noise of 64 samples)
    finally:
        head.port.close()
        led.unregister()


def test_a_bright_source_saturates_and_the_driver_flags_it(css):
    bench, _, head = css
    point(bench.world, 0, 0)
    assert not head.read().any_saturated
    # 3 kW/m²: the BPW 21 would give 2.4 mA, beyond its channel's 2 mA; the EPD's 11.5 µA still fits in 12 µA
    bench.world.lamp.current_a = 3 * bench.world.lamp.spec.nominal_current_a
    reading = head.read(16)
    full = head.identity.full_scale_counts
    assert [c for c, s in zip(CHANNELS, reading.saturated) if s] == ["pz_vis"]
    assert 10e-6 < reading.signal("pz_uv") < 12e-6
    assert reading.counts[CHANNELS.index("pz_vis")] == full and reading.signal("pz_vis") == pytest.approx(2e-3, 1e-4)


# -- noise ----------------------------------------------------------------------------------------------------
def _scatter(head, average, reads):
    return np.std([head.read(average).signals for _ in range(reads)], axis=0, ddof=1)


def test_averaging_n_samples_cuts_the_scatter_by_root_n(css):
    """Shutter closed (no lamp drift in the scatter): 300 reads of 1 sample against 300 of 16 — the ratio of their
    standard deviations is √16 = 4 on every channel (measured at this seed: median 4.06, 3.62 … 4.66 over the 18
    channels; seeds 4 … 7 give medians 3.93 … 4.09)."""
    bench, sim, head = css
    bench.world.lamp.shutter_open = False
    one, sixteen = _scatter(head, 1, 300), _scatter(head, 16, 300)
    ratio = one / sixteen
    assert 3.8 < np.median(ratio) < 4.2, ratio
    assert np.all((ratio > 3.2) & (ratio < 4.9)), ratio  # each channel's ratio is known to ±6 % (1σ)
    # one sample's scatter: the ADC's 0.7 counts and the physics' (× √16 of css_optics' 16-sample noise)
    upc = np.array(head.identity.units_per_count)
    clean = sim.signals()
    per_sample = np.hypot(sim.optics.noise_sd(clean, sim.tec.true_c()) * 4, 0.7 * upc)
    assert one == pytest.approx(np.sqrt(per_sample ** 2 + upc ** 2 / 12), rel=0.25)  # + the quantisation's
    assert by_face(one, "ir")["pz"] == pytest.approx(12 * upc[2], rel=0.15)  # the thermopile's ~1.8 µV: 12 counts


# -- faults ---------------------------------------------------------------------------------------------------
def test_channel_faults_show_as_documented(css):
    bench, sim, head = css
    point(bench.world, 0, 0)
    full = head.identify().full_scale_counts
    sim.stick_channel("py_vis", 12345)
    sim.kill_channel("pz_vis")
    sim.saturate_channel("px_uv")
    reading = head.read(64)
    assert reading.counts[CHANNELS.index("py_vis")] == 12345.0  # the ADC repeats the code: no noise at all
    dead = sim.truth.diode("pz_vis")
    offset = dead.bias + dead.bias_temp_coeff * (sim.tec.true_c() - 25.0)
    assert reading.signal("pz_vis") == pytest.approx(offset, abs=3 * head.identity.units_per_count[13])
    assert reading.signal("pz_uv") > 3e-6  # its neighbour on the lit face still sees the lamp
    assert reading.counts[0] == full and [c for c, s in zip(CHANNELS, reading.saturated) if s] == ["px_uv"]
    assert not any(reading.under_range)
    with pytest.raises(ValueError, match="no channel 'pz_xx'"):
        sim.kill_channel("pz_xx")
    sim.clear_faults()
    reading = head.read(64)
    assert reading.signal("pz_vis") > 0.5e-3 and not reading.any_saturated
    assert reading.counts[CHANNELS.index("py_vis")] < 100


@pytest.mark.parametrize("fault", ["garble", "truncate", "corrupt_crc"])
def test_one_bad_reply_is_a_counted_retry(css, fault):
    _, sim, head = css
    head.identify()
    inject(sim, fault, 1)
    assert head.read(3).n_samples == 3  # asked again: a fresh read
    assert head.retry_count == 1


@pytest.mark.parametrize("fault, error", [("no_reply", DeviceTimeout), ("garble", ProtocolError),
                                          ("truncate", DeviceTimeout), ("corrupt_crc", ChecksumError)])
def test_faults_give_typed_errors_then_a_clean_exchange(css, fault, error):
    bench, sim, head = css
    head.port.timeout_s = 0.05
    inject(sim, fault, head.retries + 1)
    with pytest.raises(error, match=head.name) as info:
        head.temperature_status()
    assert info.value.attempts == head.retries + 1
    sim.faults.clear()
    assert head.temperature_status().temperature_c == pytest.approx(bench.world.temperature_c + 0.2, abs=0.1)


def test_the_module_answers_bad_commands_with_error_frames(css):
    _, sim, head = css

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
    assert ask(wire.encode_frame(wire.READ, 9, wire.READ_REQUEST.pack(1025))) == (9, wire.OUT_OF_RANGE)
    assert ask(wire.encode_frame(wire.SET_TEMPERATURE, 10, wire.TEC_REQUEST.pack(1, 9000))) == (10, wire.OUT_OF_RANGE)
    assert ask(wire.encode_frame(wire.SET_TEMPERATURE, 11, wire.TEC_REQUEST.pack(2, 0))) == (11, wire.OUT_OF_RANGE)
    assert ask(wire.encode_frame(wire.IDENTIFY, 12, b"\x00")) == (12, wire.BAD_LENGTH)
    frame, _ = wire.decode_frame(sim.receive(wire.encode_frame(wire.READ, 13)))  # no payload: one sample
    assert frame.code == wire.READ | wire.REPLY and wire.READ_REPLY.unpack(frame.payload)[0] == 1
    with pytest.raises(CssHeadError, match="value out of range"):
        CssHead(head.port, setpoint_range_c=(-100, 100)).set_temperature_setpoint_c(90.0)


# -- temperature and timing -------------------------------------------------------------------------------------
def test_the_thermal_plate_settles_and_the_thermopile_offsets_follow(css):
    bench, sim, head = css
    clock = bench.world.clock
    bench.world.lamp.shutter_open = False
    start = head.read()
    assert start.temperature_c == pytest.approx(bench.world.temperature_c + 0.2, abs=0.1)
    assert not start.plate_on and start.plate_settled
    status = head.set_temperature_setpoint_c(40.0)
    assert status.enabled and status.setpoint_c == 40.0 and not status.settled
    tau = sim.config.tec_tau_s
    clock.advance(tau)
    assert head.read(16).temperature_c == pytest.approx(40.0 - (40.0 - start.temperature_c) / math.e, abs=0.15)
    settled = head.wait_until_settled()
    assert settled.settled and settled.temperature_c == pytest.approx(40.0, abs=0.1)
    hot = head.read(256)
    assert hot.plate_on and hot.plate_settled and hot.temperature_c == pytest.approx(40.0, abs=0.1)
    # the thermopiles see the room colder than the head by ΔT: −26 µV/K (css_optics BIAS_TEMP_COEFF)
    cold = np.array(start.signals)
    step = sim.tec.true_c() - (bench.world.temperature_c)
    ir = [CHANNELS.index(f"{f}_ir") for f in FACES]
    assert np.array(hot.signals)[ir] - cold[ir] == pytest.approx(np.full(6, -26e-6 * step), rel=0.03)
    # switched off, the head drifts back to ambient; at time scale 0 asking completes the settling
    assert not head.set_temperature_setpoint_c(None).enabled
    t0 = clock.now()
    back = head.temperature_status()
    assert back.settled and back.setpoint_c is None and clock.now() - t0 > 5 * tau
    assert back.temperature_c == pytest.approx(bench.world.temperature_c + 0.2, abs=0.1)


def test_a_read_takes_its_samples_time_on_the_simulated_clock(css):
    bench, sim, head = css
    head.identify()
    t0 = bench.world.clock.now()
    reading = head.read(100)
    assert bench.world.clock.now() - t0 == pytest.approx((100 * 1.0 + sim.config.overhead_ms) / 1000.0)
    assert reading.sample_counter == 100 and head.read(5).sample_counter == 105


@pytest.mark.parametrize("css", [1.0], indirect=True)
def test_a_read_waits_for_its_samples_in_real_time_and_the_module_is_busy_meanwhile(css):
    _, sim, head = css
    head.identify()
    start = time.monotonic()
    reading = head.read(60)
    assert time.monotonic() - start >= 0.06 and reading.n_samples == 60
    assert sim.receive(wire.encode_frame(wire.READ, 9, wire.READ_REQUEST.pack(100))) == b""  # held back
    frame, _ = wire.decode_frame(sim.receive(wire.encode_frame(wire.GET_TEMPERATURE, 10)))
    assert frame.code == wire.ERROR and frame.payload[0] == wire.NOT_READY
    with pytest.raises(CssHeadError, match="not ready"):  # the driver, too, is told (typed, not retried)
        head.temperature_status()


# -- configuration and the bench file ---------------------------------------------------------------------------
def test_the_bench_config_section():
    config = SimBenchConfig(family="css", css=CssHeadConfig(
        serial="CSS-7", response="kelly", build_seed=None, overrides={"pz_vis": {"scale": 1.0e-3, "bias": 0.0}}))
    sim = SimBench(config, time_scale=0.0).devices["sensor"]
    truth = sim.truth
    assert truth.serial == "CSS-7" and {d.response for d in truth.diodes} == {"kelly"}
    assert (truth.diode("pz_vis").scale, truth.diode("pz_vis").bias) == (1.0e-3, 0.0)
    assert truth.diode("pz_uv").scale == 6.18e-6 and truth.diode("pz_vis").normal_zenith_deg == 0.0
    for bad in [dict(overrides={"pz_vs": {"scale": 1.0}}), dict(tec_range_c=(30.0, 10.0)),
                dict(adc_bits=24, max_average=1024), dict(response="cosine"), dict(irradiance_w_m2=-1.0),
                dict(overrides={"pz_vis": {"scale": -1.0}})]:
        with pytest.raises(ValueError):
            CssHeadConfig(**bad)
    assert CssHeadConfig(adc_bits=24, max_average=256).max_average == 256
    assert SimBench(time_scale=0.0).devices["sensor"].name == "cmos-sensor"  # the default family is unchanged


def test_a_bench_file_with_a_css_head():
    bench = parse_bench_file({"simulation": {"family": "css"}})
    assert bench.devices.sensor.kind == "css" and bench.devices.sensor.url is None
    assert parse_bench_file({"simulation": {}, "devices": {"sensor": {"kind": "css"}}}).simulation.family == "css"
    with pytest.raises(BenchFileError, match=r"devices\.sensor\.kind: 'css' does not match simulation\.family"):
        parse_bench_file({"simulation": {"family": "qd"}, "devices": {"sensor": {"kind": "css"}}})
    with pytest.raises(BenchFileError, match=r"devices\.sensor\.url"):
        parse_bench_file({"simulation": None, "devices": {"table": {"kind": "lx200", "url": "/dev/ttyUSB0"},
                                                          "source": {"kind": "led", "url": "/dev/ttyUSB1"},
                                                          "sensor": {"kind": "css"}}})
    real = parse_bench_file({"simulation": {"family": "css"}, "devices": {"sensor": {"url": "/dev/ttyUSB3"}}})
    assert real.devices.sensor.url == "/dev/ttyUSB3"
    with connect_bench(bench, time_scale=0.0) as devices:
        assert isinstance(devices.sensor, CssHead)
        assert devices.identities["sensor"] == "SB-CSS-HEAD, serial CSS-0001, firmware 1.0.0"
        assert devices.sensor.read(16).n_samples == 16
