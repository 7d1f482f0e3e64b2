"""The bench as a long-lived service, for the web dashboard: one session, one engine worker, a status cache
and an event bus.

* Campaigns are submitted to a queue (persisted in the catalogue) and run one after another by a worker
  thread; the web layer only enqueues and reads.
* The status (table angles, lamp and shutter, the sensor's temperature and latest frame, the engine's state
  and progress) is a cache: a status thread refreshes it from the devices while the bench is idle, and the
  engine's events refresh it during a run, so a request never waits on a serial port.
* Events go to every subscriber through its own bounded queue: a slow client loses old events, it never
  slows a measurement (research note anchors-orchestration, lesson 10).
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import asdict

import numpy as np

from calibration.centroid import CentroidError, find_spot

from .campaign import Campaign
from .engine import EngineState, IllegalTransition
from .runner import PreflightRefused, check_campaign, continue_campaign, open_session


class BenchBusy(IllegalTransition):
    """A manual command (jog, lamp, shutter) while a run owns the bench."""


class EventBus:
    """Fan-out of events to subscribers, each with a bounded queue (the oldest event is dropped when full)."""

    def __init__(self, maxsize: int = 256):
        self.maxsize = maxsize
        self._queues: list[queue.Queue] = []
        self._lock = threading.Lock()
        self.dropped = 0

    def subscribe(self) -> queue.Queue:
        q: queue.Queue = queue.Queue(self.maxsize)
        with self._lock:
            self._queues.append(q)
        return q

    def unsubscribe(self, q: queue.Queue) -> None:
        with self._lock:
            if q in self._queues:
                self._queues.remove(q)

    def publish(self, event: dict) -> None:
        with self._lock:
            queues = list(self._queues)
        for q in queues:
            try:
                q.put_nowait(event)
            except queue.Full:  # a slow client: drop its oldest event, never wait
                try:
                    q.get_nowait()
                    self.dropped += 1
                except queue.Empty:
                    pass
                try:
                    q.put_nowait(event)
                except queue.Full:
                    self.dropped += 1

    @property
    def subscribers(self) -> int:
        with self._lock:
            return len(self._queues)


class BenchService:
    """See the module docstring.

    Parameters
    ----------
    bench_file : bench.benchfile.BenchFile
    catalogue : bench.catalogue.Catalogue
        Opened for writing; the service (through its engine) is its only writer.
    time_scale : float, optional
        Overrides the simulated clock.
    status_period_s : float
        How often the idle bench's status is refreshed [s].
    """

    def __init__(self, bench_file, catalogue, *, time_scale: float | None = None, status_period_s: float = 0.5):
        self.bench_file = bench_file
        self.catalogue = catalogue
        self.status_period_s = status_period_s
        self.bus = EventBus()
        self.session = open_session(bench_file, catalogue, time_scale=time_scale)
        self.engine = self.session.engine
        self.engine.subscribe(self._on_engine_event)
        self._bench_lock = threading.RLock()  # manual commands and status polls vs. the worker's runs
        self._jobs: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._status: dict = {"engine": {"state": EngineState.IDLE.value}, "updated_utc": None}
        self._frame: np.ndarray | None = None
        self._frame_spot: dict | None = None
        self._progress: dict = {}
        self._threads = [threading.Thread(target=self._worker, name="bench-worker", daemon=True),
                         threading.Thread(target=self._poller, name="bench-status", daemon=True)]
        interrupted = catalogue.mark_interrupted_runs()
        if interrupted:
            catalogue.log_event(None, "startup", f"runs {interrupted} were interrupted and are marked crashed")

    # -- life ------------------------------------------------------------------------------------------
    def start(self) -> "BenchService":
        for thread in self._threads:
            thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self.engine.state not in (EngineState.IDLE,):
            try:
                self.engine.abort()
            except IllegalTransition:
                pass
        self._jobs.put(None)
        for thread in self._threads:
            if thread.is_alive():
                thread.join(timeout=30)
        self.session.close()

    # -- campaigns ----------------------------------------------------------------------------------
    def dry_run(self, campaign: Campaign):
        return check_campaign(campaign, self.session)

    def submit(self, campaign: Campaign) -> int:
        """Preflight and queue a campaign; returns its id. Raises :class:`PreflightRefused` with every violation."""
        report = check_campaign(campaign, self.session)
        if not report.ok:
            raise PreflightRefused(report.violations)
        campaign_id = self.catalogue.create_campaign(campaign.name, campaign.plan, campaign.model_dump(mode="json"))
        self.catalogue.enqueue_sensors(campaign_id, list(campaign.sensors))
        self._jobs.put(campaign_id)
        self.bus.publish({"kind": "queued", "campaign_id": campaign_id, "points": len(report.points)})
        return campaign_id

    def _worker(self) -> None:
        while not self._stop.is_set():
            campaign_id = self._jobs.get()
            if campaign_id is None:
                return
            with self._bench_lock:
                try:
                    continue_campaign(campaign_id, self.session, on_run=self._on_run)
                except Exception as exc:  # noqa: BLE001 - the service outlives a failed campaign
                    self.catalogue.log_event(None, "error", f"campaign {campaign_id}: {exc}")
                    self.bus.publish({"kind": "error", "campaign_id": campaign_id, "message": str(exc)})
            self.bus.publish({"kind": "campaign-finished", "campaign_id": campaign_id})

    def _on_run(self, run_id: int, sensor_id: str) -> None:
        self._progress = {"run_id": run_id, "sensor_id": sensor_id, "index": 0, "total": None, "eta_s": None}
        self.bus.publish({"kind": "run-started", "run_id": run_id, "sensor_id": sensor_id})

    def _on_engine_event(self, event) -> None:
        data = {"kind": event.kind, "run_id": event.run_id, **event.data}
        if event.kind == "point":
            self._progress.update(index=event.data["index"], total=event.data["total"], eta_s=event.data["eta_s"])
            self._frame = self.engine.last_frame
            self._status["table"] = {"azimuth_deg": event.data["azimuth_deg"],
                                     "zenith_deg": event.data["zenith_stage_deg"], "moving": False}
            self._locate_spot()
        self._status["engine"] = {"state": self.engine.state.value, **self._progress}
        self.bus.publish(data)

    # -- pause, resume, abort (the engine refuses illegal transitions) ---------------------------------
    def pause(self) -> None:
        self.engine.pause()

    def resume(self) -> None:
        self.engine.resume()

    def abort(self) -> None:
        self.engine.abort()

    def emergency_stop(self) -> None:
        self.engine.emergency_stop()

    # -- manual commands ------------------------------------------------------------------------------
    def _idle(self):
        if self.engine.state is not EngineState.IDLE or not self._bench_lock.acquire(timeout=0.5):
            raise BenchBusy(f"a run owns the bench (engine {self.engine.state.value})")
        return self._bench_lock

    def jog(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Move the table; limits are checked before it moves (LimitError)."""
        lock = self._idle()
        try:
            self.session.devices.table.move_to(azimuth_deg, zenith_deg)
        finally:
            lock.release()
        self.refresh_status()

    def set_lamp(self, on: bool) -> None:
        lock = self._idle()
        try:
            source = self.session.devices.source
            source.lamp_on() if on else source.standby()
        finally:
            lock.release()
        self.refresh_status()

    def set_shutter(self, open_: bool) -> None:
        lock = self._idle()
        try:
            source = self.session.devices.source
            source.open_shutter() if open_ else source.close_shutter()
        finally:
            lock.release()
        self.refresh_status()

    # -- status cache ---------------------------------------------------------------------------------
    def status(self) -> dict:
        """The cached status (never touches a device)."""
        return dict(self._status)

    def latest_frame(self) -> tuple[np.ndarray | None, dict | None]:
        return self._frame, self._frame_spot

    def refresh_status(self) -> None:
        """Read the devices (only while no run owns the bench) into the cache."""
        if self.engine.state is not EngineState.IDLE or not self._bench_lock.acquire(blocking=False):
            return
        try:
            d = self.session.devices
            azimuth, zenith = d.table.position()
            source = d.source.status()
            sensor = {"temperature_c": d.sensor.temperature_c(), "exposure_ms": d.sensor.exposure_ms()}
            if source.shutter_open:
                self._frame = d.sensor.capture()
            table = {"azimuth_deg": azimuth, "zenith_deg": zenith, "moving": d.table.is_moving()}
        except Exception as exc:  # noqa: BLE001 - a device error shows in the status, it does not end the service
            self._status["error"] = str(exc)
            return
        finally:
            self._bench_lock.release()
        self._status.update(table=table, source=asdict(source), sensor=sensor, error=None,
                            engine={"state": self.engine.state.value, **self._progress},
                            updated_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
        self._locate_spot()
        self.bus.publish({"kind": "status", **{k: self._status[k] for k in ("table", "source", "sensor")}})

    def _locate_spot(self) -> None:
        frame = self._frame
        if frame is None:
            self._frame_spot = None
            return
        try:
            spot = find_spot(frame, saturation_dn=self.session.engine.full_scale_dn)
            self._frame_spot = {"x_px": spot.x_px, "y_px": spot.y_px, "peak_dn": spot.peak_dn}
        except CentroidError as exc:
            self._frame_spot = {"error": type(exc).__name__}

    def _poller(self) -> None:
        while not self._stop.wait(self.status_period_s):
            self.refresh_status()
