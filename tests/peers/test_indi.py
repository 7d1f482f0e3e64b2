"""INDI's LX200 drivers (Debian indi-bin 1.9.9) against the simulated mount, as a lab tests its INDI set-up
before the hardware arrives (issue 11; peer-clients.md).

Each test serves a simulated LX200 bench on TCP in-process (``SimBench(...).serve()``), starts
``indiserver -p PORT DRIVER`` as a subprocess in a session of its own, points the driver at the simulator
with ``indi_setprop`` (CONNECTION_MODE TCP, DEVICE_ADDRESS, CONNECT) and reads with ``indi_getprop``. HOME is
the test's temporary directory, so no INDI configuration is read or written elsewhere. Every wait is bounded,
and the server's process group (indiserver and its driver) is ended at the end of each test.

The simulated clock runs TIME_SCALE times faster than the wall clock: a 180° slew at the table's 10 °/s is
about 2 s of wall time, and the sky turns TIME_SCALE times faster too, which the RA/Dec checks allow for.
"""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import time
from datetime import UTC, datetime
from pathlib import Path

import pytest
from peers.peer import indi_tool

from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.lx200 import SIDEREAL_RATE_DEG_S, horizontal_to_equatorial

TIME_SCALE = 10.0
POLL_MS = 100  # the driver's POLLING_PERIOD: how often INDI reads the mount (default 1000 ms)
CONNECT_LIMIT_S = 2.0
DEVICES = {"indi_lx200autostar": "LX200 Autostar", "indi_lx200_16": "LX200 16", "indi_lx200basic": "LX200 Basic"}
ARCMIN = 1.0 / 60.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _running_in_group(pgid: int) -> bool:
    """Whether a process of process group `pgid` is still running (not exited; Linux /proc)."""
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()  # after "pid (comm)": state ppid pgrp ...
        except (OSError, IndexError):
            continue
        if int(fields[2]) == pgid and fields[0] not in "ZX":
            return True
    return False


