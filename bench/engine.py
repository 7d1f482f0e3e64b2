"""The run engine: the one thing that acts on the bench and writes the catalogue.

It executes a plan (a generator of :mod:`bench.messages`) against the bench's devices. Its states and
their legal transitions are one table; commands from other threads (pause, resume, abort, emergency stop)
are flags it looks at between frames and at every checkpoint (every point is one). Interlocks (lamp fault,
sensor over-temperature, enclosure open) suspend the run and resume it once cleared; a pause or an
interlock in the middle of a point discards the point's partial frames, and the point is measured again.
Whatever happens, the run ends with the shutter closed, the lamp at standby and the table stopped; when the
shutter cannot be closed the lamp is switched off instead, and the run is journaled as "ended unsafe".

An emergency stop latches: the engine stays in ``estop``, refusing every move and every light, until an
operator acknowledges it (:meth:`RunEngine.acknowledge_estop`). Manual commands (jog, lamp, shutter) go through
the engine too, so an emergency stop interrupts them like a run.

A motion that takes time (a table's move, an Earth simulator's iris or cover) is started under the engine's lock (so
it never starts after an emergency stop) and waited for outside it, waking at once on an abort or an emergency stop:
a stop never waits for a motion to end. A move is expected to take what the table's own speeds say
(:meth:`drivers.interfaces.RotaryTable.expected_motion`, :class:`~bench.preflight.TimingModel`), an iris move what
its driver says (:meth:`drivers.interfaces.EarthSimulator.expected_iris_move_s`); one still going on
``MOVE_TIMEOUT_FACTOR`` × that plus ``MOVE_TIMEOUT_MARGIN_S`` after the start is stalled: it is stopped and faults.

The engine emits one event type (:class:`bench.events.BenchEvent`) for what it does and reads (``table``,
``source``, ``sensor``, ``point`` …), so a status view can follow a run without asking devices the engine owns;
the journal (:class:`bench.events.Journal`, the catalogue's ``events`` table) takes the journaled ones first, so
a run never goes on unrecorded; the event stream, the status cache and the CLI's progress subscribe. Plan
messages are dispatched through one table (:attr:`RunEngine.handlers`), and what a reading is comes from the
run's sensor family (:mod:`bench.families`): the engine knows no family.

A point is recorded in one catalogue transaction, so a killed process leaves whole points only; a resumed
run skips the keys its lineage recorded (research note anchors-orchestration, lessons 2, 3, 9).
"""

from __future__ import annotations

import dataclasses
import enum
import re
import threading
import time

import numpy as np

from calibration.geometry import zenith_azimuth_from_vector
from calibration.mount import ForkMount, fork_vectors
from calibration.stage_geometry import arm_ratio, body_direction_deg
from drivers.errors import DeviceFault, DeviceTimeout
from drivers.interfaces import EarthSimulator

from .descriptor import ReadingRecord
from .events import BenchEvent, Journal
from .families import Family
from .families import family as family_named
from .interlocks import DEFAULT_INTERLOCKS, Interlocks
from .messages import (
    Capture,
    Checkpoint,
    CloseShutter,
    LampOn,
    Log,
    MayStopEarly,
    Measure,
    Move,
    OpenShutter,
    Plan,
    Reading,
    Record,
    SetDiscRadius,
    SetExposure,
    SetTemperature,
    WaitWarm,
)
from .preflight import TimingModel, timing_from_motion

#: A move faults once it has lasted this many times its expected duration plus the margin [s]: the margin
#: covers settling, the controller's own start-up and a table slower than its reported speed.
MOVE_TIMEOUT_FACTOR = 1.5
MOVE_TIMEOUT_MARGIN_S = 5.0
#: The wait for a table that cannot tell its speeds (a manual stage, an LX200 without a slew rate) [s].
UNKNOWN_MOVE_TIMEOUT_S = 600.0
#: Readings the engine takes often (temperature, lamp status) are emitted at most this often, unless a flag
#: changes [s]: a status view needs no more, and every event goes to every client.
OBSERVE_PERIOD_S = 1.0


class EngineState(str, enum.Enum):
    IDLE = "idle"
    RUNNING = "running"
    PAUSING = "pausing"
    PAUSED = "paused"
    SUSPENDED = "suspended"
    ABORTING = "aborting"
    FAULTED = "faulted"
    ESTOP = "estop"  # an emergency stop, latched until acknowledged


S = EngineState
TRANSITIONS: dict[EngineState, set[EngineState]] = {
    S.IDLE: {S.RUNNING},
    S.RUNNING: {S.PAUSING, S.SUSPENDED, S.ABORTING, S.FAULTED, S.IDLE},
    S.PAUSING: {S.PAUSED, S.SUSPENDED, S.RUNNING, S.ABORTING, S.FAULTED, S.IDLE},
    S.PAUSED: {S.RUNNING, S.ABORTING, S.FAULTED},
    S.SUSPENDED: {S.RUNNING, S.ABORTING, S.FAULTED},
    S.ABORTING: {S.IDLE, S.FAULTED},
    S.FAULTED: {S.IDLE},
    S.ESTOP: {S.IDLE},  # only an acknowledgement leaves it
}
for _state in TRANSITIONS:  # an emergency stop may come in any state
    if _state is not S.ESTOP:
        TRANSITIONS[_state].add(S.ESTOP)


class IllegalTransition(RuntimeError):
    """A command that the engine's present state does not allow (the web answers 409)."""


