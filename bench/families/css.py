"""The coarse-sun-sensor (CSS) head of seed 000: one reading is one signal per detector and the head's temperature.

The head is a cube whose six faces (px, py, mx, my, pz, mz: outward normals +X, +Y, −X, −Y, +Z, −Z) each carry a UV
photodiode, a visible photodiode and a thermopile (:mod:`calibration.css.head`): 18 channels, read at once by the
module (:class:`drivers.interfaces.CoarseSunHead`, :mod:`drivers.css_sensor`), which averages :data:`AVERAGE`
samples per reading as the thesis' ADC does (digest §3.6).

Its plan, ``css-sweep``, sweeps each face through its field (:class:`bench.campaign.CssSweepProcedure`,
:mod:`calibration.css.sweep`): rings of incidence around every face's normal, every channel read at each point,
directions two faces share measured once, each set through the table's kinematics — over the whole sphere, since a
face other than +z faces the source at body zeniths beyond 90° (:func:`table_poses`) —, dark readings with the
shutter closed and a reduced sweep at each further temperature of the head's thermal plate, and check directions
spread over the sphere that are never fitted. The fit at a run's end is :func:`calibration.css.calibrate.calibrate_css`
(each detector's scale, bias, normal, response and their temperature coefficients; the sun direction held out).
"""

from __future__ import annotations

import numpy as np

from calibration.css.head import CHANNELS, DETECTORS, FACES, UNITS
from calibration.css.sweep import halton_directions, sweep_directions
from calibration.geometry import direction_vector
from calibration.mount import ForkMount, fork_for_vectors, table_for_vectors
from calibration.stage_geometry import StageGeometry

from ..campaign import CssSweepProcedure
from ..descriptor import FieldSpec, ReadingDescriptor
from ..messages import CloseShutter, LampOn, Log, Measure, OpenShutter, Point, Reading, SetTemperature, WaitWarm
from . import Family, journal_fit, register

#: Samples the module averages into one reading (the thesis' ADuC842 averages 16 conversions, digest §3.6)
AVERAGE = 16

#: The response laws fitted when a run ends unless the campaign's `methods` says otherwise: the Kelly law and the
#: spline (calibration.css.spline), the better held out kept (:func:`bench.css_datafile.rank_css_fits`); each is a
#: full fit with its held-out folds, the spline's started from the Kelly fit's normals
DEFAULT_METHODS = ("kelly", "spline")

#: Stages of a CSS plan: shutter-closed dark readings, fitted sweep points, never-fitted check directions
DARK, SWEEP, CHECK = "dark", "sweep", "check"

_UNIT_NAMES = {"a": "A", "v": "V"}

DESCRIPTOR = ReadingDescriptor("css", (
    FieldSpec("signals", "number", "A|V", (len(CHANNELS),),
              doc="one signal per detector in the head's channel order " + ", ".join(CHANNELS)
                  + " (face-major: faces " + ", ".join(FACES) + "; detectors " + ", ".join(DETECTORS)
                  + "): the photodiodes' (uv, vis) photocurrent in A, the thermopile's (ir) voltage in V; "
                    "offsets (dark current, front-end offset, the thermopile's scene) included"),
    FieldSpec("temperature_c", "number", "degC", doc="head temperature from the module's thermometer"),
    FieldSpec("saturated", "integer", "", required=False,
              doc="bit k set: channel k (head order) reached the ADC's full scale (its signal is a lower bound)"),
    FieldSpec("under_range", "integer", "", required=False,
              doc="bit k set: channel k read 0 counts (its signal is an upper bound)"),
    FieldSpec("n_samples", "integer", "", required=False, doc="samples averaged"),
))

#: The unit of each entry of ``signals`` ("A" or "V"), in :data:`calibration.css.head.CHANNELS` order
SIGNAL_UNITS = tuple(_UNIT_NAMES[UNITS[c.split("_", 1)[1]]] for c in CHANNELS)


def _mask(flags) -> int:
    return sum(1 << k for k, flag in enumerate(flags) if flag)


