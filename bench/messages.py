"""The small vocabulary of messages a calibration plan yields and the run engine executes.

A plan is a generator of these messages (Bluesky's idea, research note anchors-orchestration lesson 1):
the same plan can be run by the engine, dry-run by the preflight (which answers with synthetic readings),
limit-checked and unit-tested by asserting on the messages, with no hardware. The value a plan gets back
from ``yield`` is the engine's answer (the readings of a ``Measure``, the exposure actually set …).
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Point:
    """One table pose of a plan and the frames to take there.

    Attributes
    ----------
    key : str
        Identity of the point within its plan, stable across runs (resume skips keys already recorded).
    stage : str
        Which part of the procedure ("centre", "tilt", "grid" …).
    azimuth_deg : float
        Azimuth-stage angle [°].
    zenith_stage_deg : float
        Zenith-stage angle Ω [°] (the true incidence follows seed 003 eq. 8, or an alt-az fork's rotations).
    repeats : int
        Readings to take.
    """

    key: str
    stage: str
    azimuth_deg: float
    zenith_stage_deg: float
    repeats: int = 1


@dataclass(frozen=True)
class Reading:
    """One reading of the sensor, as its family declares it (:mod:`bench.descriptor`).

    Attributes
    ----------
    repeat : int
    status : str
        "ok" or the name of what went wrong (a centroid error, a saturated channel …).
    t_s : float
        Time of the reading on the bench clock [s].
    values : dict
        The family's fields (the CMOS spot centre ``x_px, y_px, peak_dn, n_pixels, flags``; the QD currents …);
        a missing number is NaN or None.
    frame : ndarray or None
        The image behind the reading (image families), kept as a file, never in the catalogue.
    zenith_deg, azimuth_body_deg : float
        The sun direction in the sensor body frame the bench believes for the point's table angles (through
        the table's kinematics, :meth:`bench.engine.RunEngine.body_direction`), as the engine records it [°];
        NaN where no bench answered (preflight).
    """

    repeat: int
    status: str
    t_s: float = 0.0
    values: dict = field(default_factory=dict, compare=False)
    frame: np.ndarray | None = field(default=None, compare=False, repr=False)
    zenith_deg: float = float("nan")
    azimuth_body_deg: float = float("nan")

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def value(self, name: str, default: Any = float("nan")) -> Any:
        """A field of the family's reading; `default` when missing."""
        v = self.values.get(name)
        return default if v is None else v


class Msg:
    """Base class of plan messages."""


@dataclass(frozen=True)
class Log(Msg):
    message: str


@dataclass(frozen=True)
class LampOn(Msg):
    """Switch the sun simulator on (no-op if it burns)."""


@dataclass(frozen=True)
class WaitWarm(Msg):
    """Wait until the lamp is warm."""


@dataclass(frozen=True)
class OpenShutter(Msg):
    pass


@dataclass(frozen=True)
class CloseShutter(Msg):
    pass


@dataclass(frozen=True)
class Move(Msg):
    """Move the table (limits are checked first) and wait until it stops."""

    azimuth_deg: float
    zenith_stage_deg: float


@dataclass(frozen=True)
class SetExposure(Msg):
    """Set the sensor's exposure [ms]; the answer is what the sensor set."""

    exposure_ms: float


@dataclass(frozen=True)
class SetTemperature(Msg):
    """Set the sensor's temperature (its on-board thermal control) and wait until it is within `tolerance_c`;
    the answer is the temperature reached [°C]. A sensor still off after `timeout_s` faults the run. When every
    point of `for_points` is already recorded (a resumed run), nothing is set and the answer is None: minutes of
    waiting on a thermal controller for readings that are kept."""

    temperature_c: float
    tolerance_c: float = 0.2
    timeout_s: float = 900.0
    for_points: tuple[str, ...] = ()


@dataclass(frozen=True)
class SetDiscRadius(Msg):
    """Set the Earth simulator's disc radius (its iris) and wait until it has settled within `tolerance_deg`; the
    answer is the radius the source reports [°]. A source that is no Earth simulator, or an iris that stops off the
    target, faults the run. When every point of `for_points` is already recorded (a resumed run), nothing is set and
    the answer is None."""

    radius_deg: float
    tolerance_deg: float = 0.02
    for_points: tuple[str, ...] = ()


@dataclass(frozen=True)
class Capture(Msg):
    """Take readings where the table is and answer them (not recorded: probes, auto-exposure)."""

    frames: int = 1


@dataclass(frozen=True)
class Measure(Msg):
    """A recorded point: a checkpoint, the move, `point.repeats` readings, one catalogue transaction.

    The answer is the point's readings. A point already recorded by this run's lineage is not measured again:
    the engine answers with the recorded readings.
    """

    point: Point


@dataclass(frozen=True)
class Record(Msg):
    """Keep a value the run decided (chosen exposure, tilt-stage result) in the catalogue."""

    key: str
    value: Any


@dataclass(frozen=True)
class MayStopEarly(Msg):
    """The plan may end before its last point (a stopping rule decides on the readings).

    The engine only logs it; preflight, whose dry readings decide nothing, expands every point and reports its
    counts and duration as upper bounds, with `reason`.
    """

    reason: str


@dataclass(frozen=True)
class Checkpoint(Msg):
    """A place where the run may pause (every Measure is one too)."""


Plan = Generator[Msg, Any, Any]
