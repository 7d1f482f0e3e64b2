"""The bench as a long-lived service, for the web dashboard: one session, one engine worker, a status cache
and an event bus.

* Campaigns are submitted to a queue (persisted in the catalogue) and run one after another by a worker
  thread; the web layer only enqueues and reads. Between the sensors of a fleet the worker waits for the
  operator to confirm the next mount (status ``mount``). Runs and campaigns a dead server left are marked
  crashed and aborted at start, and resumed only when asked (:meth:`BenchService.resume_run`,
  :meth:`BenchService.resume_campaign`).
* The status (table angles, lamp and shutter, the sensor's temperature and latest frame, the engine's state
  and progress) is a cache: a status thread refreshes it from the devices while no run owns the bench, and
  during a run the engine's own events (every move, lamp and shutter action and every reading it takes) refresh
  it, so a request never waits on a serial port and nothing polls a device the engine is driving.
* Events go to every subscriber through its own bounded buffer: a slow client loses old events, it never
  slows a measurement (research note anchors-orchestration, lesson 10). The publisher hands each event once to
  each event loop with subscribers, however many streams that loop serves; the loop fans it out.
"""

from __future__ import annotations

import asyncio
import dataclasses
import queue
import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from calibration.centroid import CentroidError, find_spot

from .campaign import Campaign
from .engine import EngineState, IllegalTransition
from .events import BenchEvent
from .families.cmos import FULL_SCALE_DN
from .runner import (
    MountRequest,
    PreflightRefused,
    ResumeRefused,
    check_campaign,
    check_resumable,
    continue_campaign,
    open_session,
    resume_and_continue,
)


class BenchBusy(IllegalTransition):
    """A manual command (jog, lamp, shutter) while a run owns the bench."""


def _utc_now() -> str:
    """Now, ISO 8601 UTC to the millisecond: a status refreshed several times a second shows it."""
    now = time.time()
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(now)) + f".{int(now % 1 * 1000):03d}Z"


class AsyncSubscription:
    """One asyncio reader's subscription to an :class:`EventBus` (see :meth:`EventBus.subscribe_async`): a
    bounded buffer filled in the reader's own event loop, the oldest item dropped when it is full.

    Everything but :meth:`close` runs in that loop's thread, so the buffer needs no lock.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, encode: Callable[[dict], object] | None, maxsize: int):
        self.loop = loop
        self.encode = encode
        self.closed = False
        self._items: deque = deque(maxlen=maxsize)
        self._waiter: asyncio.Future | None = None
        self._idle_timer: asyncio.TimerHandle | None = None
        self._quiet = True  # nothing delivered since the idle timer was armed

    def _deliver(self, item) -> bool:
        """Buffer `item` and wake the reader; True when the oldest buffered item was dropped for it."""
        full = len(self._items) == self._items.maxlen
        self._items.append(item)
        self._quiet = False
        self._wake()
        return full

    def _wake(self) -> None:
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result(None)

    def _idle_check(self, idle_s: float) -> None:
        # one timer per idle period, not one per wait (50 streams arming and cancelling a timer on every
        # event cost the loop some 15 % more): while items flow, the timer only re-arms itself
        if self._quiet:
            self._idle_timer = None
            self._wake()
        else:
            self._quiet = True
            self._idle_timer = self.loop.call_later(idle_s, self._idle_check, idle_s)

    async def next_batch(self, idle_s: float) -> list:
        """Every buffered item, oldest first, waiting for the first one. Empty when the subscription was
        closed, or when nothing arrived for `idle_s` [s] (between one and two `idle_s` after the last item)."""
        if not self._items and not self.closed:
            if self._idle_timer is None:
                self._quiet = True
                self._idle_timer = self.loop.call_later(idle_s, self._idle_check, idle_s)
            # a bare future: no task and no cancel scope per wait, and an idle reader costs nothing
            self._waiter = self.loop.create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None
        batch = list(self._items)
        self._items.clear()
        return batch

    def close(self) -> None:
        """Mark the subscription closed and end the reader's wait; callable from any thread."""
        self.closed = True
        try:
            self.loop.call_soon_threadsafe(self._end)
        except RuntimeError:  # the loop has closed: nobody is waiting
            pass

    def _end(self) -> None:
        if self._idle_timer is not None:
            self._idle_timer.cancel()
            self._idle_timer = None
        self._wake()