def read(sensor, repeat: int, clock) -> Reading:
    """One averaged READ of the head, its channels put in :data:`calibration.css.head.CHANNELS` order by name. A
    channel clipped at either end of its range is recorded with its bit set in ``saturated`` or ``under_range``: the
    reading's other channels stand (a cube lit on one face is not spoilt by another's), that channel's signal is only
    a bound and is never fitted (:func:`bench_data`)."""
    from drivers.errors import ProtocolError

    r = sensor.read(average=AVERAGE)
    t = clock()
    channels = tuple(r.channels)
    if channels != CHANNELS:
        missing = [c for c in CHANNELS if c not in channels]
        if missing:
            raise ProtocolError(getattr(sensor, "name", "css head"),
                                f"the head reports channels {', '.join(channels)}; the CSS family needs "
                                f"{', '.join(CHANNELS)} (missing {', '.join(missing)})")
    order = [channels.index(c) for c in CHANNELS]
    saturated = _mask(r.saturated[i] for i in order)
    under = _mask(r.under_range[i] for i in order)
    return Reading(repeat, "ok", t,
                   {"signals": [float(r.signals[i]) for i in order], "temperature_c": float(r.temperature_c),
                    "saturated": int(saturated), "under_range": int(under), "n_samples": int(r.n_samples)})


#: Preflight's signals: a face lit at about 45° (the simulated head's nominal scale × 0.7), the others dark
_DRY_SIGNALS = [{"uv": 4.4e-6, "vis": 8.3e-4, "ir": 9e-5}[c.split("_", 1)[1]] if c.startswith("pz") else 0.0
                for c in CHANNELS]


def dry_reading(repeat: int, campaign) -> Reading:
    """Preflight's answer: a head lit on its top face at room temperature."""
    return Reading(repeat, "ok", 0.0, {"signals": list(_DRY_SIGNALS), "temperature_c": 25.0, "saturated": 0,
                                       "under_range": 0, "n_samples": AVERAGE})


def summary(readings) -> dict:
    """A point's mean signals by channel and its temperature, for the live view."""
    ok = [r for r in readings if r.ok]
    if not ok:
        return {"signals": None, "temperature_c": None}
    signals = np.mean([r.values["signals"] for r in ok], axis=0)
    return {"signals": dict(zip(CHANNELS, (float(s) for s in signals))),
            "temperature_c": float(np.mean([r.values["temperature_c"] for r in ok]))}


def status(sensor) -> dict:
    reading = sensor.read(average=AVERAGE)
    return {"temperature_c": float(reading.temperature_c),
            "signals": {c: float(s) for c, s in zip(reading.channels, reading.signals)}}


# --- the plan ------------------------------------------------------------------------------------------------
def table_poses(zenith_deg, azimuth_deg, mount) -> tuple[np.ndarray, np.ndarray]:
    """The table's readings that put the Sun at body directions (zenith, azimuth) [°] anywhere on the sphere.

    An alt-az fork (:class:`calibration.mount.ForkMount`) reaches every direction through its inverse
    (:func:`calibration.mount.fork_for_vectors`: a = asin s_x, b = atan2(s_y, s_z), |b| up to 180°). Seed 003's
    azimuth-on-zenith table is inverted exactly (:func:`calibration.mount.table_for_vectors`) in front of the
    sensor; behind it (s_z ≤ 0, where that inversion does not run) by the ideal table's closed form, φ_s = φ and
    Ω = θ − asin(q sin θ) + Ω₀ (seed 003 eq. 8 inverted; Ω up to 180°), exact for the table the plans are given
    (:func:`bench.families.table_mount`: the arm ratio alone). Whether the table can turn that far is preflight's
    soft-limit check. A direction no reading reaches raises :class:`~bench.plans.PlanError`.
    """
    zenith = np.atleast_1d(np.asarray(zenith_deg, float))
    azimuth = np.atleast_1d(np.asarray(azimuth_deg, float))
    s = direction_vector(zenith, azimuth)
    if isinstance(mount, ForkMount):
        first, second = fork_for_vectors(s, mount)
    else:
        first = np.full(zenith.shape, np.nan)
        second = np.full(zenith.shape, np.nan)
        front = s[..., 2] > 1e-9
        if front.any():
            first[front], second[front] = table_for_vectors(s[front], mount)
        back = ~front
        theta = np.radians(zenith[back])
        first[back] = np.mod(azimuth[back], 360.0)
        second[back] = np.degrees(theta - np.arcsin(np.clip(mount.arm_ratio * np.sin(theta), -1.0, 1.0))) \
            + mount.zenith_zero_deg
    missed = ~(np.isfinite(first) & np.isfinite(second))
    if missed.any():
        from ..plans import PlanError

        i = int(np.flatnonzero(missed)[0])
        raise PlanError(f"{int(missed.sum())} direction(s) of the CSS sweep cannot be set on the table, the first "
                        f"zenith {zenith[i]:g}°, azimuth {azimuth[i]:g}°")
    return first, second


