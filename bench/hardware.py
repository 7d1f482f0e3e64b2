"""Bring a bench up from its bench file: open every device, real or simulated, behind the interfaces.

:func:`connect_bench` is the one place that knows how each driver is opened — its line settings, its
initialisation, whether it homes — so the run engine only sees a :class:`~drivers.interfaces.RotaryTable`,
a :class:`~drivers.interfaces.SunSimulator` (the IR Earth simulator of a horizon bench is one) and the sensor (an
:class:`~drivers.interfaces.ImageSensor`, a :class:`~drivers.interfaces.QuadrantSensor`, a
:class:`~drivers.interfaces.CoarseSunHead` or a :class:`~drivers.interfaces.HorizonSensor`).

Simulated devices. When the file has a ``simulation:`` section, a :class:`~drivers.sim.bench.SimBench` is
built and served in-process; a device without a URL (or ``url: sim``) is opened at its ``sim://`` URL. The
simulated camera (``simulation.family: camera``, a camera sensor without a source) has no wire to open (a USB
camera's is UVC in the kernel, :mod:`drivers.sim.camera`): the simulator itself is the bench's sensor. The
sources of the simulated world measure their warm-up on the world's clock and use the simulated lamp's
own warm time (:attr:`drivers.sim.lamp.LampSpec.warm_time_s`) instead of the file's ``warmup_s`` (which
is for the real lamp): the simulated lamp completes its warm-up exactly at that simulated time (in instant
mode when it is observed), so a longer ``warmup_s`` would never be reached at time scale 0 and a shorter
one would call a still-warming lamp warm. Waits that only matter for real hardware (APT RTS-cycle dwell,
SMC100 reset wait) are skipped for in-process simulators.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from drivers.cmos_sensor import CmosSunSensor
from drivers.css_sensor import CssHead
from drivers.earth_simulator import EarthSimulatorSource
from drivers.errors import DeviceError
from drivers.horizon_sensor import HorizonSensorModule
from drivers.interfaces import (
    CoarseSunHead,
    HorizonSensor,
    ImageSensor,
    Limits,
    QuadrantSensor,
    RotaryTable,
    SunSimulator,
    TwoAxisTable,
)
from drivers.manual import AskCallback, ManualAxis, console_ask
from drivers.meade import LX200Table
from drivers.newport_smc100 import Smc100Axis
from drivers.oriel69907 import BAUDRATE as ORIEL_BAUDRATE
from drivers.oriel69907 import Oriel69907
from drivers.qd_sensor import QdSunSensor
from drivers.scpi_supply import E363XA_SERIAL, ScpiSupply
from drivers.shutter import BAUDRATE as SC10_BAUDRATE
from drivers.shutter import ThorlabsSC10
from drivers.sim.bench import SimBench
from drivers.sources import ArcLampSource, LedSource
from drivers.thorlabs_apt import AptRotationStage
from drivers.transport import DEFAULT_RETRIES, open_port

from .benchfile import BenchFile

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

LX200_BAUDRATE = 9600  # 8N1, no handshake (drivers/meade.py, anchors-protocols §1.1)
SMC100_SERIAL = {"baudrate": 57600, "xonxoff": True}  # drivers/newport_smc100.py, anchors-protocols §3.1
CMOS_BAUDRATE = 921600  # RS-485 adapter of the module (drivers/cmos_sensor.py)
QD_BAUDRATE = 115200  # the QD module's UART (drivers/qd_protocol.py)
CSS_BAUDRATE = 115200  # the CSS head's UART (drivers/css_protocol.py)
HORIZON_BAUDRATE = 115200  # the horizon sensor module's UART (drivers/horizon_protocol.py)
EARTH_BAUDRATE = 9600  # the Earth simulator's controller, RS-232 (drivers/earth_simulator.py)
APT_DWELL_S = 0.05  # RTS-cycle dwell of the APT init on hardware (anchors-protocols §2.1)
SMC100_RESET_WAIT_S = 1.0  # wait after RS before the controller answers (pymeasure)

#: Every device link on the bench retries a garbled, cut or late reply this often (idempotent commands only;
#: drivers.transport.ask_again), then raises a typed error naming the device.
LINK_RETRIES = DEFAULT_RETRIES


class BenchConnectionError(DeviceError):
    """A device of the bench could not be opened, initialised, homed or identified.

    Attributes
    ----------
    role : str
        ``table``, ``table-azimuth``, ``table-zenith``, ``lamp``, ``shutter``, ``led``, ``earth`` or ``sensor``.
    url : str
        Where it was opened (a ``sim://`` URL for a simulated device, the source of a camera).
    cause : BaseException
        The driver's error (also ``__cause__``).
    """

    def __init__(self, role: str, url: str, cause: BaseException):
        self.role, self.url, self.cause = role, url, cause
        super().__init__(role, f"cannot connect to {url}: {cause}")


@dataclass(frozen=True)
class BenchDevices:
    """The bench's devices, connected (see :func:`connect_bench`).

    Attributes
    ----------
    table : RotaryTable
    source : SunSimulator
    sensor : ImageSensor, QuadrantSensor, CoarseSunHead or HorizonSensor
        The sensor of the bench's family (bench.families).
    identities : dict of str to str
        ``table``, ``source``, ``sensor`` → what the device reported as its identity, for run provenance.
    simulated : bool
        The bench has a simulation (devices given a real URL may still be real).
    sim : SimBench or None
        The simulated bench (its ``world`` is the truth behind the simulated devices).
    """

    table: RotaryTable
    source: SunSimulator
    sensor: ImageSensor | QuadrantSensor | CoarseSunHead | HorizonSensor
    identities: dict[str, str]
    simulated: bool
    sim: SimBench | None = None
    _closers: list[Callable[[], None]] = field(default_factory=list, repr=False, compare=False)

    def close(self) -> None:
        """Close every port (last opened first) and unregister the simulators; safe to call twice.

        Sends nothing to the devices (a dead port must not stop the others from closing): putting the
        source in standby is the run's business. The first error is re-raised once all are closed.
        """
        errors = _close_all(self._closers)
        if self.sim is not None:
            self.sim.unregister()
        if errors:
            raise errors[0]

    def __enter__(self) -> BenchDevices:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def _close_all(closers: list[Callable[[], None]]) -> list[Exception]:
    errors = []
    while closers:
        closer = closers.pop()
        try:
            closer()
        except Exception as exc:  # noqa: BLE001 - every port is closed, the first error re-raised by the caller
            errors.append(exc)
    return errors


@contextmanager
def _connecting(role: str, url: str) -> Iterator[None]:
    """Turn any failure while bringing `role` up into a :class:`BenchConnectionError`."""
    try:
        yield
    except BenchConnectionError:
        raise
    except Exception as exc:
        raise BenchConnectionError(role, url, exc) from exc


class _Connector:
    """Opens the devices of one bench file, remembering how to close each."""

    def __init__(self, bench_file: BenchFile, sim: SimBench | None, urls: dict[str, str], ask: AskCallback):
        self.file, self.sim, self.sim_urls, self.ask = bench_file, sim, urls, ask
        self.closers: list[Callable[[], None]] = []
        self.where: dict[str, str] = {}  # table / source / sensor -> URL(s), for errors after opening

    def url(self, configured: str | None, role: str) -> tuple[str, bool]:
        """(URL to open, whether it is the in-process simulator) for a device's configured URL."""
        if configured is None:
            return self.sim_urls[role], True  # the file validated that a simulation exists
        return configured, False

    # -- table ----------------------------------------------------------------------------------------
    def table(self) -> RotaryTable:
        config = self.file.devices.table
        if config.kind == "lx200":
            url, _ = self.url(config.url, "table")
            with _connecting("table", url):
                port = open_port(url, baudrate=LX200_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                # slew_reply="auto": a mount that answers :MA# as the Meade manual says or as INDI expects (the
                # simulator's indi_compatible mode) both work; the slew is judged by what the mount does
                table = LX200Table(port, Limits(*config.azimuth_limits_deg), Limits(*config.zenith_limits_deg),
                                   high_precision=config.high_precision, slew_reply="auto",
                                   retries=LINK_RETRIES)
                table.connect()
            self.where["table"] = url
            return table  # an alt-az mount has no homing: its position is absolute
        if config.kind == "manual":
            axes = [ManualAxis(f"{name} stage", ask=self.ask, limits=Limits(*axis.limits_deg),
                               initial_deg=axis.initial_deg)
                    for name, axis in (("azimuth", config.azimuth), ("zenith", config.zenith))]
            self.where["table"] = "manual"
            return TwoAxisTable(*axes)  # not homed: that would ask the operator before the run starts
        axes = self._apt_axes(config) if config.kind == "apt" else self._smc100_axes(config)
        table = TwoAxisTable(*axes)
        self.where["table"] = f"{axes[0].port.name}, {axes[1].port.name}"
        # both axes home together; their positions mean nothing until they have
        with _connecting("table", self.where["table"]):
            table.home()
        return table

    def _apt_axes(self, config) -> list[AptRotationStage]:
        axes = []
        for name, axis in (("azimuth", config.azimuth), ("zenith", config.zenith)):
            role = f"table-{name}"
            url, simulated = self.url(axis.url, role)
            with _connecting(role, url):
                stage = AptRotationStage.open(url, timeout_s=axis.timeout_s, dwell_s=0.0 if simulated else APT_DWELL_S,
                                              limits=Limits(*axis.limits_deg), channel=axis.channel, dest=axis.dest)
            self.closers.append(stage.close)
            axes.append(stage)
        return axes

    def _smc100_axes(self, config) -> list[Smc100Axis]:
        axes, ports = [], {}
        for name, axis in (("azimuth", config.azimuth), ("zenith", config.zenith)):
            role = f"table-{name}"
            url, simulated = self.url(axis.url, role)
            if simulated:
                self.sim.devices[role].address = axis.address  # the simulator answers the configured address
            with _connecting(role, url):
                if url not in ports:  # two controllers chained on one RS-485 line share its port (and its lock)
                    ports[url] = open_port(url, timeout_s=axis.timeout_s, **SMC100_SERIAL)
                    self.closers.append(ports[url].close)
                stage = Smc100Axis(ports[url], address=axis.address, limits=Limits(*axis.limits_deg),
                                   reset_wait_s=0.0 if simulated else SMC100_RESET_WAIT_S, retries=LINK_RETRIES)
                stage.identify()  # the constructor sends nothing: make a silent axis fail here, named
            axes.append(stage)
        return axes

    # -- source ---------------------------------------------------------------------------------------
    def _timing(self, simulated: bool, warmup_s: float) -> tuple[Callable[[], float], float]:
        """(clock, warm-up [s]) of a supply: the simulated world's for a simulated one (module docstring)."""
        if simulated:
            return self.sim.clock.now, self.sim.lamp_warm_time_s
        return time.monotonic, warmup_s

    def source(self) -> SunSimulator:
        config = self.file.devices.source
        if config.kind == "earth":
            url, _ = self.url(config.url, "earth")
            with _connecting("earth", url):
                port = open_port(url, baudrate=EARTH_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                earth = EarthSimulatorSource(port, radius_limits_deg=tuple(config.radius_limits_deg),
                                             temperature_limits_k=tuple(config.temperature_limits_k),
                                             disc_temperature_k=config.disc_temperature_k,
                                             standby_temperature_k=config.standby_temperature_k, retries=LINK_RETRIES)
                earth.identify()  # a silent controller fails here, named
            self.where["source"] = url
            return earth
        if config.kind == "xenon":
            url, simulated = self.url(config.lamp_url, "lamp")
            clock, warmup_s = self._timing(simulated, config.warmup_s)
            with _connecting("lamp", url):
                port = open_port(url, baudrate=ORIEL_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                supply = Oriel69907(port, max_current_a=config.max_current_a, clock=clock, retries=LINK_RETRIES)
                supply.identify()  # a silent supply fails here, named, rather than at the first lamp_on
            url, _ = self.url(config.shutter_url, "shutter")
            with _connecting("shutter", url):
                port = open_port(url, baudrate=SC10_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                shutter = ThorlabsSC10(port, retries=LINK_RETRIES)
                shutter.configure()  # manual mode: `ens` then opens and closes the shutter
            self.where["source"] = f"{supply.port.name}, {url}"
            return ArcLampSource(supply, shutter, current_a=config.current_a, warmup_s=warmup_s)
        url, simulated = self.url(config.url, "led")
        clock, warmup_s = self._timing(simulated, config.warmup_s)
        with _connecting("led", url):
            port = open_port(url, timeout_s=config.timeout_s, **E363XA_SERIAL)
            self.closers.append(port.close)
            supply = ScpiSupply(port, max_current_a=config.max_current_a, max_voltage_v=config.max_voltage_v,
                                output=config.output, clock=clock, retries=LINK_RETRIES)
            supply.remote()  # the E363xA takes RS-232 commands only in remote mode
            self.where["source"] = url
            return LedSource(supply, config.current_a, voltage_v=config.voltage_v, warmup_s=warmup_s)

    # -- sensor ---------------------------------------------------------------------------------------
    def sensor(self) -> ImageSensor | QuadrantSensor | CoarseSunHead | HorizonSensor:
        config = self.file.devices.sensor
        if config.kind == "camera":
            if config.source is None:
                # the simulated camera: in-process, handed over as it is (no wire to open, drivers/sim/camera.py)
                self.where["sensor"] = "the simulated camera (in-process)"
                return self.sim.camera  # the file validated that the simulation's family is camera
            from drivers.usb_camera import UsbCamera  # OpenCV loads only for a camera bench

            with _connecting("sensor", str(config.source)):
                camera = UsbCamera(config.source, exposure_ms=config.exposure_ms)
            self.where["sensor"] = str(config.source)
            self.closers.append(camera.close)
            return camera
        url, _ = self.url(config.url, "sensor")
        if config.kind == "qd":
            with _connecting("sensor", url):
                port = open_port(url, baudrate=QD_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                sensor = QdSunSensor(port)
                sensor.identify()  # a silent module fails here, named
            self.where["sensor"] = url
            return sensor
        if config.kind == "horizon":
            with _connecting("sensor", url):
                port = open_port(url, baudrate=HORIZON_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                module = HorizonSensorModule(port, retries=LINK_RETRIES)
                module.identify()  # a silent module fails here, named
            self.where["sensor"] = url
            return module
        if config.kind == "css":
            with _connecting("sensor", url):
                port = open_port(url, baudrate=CSS_BAUDRATE, timeout_s=config.timeout_s)
                self.closers.append(port.close)
                head = CssHead(port, retries=LINK_RETRIES)
                head.identify()  # a silent head fails here, named
            self.where["sensor"] = url
            return head
        with _connecting("sensor", url):
            port = open_port(url, baudrate=CMOS_BAUDRATE, timeout_s=config.timeout_s)
            self.closers.append(port.close)
            sensor = CmosSunSensor(port, exposure_range_ms=tuple(config.exposure_range_ms),
                                   frame_timeout_s=config.frame_timeout_s)
            sensor.identify()  # the constructor sends nothing: make a silent module fail here, named
        self.where["sensor"] = url
        return sensor


def _identity_text(identity) -> str:
    if hasattr(identity, "serial"):  # SensorIdentity
        return f"{identity.model}, serial {identity.serial}, firmware {identity.firmware}"
    return str(identity)


def connect_bench(bench_file: BenchFile, *, time_scale: float | None = None,
                  ask: AskCallback | None = None) -> BenchDevices:
    """Open every device of `bench_file`, home the motorised table axes and identify everything.

    Parameters
    ----------
    bench_file : BenchFile
        The bench (``BenchFile()`` is the default simulated bench).
    time_scale : float, optional
        Overrides ``simulation.time_scale`` (0 = instant, for tests); ignored without a simulation.
    ask : callable, optional
        ``ask(axis_name, target_deg) -> reading`` for manual axes (:data:`drivers.manual.AskCallback`);
        default :func:`drivers.manual.console_ask`.

    Returns
    -------
    BenchDevices
        Close it (or use it as a context manager) to release the ports and the simulators.

    Raises
    ------
    BenchConnectionError
        A device could not be opened, initialised, homed or identified; it names the role and the URL.
        Everything opened before is closed and the simulators unregistered.
    """
    sim = urls = None
    if bench_file.simulation is not None:
        sim = SimBench(bench_file.simulation, time_scale=time_scale)
        urls = sim.register()
    connector = _Connector(bench_file, sim, urls or {}, ask or console_ask)
    try:
        table = connector.table()
        source = connector.source()
        sensor = connector.sensor()
        identities = {}
        for role, device in (("table", table), ("source", source), ("sensor", sensor)):
            with _connecting(role, connector.where[role]):
                identities[role] = _identity_text(device.identify())
    except BaseException:
        _close_all(connector.closers)
        if sim is not None:
            sim.unregister()
        raise
    log.info("bench connected: %s", "; ".join(f"{role}: {text}" for role, text in identities.items()))
    return BenchDevices(table=table, source=source, sensor=sensor, identities=identities,
                        simulated=sim is not None, sim=sim, _closers=connector.closers)