class EventBus:
    """Fan-out of events to subscribers, each with a bounded buffer (the oldest event is dropped when full).

    A thread subscribes with :meth:`subscribe` and reads a :class:`queue.Queue`; an asyncio task (an event
    stream of the web API) subscribes with :meth:`subscribe_async`. :meth:`publish` runs in the publisher's
    thread, often the engine's in the middle of a measurement, so it pays one put per queue but one hand-off
    per event loop, however many tasks of that loop subscribe: the loop fans the event out itself.
    """

    def __init__(self, maxsize: int = 256):
        self.maxsize = maxsize
        self._lock = threading.Lock()
        # replaced, never mutated, under the lock: publish takes a consistent snapshot without copying
        self._queues: tuple[queue.Queue, ...] = ()
        self._groups: dict[tuple, tuple[AsyncSubscription, ...]] = {}  # by (loop, encode)
        self.dropped = 0

    def subscribe(self) -> queue.Queue:
        """A queue of the events published from now on, for a thread to read."""
        q: queue.Queue = queue.Queue(self.maxsize)
        with self._lock:
            self._queues += (q,)
        return q

    def unsubscribe(self, q: queue.Queue) -> None:
        with self._lock:
            self._queues = tuple(x for x in self._queues if x is not q)

    def subscribe_async(self, encode: Callable[[dict], object] | None = None) -> AsyncSubscription:
        """A subscription read in the running event loop (call it from that loop).

        Parameters
        ----------
        encode : callable, optional
            What the subscription buffers for each event, instead of the event itself (an event stream's wire
            bytes). Called in the loop, once per event for all of the loop's subscriptions with the same
            `encode`, never in the publisher's thread.
        """
        subscription = AsyncSubscription(asyncio.get_running_loop(), encode, self.maxsize)
        key = (subscription.loop, encode)
        with self._lock:
            self._groups = {**self._groups, key: self._groups.get(key, ()) + (subscription,)}
        return subscription

    def unsubscribe_async(self, subscription: AsyncSubscription) -> None:
        """Stop delivering to `subscription`, and close it."""
        key = (subscription.loop, subscription.encode)
        with self._lock:
            groups = dict(self._groups)
            rest = tuple(s for s in groups.pop(key, ()) if s is not subscription)
            if rest:
                groups[key] = rest
            self._groups = groups
        subscription.close()

    def publish(self, event: BenchEvent) -> None:
        """Deliver `event` to every subscriber, as the stream sends it (:meth:`BenchEvent.to_dict`); never waits
        for one."""
        event = event.to_dict()
        with self._lock:
            queues, groups = self._queues, self._groups
        for q in queues:
            try:
                q.put_nowait(event)
            except queue.Full:  # a slow reader: drop its oldest event, never wait
                try:
                    q.get_nowait()
                    self._count_dropped(1)
                except queue.Empty:
                    pass
                try:
                    q.put_nowait(event)
                except queue.Full:
                    self._count_dropped(1)
        for (loop, encode), subscriptions in groups.items():
            try:
                loop.call_soon_threadsafe(self._fan_out, subscriptions, encode, event)
            except RuntimeError:  # the loop has closed without unsubscribing: forget its subscriptions
                with self._lock:
                    self._groups = {k: v for k, v in self._groups.items() if k[0] is not loop}

    def _fan_out(self, subscriptions: tuple[AsyncSubscription, ...], encode, event: dict) -> None:
        # in the subscriptions' loop, to those subscribed when `event` was published
        item = event if encode is None else encode(event)
        dropped = sum(s._deliver(item) for s in subscriptions)
        if dropped:
            self._count_dropped(dropped)

    def _count_dropped(self, n: int) -> None:
        with self._lock:  # publishers' threads and event loops all count here
            self.dropped += n

    @property
    def subscribers(self) -> int:
        """Queues and asynchronous subscriptions."""
        with self._lock:
            return len(self._queues) + sum(len(group) for group in self._groups.values())


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
        self._jobs: queue.Queue = queue.Queue()  # ("campaign", id) or ("resume", run id); None ends the worker
        self._pending: set[tuple[str, int]] = set()  # jobs queued or in progress, under _mount_lock
        self._mount_lock = threading.Condition()
        self._mount: dict | None = None  # the sensor mount the worker waits for the operator to confirm
        self._mount_answer: bool | None = None
        self._stop = threading.Event()
        self._status: dict = {"engine": {"state": EngineState.IDLE.value}, "bench": self.bench_info(),
                              "updated_utc": None}
        self._status_published = 0.0  # when the engine's readings were last published as a "status" event
        self._frame: np.ndarray | None = None
        self._frame_spot: tuple[np.ndarray, dict] | None = None  # (frame, its spot), found when first asked for
        self._frame_size: dict | None = None  # width_px, height_px of the sensor's frames
        self._progress: dict = {}
        self._threads = [threading.Thread(target=self._worker, name="bench-worker", daemon=True),
                         threading.Thread(target=self._poller, name="bench-status", daemon=True)]
        interrupted = catalogue.mark_interrupted_runs()
        if interrupted:
            catalogue.log_event(None, "startup", f"runs {interrupted} were interrupted and are marked crashed")
        # not run again by themselves: a bench that starts moving when a server restarts could catch the hands
        # of whoever is clearing the cause of the crash; the operator resumes them (README, Web dashboard)
        self.interrupted_campaigns = catalogue.mark_interrupted_campaigns()

    # -- life ------------------------------------------------------------------------------------------
    def start(self) -> BenchService:
        for thread in self._threads:
            thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self._answer_mount(False)  # a worker waiting for a mount ends its campaign
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

    def bench_info(self) -> dict:
        """Whether the bench is simulated, and its time scale (bench seconds per wall-clock second; 0: every wait
        is skipped) when it is: a dashboard must never let a simulated bench pass for the real one."""
        sim = self.session.devices.sim
        return {"simulated": sim is not None, "time_scale": float(sim.time_scale) if sim else None}

    def wall_time_s(self, bench_time_s: float) -> float | None:
        """How long `bench_time_s` of bench time takes on the wall clock: the same on a real bench, divided by
        the time scale on a simulated one; None when the simulation skips every wait (time scale 0)."""
        scale = self.bench_info()["time_scale"]
        if scale is None:
            return bench_time_s
        return bench_time_s / scale if scale > 0 else None

    # -- campaigns ----------------------------------------------------------------------------------
    def dry_run(self, campaign: Campaign):
        """The campaign's preflight report, for every sensor: :func:`~bench.runner.check_campaign` scales the
        duration by the number of sensors; the warm-up included in it is scaled alike (as ``sunbench run``
        prints it), so it stays a part of the duration."""
        report = check_campaign(campaign, self.session)
        return dataclasses.replace(report, warmup_s=report.warmup_s * len(campaign.sensors))

    def submit(self, campaign: Campaign) -> int:
        """Preflight and queue a campaign; returns its id. Raises :class:`PreflightRefused` with every violation,
        :class:`~bench.engine.EstopLatched` while an emergency stop is latched."""
        self.engine.check_unlatched()
        report = check_campaign(campaign, self.session)
        if not report.ok:
            raise PreflightRefused(report.violations)
        campaign_id = self.catalogue.create_campaign(campaign.name, campaign.plan, campaign.model_dump(mode="json"))
        self.catalogue.enqueue_sensors(campaign_id, list(campaign.sensors))
        self._put(("campaign", campaign_id))
        self.bus.publish(BenchEvent("queued", None, {"campaign_id": campaign_id, "points": len(report.points),
                          "upper_bound": report.upper_bound is not None}))
        return campaign_id

    def resume_run(self, run_id: int) -> None:
        """Queue the resumption of an ended run (a new run measuring only its missing points), then the rest of
        its campaign. Raises :class:`~bench.runner.ResumeRefused` when it cannot be resumed."""
        self.engine.check_unlatched()
        run = check_resumable(self.catalogue, run_id)
        self._refuse_pending(run["campaign_id"], f"the campaign of run {run_id}", ("resume", run_id))
        self._put(("resume", run_id))
        self.bus.publish(BenchEvent("resume-queued", run_id, {"campaign_id": run["campaign_id"]}))

    def resume_campaign(self, campaign_id: int) -> None:
        """Queue the rest of a campaign that stopped (aborted, failed, or left when the server stopped): its
        queued and failed sensors, each resumed from its last run when it has one."""
        self.engine.check_unlatched()
        campaign = self.catalogue.campaign(campaign_id)
        if campaign["status"] == "completed":
            raise ResumeRefused(f"campaign {campaign_id} is complete; nothing to resume")
        self._refuse_pending(campaign_id, f"campaign {campaign_id}", ("campaign", campaign_id))
        for entry in self.catalogue.fleet(campaign_id):
            if entry["status"] == "failed":  # tried again, from its run (the operator fixed the cause)
                self.catalogue.set_queue_status(campaign_id, entry["sensor_id"], "queued")
        self._put(("campaign", campaign_id))
        self.bus.publish(BenchEvent("resume-queued", None, {"campaign_id": campaign_id}))

    def _refuse_pending(self, campaign_id: int | None, what: str, job: tuple[str, int]) -> None:
        with self._mount_lock:
            pending = list(self._pending)
        if job in pending or campaign_id is not None and any(self._job_campaign(j) == campaign_id for j in pending):
            raise ResumeRefused(f"{what} is already queued or running")

    def _job_campaign(self, job: tuple[str, int]) -> int | None:
        kind, target = job
        return target if kind == "campaign" else self.catalogue.run(target)["campaign_id"]

    def _put(self, job: tuple[str, int]) -> None:
        with self._mount_lock:
            self._pending.add(job)
        self._jobs.put(job)

    def _worker(self) -> None:
        while not self._stop.is_set():
            job = self._jobs.get()
            if job is None:
                return
            kind, target = job
            campaign_id = self._job_campaign(job)
            with self._bench_lock:
                try:
                    if kind == "campaign":
                        continue_campaign(target, self.session, confirm_mount=self._confirm_mount, on_run=self._on_run)
                    else:
                        resume_and_continue(target, self.session, confirm_mount=self._confirm_mount,
                                            on_run=self._on_run)
                except Exception as exc:  # noqa: BLE001 - the service outlives a failed campaign
                    self.catalogue.log_event(None, "error", f"campaign {campaign_id}: {exc}")
                    self.bus.publish(BenchEvent("error", None, {"campaign_id": campaign_id, "message": str(exc)}))
                finally:
                    with self._mount_lock:
                        self._pending.discard(job)
            self.bus.publish(BenchEvent("campaign-finished", None, {"campaign_id": campaign_id,
                              **self._campaign_outcome(campaign_id)}))

    def _campaign_outcome(self, campaign_id: int | None) -> dict:
        """How the campaign stands now, and why when it did not complete (its last run's exit reason)."""
        if campaign_id is None:
            return {}
        status = self.catalogue.campaign(campaign_id)["status"]
        runs = self.catalogue.runs(campaign_id)
        reason = runs[-1]["exit_reason"] if runs and status != "completed" else None
        return {"status": status, "reason": reason}

    # -- sensor mounts between the runs of a fleet ------------------------------------------------------
    def _confirm_mount(self, request: MountRequest) -> bool:
        """In the worker: ask the dashboard to confirm `request`'s mount and wait for the answer.

        The bench is the operator's meanwhile (jog, lamp, shutter), so the worker lets go of it."""
        prompt = {"campaign_id": request.campaign_id, "sensor_id": request.sensor_id, "position": request.position,
                  "count": request.count, "resumes_run": request.resumes_run, "prompt": request.prompt()}
        with self._mount_lock:
            self._mount, self._mount_answer = prompt, None
        self._status["mount"] = prompt
        self.catalogue.log_event(request.resumes_run, "mount", f"waiting for the operator: {request.prompt()}")
        self.bus.publish(BenchEvent("mount", None, prompt))
        self._bench_lock.release()
        try:
            with self._mount_lock:
                while self._mount_answer is None and not self._stop.is_set():
                    self._mount_lock.wait(0.5)
                answer = bool(self._mount_answer)
                self._mount = None
        finally:
            self._bench_lock.acquire()
            self._status["mount"] = None
        self.bus.publish(BenchEvent("mount-answered", None, {"sensor_id": request.sensor_id, "confirmed": answer}))
        return answer

    def confirm_mount(self, sensor_id: str) -> None:
        """The operator says `sensor_id` is on the bench: its run starts (after its serial is checked).

        Raises :class:`~bench.engine.IllegalTransition` when no mount is awaited, or another sensor's."""
        self.engine.check_unlatched()
        with self._mount_lock:
            if self._mount is None:
                raise IllegalTransition("no sensor mount is awaited")
            if self._mount["sensor_id"] != sensor_id:
                raise IllegalTransition(f"the bench awaits sensor {self._mount['sensor_id']}, not {sensor_id}")
        self._answer_mount(True)

    def _answer_mount(self, answer: bool) -> bool:
        """Answer the awaited mount, if any; True when one was awaited."""
        with self._mount_lock:
            if self._mount is None or self._mount_answer is not None:
                return False
            self._mount_answer = answer
            self._mount_lock.notify_all()
            return True

    def _on_run(self, run_id: int, sensor_id: str) -> None:
        self._progress = {"run_id": run_id, "sensor_id": sensor_id, "index": 0, "total": None, "eta_s": None}
        self.bus.publish(BenchEvent("run-started", run_id, {"sensor_id": sensor_id}))

    # what the engine's readings may change in the cached status, by event kind
    _READINGS = {"table": ("azimuth_deg", "zenith_deg", "moving"),
                 "source": ("lamp_on", "warm", "shutter_open", "fault", "output", "output_unit"),
                 "sensor": ("temperature_c", "exposure_ms", "currents_a")}

    def _on_engine_event(self, event) -> None:
        fields = self._READINGS.get(event.kind)
        if fields is not None:  # the engine moved, switched or read something: the cache follows it
            merged = {**(self._status.get(event.kind) or {}), **{k: event.data[k] for k in fields if k in event.data}}
            if event.kind != "table" or {"azimuth_deg", "zenith_deg"} <= merged.keys():
                self._status[event.kind] = merged  # replaced, never mutated: readers copy the status unlocked
                self._status["updated_utc"] = _utc_now()
            # the streams get them as "status" events, as from the idle poller, at most one per status period:
            # one event per move and reading would triple what every client is sent during a run
            now = time.monotonic()
            if now - self._status_published >= self.status_period_s:
                self._status_published = now
                self.bus.publish(BenchEvent("status", None,
                                            {k: self._status.get(k) for k in ("table", "source", "sensor")}))
            return
        if event.kind == "point":
            self._progress.update(index=event.data["index"], total=event.data["total"], eta_s=event.data["eta_s"])
            self._frame = self.engine.last_frame
            self._status["updated_utc"] = _utc_now()
        elif event.kind == "finished":
            self._progress = {**self._progress, "ended_unsafe": event.data.get("unsafe")}
        self._status["engine"] = {"state": self.engine.state.value, **self._progress}
        self.bus.publish(event)

    # -- pause, resume, abort (the engine refuses illegal transitions) ---------------------------------
    def pause(self) -> None:
        self.engine.pause()

    def resume(self) -> None:
        self.engine.resume()

    def abort(self) -> None:
        if self._answer_mount(False):  # waiting for a sensor mount: the campaign stops there
            return
        self.engine.abort()

    def emergency_stop(self) -> list[str]:
        """Stop everything and latch (:meth:`bench.engine.RunEngine.emergency_stop`); returns what could not be
        made safe."""
        return self.engine.emergency_stop()

    def acknowledge_estop(self) -> None:
        self.engine.acknowledge_estop()
        self.refresh_status()

    # -- manual commands (the engine acts: it refuses them while latched, and an e-stop interrupts them) --
    def _idle(self):
        if self.engine.state not in (EngineState.IDLE, EngineState.ESTOP) \
                or not self._bench_lock.acquire(timeout=0.5):
            raise BenchBusy(f"a run owns the bench (engine {self.engine.state.value})")
        return self._bench_lock

    def jog(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Move the table; limits are checked before it moves (LimitError). An emergency stop that interrupts
        it raises :class:`~bench.engine.EstopLatched` naming where the table stopped."""
        lock = self._idle()
        try:
            self.engine.jog(azimuth_deg, zenith_deg)
        finally:
            lock.release()
            self.refresh_status()

    def set_lamp(self, on: bool) -> None:
        lock = self._idle()
        try:
            self.engine.set_lamp(on)
        finally:
            lock.release()
        self.refresh_status()

    def set_shutter(self, open_: bool) -> None:
        lock = self._idle()
        try:
            self.engine.set_shutter(open_)
        finally:
            lock.release()
        self.refresh_status()

    # -- status cache ---------------------------------------------------------------------------------
    def status(self) -> dict:
        """The cached status (never touches a device)."""
        return dict(self._status)

    def latest_frame(self) -> tuple[np.ndarray | None, dict | None]:
        """The latest frame and its spot (``x_px, y_px, peak_dn``, or ``error`` naming the centroid's error).

        The spot is found here, when a client asks, once per frame: not in the engine's thread for every
        point, where nobody may be looking."""
        frame, cached = self._frame, self._frame_spot
        if frame is None:
            return None, None
        if cached is not None and cached[0] is frame:
            return frame, cached[1]
        try:
            found = find_spot(frame, saturation_dn=FULL_SCALE_DN)
            spot = {"x_px": found.x_px, "y_px": found.y_px, "peak_dn": found.peak_dn}
        except CentroidError as exc:
            spot = {"error": type(exc).__name__}
        self._frame_spot = (frame, spot)
        return frame, spot

    def refresh_status(self) -> None:
        """Read the devices (only while no run owns the bench) into the cache."""
        if self.engine.state not in (EngineState.IDLE, EngineState.ESTOP) \
                or not self._bench_lock.acquire(blocking=False):
            return
        try:
            d = self.session.devices
            azimuth, zenith = d.table.position()
            source = d.source.status()
            family = self.session.engine.family
            sensor = {"family": family.name, **family.status(d.sensor)}
            if family.has_exposure and (source.shutter_open or self._frame_size is None):
                frame = d.sensor.capture()  # one dark frame tells the detector's size
                self._frame_size = {"width_px": int(frame.shape[1]), "height_px": int(frame.shape[0])}
                if source.shutter_open:
                    self._frame = frame
            sensor.update(self._frame_size or {})
            table = {"azimuth_deg": azimuth, "zenith_deg": zenith, "moving": d.table.is_moving()}
        except Exception as exc:  # noqa: BLE001 - a device error shows in the status, it does not end the service
            self._status["error"] = str(exc)
            return
        finally:
            self._bench_lock.release()
        self._status.update(table=table, source=dataclasses.asdict(source), sensor=sensor, error=None,
                            engine={"state": self.engine.state.value, **self._progress}, updated_utc=_utc_now())
        self.bus.publish(BenchEvent("status", None, {k: self._status[k] for k in ("table", "source", "sensor")}))

    def _poller(self) -> None:
        while not self._stop.wait(self.status_period_s):
            self.refresh_status()
