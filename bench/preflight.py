"""Preflight: expand a plan without hardware, check every move against the limits, count, estimate.

The plan is driven by a dry executor that answers like the engine would (the exposure asked for, readings
with no position), so adaptive plans expand too. Every pose is checked against the table's limits and every disc
radius a plan sets against the Earth simulator's (:func:`disc_radius_check`). A plan with any violation is refused,
with the list of every violation, before anything moves (research note anchors-orchestration, lesson 9).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from calibration.design_of_experiments import move_time_s
from drivers.errors import LimitError
from drivers.interfaces import EarthSimulator

from .messages import (
    Capture,
    MayStopEarly,
    Measure,
    Move,
    Plan,
    Point,
    Reading,
    SetDiscRadius,
    SetExposure,
    SetTemperature,
    WaitWarm,
)


@dataclass(frozen=True)
class TimingModel:
    """How long things take on the bench, for the duration estimate.

    Attributes
    ----------
    rate_deg_s, accel_deg_s2 : float
        Zenith axis's speed [°/s] and acceleration [°/s²], and the azimuth axis's unless given apart.
    settle_s : float
        Settling after a move [s].
    frame_overhead_s : float
        Read-out, transfer and centroid per frame, beyond the exposure [s].
    warmup_s : float
        Lamp warm-up from cold [s].
    temperature_settle_s : float
        A sensor's thermal control reaching a new set-point (an upper estimate) [s].
    disc_settle_s : float
        An Earth simulator's iris moving to a new disc radius and settling (an upper estimate) [s].
    azimuth_rate_deg_s, azimuth_accel_deg_s2 : float or None
        The azimuth axis's speed and acceleration when they differ from the zenith axis's.

    The two axes move at once: a move takes the slower axis's trapezoidal move plus `settle_s`.
    """

    rate_deg_s: float = 10.0
    accel_deg_s2: float = 20.0
    settle_s: float = 0.05
    frame_overhead_s: float = 0.02
    warmup_s: float = 0.0
    temperature_settle_s: float = 180.0
    disc_settle_s: float = 30.0
    azimuth_rate_deg_s: float | None = None
    azimuth_accel_deg_s2: float | None = None

    @property
    def rates_deg_s(self) -> tuple[float, float]:
        """(azimuth, zenith) speeds [°/s]."""
        return (self.rate_deg_s if self.azimuth_rate_deg_s is None else self.azimuth_rate_deg_s, self.rate_deg_s)

    @property
    def accels_deg_s2(self) -> tuple[float, float]:
        """(azimuth, zenith) accelerations [°/s²]."""
        return (self.accel_deg_s2 if self.azimuth_accel_deg_s2 is None else self.azimuth_accel_deg_s2,
                self.accel_deg_s2)

    def move_s(self, start, end) -> float:
        """Duration of a table move between poses (azimuth_deg, zenith_stage_deg), settling included [s]."""
        return float(move_time_s(start, end, self.rates_deg_s, self.accels_deg_s2, self.settle_s))


def timing_from_table(table, base: TimingModel = TimingModel()) -> TimingModel:
    """`base` with the axes' speed and acceleration the connected table reports
    (:meth:`drivers.interfaces.RotaryTable.expected_motion`); what the table cannot tell stays `base`'s.

    A table that cannot be asked (a failing port) leaves the estimate at `base`: an estimate is no reason to
    refuse a campaign.
    """
    try:
        azimuth, zenith = table.expected_motion()
    except Exception:  # noqa: BLE001 - see the docstring
        return base
    return timing_from_motion(azimuth, zenith, base)


def timing_from_motion(azimuth, zenith, base: TimingModel = TimingModel()) -> TimingModel:
    """`base` with the (azimuth, zenith) :class:`~drivers.interfaces.AxisMotion` a table reported; an axis
    reported as None, or without a positive speed, keeps `base`'s."""
    zenith_rate = zenith.rate_deg_s if zenith and zenith.rate_deg_s > 0 else base.rate_deg_s
    zenith_accel = zenith.accel_deg_s2 if zenith and zenith.accel_deg_s2 else base.accel_deg_s2
    azimuth_rate = azimuth.rate_deg_s if azimuth and azimuth.rate_deg_s > 0 else base.rates_deg_s[0]
    azimuth_accel = azimuth.accel_deg_s2 if azimuth and azimuth.accel_deg_s2 else base.accels_deg_s2[0]
    return dataclasses.replace(base, rate_deg_s=zenith_rate, accel_deg_s2=zenith_accel,
                               azimuth_rate_deg_s=azimuth_rate, azimuth_accel_deg_s2=azimuth_accel)


@dataclass(frozen=True)
class PreflightReport:
    """What a plan will do.

    Attributes
    ----------
    points : list of Point
        Every recorded point, in order.
    n_frames : int
        Frames of the recorded points plus the probes.
    n_moves : int
    duration_s : float
        Estimated duration [s].
    violations : list of str
        Every move outside the limits and every other refusal; empty when the plan may run.
    warmup_s : float
        Of `duration_s`, the lamp's warm-up [s] (nothing when the lamp already burns).
    upper_bound : str or None
        Why the counts and the duration are upper bounds (a plan with a stopping rule, expanded to its cap),
        None when they are what the run will do.
    """

    points: list[Point]
    n_frames: int
    n_moves: int
    duration_s: float
    violations: list[str] = field(default_factory=list)
    warmup_s: float = 0.0
    upper_bound: str | None = None

    @property
    def ok(self) -> bool:
        return not self.violations


