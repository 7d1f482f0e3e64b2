"""The run engine: the one thing that acts on the bench and writes the catalogue.

It executes a plan (a generator of :mod:`bench.messages`) against the bench's devices. Its states and
their legal transitions are one table; commands from other threads (pause, resume, abort, emergency stop)
are flags it looks at between frames and at every checkpoint (every point is one). Interlocks (lamp fault,
sensor over-temperature, enclosure open) suspend the run and resume it once cleared; a pause or an
interlock in the middle of a point discards the point's partial frames, and the point is measured again.
Whatever happens, the run ends with the shutter closed, the lamp at standby and the table stopped.

A point is recorded in one catalogue transaction, so a killed process leaves whole points only; a resumed
run skips the keys its lineage recorded (research note anchors-orchestration, lessons 2, 3, 9).
"""

from __future__ import annotations

import dataclasses
import enum
import re
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from calibration.centroid import CentroidError, find_spot
from calibration.geometry import incidence_from_stage_angle
from drivers.errors import DeviceFault, DeviceTimeout

from .messages import (Capture, Checkpoint, CloseShutter, LampOn, Log, Measure, MayStopEarly, Move, OpenShutter, Plan,
                       Reading, Record, SetExposure, WaitWarm)


class EngineState(str, enum.Enum):
    IDLE = "idle"
    RUNNING = "running"
    PAUSING = "pausing"
    PAUSED = "paused"
    SUSPENDED = "suspended"
    ABORTING = "aborting"
    FAULTED = "faulted"


S = EngineState
TRANSITIONS: dict[EngineState, set[EngineState]] = {
    S.IDLE: {S.RUNNING},
    S.RUNNING: {S.PAUSING, S.SUSPENDED, S.ABORTING, S.FAULTED, S.IDLE},
    S.PAUSING: {S.PAUSED, S.SUSPENDED, S.RUNNING, S.ABORTING, S.FAULTED, S.IDLE},
    S.PAUSED: {S.RUNNING, S.ABORTING, S.FAULTED},
    S.SUSPENDED: {S.RUNNING, S.ABORTING, S.FAULTED},
    S.ABORTING: {S.IDLE, S.FAULTED},
    S.FAULTED: {S.IDLE},
}


class IllegalTransition(RuntimeError):
    """A command that the engine's present state does not allow (the web answers 409)."""


class Aborted(Exception):
    """Raised inside the engine when an abort or an emergency stop ends the run."""


@dataclass(frozen=True)
class Interlocks:
    """What suspends a run.

    Attributes
    ----------
    sensor_max_temperature_c : float
        Above this the sensor is too hot [°C].
    lamp_fault : bool
        A lamp fault (or open interlock of the supply) suspends the run.
    enclosure_open : callable or None
        Returns True while the enclosure is open (a door switch); None when the bench has none.
    poll_s : float
        How often a suspended run looks at the interlocks [s].
    hold_off_s : float
        How long a cleared interlock must stay clear before the run goes on [s].
    """

    sensor_max_temperature_c: float = 60.0
    lamp_fault: bool = True
    enclosure_open: object = None
    poll_s: float = 0.5
    hold_off_s: float = 1.0


@dataclass
class EngineEvent:
    kind: str
    run_id: int | None
    data: dict = field(default_factory=dict)
    t_s: float = field(default_factory=time.time)


def _safe_name(key: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=+-]", "_", key)