class EstopLatched(IllegalTransition):
    """A move or a light refused, or a manual move interrupted, by the latched emergency stop (the web answers
    409)."""


LATCHED = ("emergency stop latched: nothing moves or lights until it is acknowledged "
           "(Acknowledge e-stop, POST /api/stop/acknowledge)")


class Aborted(Exception):
    """Raised inside the engine when an abort or an emergency stop ends the run."""


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
        What is kept of each frame of an image family: "roi" (64×64 px around the spot, and the whole frame
        when the centroid failed), "full" or "none".
    family : bench.families.Family or str
        The sensor family on the bench: what one reading is and how it is taken.
    axis_order : str
        The table's kinematics: "azimuth-on-zenith" (seed 003's two stages) or "zenith-on-azimuth" (an alt-az
        fork mount such as the LX200).
    clock : callable
        Time source for reading timestamps and durations [s].
    """

    ROI_HALF_PX = 32
    ARRIVAL_TOLERANCE_DEG = 2.0 / 60.0  # the LX200's low-precision resolution is 1′

    def __init__(self, devices, catalogue, *, geometry, interlocks: Interlocks = DEFAULT_INTERLOCKS,
                 frames: str = "roi", family: Family | str = "cmos", axis_order: str = "azimuth-on-zenith",
                 clock=time.monotonic, warm_timeout_s: float = 7200.0):
        if frames not in ("roi", "full", "none"):
            raise ValueError(f"`frames` must be roi, full or none, got {frames!r}")
        self.devices = devices
        self.catalogue = catalogue
        self.geometry = geometry
        self.interlocks = interlocks
        self.frames = frames
        self.family = family_named(family) if isinstance(family, str) else family
        if axis_order not in ("azimuth-on-zenith", "zenith-on-azimuth"):
            raise ValueError(f"`axis_order` must be azimuth-on-zenith or zenith-on-azimuth, got {axis_order!r}")
        self.axis_order = axis_order
        self.clock = clock
        self.warm_timeout_s = warm_timeout_s
        self._state = EngineState.IDLE
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self._pause = self._abort = self._estop = False  # _estop: the latch, cleared only by an acknowledgement
        self._executing = False  # a plan is being executed and its run has not ended yet
        self._journal_writer = Journal(catalogue)  # the one subscriber whose failure is the run's failure
        self._listeners = []
        self.handlers = {Measure: self._on_measure, Move: self._on_move, Capture: self._on_capture,
                         SetExposure: self._on_set_exposure, SetTemperature: self._on_set_temperature,
                         LampOn: self._on_lamp_on, WaitWarm: self._on_wait_warm, OpenShutter: self._on_open_shutter,
                         CloseShutter: self._on_close_shutter, Record: self._on_record, Log: self._on_log,
                         Checkpoint: self._on_checkpoint, MayStopEarly: self._on_may_stop_early,
                         SetDiscRadius: self._on_set_disc_radius}
        self._run_id: int | None = None
        self._shutter_open = False
        self._shutter_wanted = False
        self._lamp_wanted = False
        self._progress = (0, 0)
        self._point_times: list[float] = []
        self._pose: tuple[float, float] | None = None  # where the table was last seen still (azimuth, zenith)
        self._timing: TimingModel | None | bool = False  # the table's speeds; False: not asked yet, None: unknown
        self._observed: dict[str, tuple[float, dict]] = {}  # kind -> (when, data) of the last reading emitted
        self._lineage_readings: dict[str, list[ReadingRecord]] | None = None  # by point key, read once (_recorded)
        self.last_frame = None

    # -- state and commands ----------------------------------------------------------------------------
    @property
    def state(self) -> EngineState:
        return self._state

    def subscribe(self, callback) -> None:
        """`callback(BenchEvent)` for every state change, point, reading, log line and warning."""
        self._listeners.append(callback)

    def _emit(self, kind: str, *, message: str = "", journal: bool = False, **data) -> None:
        """Emit a :class:`BenchEvent`; a `journal` one is kept in the run's journal first (a journal that
        cannot be written fails what the engine was doing: a run must not go on unrecorded)."""
        event = BenchEvent(kind, self._run_id, data, message, journal)
        if journal:
            self._journal_writer(event)
        for callback in list(self._listeners):
            try:
                callback(event)
            except Exception:  # noqa: BLE001 - a listener must never stop a measurement
                pass

    def _to(self, new: EngineState) -> None:
        with self._lock:
            if new is self._state:
                return
            if self._state is EngineState.ESTOP and new is not EngineState.IDLE:
                raise Aborted()  # the run's thread, after an emergency stop came in: it ends as aborted
            if new not in TRANSITIONS[self._state]:
                raise IllegalTransition(f"cannot go from {self._state.value} to {new.value}")
            old, self._state = self._state, new
            self._wake.notify_all()
        self._emit("state", message=f"{old.value} → {new.value}", journal=self._run_id is not None,
                   state=new.value, previous=old.value)

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
            if self._state in (EngineState.IDLE, EngineState.ABORTING, EngineState.FAULTED, EngineState.ESTOP):
                raise IllegalTransition(f"cannot abort: the engine is {self._state.value}")
            self._abort = True
            self._wake.notify_all()

    def emergency_stop(self) -> list[str]:
        """Stop the table and close the shutter now, from the caller's thread, end any run or manual command,
        and latch: the engine stays in ``estop`` and refuses every move and light until
        :meth:`acknowledge_estop`. Allowed in any state.

        Returns
        -------
        list of str
            What could not be made safe, in words; empty when the table stopped and the shutter closed.
        """
        with self._lock:
            self._abort = self._estop = True
            previous, self._state = self._state, EngineState.ESTOP
            self._wake.notify_all()
        if previous is not EngineState.ESTOP:
            self._emit("state", state=EngineState.ESTOP.value, previous=previous.value)
        # the table first: a moving table is the hazard to hands; then the light
        problems = [f"the table may still be moving ({error})"
                    for error in [self._safe("table", self.devices.table.stop, "emergency stop")] if error]
        problems += self._make_dark("emergency stop")
        self._pose = None
        self._stopped_where()  # where the table came to rest, for a status view
        self._journal("estop", "emergency stop, latched until acknowledged"
                      + (f": {'; '.join(problems)}" if problems else ": table stopped, shutter closed"))
        return problems

    def acknowledge_estop(self, wait_s: float = 10.0) -> None:
        """Release the emergency stop's latch (the operator has seen to the bench); the engine goes idle. A run
        the stop ended is given `wait_s` [s] to finish making the bench safe first.

        Raises
        ------
        IllegalTransition
            Nothing is latched, or the stopped run is still being made safe (acknowledge again once it ended).
        """
        with self._lock:
            if self._state is not EngineState.ESTOP:
                raise IllegalTransition(f"no emergency stop to acknowledge: the engine is {self._state.value}")
            self._wake.wait_for(lambda: not self._executing, timeout=wait_s)
            if self._executing:
                raise IllegalTransition("the stopped run is still being made safe: acknowledge once it has ended")
            self._estop = self._abort = self._pause = False
            self._state = EngineState.IDLE
            self._wake.notify_all()
        self._emit("state", state=EngineState.IDLE.value, previous=EngineState.ESTOP.value)
        self._journal("estop", "emergency stop acknowledged")

    def check_unlatched(self) -> None:
        """Raise :class:`EstopLatched` while an emergency stop is latched (before queueing a campaign)."""
        if self._estop:
            raise EstopLatched(LATCHED)

    def journal(self, kind: str, message: str) -> None:
        """A journaled event of the run in progress (the fits at its end say what they found through it, so the
        journal, the event stream and the CLI's progress all hear it)."""
        self._emit(kind, message=message, journal=True)

    def _journal(self, kind: str, message: str) -> None:
        """Journal an event of the run in progress, or of the bench (no run); never raises."""
        try:
            self._journal_writer(BenchEvent(kind, self._run_id, {}, message, True))
        except Exception:  # noqa: BLE001 - the catalogue may be what failed
            pass

    # -- manual commands (outside a run) ---------------------------------------------------------------
    def _manual(self, what: str, *, safe: bool = False) -> None:
        """Refuse a manual command while a run owns the bench, or (unless it makes the bench safer: `safe`)
        while an emergency stop is latched."""
        with self._lock:
            if self._estop and not safe:
                raise EstopLatched(f"{LATCHED}; refused: {what}")
            if self._executing or self._state not in (EngineState.IDLE, EngineState.ESTOP):
                raise IllegalTransition(f"a run owns the bench (engine {self._state.value}); refused: {what}")

    def jog(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Move the table outside a run; returns once it is there.

        Raises
        ------
        EstopLatched
            The latch holds, or an emergency stop interrupted the move: the message says where the table stopped.
        IllegalTransition
            A run owns the bench.
        drivers.errors.LimitError
            Outside the soft limits; nothing moved.
        drivers.errors.DeviceTimeout
            The table did not arrive in time (a stalled axis): it was stopped.
        """
        self._manual(f"move the table to azimuth {azimuth_deg:g}°, zenith {zenith_deg:g}°")
        try:
            self._move(azimuth_deg, zenith_deg)
        except Aborted:
            raise EstopLatched(f"emergency stop: the move to azimuth {azimuth_deg:g}°, zenith {zenith_deg:g}° was "
                               f"interrupted; {self._stopped_where()}. {LATCHED}") from None

    def set_lamp(self, on: bool) -> None:
        """Lamp on, or at standby (allowed while latched: it makes the bench safer)."""
        source = self.devices.source
        if on:
            self._source_action("switch the lamp on", source.lamp_on, lamp_on=True)
        else:
            self._source_action("put the lamp at standby", source.standby, darker=True, shutter_open=False)
            self._shutter_open = False

    def set_shutter(self, open_: bool) -> None:
        """Open the shutter, or close it (allowed while latched: it makes the bench safer)."""
        source = self.devices.source
        if open_:
            # an Earth simulator's cover travels: _open_shutter starts it under the lock and waits outside
            self._source_action("open the shutter", self._open_shutter, shutter_open=True, locks_itself=True)
        else:
            self._source_action("close the shutter", source.close_shutter, darker=True, shutter_open=False)

    def _source_action(self, what: str, action, *, darker: bool = False, locks_itself: bool = False,
                       **implied) -> None:
        """A manual lamp or shutter `action`, then the source's status (`implied`: what the action implies when
        the source cannot be read). One that makes the bench `darker` is allowed while latched; any other is
        refused, also when an emergency stop comes first (:class:`EstopLatched`); it is started under the lock,
        unless it `locks_itself` (it raises :class:`Aborted` itself)."""
        self._manual(what, safe=darker)
        if darker:
            action()
        else:
            try:
                action() if locks_itself else self._act(action)
            except Aborted:
                raise EstopLatched(LATCHED) from None
        self._observe_source(**implied)

    def _stopped_where(self) -> str:
        """Where the stopped table is, in words, once it has come to rest (a profiled stop decelerates)."""
        table = self.devices.table
        try:
            deadline = time.monotonic() + 2.0
            while table.is_moving() and time.monotonic() < deadline:
                time.sleep(0.02)
            azimuth, zenith = table.position()
        except Exception as exc:  # noqa: BLE001 - the answer must still say the move did not end where asked
            return f"the table's position is unknown ({exc})"
        self._emit("table", azimuth_deg=azimuth, zenith_deg=zenith, moving=False)
        return f"the table stopped at azimuth {azimuth:.3f}°, zenith {zenith:.3f}°"

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
        with self._lock:
            if self._estop:
                raise EstopLatched(LATCHED)
            if self._executing or self._state is not EngineState.IDLE:
                raise IllegalTransition(f"cannot start a run: the engine is {self._state.value}")
            self._executing = True
            self._run_id = run_id
            self._pause = self._abort = False
        self._shutter_wanted = self._shutter_open = self._lamp_wanted = False
        self._done, self._lineage = set(done_keys), list(lineage) or [run_id]
        self._progress = (len(self._done), n_points)
        self._point_times = []
        self._pose, self._timing = None, False  # read afresh: the table may have been moved or reconfigured
        self._lineage_readings = None
        status, reason, unsafe = "completed", None, None
        answer, interrupt = None, None
        try:
            self._to(EngineState.RUNNING)
            self.catalogue.set_run_status(run_id, "running")
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
            problems = self._finalise()  # first: nothing the plan does on closing may keep the bench unsafe
            if problems:
                unsafe = "ended unsafe: " + "; ".join(problems)
                reason = f"{reason}; {unsafe}" if reason else unsafe
                self._journal("unsafe", unsafe)
                self._emit("unsafe", message=unsafe)
            try:
                plan.close()
            except Exception as exc:  # noqa: BLE001 - a plan that misbehaves while closing
                self._emit("warning", message=f"plan close: {exc}")
        try:
            if status == "completed" and on_completed is not None:
                try:
                    on_completed()
                except Exception as exc:  # noqa: BLE001 - a failed fit leaves the recorded data intact
                    self._journal_writer(BenchEvent("warning", run_id, {},
                                                    f"after the run: {type(exc).__name__}: {exc}", True))
            self.catalogue.set_run_status(run_id, status, reason)
        except Exception as exc:  # noqa: BLE001 - the catalogue itself failed (disk full …): say so, go idle
            status, reason = "failed", f"could not record the end of the run: {exc}"
        finally:
            with self._lock:  # whatever happened, the engine can take the next run, unless an e-stop is latched
                final = EngineState.ESTOP if self._estop else EngineState.IDLE
                previous, self._state = self._state, final
                self._run_id = None
                self._executing = False
                self._pause, self._abort = False, self._estop
                self._wake.notify_all()
            if previous is not final:
                try:
                    self._journal_writer(BenchEvent("state", run_id, {}, f"{previous.value} → {final.value}", True))
                except Exception:  # noqa: BLE001 - the catalogue may be what failed
                    pass
            self._emit("finished", status=status, reason=reason, unsafe=unsafe)
            self._emit("state", state=final.value, previous=previous.value)
        if interrupt is not None:
            raise interrupt
        return status

    def _enter(self, state: EngineState) -> None:
        try:
            self._to(state)
        except Exception:  # noqa: BLE001 - the end of a run must go on whatever the bookkeeping says
            pass

    def _finalise(self) -> list[str]:
        """Shutter closed, lamp at standby, table stopped — each tried even if another fails. Returns what could
        not be made safe, in words (empty: the bench is safe)."""
        problems = self._make_dark()
        error = self._safe("table", self.devices.table.stop)
        if error is not None:
            problems.append(f"the table could not be stopped ({error})")
        return problems

    def _make_dark(self, when: str = "finalisation") -> list[str]:
        """Shutter closed and lamp at standby; when the shutter cannot be closed, the lamp switched off instead
        (an arc lamp at standby keeps burning: with the shutter open it would go on lighting the sensor).
        Returns what could not be made safe, in words."""
        source = self.devices.source
        error = self._safe("shutter", source.close_shutter, when)
        if error is None:
            self._shutter_open = False
            self._safe("lamp", source.standby, when)  # the shutter is closed: a failed standby is a warning only
            self._observe_source(shutter_open=False)
            return []
        off = self._safe("lamp", source.lamp_off, when)
        if off is None:
            self._observe_source(lamp_on=False)
            return [f"the shutter did not close ({error}); the lamp was switched off instead"]
        return [f"the shutter did not close ({error}) and the lamp could not be switched off ({off}): "
                "the sensor may still be lit"]

    def _safe(self, what: str, action, when: str = "finalisation") -> Exception | None:
        """`action()`, its failure journaled as a warning and returned instead of raised (making the bench safe
        must go on)."""
        try:
            action()
        except Exception as exc:  # noqa: BLE001 - finalisation must go on
            try:
                self._emit("warning", message=f"{when}, {what}: {exc}", journal=self._run_id is not None)
            except Exception:  # noqa: BLE001 - the catalogue may be what failed
                pass
            return exc
        return None

    # -- what the engine reads, for a status view -------------------------------------------------------
    def _observe(self, kind: str, data: dict, *, flags=()) -> None:
        """Emit a reading the engine took (`kind` "source" or "sensor") unless one was emitted less than
        OBSERVE_PERIOD_S ago with the same `flags`."""
        now = time.monotonic()
        last = self._observed.get(kind)
        if last is not None and now - last[0] < OBSERVE_PERIOD_S and all(last[1].get(f) == data.get(f) for f in flags):
            return
        self._observed[kind] = (now, data)
        self._emit(kind, **data)

    def _observe_source(self, **implied) -> None:
        """After a lamp or shutter action: the source's status as it now reads, else what the action implies."""
        try:
            data = dataclasses.asdict(self.devices.source.status())
        except Exception:  # noqa: BLE001 - a source that cannot be read (the shutter that failed) tells no more
            data = implied
        self._observed.pop("source", None)
        self._observe("source", data)

    # -- messages --------------------------------------------------------------------------------------
    def _handle(self, msg):
        """Dispatch a plan message through :attr:`handlers` (its type → the method that executes it)."""
        if not isinstance(msg, (Log, Record, MayStopEarly)) and self._abort:
            raise Aborted()  # nothing acts on the bench once an abort or an emergency stop is asked for
        handler = self.handlers.get(type(msg))
        if handler is None:
            raise TypeError(f"the engine does not know the message {msg!r}")
        return handler(msg)

    def _on_measure(self, msg: Measure):
        return self._measure(msg.point)

    def _on_move(self, msg: Move) -> None:
        self._checkpoint()
        self._move(msg.azimuth_deg, msg.zenith_stage_deg)

    def _on_capture(self, msg: Capture) -> list[Reading]:
        self._checkpoint()  # no reading while an interlock holds or the bench is paused
        return [self._read(i) for i in range(msg.frames)]

    def _on_set_exposure(self, msg: SetExposure) -> float:
        actual = self.devices.sensor.set_exposure_ms(msg.exposure_ms)
        exposure = msg.exposure_ms if actual is None else actual
        self._emit("sensor", exposure_ms=exposure)
        return exposure

    def _on_set_temperature(self, msg: SetTemperature) -> float | None:
        """Set the sensor's temperature (its on-board thermal control) and wait until it is within the
        tolerance, watching for an abort; answers the temperature reached [°C]."""
        if msg.for_points and all(key in self._done for key in msg.for_points):
            return None  # a resumed run: the readings this temperature is for are recorded
        sensor = self.devices.sensor
        sensor.set_temperature_setpoint_c(msg.temperature_c)
        wall0, bench0 = time.monotonic(), self.clock()
        while True:
            temperature = float(sensor.temperature_c())
            self._observe("sensor", {"temperature_c": temperature})
            if abs(temperature - msg.temperature_c) <= msg.tolerance_c:
                return temperature
            bench = self.clock() - bench0
            if (bench if bench > 0 else time.monotonic() - wall0) > msg.timeout_s:
                raise DeviceTimeout(getattr(sensor, "name", "sensor"),
                                    f"the sensor reached {temperature:.2f} °C, not {msg.temperature_c:.2f} ± "
                                    f"{msg.tolerance_c:g} °C, in {msg.timeout_s:g} s")
            with self._lock:
                self._wake.wait(self.interlocks.poll_s)
            if self._abort:
                raise Aborted()

    def _on_set_disc_radius(self, msg: SetDiscRadius) -> float | None:
        """Move the Earth simulator's iris to the disc radius: started under the lock, waited for outside it (an abort
        or an emergency stop tells the iris to stop where it is and ends the run at once), for at most
        MOVE_TIMEOUT_FACTOR × the driver's expected duration + MOVE_TIMEOUT_MARGIN_S; answers the radius the source
        reports [°], checked against the tolerance."""
        if msg.for_points and all(key in self._done for key in msg.for_points):
            return None  # a resumed run: the readings this radius is for are recorded
        source = self.devices.source
        name = getattr(source, "name", "source")
        if not isinstance(source, EarthSimulator):
            raise DeviceFault(name, "the plan sets a disc radius: the bench's source must be an Earth simulator "
                                    "(devices.source.kind: earth)")
        self._checkpoint()  # no move while paused or held by an interlock
        expected = float(source.expected_iris_move_s(msg.radius_deg))
        timeout = MOVE_TIMEOUT_FACTOR * expected + MOVE_TIMEOUT_MARGIN_S
        self._act(lambda: source.set_disc_radius_deg(msg.radius_deg, wait=False))
        self._emit("source", iris_moving=True, target_disc_radius_deg=msg.radius_deg, expected_s=expected,
                   timeout_s=timeout)

        def stuck(elapsed: float) -> DeviceTimeout:
            try:
                where = f"it reads {source.disc_radius_deg():.4f}°"
            except Exception as exc:  # noqa: BLE001 - the timeout must still be reported
                where = f"its position is unknown ({exc})"
            return DeviceTimeout(name, f"iris not settled at its target {elapsed:.1f} s after the start of a move to "
                                       f"{msg.radius_deg:.4f}° that should take {expected:.1f} s (timeout "
                                       f"{timeout:.1f} s = {MOVE_TIMEOUT_FACTOR:g} × expected + "
                                       f"{MOVE_TIMEOUT_MARGIN_S:g} s); {where}: stuck? The iris was told to stop.")

        self._await(source.disc_settled, timeout, stuck, stop=("iris", source.stop_iris))
        radius = float(source.disc_radius_deg())
        self._emit("source", disc_radius_deg=radius, iris_moving=False)
        if not abs(radius - msg.radius_deg) <= msg.tolerance_deg:
            raise DeviceFault(name, f"the iris stopped at a disc radius of {radius:.5f}°, not {msg.radius_deg:.5f} ± "
                                    f"{msg.tolerance_deg:g}°")
        return radius

    def _on_lamp_on(self, msg: LampOn) -> None:
        self._lamp_wanted = True
        self.devices.source.lamp_on()
        self._observe_source(lamp_on=True)

    def _on_wait_warm(self, msg: WaitWarm) -> None:
        self._wait_warm()

    def _on_open_shutter(self, msg: OpenShutter) -> None:
        self._shutter_wanted = True
        self._checkpoint()  # opens it once nothing holds the bench

    def _on_close_shutter(self, msg: CloseShutter) -> None:
        self._shutter_wanted = False
        self.devices.source.close_shutter()
        self._shutter_open = False
        self._observe_source(shutter_open=False)

    def _on_record(self, msg: Record) -> None:
        self.catalogue.set_run_value(self._run_id, msg.key, msg.value)
        self._emit("record", key=msg.key, value=msg.value)  # a stage's result (the exposure, the centre …)

    def _on_log(self, msg: Log) -> None:
        self._emit("log", message=msg.message, journal=True)

    def _on_checkpoint(self, msg: Checkpoint) -> None:
        self._checkpoint()

    def _on_may_stop_early(self, msg: MayStopEarly) -> None:
        self._journal_writer(BenchEvent("log", self._run_id, {}, f"this plan may stop early ({msg.reason})", True))

    def _act(self, action) -> None:
        """Start an action on the bench unless an abort came first (an e-stop sets its flag under this lock). The
        action must return at once: a motion is started here and waited for outside the lock (:meth:`_await`)."""
        with self._lock:
            if self._abort:
                raise Aborted()
            action()

    def _await(self, done, timeout_s: float, timed_out, *, stop=None) -> None:
        """Poll `done()` every ``interlocks.poll_s``, outside the lock, until it is true. An abort or an emergency stop
        wakes the wait at once: `stop` = (what, action) is done (its failure journaled) and :class:`Aborted` raised.
        Past `timeout_s` of the bench's clock (the wall's while a simulated clock stands still, as a stuck motion
        makes it at time scale 0) `stop` is done and ``timed_out(elapsed_s)`` raised."""
        def halt(when: str) -> None:
            if stop is not None:
                self._safe(stop[0], stop[1], when)

        wall0, bench0 = time.monotonic(), self.clock()
        while not done():
            if self._abort:
                halt("emergency stop" if self._estop else "abort")
                raise Aborted()
            bench = self.clock() - bench0
            elapsed = bench if bench > 0 else time.monotonic() - wall0
            if elapsed > timeout_s:
                halt("timeout")
                raise timed_out(elapsed)
            with self._lock:
                if not self._abort:
                    self._wake.wait(self.interlocks.poll_s)
        if self._abort:
            raise Aborted()

    def _open_shutter(self) -> None:
        """Open the source's shutter. An Earth simulator's cover travels for a second or more (stuck: until its
        ``cover_timeout_s``): it is started under the lock and waited for outside it; a sun simulator's shutter opens
        at once."""
        source = self.devices.source
        if not isinstance(source, EarthSimulator):
            self._act(source.open_shutter)
            return
        self._act(lambda: source.open_shutter(wait=False))

        def stuck(elapsed: float) -> DeviceFault:
            try:
                where = f"it reads {source.cover_state()}"
            except Exception as exc:  # noqa: BLE001 - the fault must still be reported
                where = f"its state is unknown ({exc})"
            return DeviceFault(getattr(source, "name", "source"),
                               f"the cover did not open within {elapsed:.1f} s ({where}): stuck?")

        self._await(lambda: source.cover_state() == "OPEN", source.cover_timeout_s, stuck)

    def _timing_model(self) -> TimingModel | None:
        """The table's speeds as it reports them (asked once per run), None when it cannot tell both axes'."""
        if self._timing is False:
            try:
                azimuth, zenith = self.devices.table.expected_motion()
            except Exception:  # noqa: BLE001 - no speeds: the moves get the long timeout
                azimuth = zenith = None
            known = all(m is not None and m.rate_deg_s > 0 for m in (azimuth, zenith))
            self._timing = timing_from_motion(azimuth, zenith) if known else None
        return self._timing

    def move_timeout(self, start, end) -> tuple[float | None, float]:
        """(expected duration, timeout) of a table move between poses (azimuth_deg, zenith_stage_deg) [s].

        The expected duration is the table's trapezoidal move at its reported speeds plus settling
        (:meth:`bench.preflight.TimingModel.move_s`); the timeout is MOVE_TIMEOUT_FACTOR × that +
        MOVE_TIMEOUT_MARGIN_S. A table that cannot tell its speeds, or a move from an unknown pose, gets
        (None, UNKNOWN_MOVE_TIMEOUT_S).
        """
        timing = self._timing_model()
        if timing is None or start is None:
            return None, UNKNOWN_MOVE_TIMEOUT_S
        expected = timing.move_s(start, end)
        return expected, MOVE_TIMEOUT_FACTOR * expected + MOVE_TIMEOUT_MARGIN_S

    def _move(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Move the table, watching for an abort while it moves; a table still moving well past the move's
        expected duration (:meth:`move_timeout`) is stalled: it is stopped and the move faults."""
        table = self.devices.table
        start = self._pose
        if start is None:
            try:
                start = table.position()
            except Exception:  # noqa: BLE001 - the move itself will tell whether the table answers
                start = None
        expected, timeout = self.move_timeout(start, (azimuth_deg, zenith_deg))
        self._pose = None  # unknown until the table is seen still again
        self._act(lambda: table.move_to(azimuth_deg, zenith_deg, wait=False))
        here = {"azimuth_deg": start[0], "zenith_deg": start[1]} if start is not None else {}
        self._emit("table", moving=True, **here, target_azimuth_deg=azimuth_deg, target_zenith_deg=zenith_deg,
                   expected_s=expected, timeout_s=timeout)
        # elapsed time on the bench's clock (a simulation's runs at its time scale); a simulated clock at time
        # scale 0 stands still while nothing completes (a stalled axis), so then the wall clock counts
        wall0, bench0 = time.monotonic(), self.clock()
        next_report = wall0 + 0.25
        while table.is_moving():
            if self._abort:
                self._safe("table", table.stop, "move")
                raise Aborted()
            now = time.monotonic()
            bench = self.clock() - bench0
            elapsed = bench if bench > 0 else now - wall0
            if elapsed > timeout:
                self._safe("table", table.stop, "move")
                raise DeviceTimeout(table.name, f"table still moving {elapsed:.1f} s after the start of a move to "
                                                f"({azimuth_deg:.4f}°, {zenith_deg:.4f}°) that should take "
                                                + (f"{expected:.1f} s (timeout {timeout:.1f} s = "
                                                   f"{MOVE_TIMEOUT_FACTOR:g} × expected + {MOVE_TIMEOUT_MARGIN_S:g} s)"
                                                   if expected is not None else f"at most {timeout:.0f} s")
                                                + ": stalled? The table was stopped.")
            if now >= next_report:  # the table's position while it moves, for a status view
                next_report = now + 0.25
                try:
                    azimuth, zenith = table.position()
                    self._emit("table", azimuth_deg=azimuth, zenith_deg=zenith, moving=True)
                except Exception:  # noqa: BLE001 - a missed position is no reason to stop the move
                    pass
            with self._lock:
                self._wake.wait(0.005)
        if self._abort:  # an emergency stop stopped the table from its own thread: not a fault of the table
            raise Aborted()
        azimuth, zenith = table.position()  # a limit switch or a stall that stopped it short is a fault
        self._pose = (azimuth, zenith)
        self._emit("table", azimuth_deg=azimuth, zenith_deg=zenith, moving=False)
        off = max(abs((azimuth - azimuth_deg + 180.0) % 360.0 - 180.0), abs(zenith - zenith_deg))
        if off > self.ARRIVAL_TOLERANCE_DEG:
            raise DeviceFault(table.name, f"table stopped at ({azimuth:.4f}°, {zenith:.4f}°), "
                                          f"not at ({azimuth_deg:.4f}°, {zenith_deg:.4f}°)")

    def _wait_warm(self) -> None:
        """Wait for the lamp, watching for an abort (an arc lamp warms for half an hour)."""
        def pause(seconds):
            # the source was just read: lit, not warm yet, no fault (wait_until_warm raises otherwise)
            self._observe("source", {"lamp_on": True, "warm": False, "fault": False}, flags=("warm",))
            with self._lock:
                self._wake.wait(seconds)  # an abort wakes it at once
            if self._abort:
                raise Aborted()

        if self._abort:
            raise Aborted()
        self.devices.source.wait_until_warm(timeout_s=self.warm_timeout_s, poll_s=min(0.5, self.interlocks.poll_s),
                                            pause=pause)
        self._observe("source", {"lamp_on": True, "warm": True, "fault": False}, flags=("warm",))

    def _read(self, repeat: int) -> Reading:
        """One reading, taken as the run's family takes it (:attr:`bench.families.Family.read`)."""
        if self.family.reads_source:  # a reading that records what the source set (the Earth simulator's disc)
            reading = self.family.read(self.devices.sensor, repeat, self.clock, source=self.devices.source)
        else:
            reading = self.family.read(self.devices.sensor, repeat, self.clock)
        if reading.frame is not None:
            self.last_frame = reading.frame  # for a live view; never read by the engine itself
        return reading

    def _measure(self, point):
        if point.key in self._done:
            return self._recorded(point.key)
        while True:
            # a Measure is a Move and its readings (the same handlers as the messages), kept as one point
            started = time.time()
            t0 = time.monotonic()
            self._on_move(Move(point.azimuth_deg, point.zenith_stage_deg))
            readings = []
            for repeat in range(point.repeats):
                if self._abort or self._pause:
                    break
                readings.append(self._read(repeat))
            if len(readings) < point.repeats or self._interlock_tripped() is not None:
                self._emit("warning", message=f"point {point.key} interrupted; it will be measured again", journal=True)
                continue  # the checkpoint pauses or suspends; the point starts over
            zenith, azimuth = self.body_direction(point)
            readings = [dataclasses.replace(r, zenith_deg=zenith, azimuth_body_deg=azimuth) for r in readings]
            exposure = self._exposure()
            self._record(point, readings, started, exposure, zenith, azimuth)
            self._lineage_readings = None  # read again if a recorded point is asked for
            self._done.add(point.key)
            self._point_times.append(time.monotonic() - t0)
            done, total = len(self._done), self._progress[1]
            mean = float(np.mean(self._point_times[-20:]))
            self._emit("point", key=point.key, stage=point.stage, azimuth_deg=point.azimuth_deg,
                       zenith_stage_deg=point.zenith_stage_deg, zenith_deg=zenith, azimuth_body_deg=azimuth,
                       exposure_ms=exposure, index=done, total=total, eta_s=max(total - done, 0) * mean,
                       n_frames=len(readings), family=self.family.name, **self.family.summary(readings))
            return readings

    def _recorded(self, key: str) -> list[Reading]:
        """The readings the lineage recorded for a point (the answer to a Measure of a point already done).

        The lineage's readings are read from the catalogue once, not once per skipped point (a resumed run skips
        hundreds), and again only after the run recorded a point."""
        if self._lineage_readings is None:
            self._lineage_readings = {}
            for record in self.catalogue.readings(self._lineage):
                self._lineage_readings.setdefault(record.key, []).append(record)
        nan = float("nan")
        return [Reading(r.repeat, r.status, r.t_s or 0.0, dict(r.values), None,
                        r.zenith_deg if r.zenith_deg is not None else nan,
                        r.azimuth_body_deg if r.azimuth_body_deg is not None else nan)
                for r in self._lineage_readings.get(key, ())]

    def body_direction(self, point) -> tuple[float, float]:
        """The sun direction in the body frame the bench believes for a point (zenith, azimuth) [°]: seed 003's
        azimuth-on-zenith table through eq. 8 with the bench geometry, or an alt-az fork mount's two rotations
        (:mod:`calibration.mount`; the fork's angles are not the sun's, digest 002 §7 item 9).

        References
        ----------
        seed 003, eq. 8 (:func:`calibration.stage_geometry.body_direction_deg`); seed 002 §3.2.1.
        """
        if self.axis_order == "zenith-on-azimuth":
            fork = ForkMount(arm_ratio=arm_ratio(self.geometry.lever_arm_mm, self.geometry.source_distance_mm))
            zenith, azimuth = zenith_azimuth_from_vector(fork_vectors(point.azimuth_deg, point.zenith_stage_deg, fork))
        else:
            zenith, azimuth = body_direction_deg(point.azimuth_deg, point.zenith_stage_deg, self.geometry)
        return float(zenith), float(azimuth)

    def _record(self, point, readings, started, exposure_ms: float | None, zenith: float,
                azimuth_body: float) -> None:
        paths = self._save_frames(point, readings)
        rows = [{**r.values, "repeat": r.repeat, "status": r.status, "frame_path": paths.get(r.repeat), "t_s": r.t_s}
                for r in readings]
        self.catalogue.record_point(self._run_id, point.key, stage=point.stage, azimuth_deg=point.azimuth_deg,
                                    zenith_stage_deg=point.zenith_stage_deg, zenith_deg=zenith,
                                    azimuth_body_deg=azimuth_body, exposure_ms=exposure_ms,
                                    readings=rows, started_utc=started)

    def _exposure(self) -> float | None:
        if not self.family.has_exposure:
            return None
        try:
            return float(self.devices.sensor.exposure_ms())
        except Exception:  # noqa: BLE001 - the exposure is provenance, not worth a failed point
            return None

    def _save_frames(self, point, readings) -> dict[int, str]:
        if self.frames == "none" or not any(r.frame is not None for r in readings):
            return {}
        folder = self.catalogue.frames_dir(self._run_id)
        folder.mkdir(parents=True, exist_ok=True)
        name = _safe_name(point.key) + ".npz"
        arrays = {}
        for r in readings:
            frame = r.frame
            if frame is None:
                continue
            x, y = r.values.get("x_px"), r.values.get("y_px")  # a reading with a spot keeps the frame around it
            if self.frames == "roi" and r.ok and x is not None and y is not None and np.isfinite([x, y]).all():
                h, w = frame.shape
                x0 = int(min(max(round(x) - self.ROI_HALF_PX, 0), max(w - 2 * self.ROI_HALF_PX, 0)))
                y0 = int(min(max(round(y) - self.ROI_HALF_PX, 0), max(h - 2 * self.ROI_HALF_PX, 0)))
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
        if lock.lamp_fault and self._lamp_wanted:
            source = self.devices.source.status()
            self._observe("source", dataclasses.asdict(source), flags=("lamp_on", "warm", "shutter_open", "fault"))
            if source.fault:
                return "lamp fault"
        temperature = self.devices.sensor.temperature_c()
        self._observe("sensor", {"temperature_c": float(temperature) if np.isfinite(temperature) else None})
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
                self._open_shutter()
                self._shutter_open = True
                self._observe_source(shutter_open=True)
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
        # a shutter that cannot be closed fails the run, rather than hold it lit: finalisation puts the lamp out
        self.devices.source.close_shutter()
        self._shutter_open = False
        self._observe_source(shutter_open=False)
        self._safe("table", self.devices.table.stop, state.value)
        self._pose = None
        self._to(state)
        self.catalogue.set_run_status(self._run_id, state.value, reason)  # a reader beside the engine sees it too
        self._emit(state.value, message=reason, journal=True, reason=reason)
        self._clear_since = None
        with self._lock:
            while not self._abort and not cleared():
                self._wake.wait(self.interlocks.poll_s if state is EngineState.SUSPENDED else 0.5)
        if self._abort:
            raise Aborted()
        if self._lamp_wanted and not self.devices.source.status().lamp_on:
            self._act(self.devices.source.lamp_on)  # a lamp fault put the lamp out
            self._observe_source(lamp_on=True)
        if self._lamp_wanted:
            self._wait_warm()
        self._to(EngineState.RUNNING)
        self.catalogue.set_run_status(self._run_id, "running")
        self._emit("running", message=f"resumed after: {reason}", journal=True)
