"""A simulated field day for `sunbench field simulate`: the sensor of a simulated bench taken outdoors.

The sensor's truth (its build, its serial in a fleet) comes from the simulated bench file, so the field day is
of the very sensor a bench run calibrated; a CMOS module's simulator is served at a ``sim://`` URL and read through
the family's driver, the camera's is the in-process simulated camera (:func:`field_sensor`).
"""

from __future__ import annotations

import contextlib
import itertools
from pathlib import Path

import numpy as np

from calibration.errors import FieldDataError
from drivers.sim.sky import CloudBank, random_clouds
from drivers.sim.world import SimWorld

_names = itertools.count()

#: Families a simulated field day can take outdoors (the image sensors, whose spot a sky can render).
FIELD_FAMILIES = ("cmos", "camera")


def cloud_banks(spec: str, start_s: float, end_s: float, rng: np.random.Generator
                ) -> tuple[tuple[CloudBank, ...], tuple[tuple[float, float, float], ...]]:
    """The clouds of a simulated day: ``none``; a number of banks per hour at random; or ``seed003``, seed 003
    §5's day — clear until local noon (the first 62 min), then clouds, the Sun wholly covered for an hour from
    13:00 (2 h into the run), and partly or wholly covered most of the time after it, with some haze."""
    if spec == "none":
        return (), ()
    if spec == "seed003":
        noon, one_pm, two_pm = start_s + 62 * 60, start_s + 122 * 60, start_s + 182 * 60
        banks = random_clouds(rng, noon, one_pm, banks_per_hour=3.0, mean_duration_s=300.0)
        banks += (CloudBank(start_s=one_pm, duration_s=3600.0, speed_deg_s=0.003, direction_deg=200.0,
                            transmission=0.02, aureole=0.08),)
        banks += random_clouds(rng, two_pm, end_s, banks_per_hour=6.0, mean_duration_s=420.0)
        return banks, ((noon, end_s, 0.9),)
    try:
        rate = float(spec)
    except ValueError:
        raise FieldDataError(f"--clouds must be 'none', 'seed003' or banks per hour, got {spec!r}") from None
    if not 0 <= rate <= 60:
        raise FieldDataError(f"--clouds: {rate:g} banks per hour is outside 0…60")
    return random_clouds(rng, start_s, end_s, banks_per_hour=rate), ()


def sensor_world(bench: Path | None, serial: str | None) -> tuple[SimWorld, str, object]:
    """The world of the simulated bench in `bench` (default: the built-in simulated bench), with the sensor of
    `serial` mounted, its family, and the truth of that family's simulator beyond the world's (the camera's lens and
    detector; None for a CMOS module, whose build is the world's)."""
    from drivers.sim.bench import SimBench, SimBenchConfig

    from .benchfile import BenchFileError, load_bench_file

    config = SimBenchConfig()
    if bench is not None:
        bench_file = load_bench_file(bench)
        if bench_file.simulation is None:
            raise BenchFileError(f"{bench}: not a simulated bench (no simulation section): a real sensor goes "
                                 "outdoors by itself")
        config = bench_file.simulation
    if config.family not in FIELD_FAMILIES:
        raise FieldDataError(f"a simulated field day takes the {', '.join(FIELD_FAMILIES)} family outdoors; "
                             f"this bench's sensor is of the {config.family!r} family")
    sim = SimBench(config, time_scale=0.0)
    if serial is not None:
        sim.mount_sensor(serial)  # as the bench mounts a fleet's sensor (a CMOS module's build goes into the world)
    return sim.world, config.family, None if sim.camera is None else sim.camera.truth


@contextlib.contextmanager
def field_sensor(family: str, world: SimWorld, truth=None):
    """The family's simulator on `world` and its driver: yields ``(driver, read, full_scale_dn)`` (`read` is the
    family's reading function). A CMOS module is served at a ``sim://`` URL and read through its driver and wire
    protocol; the camera is the in-process :class:`~drivers.sim.camera.SimulatedCamera` (of `truth`, a
    :class:`~drivers.sim.camera.CameraTruth`), as on the bench (drivers/sim/camera.py says why)."""
    from drivers.sim import registry

    from .families import family as family_of

    if family not in FIELD_FAMILIES:
        raise FieldDataError(f"no simulated field for the {family!r} family")
    if family == "camera":
        from drivers.sim.camera import CameraTruth, SimulatedCamera

        camera = SimulatedCamera(world, truth if truth is not None else CameraTruth())
        yield camera, family_of("camera").read, float(camera.full_scale_dn)
        return
    from drivers.cmos_sensor import CmosSunSensor
    from drivers.sim.cmos_sensor import CmosSensorSimulator
    from drivers.transport import open_port

    from .families.cmos import FULL_SCALE_DN

    name = f"field{next(_names)}-sensor"
    url = registry.register(name, CmosSensorSimulator(world))
    port = None
    try:
        port = open_port(url)
        yield CmosSunSensor(port), family_of("cmos").read, float(FULL_SCALE_DN)
    finally:
        if port is not None:
            port.close()
        registry.unregister(name)
