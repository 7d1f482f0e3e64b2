"""Calibration plans: generators of :mod:`bench.messages`, executed by the run engine.

* :func:`seed003_plan` — the seed 003 procedure: alignment check (preflight), lamp and shutter, auto-exposure,
  centre stage (8 azimuths × 5 frames at normal incidence), tilt stage of the revised procedure (§4.4–4.5),
  grid stage (8 azimuths × zenith 0–60° in 10° steps × 4 frames, all azimuths at each zenith).
* :func:`grid_plan` — a plain grid.
* :func:`physical_plan` — the physical model's procedure: D-optimal directions in batches along a short table
  tour, a fit after each batch, stopped once the parameters and the check directions meet their targets.

Point keys are built from the stage and the angles only, so a plan expands to the same keys every time and
a resumed run can skip what its lineage already recorded.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from calibration.data import BenchData
from calibration.design import FULL_SCALE_DN, BenchGeometry
from calibration.design_of_experiments import design_experiment, order_tour, parameter_targets, stopping_decision
from calibration.procedure import centre_crossing_deg, tilt_harmonic_deg

from .campaign import Alignment, AutoExposure, Campaign, GridProcedure, PhysicalProcedure, Seed003Procedure
from .families.cmos import EDGE_FLAGS  # a spot cut by the frame's edge: recorded, never fitted
from .messages import (
    Capture,
    CloseShutter,
    LampOn,
    Log,
    MayStopEarly,
    Measure,
    Move,
    OpenShutter,
    Plan,
    Point,
    Record,
    SetExposure,
    WaitWarm,
)
from .preflight import TimingModel

# seed 003 §4.1 alignment tolerances
LATERAL_TOLERANCE_MM = 0.5
HEIGHT_TOLERANCE_MM = 0.5
DISTANCE_TOLERANCE_MM = 5.0


def point_key(stage: str, azimuth_deg: float, zenith_stage_deg: float) -> str:
    return f"{stage}/zen={zenith_stage_deg:+08.3f}/az={azimuth_deg:07.3f}"


def alignment_violations(alignment: Alignment | None, geometry: BenchGeometry) -> list[str]:
    """The seed 003 §4.1 alignment checks that fail, each with the corrective move.

    |L1 − L2| ≤ 0.5 mm (move the mechanism by ΔL = L2 − L1), |h1 − h2| ≤ 0.5 mm (Δh = h2 − h1),
    |L − source distance| ≤ 5 mm.
    """
    if alignment is None:
        return []
    problems = []
    if abs(alignment.l1_mm - alignment.l2_mm) > LATERAL_TOLERANCE_MM:
        problems.append(f"alignment: |L1 − L2| = {abs(alignment.l1_mm - alignment.l2_mm):.2f} mm > "
                        f"{LATERAL_TOLERANCE_MM} mm; move the mechanism by "
                        f"ΔL = {alignment.l2_mm - alignment.l1_mm:+.2f} mm")
    if abs(alignment.h1_mm - alignment.h2_mm) > HEIGHT_TOLERANCE_MM:
        problems.append(f"alignment: |h1 − h2| = {abs(alignment.h1_mm - alignment.h2_mm):.2f} mm > "
                        f"{HEIGHT_TOLERANCE_MM} mm; move the mechanism by "
                        f"Δh = {alignment.h2_mm - alignment.h1_mm:+.2f} mm")
    if abs(alignment.distance_mm - geometry.source_distance_mm) > DISTANCE_TOLERANCE_MM:
        problems.append(f"alignment: sensor-to-simulator distance {alignment.distance_mm:.1f} mm differs from the "
                        f"bench's {geometry.source_distance_mm:.1f} mm by more than {DISTANCE_TOLERANCE_MM} mm")
    return problems


def auto_exposure(spec: AutoExposure, full_scale_dn: float) -> Plan:
    """Find an exposure that puts the spot's peak near the target fraction of full scale.

    No spot → ×4; saturated → ÷3; otherwise scale by target / measured (the response is linear). Answers
    the exposure [ms]; raises :class:`PlanError` when no exposure in range works.

    References
    ----------
    seed 003, §4.2 step 0 (raise the exposure when there is no source, lower it on flare); the thesis gives
    no steps or limits, these are ours.
    """
    exposure = spec.start_ms
    for _ in range(spec.max_steps):
        exposure = yield SetExposure(exposure)
        reading = (yield Capture(1))[0]
        if reading.status == "NoSpotError":
            wanted = exposure * 4.0
        elif reading.status == "SaturatedSpotError":
            wanted = exposure / 3.0
        elif reading.ok:
            fraction = reading.value("peak_dn") / full_scale_dn
            if abs(fraction - spec.target_peak_fraction) <= spec.tolerance * spec.target_peak_fraction:
                yield Record("exposure_ms", exposure)
                return exposure
            wanted = exposure * spec.target_peak_fraction / max(fraction, 1e-3)
        else:
            raise PlanError(f"auto-exposure: the frame shows {reading.status}; fix the bench before a run")
        if (wanted > spec.max_ms and exposure >= spec.max_ms) or (wanted < spec.min_ms and exposure <= spec.min_ms):
            raise PlanError(f"auto-exposure: no exposure in [{spec.min_ms}, {spec.max_ms}] ms gives a usable spot "
                            f"(last: {reading.status} at {exposure} ms)")
        exposure = float(np.clip(wanted, spec.min_ms, spec.max_ms))
    raise PlanError(f"auto-exposure did not settle in {spec.max_steps} steps")


class PlanError(RuntimeError):
    """A plan cannot go on (no usable exposure, a stage that found nothing)."""


def _mean_spot(readings) -> np.ndarray | None:
    ok = [(r.value("x_px"), r.value("y_px")) for r in readings if r.ok and np.isfinite(r.value("x_px"))]
    return np.mean(ok, axis=0) if ok else None


def centre_stage(azimuths, repeats: int) -> Plan:
    """Stage 1: normal incidence at every azimuth; answers the centre (x0, y0) [px] or None.

    References
    ----------
    seed 003, §4.2 stage 1 (8 azimuths × 5 frames, x0, y0 = the mean of the 40 centres).
    """
    readings = []
    for azimuth in azimuths:
        readings += (yield Measure(Point(point_key("centre", azimuth, 0.0), "centre", azimuth, 0.0, repeats)))
    centre = _mean_spot(readings)
    yield Record("centre_px", None if centre is None else [float(centre[0]), float(centre[1])])
    return centre


def tilt_stage(azimuths, probe_deg: float, repeats: int, centre) -> Plan:
    """Stage 2 of the revised procedure: along each azimuth, the zenith-stage angle that brings the spot back
    onto the centre found in stage 1.

    Each azimuth is probed at Ω = ±`probe_deg`; the angle where the spot crosses the centre is interpolated
    (:func:`calibration.procedure.centre_crossing_deg`). The first harmonic of those angles over azimuth
    (:func:`calibration.procedure.tilt_harmonic_deg`) gives the bench's non-parallelism (its mean; seed 003
    found 0.47°) and the tilt seen along 0° (α) and 90° (β) (eqs. 14–15).

    References
    ----------
    seed 003, §4.4–4.5 and Fig. 4.12.
    """
    offsets = {}
    for azimuth in azimuths:
        spots = []
        for omega in (-probe_deg, probe_deg):
            readings = yield Measure(Point(point_key("tilt", azimuth, omega), "tilt", azimuth, omega, repeats))
            spots.append(_mean_spot(readings))
        if centre is None or spots[0] is None or spots[1] is None:
            continue
        offset = float(centre_crossing_deg(spots[0], spots[1], centre, probe_deg))
        if np.isfinite(offset):  # NaN: the spot did not move
            offsets[azimuth] = offset
    result = None
    if len(offsets) >= 3:
        mean, alpha, beta = tilt_harmonic_deg(list(offsets), list(offsets.values()))
        result = {"offsets_deg": {f"{a:g}": v for a, v in offsets.items()}, "mean_offset_deg": mean,
                  "tilt_x_deg": alpha, "tilt_y_deg": beta}
    yield Record("tilt_stage", result)
    return result


def grid_stage(azimuths, zeniths, repeats: int, *, stage: str = "grid", order: str = "zenith-outer") -> Plan:
    """Stage 2 of seed 003 (3 of the revised procedure): the grid, zenith outer loop and every azimuth at each
    zenith by default (the optimised order of §4.2).

    References
    ----------
    seed 003, §4.2 stage 2 (8 azimuths × zenith 0–60° in 10° steps, 4 frames each).
    """
    pairs = ([(z, a) for z in zeniths for a in azimuths] if order == "zenith-outer"
             else [(z, a) for a in azimuths for z in zeniths])
    for zenith, azimuth in pairs:
        yield Measure(Point(point_key(stage, azimuth, zenith), stage, azimuth, zenith, repeats))


def _light_up(exposure_spec: AutoExposure, full_scale_dn: float) -> Plan:
    yield LampOn()
    yield WaitWarm()
    yield OpenShutter()
    yield Move(0.0, 0.0)
    return (yield from auto_exposure(exposure_spec, full_scale_dn))


def seed003_plan(procedure: Seed003Procedure, *, full_scale_dn: float = FULL_SCALE_DN) -> Plan:
    """The seed 003 calibration procedure (module docstring)."""
    azimuths = list(procedure.azimuths_deg)
    yield Log(f"seed 003 procedure: {len(azimuths)} azimuths, zenith stage {list(procedure.zenith_stage_deg)}°")
    yield from _light_up(procedure.auto_exposure, full_scale_dn)
    centre = yield from centre_stage(azimuths, procedure.centre_repeats)
    if procedure.tilt_stage:
        yield from tilt_stage(azimuths, procedure.tilt_probe_deg, procedure.tilt_repeats, centre)
    yield from grid_stage(azimuths, procedure.zenith_stage_deg, procedure.repeats)
    yield CloseShutter()


def grid_plan(procedure: GridProcedure, *, full_scale_dn: float = FULL_SCALE_DN) -> Plan:
    """A plain grid of every azimuth at every zenith-stage angle."""
    yield from _light_up(procedure.auto_exposure, full_scale_dn)
    yield from grid_stage(procedure.azimuths_deg, procedure.zenith_stage_deg, procedure.repeats, order=procedure.order)
    yield CloseShutter()


def bench_data_of(readings) -> BenchData:
    """The fittable frames of readings answered by the engine: a spot, not flagged as cut by an edge, and the
    body direction the bench believes (the dry readings of preflight have neither, so they give no data)."""
    rows = [r for r in readings
            if r.ok and np.isfinite(r.value("x_px")) and np.isfinite(r.value("y_px"))
            and not int(r.value("flags", 0)) & EDGE_FLAGS
            and np.isfinite(r.zenith_deg) and 0.0 <= r.zenith_deg < 90.0 and np.isfinite(r.azimuth_body_deg)]
    pose = lambda name: np.array([getattr(r, name) for r in rows], dtype=float)  # noqa: E731
    spot = lambda name: np.array([r.value(name) for r in rows], dtype=float)  # noqa: E731
    return BenchData(pose("zenith_deg"), pose("azimuth_body_deg"), spot("x_px"), spot("y_px"),
                     repeat=np.array([r.repeat for r in rows], dtype=int))


def _stage_point(stage: str, zenith_deg: float, azimuth_deg: float, repeats: int) -> Point:
    # the design's body zenith is set as the stage angle Ω: eq. 8 moves it by < 1° on a bench whose source is
    # metres away, and the poses stay independent of the bench file, so preflight checks what the run visits
    azimuth, omega = round(float(azimuth_deg), 3), round(float(zenith_deg), 3)
    return Point(point_key(stage, azimuth, omega), stage, azimuth, omega, repeats)


def physical_plan(procedure: PhysicalProcedure, *, full_scale_dn: float = FULL_SCALE_DN,
                  timing: TimingModel = TimingModel()) -> Plan:
    """The physical model's procedure (issue 9): light up, then measure D-optimal directions batch by batch.

    1. Light up and auto-exposure at normal incidence, as seed 003 §4.2 step 0.
    2. Batch 1: the first `first_batch` directions of the greedy D-optimal design (normal incidence first,
       where the table already is) and the `check_directions` check directions, in the order of a short
       table tour (:func:`calibration.design_of_experiments.order_tour` with `timing`'s axis speeds).
    3. After each batch, :func:`calibration.design_of_experiments.stopping_decision` fits the physical model to
       the fit directions measured so far and scores it on the check directions, which it never fits. The
       decision is recorded (``physical_batch_<k>``) and logged; the run stops once every parameter's 1σ is
       below its target and the check RMS is at most `check_rms_target_deg`.
    4. Otherwise the next `batch_size` directions of the design, toured from where the table is, up to
       `max_batches` batches. The final decision is recorded as ``physical_stop``.

    In preflight the readings have no spot, so nothing is fitted and the plan expands to every batch: its
    counts and duration are the upper bound (the plan says so with :class:`MayStopEarly`).

    References
    ----------
    Atkinson, Donev & Tobias, *Optimum Experimental Designs* (2007), ch. 12 and 17 (sequential locally
    D-optimal designs); seed 003 §4.2 (the grid it replaces: 80 poses, 312 frames).
    """
    design = design_experiment(first_batch=procedure.first_batch, batch_size=procedure.batch_size,
                               max_batches=procedure.max_batches, n_check=procedure.check_directions,
                               zenith_max_deg=procedure.zenith_max_deg, zenith_step_deg=procedure.zenith_step_deg,
                               azimuth_step_deg=procedure.azimuth_step_deg, margin_px=procedure.edge_margin_px)
    targets = {**parameter_targets(procedure.parameter_budget_deg, zenith_max_deg=procedure.zenith_max_deg),
               **procedure.parameter_targets}
    n_batches = len(design.batches)
    yield Log(f"physical procedure: at most {design.n_fit} D-optimal directions in {n_batches} batch(es) and "
              f"{design.n_check} check directions, {procedure.repeats} frames each; it stops once every "
              f"parameter's 1σ is below its target and the check RMS is ≤ {procedure.check_rms_target_deg}°")
    yield MayStopEarly(f"the physical plan stops after the first of its {n_batches} batches whose fit meets the "
                       "targets")
    yield Record("physical_design", {
        "fit_directions_deg": [[float(z), float(a)] for z, a in zip(design.zenith_deg, design.azimuth_deg)],
        "check_directions_deg": [[float(z), float(a)] for z, a in zip(design.check_zenith_deg,
                                                                      design.check_azimuth_deg)],
        "batches": [list(b) for b in design.batches], "log_det": list(design.log_det),
        "parameter_targets": targets, "check_rms_target_deg": procedure.check_rms_target_deg})
    yield from _light_up(procedure.auto_exposure, full_scale_dn)
    fit_readings, check_readings = [], []
    pose = (0.0, 0.0)  # the light-up leaves the table at normal incidence
    for number, (first, end) in enumerate(design.batches, start=1):
        points = [_stage_point("physical", z, a, procedure.repeats)
                  for z, a in zip(design.zenith_deg[first:end], design.azimuth_deg[first:end])]
        if number == 1:
            points += [_stage_point("check", z, a, procedure.repeats)
                       for z, a in zip(design.check_zenith_deg, design.check_azimuth_deg)]
        poses = [(p.azimuth_deg, p.zenith_stage_deg) for p in points]
        for index in order_tour(poses, pose, rates_deg_s=timing.rates_deg_s, accels_deg_s2=timing.accels_deg_s2,
                                settle_s=timing.settle_s):
            point = points[index]
            readings = yield Measure(point)
            # keep the centroids, not the frames (0.6 MB each): the whole plan's would be ~100 MB
            kept = [dataclasses.replace(r, frame=None) for r in readings]
            (check_readings if point.stage == "check" else fit_readings).extend(kept)
            pose = poses[index]
        decision = stopping_decision(bench_data_of(fit_readings), bench_data_of(check_readings),
                                     check_rms_target_deg=procedure.check_rms_target_deg, targets=targets)
        yield Record(f"physical_batch_{number}", decision.to_dict())
        yield Log(f"batch {number}/{n_batches}: {decision.summary()}")
        if decision.stop:
            break
    final = decision.to_dict()  # the design has at least one batch
    if decision.stop:
        final["reason"] = "targets met"
        message = f"stopped after batch {number} of {n_batches}: every target met"
    else:
        final["reason"] = "cap reached"
        message = (f"all {n_batches} batches measured (the cap) without meeting every target: "
                   + "; ".join(decision.reasons))
    final["batches_measured"] = number
    yield Record("physical_stop", final)
    yield Log(message)
    yield CloseShutter()


def make_plan(campaign: Campaign, *, full_scale_dn: float = FULL_SCALE_DN, timing: TimingModel | None = None) -> Plan:
    """The plan a campaign names. `timing` (the table's axis speeds) orders the physical plan's tour."""
    if campaign.plan == "seed003":
        return seed003_plan(campaign.seed003, full_scale_dn=full_scale_dn)
    if campaign.plan == "physical":
        return physical_plan(campaign.physical, full_scale_dn=full_scale_dn, timing=timing or TimingModel())
    return grid_plan(campaign.grid, full_scale_dn=full_scale_dn)


def procedure_auto_exposure(campaign: Campaign) -> AutoExposure:
    """The auto-exposure settings of the procedure the campaign runs (preflight answers at its target)."""
    procedures = {"seed003": campaign.seed003, "grid": campaign.grid, "physical": campaign.physical}
    return procedures[campaign.plan].auto_exposure