class RunEngine:
    """Executes plans on a bench (see the module docstring).

    Parameters
    ----------
    devices
        The bench: ``table`` (RotaryTable), ``source`` (SunSimulator), ``sensor`` (ImageSensor) attributes.
    catalogue : bench.catalogue.Catalogue
        Where points, readings, values and events go (the engine is its only writer).
    geometry : calibration.design.BenchGeometry
        The bench geometry the bench believes: turns zenith-stage angles into true zenith (seed 003 eq. 8).
    interlocks : Interlocks
    frames : str
        What is kept of each frame: "roi" (64×64 px around the spot, and the whole frame when the centroid
        failed), "full" or "none".
    full_scale_dn : float
        Saturation level of the sensor [DN].
    clock : callable
        Time source for reading timestamps and durations [s].
    """

    ROI_HALF_PX = 32
    ARRIVAL_TOLERANCE_DEG = 2.0 / 60.0  # the LX200's low-precision resolution is 1′

    def __init__(self, devices, catalogue, *, geometry, interlocks: Interlocks = Interlocks(), frames: str = "roi",
                 full_scale_dn: float = 1023.0, clock=time.monotonic, warm_timeout_s: float = 7200.0):
        if frames not in ("roi", "full", "none"):
            raise ValueError(f"`frames` must be roi, full or none, got {frames!r}")
        self.devices = devices
        self.catalogue = catalogue
        self.geometry = geometry
        self.interlocks = interlocks
        self.frames = frames
        self.full_scale_dn = full_scale_dn
        self.clock = clock
        self.warm_timeout_s = warm_timeout_s
        self._state = EngineState.IDLE
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self._pause = self._abort = self._estop = False
        self._listeners = []
        self._run_id: int | None = None
        self._shutter_open = False
        self._shutter_wanted = False
        self._lamp_wanted = False
        self._progress = (0, 0)
        self._point_times: list[float] = []
        self.last_frame = None

    # -- state and commands ----------------------------------------------------------------------------
    @property
    def state(self) -> EngineState:
        return self._state

    def subscribe(self, callback) -> None:
        """`callback(EngineEvent)` for every state change, point, log line and warning."""
        self._listeners.append(callback)

    def _emit(self, kind: str, **data) -> None:
        event = EngineEvent(kind, self._run_id, data)
        for callback in list(self._listeners):
            try:
                callback(event)
            except Exception:  # noqa: BLE001 - a listener must never stop a measurement
                pass

    def _to(self, new: EngineState) -> None:
        with self._lock:
            if new is self._state:
                return
            if new not in TRANSITIONS[self._state]:
                raise IllegalTransition(f"cannot go from {self._state.value} to {new.value}")
            old, self._state = self._state, new
            self._wake.notify_all()
        self._emit("state", state=new.value, previous=old.value)
        if self._run_id is not None:
            self.catalogue.log_event(self._run_id, "state", f"{old.value} → {new.value}")

    def pause(self) -> None:
        """Ask the run to pause at its next checkpoint (a point in progress is measured again on resume)."""
        with self._lock:
            if self._state is not EngineState.RUNNING:
                raise IllegalTransition(f"cannot pause a run that is {self._state.value}")
            self._pause = True
            self._to(EngineState.PAUSING)

    def resume(self) -> None:
        with self._lock:
            if self._state not in (EngineState.PAUSED, EngineState.PAUSING):
                raise IllegalTransition(f"cannot resume a run that is {self._state.value}")
            self._pause = False
            self._wake.notify_all()

    def abort(self) -> None:
        with self._lock:
            if self._state in (EngineState.IDLE, EngineState.ABORTING, EngineState.FAULTED):
                raise IllegalTransition(f"cannot abort: the engine is {self._state.value}")
            self._abort = True
            self._wake.notify_all()

    def emergency_stop(self) -> None:
        """Stop the table and close the shutter now, from the caller's thread, then end the run."""
        with self._lock:
            self._abort = self._estop = True
            self._wake.notify_all()
        self._safe("table", self.devices.table.stop)
        self._safe("shutter", self.devices.source.close_shutter)

    # -- running ---------------------------------------------------------------------------------------
    def execute(self, plan: Plan, *, run_id: int, done_keys=frozenset(), lineage=(), n_points: int = 0,
                on_completed=None) -> str:
        """Run `plan` as run `run_id`; returns its final status (completed, aborted, failed).

        Parameters
        ----------
        done_keys : set of str
            Point keys the run's lineage already recorded (a resumed run); they are not measured again.
        lineage : sequence of int
            Runs whose readings answer a skipped point.
        n_points : int
            Points of the plan, for progress.
        on_completed : callable, optional
            Called once the plan has run to its end and the bench is safe, before the run is marked completed
            (the fits), so a reader never sees a completed run without its results. Its failure is logged.
        """
        self._run_id = run_id
        self._pause = self._abort = self._estop = False
        self._shutter_wanted = self._shutter_open = self._lamp_wanted = False
        self._done, self._lineage = set(done_keys), list(lineage) or [run_id]
        self._progress = (len(self._done), n_points)
        self._point_times = []
        self._to(EngineState.RUNNING)
        self.catalogue.set_run_status(run_id, "running")
        status, reason = "completed", None
        answer, interrupt = None, None
        try:
            while True:
                try:
                    msg = plan.send(answer)
                except StopIteration:
                    break
                answer = self._handle(msg)
        except Aborted:
            status, reason = "aborted", "emergency stop" if self._estop else "aborted by the operator"
            self._enter(EngineState.ABORTING)
        except Exception as exc:  # noqa: BLE001 - every failure ends the run cleanly and is recorded
            status, reason = "failed", f"{type(exc).__name__}: {exc}"
            self._enter(EngineState.FAULTED)
            self._emit("error", message=reason)
        except BaseException as exc:  # KeyboardInterrupt, SystemExit: made safe and recorded, then re-raised
            status, reason, interrupt = "aborted", f"interrupted ({type(exc).__name__})", exc
        finally:
            self._finalise()  # first: nothing the plan does on closing may keep the bench unsafe
            try:
                plan.close()
            except Exception as exc:  # noqa: BLE001 - a plan that misbehaves while closing
                self._emit("warning", message=f"plan close: {exc}")
        try:
            if status == "completed" and on_completed is not None:
                try:
                    on_completed()
                except Exception as exc:  # noqa: BLE001 - a failed fit leaves the recorded data intact
                    self.catalogue.log_event(run_id, "warning", f"after the run: {type(exc).__name__}: {exc}")
            self.catalogue.set_run_status(run_id, status, reason)
        except Exception as exc:  # noqa: BLE001 - the catalogue itself failed (disk full …): say so, go idle
            status, reason = "failed", f"could not record the end of the run: {exc}"
        finally:
            with self._lock:  # whatever happened, the engine can take the next run
                previous, self._state = self._state, EngineState.IDLE
                self._run_id = None
                self._wake.notify_all()
            if previous is not EngineState.IDLE:
                try:
                    self.catalogue.log_event(run_id, "state", f"{previous.value} → idle")
                except Exception:  # noqa: BLE001 - the catalogue may be what failed
                    pass
            self._emit("finished", status=status, reason=reason)
            self._emit("state", state=EngineState.IDLE.value, previous=previous.value)
        if interrupt is not None:
            raise interrupt
        return status

    def _enter(self, state: EngineState) -> None:
        try:
            self._to(state)
        except Exception:  # noqa: BLE001 - the end of a run must go on whatever the bookkeeping says
            pass

    def _finalise(self) -> None:
        """Shutter closed, lamp at standby, table stopped — each tried even if another fails."""
        self._safe("shutter", self.devices.source.close_shutter)
        self._safe("lamp", self.devices.source.standby)
        self._safe("table", self.devices.table.stop)
        self._shutter_open = False

    def _safe(self, what: str, action) -> None:
        try:
            action()
        except Exception as exc:  # noqa: BLE001 - finalisation must go on
            self._emit("warning", message=f"{what}: {exc}")
            if self._run_id is not None:
                try:
                    self.catalogue.log_event(self._run_id, "warning", f"finalisation, {what}: {exc}")
                except Exception:  # noqa: BLE001
                    pass

    # -- messages --------------------------------------------------------------------------------------
    def _handle(self, msg):
        d = self.devices
        if not isinstance(msg, (Log, Record, MayStopEarly)) and self._abort:
            raise Aborted()  # nothing acts on the bench once an abort or an emergency stop is asked for
        if isinstance(msg, Measure):
            return self._measure(msg.point)
        if isinstance(msg, Move):
            self._checkpoint()
            self._move(msg.azimuth_deg, msg.zenith_stage_deg)
            return None
        if isinstance(msg, Capture):
            self._checkpoint()  # no frame while an interlock holds or the bench is paused
            return [self._read(i) for i in range(msg.frames)]
        if isinstance(msg, SetExposure):
            actual = d.sensor.set_exposure_ms(msg.exposure_ms)
            return msg.exposure_ms if actual is None else actual
        if isinstance(msg, LampOn):
            self._lamp_wanted = True
            d.source.lamp_on()
            return None
        if isinstance(msg, WaitWarm):
            self._wait_warm()
            return None
        if isinstance(msg, OpenShutter):
            self._shutter_wanted = True
            self._checkpoint()  # opens it once nothing holds the bench
            return None
        if isinstance(msg, CloseShutter):
            self._shutter_wanted = False
            d.source.close_shutter()
            self._shutter_open = False
            return None
        if isinstance(msg, Record):
            self.catalogue.set_run_value(self._run_id, msg.key, msg.value)
            return None
        if isinstance(msg, Log):
            self.catalogue.log_event(self._run_id, "log", msg.message)
            self._emit("log", message=msg.message)
            return None
        if isinstance(msg, Checkpoint):
            self._checkpoint()
            return None
        if isinstance(msg, MayStopEarly):
            self.catalogue.log_event(self._run_id, "log", f"this plan may stop early ({msg.reason})")
            return None
        raise TypeError(f"the engine does not know the message {msg!r}")

    def _act(self, action) -> None:
        """Start an action on the bench unless an abort came first (an e-stop sets its flag under this lock)."""
        with self._lock:
            if self._abort:
                raise Aborted()
            action()

    def _move(self, azimuth_deg: float, zenith_deg: float, timeout_s: float = 600.0) -> None:
        """Move the table, watching for an abort while it moves (a stalled table times out)."""
        table = self.devices.table
        self._act(lambda: table.move_to(azimuth_deg, zenith_deg, wait=False))
        deadline = time.monotonic() + timeout_s
        while table.is_moving():
            if self._abort:
                self._safe("table", table.stop)
                raise Aborted()
            if time.monotonic() > deadline:
                self._safe("table", table.stop)
                raise DeviceTimeout(table.name, f"table still moving after {timeout_s} s: stalled?")
            with self._lock:
                self._wake.wait(0.005)
        azimuth, zenith = table.position()  # a limit switch or a stall that stopped it short is a fault
        off = max(abs((azimuth - azimuth_deg + 180.0) % 360.0 - 180.0), abs(zenith - zenith_deg))
        if off > self.ARRIVAL_TOLERANCE_DEG:
            raise DeviceFault(table.name, f"table stopped at ({azimuth:.4f}°, {zenith:.4f}°), "
                                          f"not at ({azimuth_deg:.4f}°, {zenith_deg:.4f}°)")

    def _wait_warm(self) -> None:
        """Wait for the lamp, watching for an abort (an arc lamp warms for half an hour)."""
        def pause(seconds):
            with self._lock:
                self._wake.wait(seconds)  # an abort wakes it at once
            if self._abort:
                raise Aborted()

        if self._abort:
            raise Aborted()
        self.devices.source.wait_until_warm(timeout_s=self.warm_timeout_s, poll_s=min(0.5, self.interlocks.poll_s),
                                            pause=pause)

    def _read(self, repeat: int) -> Reading:
        frame = self.devices.sensor.capture()
        self.last_frame = frame  # for a live view; never read by the engine itself
        t = self.clock()
        try:
            spot = find_spot(frame, saturation_dn=self.full_scale_dn)
            return Reading(repeat, spot.x_px, spot.y_px, spot.peak_dn, spot.n_pixels, int(spot.flags), "ok", t, frame)
        except CentroidError as exc:
            return Reading(repeat, float("nan"), float("nan"), float(getattr(exc, "peak_dn", np.nan) or np.nan), 0, 0,
                           type(exc).__name__, t, frame)

    def _interrupted(self) -> bool:
        return self._abort or self._pause or self._interlock_tripped() is not None

    def _measure(self, point):
        if point.key in self._done:
            return self._recorded(point.key)
        while True:
            self._checkpoint()
            started = time.time()
            t0 = time.monotonic()
            self._move(point.azimuth_deg, point.zenith_stage_deg)
            readings = []
            for repeat in range(point.repeats):
                if self._abort or self._pause:
                    break
                readings.append(self._read(repeat))
            if len(readings) < point.repeats or self._interlock_tripped() is not None:
                self.catalogue.log_event(self._run_id, "warning",
                                         f"point {point.key} interrupted; it will be measured again")
                continue  # the checkpoint pauses or suspends; the point starts over
            zenith, azimuth = self.body_direction(point)
            readings = [dataclasses.replace(r, zenith_deg=zenith, azimuth_body_deg=azimuth) for r in readings]
            self._record(point, readings, started)
            self._done.add(point.key)
            self._point_times.append(time.monotonic() - t0)
            done, total = len(self._done), self._progress[1]
            mean = float(np.mean(self._point_times[-20:]))
            self._emit("point", key=point.key, stage=point.stage, azimuth_deg=point.azimuth_deg,
                       zenith_stage_deg=point.zenith_stage_deg, index=done, total=total,
                       eta_s=max(total - done, 0) * mean,
                       spots=[(r.x_px, r.y_px) for r in readings if r.ok])
            return readings

    def _recorded(self, key: str):
        rows = [r for r in self.catalogue.readings(self._lineage) if r["key"] == key]
        nan = float("nan")
        return [Reading(r["repeat"], r["x_px"] if r["x_px"] is not None else nan,
                        r["y_px"] if r["y_px"] is not None else nan, r["peak_dn"] or 0.0,
                        r["n_pixels"] or 0, r["flags"] or 0, r["status"], r["t_s"] or 0.0,
                        zenith_deg=r["zenith_deg"] if r["zenith_deg"] is not None else nan,
                        azimuth_body_deg=r["azimuth_body_deg"] if r["azimuth_body_deg"] is not None else nan)
                for r in rows]

    def body_direction(self, point) -> tuple[float, float]:
        """The sun direction in the body frame the bench believes for a point (zenith, azimuth) [°].

        References
        ----------
        seed 003, eq. 8 (a negative stage angle is the positive zenith on the opposite azimuth).
        """
        geometry = self.geometry
        theta = float(incidence_from_stage_angle(point.zenith_stage_deg, geometry.lever_arm_mm,
                                                 geometry.source_distance_mm))
        return abs(theta), float(np.mod(point.azimuth_deg + (180.0 if theta < 0 else 0.0), 360.0))

    def _record(self, point, readings, started) -> None:
        zenith, azimuth_body = self.body_direction(point)
        paths = self._save_frames(point, readings)
        rows = [{"repeat": r.repeat, "x_px": None if not r.ok else r.x_px, "y_px": None if not r.ok else r.y_px,
                 "peak_dn": None if not np.isfinite(r.peak_dn) else float(r.peak_dn), "n_pixels": r.n_pixels,
                 "flags": r.flags, "status": r.status, "frame_path": paths.get(r.repeat), "t_s": r.t_s}
                for r in readings]
        self.catalogue.record_point(self._run_id, point.key, stage=point.stage, azimuth_deg=point.azimuth_deg,
                                    zenith_stage_deg=point.zenith_stage_deg, zenith_deg=zenith,
                                    azimuth_body_deg=azimuth_body, exposure_ms=self._exposure(),
                                    readings=rows, started_utc=started)

    def _exposure(self) -> float | None:
        try:
            return float(self.devices.sensor.exposure_ms())
        except Exception:  # noqa: BLE001 - the exposure is provenance, not worth a failed point
            return None

    def _save_frames(self, point, readings) -> dict[int, str]:
        if self.frames == "none" or not readings:
            return {}
        folder = self.catalogue.frames_dir(self._run_id)
        folder.mkdir(parents=True, exist_ok=True)
        name = _safe_name(point.key) + ".npz"
        arrays = {}
        for r in readings:
            frame = r.frame
            if frame is None:
                continue
            if self.frames == "roi" and r.ok:
                h, w = frame.shape
                x0 = int(min(max(round(r.x_px) - self.ROI_HALF_PX, 0), max(w - 2 * self.ROI_HALF_PX, 0)))
                y0 = int(min(max(round(r.y_px) - self.ROI_HALF_PX, 0), max(h - 2 * self.ROI_HALF_PX, 0)))
                arrays[f"frame_{r.repeat}"] = frame[y0: y0 + 2 * self.ROI_HALF_PX, x0: x0 + 2 * self.ROI_HALF_PX]
                arrays[f"origin_{r.repeat}"] = np.array([x0, y0])
            else:
                arrays[f"frame_{r.repeat}"] = frame
                arrays[f"origin_{r.repeat}"] = np.array([0, 0])
        np.savez(folder / name, **arrays)
        relative = f"{folder.name}/{name}"
        return {r.repeat: relative for r in readings}

    # -- checkpoints, pause, interlocks -----------------------------------------------------------------
    def _interlock_tripped(self) -> str | None:
        """The reason the bench must not measure now, or None. A device that cannot be asked raises: a run
        whose safety cannot be checked fails (and is made safe) rather than waiting for an answer."""
        lock = self.interlocks
        if lock.enclosure_open is not None and lock.enclosure_open():
            return "enclosure open"
        if lock.lamp_fault and self._lamp_wanted and self.devices.source.status().fault:
            return "lamp fault"
        temperature = self.devices.sensor.temperature_c()
        if np.isfinite(temperature) and temperature > lock.sensor_max_temperature_c:
            return f"sensor over temperature ({temperature:.1f} °C > {lock.sensor_max_temperature_c} °C)"
        return None

    def _checkpoint(self) -> None:
        """Hold while paused or while an interlock trips; then (re)open the shutter if the plan wants it open."""
        while True:
            if self._abort:
                raise Aborted()
            if self._pause:
                self._hold(EngineState.PAUSED, "paused by the operator", lambda: not self._pause)
                continue
            reason = self._interlock_tripped()
            if reason is not None:
                self._hold(EngineState.SUSPENDED, reason, self._interlocks_clear)
                continue
            with self._lock:
                if self._pause:
                    continue  # asked for while the interlocks were being read
                if self._state is EngineState.PAUSING:  # a resume before the checkpoint was reached
                    self._to(EngineState.RUNNING)
            if self._shutter_wanted and not self._shutter_open:
                self._act(self.devices.source.open_shutter)
                self._shutter_open = True
            return

    def _interlocks_clear(self) -> bool:
        if self._interlock_tripped() is not None:
            self._clear_since = None
            return False
        now = time.monotonic()
        if self._clear_since is None:
            self._clear_since = now
        return now - self._clear_since >= self.interlocks.hold_off_s

    def _hold(self, state: EngineState, reason: str, cleared) -> None:
        """Park the bench safely in `state` until `cleared()` (or an abort), then relight the lamp; the shutter
        is reopened by the checkpoint once nothing holds the bench."""
        self._safe("shutter", self.devices.source.close_shutter)
        self._shutter_open = False
        self._safe("table", self.devices.table.stop)
        self._to(state)
        self.catalogue.log_event(self._run_id, state.value, reason)
        self._emit(state.value, reason=reason)
        self._clear_since = None
        with self._lock:
            while not self._abort and not cleared():
                self._wake.wait(self.interlocks.poll_s if state is EngineState.SUSPENDED else 0.5)
        if self._abort:
            raise Aborted()
        if self._lamp_wanted and not self.devices.source.status().lamp_on:
            self._act(self.devices.source.lamp_on)  # a lamp fault put the lamp out
        if self._lamp_wanted:
            self._wait_warm()
        self._to(EngineState.RUNNING)
        self.catalogue.log_event(self._run_id, "running", f"resumed after: {reason}")