def disc_radius_check(source):
    """The check of a plan's disc radii on a bench whose source is `source`: an Earth simulator's soft limits
    (:meth:`drivers.interfaces.EarthSimulator.check_disc_radius`); on any other source every disc radius is refused.

    Returns
    -------
    callable (radius_deg) -> None
        Raises :class:`~drivers.errors.LimitError` for a radius the bench cannot set.
    """
    if isinstance(source, EarthSimulator):
        return source.check_disc_radius

    def refuse(radius_deg: float) -> None:
        raise LimitError(getattr(source, "name", "source"),
                         f"the plan sets a disc radius of {radius_deg:.4f}°, but the bench's source is not an Earth "
                         "simulator (devices.source.kind: earth)")
    return refuse


def preflight(plan: Plan, *, check, timing: TimingModel = TimingModel(), dry_reading=None,
              exposure_ms: float = 4.0, extra_violations=(), reading_s: float | None = None,
              check_radius=None) -> PreflightReport:
    """Expand `plan` with a dry executor.

    Parameters
    ----------
    plan : generator of messages
    check : callable (azimuth_deg, zenith_stage_deg) -> None
        Raises :class:`~drivers.errors.LimitError` for a pose outside the limits (``RotaryTable.check``).
    timing : TimingModel
    dry_reading : callable (repeat) -> Reading, optional
        What a reading answers in the dry run (the family's :attr:`~bench.families.Family.dry_reading`: for a
        CMOS sensor a spot at the auto-exposure's target, so it settles at once); default: an empty "ok".
    exposure_ms : float
        Exposure assumed until the plan sets one [ms].
    extra_violations : iterable of str
        Refusals found elsewhere (alignment) to report with the limit violations.
    reading_s : float, optional
        How long one reading takes [s] (the family's :attr:`~bench.families.Family.reading_s`: a scanning sensor's
        revolution); default the exposure plus the frame overhead.
    check_radius : callable (radius_deg) -> None, optional
        Raises :class:`~drivers.errors.LimitError` for a disc radius (:class:`~bench.messages.SetDiscRadius`) the
        bench cannot set (:func:`disc_radius_check`); default: radii are not checked (no bench at hand).
    """
    points: list[Point] = []
    violations = list(extra_violations)
    seen_poses, seen_radii = set(), set()
    n_frames = n_moves = 0
    duration = 0.0
    pose = (0.0, 0.0)
    exposure = exposure_ms

    def move(azimuth, zenith, label):
        nonlocal pose, duration, n_moves
        if (azimuth, zenith) not in seen_poses:
            seen_poses.add((azimuth, zenith))
            try:
                check(azimuth, zenith)
            except LimitError as exc:
                violations.append(f"{label} (azimuth {azimuth:g}°, zenith stage {zenith:g}°): {exc}")
        if (azimuth, zenith) != pose:
            n_moves += 1
            duration += timing.move_s(pose, (azimuth, zenith))
            pose = (azimuth, zenith)

    def frames(n):
        nonlocal n_frames, duration
        n_frames += n
        duration += n * (reading_s if reading_s is not None else exposure / 1000.0 + timing.frame_overhead_s)
        return [dry_reading(i) if dry_reading is not None else Reading(i, "ok") for i in range(n)]

    warmup = 0.0
    upper_bound = None
    answer = None
    while True:
        try:
            msg = plan.send(answer)
        except StopIteration:
            break
        answer = None
        if isinstance(msg, Move):
            move(msg.azimuth_deg, msg.zenith_stage_deg, "move")
        elif isinstance(msg, Measure):
            points.append(msg.point)
            move(msg.point.azimuth_deg, msg.point.zenith_stage_deg, f"point {msg.point.key}")
            answer = frames(msg.point.repeats)
        elif isinstance(msg, Capture):
            answer = frames(msg.frames)
        elif isinstance(msg, SetExposure):
            exposure = answer = msg.exposure_ms
        elif isinstance(msg, SetTemperature):
            duration += timing.temperature_settle_s
            answer = msg.temperature_c
        elif isinstance(msg, SetDiscRadius):
            duration += timing.disc_settle_s
            answer = msg.radius_deg
            if check_radius is not None and msg.radius_deg not in seen_radii:
                seen_radii.add(msg.radius_deg)
                try:
                    check_radius(msg.radius_deg)
                except LimitError as exc:
                    violations.append(f"disc radius {msg.radius_deg:.4f}° (for {len(msg.for_points)} point(s)): "
                                      f"{exc}")
        elif isinstance(msg, WaitWarm):
            duration += timing.warmup_s
            warmup += timing.warmup_s
        elif isinstance(msg, MayStopEarly):
            upper_bound = msg.reason
    keys = [p.key for p in points]
    if len(set(keys)) != len(keys):
        violations.append("plan error: a point key appears twice")
    return PreflightReport(points, n_frames, n_moves, duration, violations, warmup, upper_bound)


def preflight_campaign(campaign, *, check, timing: TimingModel = TimingModel(), mount=None,
                       extra_violations=(), check_radius=None) -> PreflightReport:
    """Dry-run the plan a campaign names, for one sensor, with the readings its sensor family answers dry
    (`mount`: the table's kinematics, :func:`bench.families.table_mount`; `check_radius`: the source's disc radii,
    :func:`disc_radius_check`)."""
    from .families import family_of_plan

    family = family_of_plan(campaign.plan)
    return preflight(family.make_plan(campaign, timing=timing, mount=mount), check=check, timing=timing,
                     dry_reading=lambda i: family.dry_reading(i, campaign), extra_violations=extra_violations,
                     reading_s=family.reading_s, check_radius=check_radius)
