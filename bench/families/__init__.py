"""Sensor families: what the bench needs to know of each kind of sensor, in one registry entry.

The engine, the catalogue, the event stream, preflight, crash-resume and the dashboard's run pages know
nothing family-specific (DESIGN.md, "Sensor families"): they work from a :class:`Family`, chosen by the bench
file's sensor kind and recorded with every run. A family says

* what one reading is (its :class:`~bench.descriptor.ReadingDescriptor`),
* how the engine takes one reading from the family's driver (`read`) and what a point's readings show in
  the event stream (`summary`), and what preflight answers in their place (`dry_reading`),
* which plans it runs (the campaign's ``plan`` names) and how a campaign becomes a plan (`make_plan`),
* which fits run when a run ends (`fit_run`),
* which results view the dashboard shows (`results_view`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..descriptor import ReadingDescriptor


@dataclass(frozen=True)
class Family:
    """One sensor family's registry entry (see the module docstring).

    Attributes
    ----------
    name : str
        "cmos", "qd", "camera" … (the bench file's ``devices.sensor.kind``, the catalogue's ``runs.family``).
    title : str
        For people ("CMOS pinhole sun sensor (seed 003)").
    descriptor : ReadingDescriptor
    plans : tuple of str
        The campaign plans this family runs.
    read : callable
        ``read(sensor, repeat, clock) -> bench.messages.Reading``: one reading from the family's driver.
    dry_reading : callable
        ``dry_reading(repeat, campaign) -> Reading``: what preflight answers for a reading (no bench).
    summary : callable
        ``summary(readings) -> dict``: what a point's readings add to its ``point`` event (live views).
    status : callable
        ``status(sensor) -> dict``: the sensor's state for the status view while no run owns the bench.
    make_plan : callable
        ``make_plan(campaign, *, timing, mount) -> Plan``: `mount` is the table's kinematics
        (:func:`table_mount`), for plans set in the sensor's own angles.
    fit_run : callable
        ``fit_run(catalogue, run_id, campaign, inputs, journal) -> list``: the fits when a run ends (`inputs`
        from `fit_inputs`; what they found goes to ``journal(kind, message)``, the engine's journaled events).
    fit_inputs : callable
        ``fit_inputs(session) -> Any``: what the fits need of the bench (design, geometry prior …).
    results_view : str
        The dashboard's results view for the family's runs.
    export_csv : callable
        ``export_csv(catalogue, run_ids, target, sensor_id)``: the runs' bench data as the CSV that
        ``sunbench fit <family>`` reads.
    c_header : callable
        ``c_header(document) -> str``: a calibration document of the family as a C header.
    sensor_kinds : tuple of str
        The bench file's ``devices.sensor.kind`` values whose sensor this family reads.
    has_exposure : bool
        Its sensor is an image sensor with an exposure time (frames for a live view).
    reads_source : bool
        Its `read` takes the bench's source too, ``read(sensor, repeat, clock, source=…)``, to record what the source
        set with each reading (the Earth simulator's disc radius).
    reading_s : float or None
        How long one reading takes on the bench [s], for preflight's estimate; None: an image sensor's, the exposure
        plus the read-out (:attr:`bench.preflight.TimingModel.frame_overhead_s`).
    """

    name: str
    title: str
    descriptor: ReadingDescriptor
    plans: tuple[str, ...]
    read: Callable[..., Any]
    dry_reading: Callable[..., Any]
    summary: Callable[..., dict]
    status: Callable[..., dict]
    make_plan: Callable[..., Any]
    fit_run: Callable[..., list]
    fit_inputs: Callable[..., Any]
    results_view: str
    export_csv: Callable[..., None]
    c_header: Callable[..., str]
    sensor_kinds: tuple[str, ...] = ()
    has_exposure: bool = False
    reads_source: bool = False
    reading_s: float | None = None


_FAMILIES: dict[str, Family] = {}


def register(family: Family) -> Family:
    if family.name in _FAMILIES and _FAMILIES[family.name] is not family:
        raise ValueError(f"the sensor family {family.name!r} is already registered")
    if family.descriptor.family != family.name:
        raise ValueError(f"family {family.name!r} declares a reading of family {family.descriptor.family!r}")
    _FAMILIES[family.name] = family
    return family


def family(name: str) -> Family:
    """The registered family `name`; KeyError naming the known ones."""
    _load()
    try:
        return _FAMILIES[name]
    except KeyError:
        raise KeyError(f"no sensor family {name!r} (known: {', '.join(sorted(_FAMILIES))})") from None


def families() -> dict[str, Family]:
    _load()
    return dict(_FAMILIES)


def family_of_plan(plan: str) -> Family:
    """The family that runs the campaign plan `plan`."""
    for f in families().values():
        if plan in f.plans:
            return f
    raise KeyError(f"no sensor family runs the plan {plan!r}")


def family_of_sensor(kind: str) -> Family:
    """The family that reads a sensor of the bench file's kind `kind`."""
    for f in families().values():
        if kind in f.sensor_kinds:
            return f
    raise KeyError(f"no sensor family reads a {kind!r} sensor")


def journal_fit(journal: Callable[[str, str], Any], summary: str, rejected, warnings, unit: str) -> None:
    """What the fits at a run's end found, as ``fit`` lines of `journal(kind, message)`: `summary`, the readings
    the fit `rejected` (counted in `unit`s, the first ten described) and its `warnings`."""
    journal("fit", summary)
    if rejected:
        journal("fit", f"{len(rejected)} {unit}(s) rejected: " + "; ".join(r.describe() for r in rejected[:10])
                + (" …" if len(rejected) > 10 else ""))
    for warning in warnings:
        journal("fit", f"warning: {warning}")


def table_mount(axis_order: str, geometry):
    """The table's kinematics as the plans set directions through it: seed 003's azimuth-on-zenith table (with
    its lever arm, :class:`calibration.stage_geometry.StageGeometry`) or an alt-az fork
    (:class:`calibration.mount.ForkMount`)."""
    from calibration.mount import ForkMount
    from calibration.stage_geometry import StageGeometry, arm_ratio

    q = arm_ratio(geometry.lever_arm_mm, geometry.source_distance_mm)
    return ForkMount(arm_ratio=q) if axis_order == "zenith-on-azimuth" else StageGeometry(q)


def _load() -> None:
    # the families register themselves on import; imported here, late, because they import the bench modules
    # that import this registry
    from . import camera, cmos, css, horizon, qd  # noqa: F401