def serpentine(first, second, band_deg: float) -> np.ndarray:
    """An order of table poses with short moves: bands of the second axis `band_deg` wide, the first axis swept to
    and fro from band to band (a boustrophedon)."""
    first, second = np.asarray(first, float), np.asarray(second, float)
    if first.size == 0:
        return np.zeros(0, int)
    band = np.floor((second - second.min()) / band_deg + 1e-9).astype(int)
    return np.lexsort((np.where(band % 2 == 0, first, -first), band))


def temperature_tag(temperature_c: float | None) -> str:
    """The temperature part of a point's key (``t+25.0``; ``tamb`` without thermal control)."""
    return "tamb" if temperature_c is None else f"t{float(temperature_c):+06.1f}"


def _points(stage_of, zenith, azimuth, repeats: int, mount, band_deg: float, tag: str) -> list[Point]:
    first, second = table_poses(zenith, azimuth, mount)
    points = []
    for i in serpentine(first, second, band_deg):
        stage = stage_of[i]
        key = f"{stage}_{tag}_z{zenith[i]:07.3f}_a{azimuth[i]:07.3f}"
        points.append(Point(key, stage, round(float(first[i]), 4), round(float(second[i]), 4), repeats))
    return points


def sweep_points(procedure: CssSweepProcedure, mount, temperature_c: float | None = None, *,
                 full: bool = True) -> list[Point]:
    """The lit points at one temperature: the full sweep and the check directions (`full`), or the reduced sweep
    (rings every `reduced_step_deg` × `reduced_around`, no field edge), in serpentine order."""
    if full:
        zenith, azimuth = sweep_directions(procedure.field_deg, procedure.step_deg, procedure.around)
        check_zenith, check_azimuth = halton_directions(procedure.check_directions)
        stages = [SWEEP] * zenith.size + [CHECK] * check_zenith.size
        zenith, azimuth = np.concatenate([zenith, check_zenith]), np.concatenate([azimuth, check_azimuth])
    else:
        zenith, azimuth = sweep_directions(procedure.field_deg, procedure.reduced_step_deg, procedure.reduced_around,
                                           edge=False)
        stages = [SWEEP] * zenith.size
    return _points(stages, zenith, azimuth, procedure.repeats, mount, procedure.step_deg,
                   temperature_tag(temperature_c))


def dark_point(procedure: CssSweepProcedure, temperature_c: float | None) -> Point:
    """The shutter-closed point at one temperature, at the table's home (the head sees the closed shutter)."""
    return Point(f"{DARK}_{temperature_tag(temperature_c)}", DARK, 0.0, 0.0, procedure.dark_repeats)


def css_sweep_plan(procedure: CssSweepProcedure, *, mount):
    """The head's bench calibration (module docstring): the lamp lit and warm behind the closed shutter, then at each
    temperature of the thermal plate the dark readings and the lit sweep (the full one and the check directions at
    the first, the reduced one at the others)."""
    temperatures: tuple[float | None, ...] = procedure.temperatures_c or (None,)
    stages = [(t, dark_point(procedure, t), sweep_points(procedure, mount, t, full=k == 0))
              for k, t in enumerate(temperatures)]
    n_lit = sum(len(p) for _, _, p in stages)
    yield Log(f"CSS sweep: every face through its field (rings 0–{procedure.field_deg:g}° every "
              f"{procedure.step_deg:g}°, up to {procedure.around} azimuths about the normal) and "
              f"{procedure.check_directions} check directions, {len(stages[0][2])} directions at "
              + ("the head's temperature" if temperatures == (None,) else
                 f"{temperatures[0]:g} °C" + (f", a reduced sweep at {', '.join(f'{t:g}' for t in temperatures[1:])} °C"
                                              if len(temperatures) > 1 else ""))
              + f"; {n_lit} lit points × {procedure.repeats}, {len(stages)} dark point(s) × {procedure.dark_repeats}")
    yield LampOn()
    yield WaitWarm()
    for temperature, dark, lit in stages:
        if temperature is not None:
            reached = yield SetTemperature(float(temperature), procedure.tolerance_c,
                                           for_points=(dark.key, *(p.key for p in lit)))
            yield Log(f"the head is at {reached:.2f} °C" if reached is not None else
                      f"{temperature:g} °C: already recorded")
        yield CloseShutter()
        yield Measure(dark)
        yield OpenShutter()
        for point in lit:
            yield Measure(point)
    yield CloseShutter()


def make_plan(campaign, *, timing=None, mount=None):
    return css_sweep_plan(campaign.css_sweep, mount=mount if mount is not None else StageGeometry(0.0))


