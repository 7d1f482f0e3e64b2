"""The simulated camera sun sensor (drivers/sim/camera.py): an ImageSensor rendering webcam frames from the shared
world, handed to the bench in-process — and the real driver (drivers/usb_camera.py) reading the simulator's frames
through OpenCV's image-sequence capture, finding the same spot."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from bench.benchfile import BenchFile
from bench.families import family
from bench.hardware import connect_bench
from calibration.camera import cloud_flag, detect_spot
from drivers.errors import DeviceDisconnected, LimitError
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.camera import EXPOSURE_RANGE_MS, READOUT_MS, CameraTruth, SimulatedCamera, camera_fleet_truth
from drivers.sim.clock import SimClock
from drivers.sim.sky import SUN_DIAMETER_DEG, CloudState
from drivers.sim.world import SimWorld
from drivers.usb_camera import UsbCamera


@dataclass
class _Sky(SimWorld):
    """A world whose Sun stands still at (10°, 30°) in the body frame, behind `state`'s clouds."""

    state: CloudState = CloudState()

    def sun_direction_body(self):
        return 10.0, 30.0

    def irradiance(self):
        return 1.0

    def clouds(self):
        return self.state


def test_identity_exposure_steps_and_the_range_of_a_webcam():
    camera = SimulatedCamera(SimWorld(), CameraTruth(serial="CAM-0042"))
    identity = camera.identify()
    assert identity.serial == "CAM-0042" and camera.reports_serial and "640x480" in identity.model
    assert camera.set_exposure_ms(4.04) == 4.0 == camera.exposure_ms()  # whole 100 µs steps (V4L2)
    assert camera.set_exposure_ms(0.01) == EXPOSURE_RANGE_MS[0]  # clamped to the range, as V4L2 does
    assert camera.set_exposure_ms(1e6) == EXPOSURE_RANGE_MS[1]
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(LimitError):
            camera.set_exposure_ms(bad)
    assert math.isnan(camera.temperature_c())  # a webcam has no thermometer (as UsbCamera)


def test_a_capture_takes_the_exposure_and_the_readout_in_simulated_time():
    world = _Sky(clock=SimClock(0.0))
    camera = SimulatedCamera(world)
    camera.set_exposure_ms(4.0)
    frame = camera.capture()
    assert frame.dtype == np.uint16 and frame.shape == (480, 640) and frame.max() <= 255  # as UsbCamera returns
    assert world.clock.now() == pytest.approx((4.0 + READOUT_MS) / 1000.0)
    world = _Sky(clock=SimClock(100.0))  # 100× real time: the call waits the wall time that is
    camera = SimulatedCamera(world)
    camera.set_exposure_ms(50.0)
    t0, s0 = time.monotonic(), world.clock.now()
    camera.capture()
    assert world.clock.now() - s0 >= (50.0 + READOUT_MS) / 1000.0 and time.monotonic() - t0 < 0.1


def test_the_spot_follows_the_worlds_sun_its_brightness_and_its_clouds():
    world = _Sky()
    camera = SimulatedCamera(world)
    camera.set_exposure_ms(4.0)
    read = family("camera").read
    clear = read(camera, 0, world.clock.now)
    assert clear.ok and not clear.values["cloud"]
    x, y = camera.true_pixel()
    assert math.hypot(clear.values["x_px"] - x, clear.values["y_px"] - y) < 0.05
    assert camera.renderer.source_diameter_deg == world.bench.source_diameter_deg == 0.5  # the bench's sun simulator
    world.state = CloudState(edge_offset_deg=0.0, edge_angle_deg=45.0)  # an opaque edge over half the disc
    cut = read(camera, 0, world.clock.now)
    assert cut.ok and cut.values["cloud"] and cut.values["flux_dn"] < 0.7 * clear.values["flux_dn"]
    world.state = CloudState(edge_offset_deg=-math.inf)  # wholly covered
    assert read(camera, 0, world.clock.now).status == "NoSpotError"
    world.state = CloudState()
    camera.set_exposure_ms(20.0)
    assert read(camera, 0, world.clock.now).status == "SaturatedSpotError"


def test_a_pulled_cable_and_the_fleet():
    camera = SimulatedCamera(_Sky())
    camera.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        camera.capture()
    camera.faults.clear()
    camera.capture()
    base = CameraTruth()
    assert camera_fleet_truth(base, base.serial) is base
    other = camera_fleet_truth(base, "CAM-0002")
    assert other == camera_fleet_truth(base, "CAM-0002") and other.lens != base.lens  # from the serial alone
    bench = SimBench(SimBenchConfig(family="camera", time_scale=0))
    assert "sensor" not in bench.devices  # in-process: no wire to serve
    bench.mount_sensor("CAM-0002")
    assert bench.camera.identify().serial == "CAM-0002" and bench.camera.truth == other


def test_the_real_driver_reads_the_simulators_frames_and_finds_the_same_spot(tmp_path):
    """The bench hands the simulated camera over as its sensor; its frames, written as a PNG image sequence, come
    back through UsbCamera (OpenCV's CAP_IMAGES) bit for bit, and the camera family reads the same spot from both."""
    bench_file = BenchFile.model_validate({"simulation": {"family": "camera", "time_scale": 0}})
    read = family("camera").read
    poses = [(0.0, 0.0), (30.0, 10.0), (200.0, 18.0), (315.0, 17.0)]
    with connect_bench(bench_file) as bench:
        camera = bench.sensor
        assert isinstance(camera, SimulatedCamera) and camera is bench.sim.camera
        assert "SB-SIM-WEBCAM" in bench.identities["sensor"]
        bench.source.lamp_on()
        bench.source.wait_until_warm()
        bench.source.open_shutter()
        camera.set_exposure_ms(4.0)
        frames, readings = [], []
        for i, (azimuth, zenith) in enumerate(poses):
            bench.table.move_to(azimuth, zenith)
            frame = camera.capture()
            assert cv2.imwrite(str(tmp_path / f"frame_{i:03d}.png"), frame.astype(np.uint8))
            frames.append(frame)
            readings.append(detect_spot(frame, saturation_dn=255))
        assert 0.55 <= readings[0].peak_dn / 255 <= 0.8  # the lamp at 4 ms: the auto-exposure's target band
    usb = UsbCamera(str(tmp_path / "frame_%03d.png"), backend=cv2.CAP_IMAGES)
    try:
        for frame, spot in zip(frames, readings):
            again = usb.capture()
            assert again.dtype == np.uint16 and np.array_equal(again, frame)
            found = detect_spot(again, saturation_dn=255)
            assert (found.x_px, found.y_px) == (spot.x_px, spot.y_px)
        with pytest.raises(DeviceDisconnected):
            usb.capture()  # the end of the sequence, as an unplugged camera
    finally:
        usb.close()
    usb = UsbCamera(str(tmp_path / "frame_%03d.png"), backend=cv2.CAP_IMAGES)
    try:
        reading = read(usb, 0, lambda: 0.0)  # the family's read on the real driver
        assert reading.ok and (reading.values["x_px"], reading.values["y_px"]) == (readings[0].x_px, readings[0].y_px)
        flagged, _ = cloud_flag(readings[0], expected_radius_px=800 * math.tan(math.radians(SUN_DIAMETER_DEG / 2)))
        assert reading.values["cloud"] == flagged is False
    finally:
        usb.close()