class IndiSession:
    """A simulated LX200 bench on TCP and an indiserver running one INDI driver against it."""

    def __init__(self, tmp_path, driver: str, *, indi_compatible: bool):
        self.driver, self.device = driver, DEVICES[driver]
        self.tools = {tool: indi_tool(tool) for tool in ("indiserver", "indi_setprop", "indi_getprop")}
        config = SimBenchConfig(table="lx200", time_scale=TIME_SCALE, lx200={"indi_compatible": indi_compatible})
        self.bench = SimBench(config)
        self.sim = self.bench.devices["table"]
        self.server = self.bench.serve()
        self.sim_port = int(self.server.urls["table"].rsplit(":", 1)[1])
        self.env = {**os.environ, "HOME": str(tmp_path)}
        self.log_path = tmp_path / "indiserver.log"
        self.log = open(self.log_path, "wb")
        self.process: subprocess.Popen | None = None
        try:
            self._start_server()
        except BaseException:
            self.close()
            raise

    def _start_server(self) -> None:
        for _ in range(3):  # a free port can be taken between asking and binding: then another one
            self.port = _free_port()
            self.process = subprocess.Popen([self.tools["indiserver"], "-p", str(self.port), self.driver],
                                            stdin=subprocess.DEVNULL, stdout=self.log, stderr=subprocess.STDOUT,
                                            env=self.env, start_new_session=True)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline and self.process.poll() is None:
                if self.get(f"{self.device}.CONNECTION._STATE", timeout_s=1):
                    return
                time.sleep(0.05)
            self._stop_server()
        raise AssertionError(f"indiserver with {self.driver} did not come up:\n{self.server_log()}")

    def server_log(self) -> str:
        self.log.flush()
        return self.log_path.read_text(errors="replace")[-4000:]

    # -- indi_setprop / indi_getprop ---------------------------------------------------------------------
    def set(self, assignment: str) -> None:
        """``indi_setprop`` of ``PROPERTY.ELEMENT=VALUE`` (or ``PROPERTY.E1;E2=V1;V2``) on the device."""
        result = subprocess.run([self.tools["indi_setprop"], "-p", str(self.port), "-t", "2",
                                 f"{self.device}.{assignment}"], capture_output=True, text=True, env=self.env,
                                timeout=10)
        assert result.returncode == 0, f"indi_setprop {assignment}: {result.stderr}\n{self.server_log()}"

    def get(self, *names: str, timeout_s: int = 2) -> dict[str, str]:
        """``indi_getprop`` of fully named elements (``DEVICE.PROPERTY.ELEMENT``, ``._STATE``) → name: value."""
        result = subprocess.run([self.tools["indi_getprop"], "-p", str(self.port), "-t", str(timeout_s), *names],
                                capture_output=True, text=True, env=self.env, timeout=timeout_s + 10)
        values = {}
        for line in result.stdout.splitlines():
            name, sep, value = line.partition("=")
            if sep:
                values[name.strip()] = value.strip()
        return values

    def value(self, name: str) -> str | None:
        return self.get(f"{self.device}.{name}").get(f"{self.device}.{name}")

    def numbers(self, prop: str, *elements: str) -> tuple[float, ...]:
        names = [f"{self.device}.{prop}.{e}" for e in elements]
        values = self.get(*names)
        assert all(n in values for n in names), f"{prop} not read: {values}\n{self.server_log()}"
        return tuple(float(values[n]) for n in names)

    def wait_state(self, prop: str, wanted: str, *, timeout_s: float) -> float:
        """Poll PROPERTY._STATE until it is `wanted`; returns the seconds waited (fails on the deadline)."""
        t0 = time.monotonic()
        state = None
        while time.monotonic() - t0 < timeout_s:
            state = self.value(f"{prop}._STATE")
            if state == wanted:
                return time.monotonic() - t0
            time.sleep(0.02)
        raise AssertionError(f"{self.device}.{prop} is {state!r}, not {wanted!r}, after {timeout_s} s\n"
                             f"{self.server_log()}")

    def connect(self) -> float:
        """Point the driver at the simulator and connect; returns the seconds from CONNECT to CONNECTION Ok."""
        self.set(f"POLLING_PERIOD.PERIOD_MS={POLL_MS}")
        self.set("CONNECTION_MODE.CONNECTION_TCP=On")
        self.set(f"DEVICE_ADDRESS.ADDRESS;PORT=127.0.0.1;{self.sim_port}")
        t0 = time.monotonic()
        self.set("CONNECTION.CONNECT=On")
        return time.monotonic() - t0 + self.wait_state("CONNECTION", "Ok", timeout_s=60.0)

    # -- the simulated mount ----------------------------------------------------------------------------
    def wait_still(self, timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + timeout_s
        while self.sim.azimuth.busy() or self.sim.altitude.busy():
            assert time.monotonic() < deadline, "the simulated mount is still moving"
            time.sleep(0.02)

    # -- clean-up -------------------------------------------------------------------------------------------
    def _stop_server(self) -> None:
        if self.process is None:
            return
        for sig, wait_s in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
            try:
                os.killpg(self.process.pid, sig)  # indiserver and the driver it started: one process group
            except ProcessLookupError:
                pass
            try:
                self.process.wait(timeout=wait_s)
                break
            except subprocess.TimeoutExpired:
                continue
        deadline = time.monotonic() + 5.0  # the driver too (a zombie until its new parent reaps it)
        while _running_in_group(self.process.pid):
            if time.monotonic() > deadline:
                os.killpg(self.process.pid, signal.SIGKILL)
                break
            time.sleep(0.02)
        self.process = None

    def close(self) -> None:
        try:
            self._stop_server()
        finally:
            self.server.stop()
            self.log.close()


@pytest.fixture
def indi(tmp_path):
    """Factory: ``indi(driver, indi_compatible=False)`` → a started :class:`IndiSession` (closed afterwards)."""
    sessions = []

    def start(driver: str, *, indi_compatible: bool = False) -> IndiSession:
        home = tmp_path / f"home{len(sessions)}"
        home.mkdir()
        session = IndiSession(home, driver, indi_compatible=indi_compatible)
        sessions.append(session)
        return session

    yield start
    problems = []
    for session in sessions:  # every one, even if another fails to close
        try:
            session.close()
        except Exception as exc:  # pragma: no cover - reported below
            problems.append(exc)
    if problems:
        raise problems[0]


def _separation_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Angle between two directions given as (longitude-like, latitude-like) [°]: (RA, Dec) or (az, alt)."""
    (l1, b1), (l2, b2) = (tuple(map(math.radians, p)) for p in (a, b))
    cos = math.sin(b1) * math.sin(b2) + math.cos(b1) * math.cos(b2) * math.cos(l1 - l2)
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def _sky_drift_deg(wall_s: float) -> float:
    """How far the RA/Dec of a still pose move in `wall_s` seconds of wall time (the sky turns) [°]."""
    return wall_s * TIME_SCALE * SIDEREAL_RATE_DEG_S


@pytest.mark.parametrize("driver", list(DEVICES))
def test_connect_takes_under_two_seconds_and_every_command_is_answered(indi, driver):
    """Before issue 11: ~50 s (each unanswered query cost INDI a 5 s timeout), lx200basic's :GR# handshake failed."""
    session = indi(driver)
    seconds = session.connect()
    assert seconds < CONNECT_LIMIT_S, f"{driver} connected in {seconds:.2f} s"
    assert session.sim.unknown == [], f"{driver} sent commands the simulator does not know: {session.sim.unknown}"
    assert b"GR" in session.sim.received  # the handshake of lx200basic, the format check of the others
    if driver != "indi_lx200basic":
        assert session.sim.received[0] == b"\x06"  # the ACK probe
        assert {b"Gc", b"GM", b"GT", b"Gt", b"Gg", b"GG", b"GL", b"GC", b"GVD", b"GVP"} <= set(session.sim.received)
        # the site as the mount tells it, in INDI's east-positive longitude
        latitude, longitude = session.numbers("GEOGRAPHIC_COORD", "LAT", "LONG")
        assert (latitude, longitude) == pytest.approx((session.sim.latitude_deg, session.sim.longitude_deg),
                                                      abs=ARCMIN / 2)


def test_ra_dec_read_is_the_simulated_pose_on_the_sky(indi):
    session = indi("indi_lx200autostar")
    session.sim.azimuth.move_to(60.0)  # back door: the table somewhere off the meridian
    session.sim.altitude.move_to(35.0)
    session.connect()
    session.wait_still()
    time.sleep(3 * POLL_MS / 1000.0)  # a few readings after the connect
    t0 = time.monotonic()
    ra_h, dec_deg = session.numbers("EQUATORIAL_EOD_COORD", "RA", "DEC")
    age_s = time.monotonic() - t0 + 1.0  # INDI reads every 0.1 s; 1 s of slack for a busy machine
    ra_sim, dec_sim = session.sim.equatorial_deg()
    assert _separation_deg((15.0 * ra_h, dec_deg), (ra_sim, dec_sim)) < _sky_drift_deg(age_s) + 2.0 / 3600.0
    # and back: INDI's RA/Dec is where the table points
    azimuth, altitude = session.sim.horizontal_deg(15.0 * ra_h, dec_deg)
    assert _separation_deg((azimuth, altitude), (60.0, 35.0)) < _sky_drift_deg(age_s) + 2.0 / 3600.0
    assert session.value("EQUATORIAL_EOD_COORD._STATE") in ("Idle", "Ok")


def test_equatorial_goto_slews_the_mount_to_the_target(indi):
    session = indi("indi_lx200autostar")
    session.connect()
    azimuth, altitude = 30.0, 25.0  # the target: where this pose is on the simulated sky now
    ra_deg, dec_deg = horizontal_to_equatorial(altitude, azimuth, session.sim.latitude_deg,
                                               session.sim.sidereal_time_deg())
    t0 = time.monotonic()
    session.set(f"EQUATORIAL_EOD_COORD.RA;DEC={ra_deg / 15.0:.6f};{dec_deg:.6f}")
    session.wait_state("EQUATORIAL_EOD_COORD", "Ok", timeout_s=15.0)  # INDI: ":D#" clear, "tracking"
    session.wait_still()
    elapsed_s = time.monotonic() - t0
    goto_commands = [c for c in session.sim.received if c[:2] in (b"Sr", b"Sd", b"MS")]
    assert [c[:2] for c in goto_commands] == [b"Sr", b"Sd", b"MS"], goto_commands
    # the mount went where the target was when :MS# arrived (it does not track: the pose now holds)
    assert _separation_deg(session.sim.pose_deg(), (azimuth, altitude)) < _sky_drift_deg(elapsed_s) + ARCMIN
    assert session.sim.unknown == []


def test_alt_az_goto_moves_the_mount_and_indi_reports_success(indi):
    session = indi("indi_lx200_16", indi_compatible=True)
    session.connect()
    session.set("HORIZONTAL_COORD.ALT;AZ=30;110")
    session.wait_state("HORIZONTAL_COORD", "Ok", timeout_s=15.0)  # INDI: "Slew is complete."
    # INDI calls a slew complete within 3′ of the target (lx200_16.cpp), so its last reading may be that far
    assert session.numbers("HORIZONTAL_COORD", "ALT", "AZ") == pytest.approx((30.0, 110.0), abs=0.05)
    session.wait_still()
    assert session.sim.pose_deg() == pytest.approx((110.0, 30.0), abs=1.0 / 3600.0)
    assert session.bench.world.stage_true_deg() == pytest.approx((110.0, 30.0), abs=0.01)
    assert [c for c in session.sim.received if c[:2] in (b"Sz", b"Sa", b"MA")] == [b"Sz110*00", b"Sa+30*00", b"MA"]


def test_the_manuals_slew_reply_is_an_indi_alert_though_the_mount_slews(indi):
    """The CONFLICT the indi_compatible option exists for: Rev L's ":MA#" → "0" (no fault) reads as failure."""
    session = indi("indi_lx200_16")  # the manual's replies (default)
    session.connect()
    session.set("HORIZONTAL_COORD.ALT;AZ=20;40")
    session.wait_state("HORIZONTAL_COORD", "Alert", timeout_s=5.0)  # INDI: "Slew is not possible."
    session.wait_still()
    assert session.sim.pose_deg() == pytest.approx((40.0, 20.0), abs=1.0 / 3600.0)  # yet the mount went there
    # INDI's ":Sa+5*00#" (its %+02d) is not the manual's sDD*MM: refused by default
    session.set("HORIZONTAL_COORD.ALT;AZ=5;40")
    session.wait_state("HORIZONTAL_COORD", "Alert", timeout_s=5.0)  # INDI: "Error setting Alt/Az."
    assert session.sim.received[-1] == b"Sa+5*00" and session.sim.target_altitude_deg == 20.0


def test_abort_stops_the_slew(indi):
    session = indi("indi_lx200_16", indi_compatible=True)
    session.connect()
    session.set("HORIZONTAL_COORD.ALT;AZ=60;300")  # 300° of azimuth at 10 °/s: 3 s of wall time
    deadline = time.monotonic() + 5.0
    while session.sim.pose_deg()[0] < 20.0:
        assert time.monotonic() < deadline, "the slew did not start"
        time.sleep(0.01)
    session.set("TELESCOPE_ABORT_MOTION.ABORT=On")
    session.wait_state("TELESCOPE_ABORT_MOTION", "Ok", timeout_s=5.0)
    session.wait_still(timeout_s=1.0)  # :Q# stops at once (the slew itself would take seconds more)
    stopped = session.sim.pose_deg()
    assert 20.0 < stopped[0] < 299.0 and stopped[1] < 59.0  # stopped on the way
    time.sleep(0.3)
    assert session.sim.pose_deg() == stopped  # and it stays stopped
    assert session.sim.received.count(b"Q") >= 1


def test_indi_sets_the_site_and_the_time(indi):
    """INDI's GEOGRAPHIC_COORD and TIME_UTC reach the mount as :Sg :St and :SG :SL :SC (Autostar order)."""
    session = indi("indi_lx200autostar")
    session.connect()
    session.set("GEOGRAPHIC_COORD.LAT;LONG;ELEV=-31.25;210.5;1100")  # INDI: east positive, 0–360
    session.wait_state("GEOGRAPHIC_COORD", "Ok", timeout_s=5.0)
    assert (session.sim.latitude_deg, session.sim.longitude_deg) == pytest.approx((-31.25, 210.5 - 360.0),
                                                                                  abs=ARCMIN)
    t0 = time.monotonic()
    session.set("TIME_UTC.UTC;OFFSET=2030-06-15T12:00:00;10")  # INDI's offset: UTC+10
    session.wait_state("TIME_UTC", "Ok", timeout_s=5.0)
    assert session.sim.utc_offset_h == -10.0  # Meade's sign
    expected = datetime(2030, 6, 15, 12, 0, 0, tzinfo=UTC)
    lag_s = (session.sim.utc() - expected).total_seconds()
    # set to the second (INDI truncates: 12:00:00 went out as :SL21:59:59#), then running on
    assert -1.0 <= lag_s <= (time.monotonic() - t0) * TIME_SCALE + 1.0
    assert [c[:2] for c in session.sim.received if c[:2] in (b"Sg", b"St", b"SG", b"SL", b"SC")] == \
        [b"Sg", b"St", b"SG", b"SL", b"SC"]
    assert session.sim.unknown == []