# --- fits when a run ends -------------------------------------------------------------------------------------
def clipped_mask(values: dict) -> np.ndarray:
    """The channels of a recorded reading clipped at either end of their range, (18,) bool in head order."""
    bits = int(values.get("saturated") or 0) | int(values.get("under_range") or 0)
    return np.array([bool(bits >> k & 1) for k in range(len(CHANNELS))])


def bench_data(catalogue, run_ids, *, sensor_id: str | None = None):
    """The CSS bench data of runs (:class:`calibration.css.data.CssBenchData`): every ok reading at the body direction
    the engine recorded, a channel clipped at either end of its range as a missing reading (NaN: its signal is only a
    bound; a reading whose every channel clipped stays in the catalogue only), dark rows from the dark stage, check
    rows from the check stage, rows named by reading id."""
    from calibration.css.data import CssBenchData
    from calibration.errors import InsufficientDataError

    rows, signals = [], []
    for r in catalogue.readings(run_ids):
        if not r.ok:
            continue
        values = np.array(r.values["signals"], float)
        values[clipped_mask(r.values)] = np.nan
        if np.isnan(values).all():
            continue
        rows.append(r)
        signals.append(values)
    if not rows:
        raise InsufficientDataError(f"runs {list(run_ids)} recorded no usable reading")
    dark = np.array([r.stage == DARK for r in rows])
    return CssBenchData(zenith_deg=np.where(dark, np.nan, [r.zenith_deg for r in rows]),
                        azimuth_deg=np.where(dark, np.nan, [r.azimuth_body_deg for r in rows]),
                        signals=np.array(signals), channels=CHANNELS,
                        temperature_c=np.array([r.values["temperature_c"] for r in rows], float),
                        repeat=np.array([r.repeat for r in rows], int), sensor_id=sensor_id, dark=dark,
                        check=np.array([r.stage == CHECK for r in rows]),
                        row_id=np.array([r.id for r in rows], int))


def fit_inputs(session):
    """Nothing of the bench: every detector's parameters start from the head's nominal design."""
    return None


def fit_run(catalogue, run_id: int, campaign, inputs=None, journal=None) -> list:
    """Fit the head's calibration to the run's lineage with every response law of the campaign's `methods` (default
    :data:`DEFAULT_METHODS`; :func:`bench.css_datafile.fit_css_laws`), keep each document, the best held out as
    chosen (:func:`bench.css_datafile.rank_css_fits`), and journal its held-out figures, the rejected readings and
    the warnings."""
    from ..css_datafile import css_calibration_file, css_fit_summary, css_metrics, fit_css_laws, rank_css_fits
    from ..runner import software_version

    journal = journal or (lambda kind, message: catalogue.log_event(run_id, kind, message))
    run = catalogue.run(run_id)
    data = bench_data(catalogue, catalogue.lineage(run_id), sensor_id=run["sensor_id"])
    outcomes = fit_css_laws(data, campaign.methods or DEFAULT_METHODS)
    chosen = rank_css_fits(outcomes)[0]
    for outcome in outcomes:
        document = css_calibration_file(outcome, source=f"run {run_id}", software=software_version(), created=False)
        catalogue.add_calibration(run_id, outcome.response, document, css_metrics(outcome), outcome is chosen)
    journal_fit(journal, css_fit_summary(chosen, len(data), others=[o for o in outcomes if o is not chosen]),
                chosen.rejected, chosen.warnings, "reading")
    return outcomes


def export_csv(catalogue, run_ids, target, sensor_id: str | None) -> None:
    from ..css_datafile import write_css_csv
    write_css_csv(target, bench_data(catalogue, run_ids, sensor_id=sensor_id))


def c_header(document: dict) -> str:
    from ..css_datafile import css_header_from_document
    return css_header_from_document(document)


FAMILY = register(Family(
    name="css", title="Coarse sun sensor head (seed 000)", descriptor=DESCRIPTOR, plans=("css-sweep",), read=read,
    dry_reading=dry_reading, summary=summary, status=status, make_plan=make_plan, fit_run=fit_run,
    fit_inputs=fit_inputs, results_view="css", export_csv=export_csv, c_header=c_header, sensor_kinds=("css",)))

__all__ = ["FAMILY", "DESCRIPTOR", "AVERAGE", "DEFAULT_METHODS", "SIGNAL_UNITS", "bench_data", "clipped_mask",
           "css_sweep_plan", "sweep_points", "table_poses", "read"]
