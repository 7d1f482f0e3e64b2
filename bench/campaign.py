"""Campaign files (YAML): which procedure to run on which sensors.

Every problem is a :class:`CampaignFileError` naming the file and the field. ``examples/seed003.yaml`` is the
seed 003 procedure with every field spelled out.
"""

from __future__ import annotations

from types import UnionType
from typing import Literal, Union, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from calibration.css.diode import RESPONSES as CSS_METHODS  # the CSS family's fits: the detectors' response law
from calibration.models import METHODS
from calibration.procedure import (
    SEED003_AZIMUTH_STEP_DEG,
    SEED003_AZIMUTHS_DEG,
    SEED003_CENTRE_REPEATS,
    SEED003_REPEATS,
    SEED003_ZENITH_STAGE_DEG,
    grid_azimuths_deg,
)
from calibration.qd.document import QD_METHODS  # the QD family's fits
from drivers.css_sensor import DEFAULT_SETPOINT_RANGE_C

from .yamlfile import field_problems, read_yaml


class CampaignFileError(Exception):
    """A campaign file that cannot be used; the message names the file and the field."""


#: Limits that keep one campaign (or one dry-run request) from exhausting the machine: a seed 003 run has 80
#: points, a flight batch 10 sensors.
MAX_POINTS_PER_SENSOR = 5000
MAX_LIST = 500
MAX_SENSORS = 100


def bool_for_a_number(annotation, value) -> bool:
    """Whether `value` holds a JSON true/false where `annotation` wants a number: itself, an element of a
    tuple or list, a value of a mapping, or an optional number (pydantic would take it for 1 or 0)."""
    if annotation in (int, float):
        return isinstance(value, bool)
    origin, args = get_origin(annotation), get_args(annotation)
    if origin in (Union, UnionType):
        return any(bool_for_a_number(a, value) for a in args if a is not type(None))
    if origin in (tuple, list) and args and isinstance(value, (list, tuple)):
        return any(bool_for_a_number(args[0], v) for v in value)
    if origin is dict and len(args) == 2 and isinstance(value, dict):
        return any(bool_for_a_number(args[1], v) for v in value.values())
    return False


class _Strict(BaseModel):
    # no NaN or infinity anywhere (`start_ms: .inf` is not an exposure)
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, value, info):
        # JSON's true is not the number 1: refuse it where a number is expected, also in a list or a mapping
        if bool_for_a_number(cls.model_fields[info.field_name].annotation, value):
            raise ValueError("must be a number, not true/false")
        return value


class AutoExposure(_Strict):
    """Exposure search at normal incidence (seed 003 §4.2 step 0): raise it when there is no spot, lower it
    when the spot saturates, until the peak sits near `target_peak_fraction` of full scale."""

    start_ms: float = Field(4.0, gt=0)
    target_peak_fraction: float = Field(0.7, gt=0.05, lt=0.95)
    tolerance: float = Field(0.2, gt=0, lt=1)
    min_ms: float = Field(0.05, gt=0)
    max_ms: float = Field(500.0, gt=0)
    max_steps: int = Field(12, ge=1, le=50)


class Seed003Procedure(_Strict):
    """The seed 003 calibration procedure (§4.2 and the revised §4.4–4.5)."""

    azimuth_step_deg: float = Field(SEED003_AZIMUTH_STEP_DEG, ge=0.5, le=180)
    zenith_stage_deg: tuple[float, ...] = Field(SEED003_ZENITH_STAGE_DEG, max_length=MAX_LIST)
    repeats: int = Field(SEED003_REPEATS, ge=1, le=100)
    centre_repeats: int = Field(SEED003_CENTRE_REPEATS, ge=1, le=100)
    tilt_stage: bool = True
    tilt_probe_deg: float = Field(1.0, gt=0, le=5)
    tilt_repeats: int = Field(3, ge=1, le=100)
    auto_exposure: AutoExposure = AutoExposure()

    @field_validator("zenith_stage_deg")
    @classmethod
    def _zeniths(cls, v):
        if len(v) < 7:
            raise ValueError("a 6th-order θ(r) needs at least 7 zenith angles")
        return v

    @property
    def azimuths_deg(self) -> tuple[float, ...]:
        """The azimuths of every stage: a full turn in `azimuth_step_deg` steps [°]."""
        return tuple(float(a) for a in grid_azimuths_deg(self.azimuth_step_deg))


class GridProcedure(_Strict):
    """A plain grid: every azimuth at every zenith-stage angle."""

    azimuths_deg: tuple[float, ...] = Field(SEED003_AZIMUTHS_DEG, min_length=1, max_length=MAX_LIST)
    zenith_stage_deg: tuple[float, ...] = Field(SEED003_ZENITH_STAGE_DEG, min_length=1, max_length=MAX_LIST)
    repeats: int = Field(1, ge=1, le=100)
    order: Literal["zenith-outer", "azimuth-outer"] = "zenith-outer"
    auto_exposure: AutoExposure = AutoExposure()


class PhysicalProcedure(_Strict):
    """The physical model's own procedure: few directions chosen by their information, measured in batches
    along a short table tour, fitted after each batch, stopped once the targets are met
    (:mod:`calibration.design_of_experiments`; examples/physical.yaml)."""

    first_batch: int = Field(16, ge=10, le=200)
    batch_size: int = Field(8, ge=1, le=200)
    max_batches: int = Field(3, ge=1, le=20)
    check_directions: int = Field(8, ge=3, le=50)
    repeats: int = Field(4, ge=1, le=100)
    check_rms_target_deg: float = Field(0.02, gt=0, le=5)
    parameter_budget_deg: float = Field(0.01, gt=0, le=5)
    parameter_targets: dict[str, float] = Field(default_factory=dict)
    zenith_max_deg: float = Field(60.0, gt=5, lt=89)
    zenith_step_deg: float = Field(5.0, gt=0, le=30)
    azimuth_step_deg: float = Field(15.0, gt=0, le=90)
    edge_margin_px: float = Field(24.0, ge=0, le=200)
    auto_exposure: AutoExposure = AutoExposure()

    @field_validator("parameter_targets")
    @classmethod
    def _targets(cls, v):
        from calibration.models.physical import FITTED

        unknown = [k for k in v if k not in FITTED]
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; known: {list(FITTED)}")
        if any(not t > 0 for t in v.values()):
            raise ValueError("every parameter target must be positive")
        return v

    @property
    def max_points(self) -> int:
        """The cap: fit directions of every batch plus the check directions."""
        return self.first_batch + (self.max_batches - 1) * self.batch_size + self.check_directions


class QdDarkSweep(_Strict):
    """Dark current over temperature, shutter closed (seed 002 §2.1: linear in temperature per quadrant): the
    module's thermal control is set to each temperature in turn and `repeats` readings are taken there."""

    temperatures_c: tuple[float, ...] = Field((10.0, 20.0, 30.0, 40.0), max_length=50)
    repeats: int = Field(8, ge=1, le=100)
    tolerance_c: float = Field(0.2, gt=0, le=5)

    @field_validator("temperatures_c")
    @classmethod
    def _enough(cls, v):
        if 0 < len(v) < 2:
            raise ValueError("a slope needs at least two temperatures (or none: no dark sweep)")
        return v


class QdGridProcedure(_Strict):
    """Seed 002's calibration: a square grid of the sensor's projection angles α, β over ±`field_deg` (the
    thesis' field is ±40°), set through the table's kinematics (calibration.mount), with check points at
    the centres of the grid's cells, never fitted (the thesis warns that the error between nodes can exceed
    the error at them), after the dark sweep."""

    field_deg: float = Field(40.0, gt=0, le=60)
    step_deg: float = Field(5.0, ge=0.5, le=40)
    check_points: bool = True
    repeats: int = Field(3, ge=1, le=100)
    temperature_c: float | None = Field(25.0, ge=-40, le=70)  # the die's temperature during the grid; None: TEC off
    dark: QdDarkSweep = QdDarkSweep()

    @model_validator(mode="after")
    def _step_divides_the_field(self):
        if abs(self.field_deg / self.step_deg - round(self.field_deg / self.step_deg)) > 1e-9:
            raise ValueError(f"the step must divide the field, so the grid reaches ±{self.field_deg:g}° exactly: "
                             f"{self.field_deg:g}° / {self.step_deg:g}° is not whole")
        return self

    def points(self) -> int:
        k = 2 * int(round(self.field_deg / self.step_deg)) + 1  # the nodes along an axis (calibration.mount)
        return k * k + (k - 1) ** 2 * self.check_points + len(self.dark.temperatures_c)


class QdPhysicalProcedure(_Strict):
    """The QD physical model's short plan: nested grids of α, β from coarse to fine (every node of a coarser grid is
    one of the next), the models fitted after each batch and scored on fixed check directions they never fit; the
    run stops at the first batch whose check figures meet the targets (at most the finest grid's nodes)."""

    field_deg: float = Field(40.0, gt=0, le=60)
    steps_deg: tuple[float, ...] = Field((20.0, 10.0, 5.0), min_length=1, max_length=6)
    check_directions: int = Field(16, ge=4, le=200)
    repeats: int = Field(2, ge=1, le=100)
    check_max_target_deg: float = Field(0.02, gt=0, le=5)
    check_rms_target_deg: float = Field(0.01, gt=0, le=5)
    temperature_c: float | None = Field(25.0, ge=-40, le=70)
    dark: QdDarkSweep = QdDarkSweep()

    @model_validator(mode="after")
    def _nested(self):
        steps = self.steps_deg
        for step in steps:
            if abs(self.field_deg / step - round(self.field_deg / step)) > 1e-9:
                raise ValueError(f"every step must divide the field: {self.field_deg:g}° / {step:g}° is not whole")
        for coarse, fine in zip(steps, steps[1:]):
            if not (fine < coarse and abs(coarse / fine - round(coarse / fine)) < 1e-9):
                raise ValueError(f"steps must shrink by whole factors, so each grid holds the one before: {coarse:g}° "
                                 f"then {fine:g}°")
        return self

    def points(self) -> int:
        k = int(round(2 * self.field_deg / self.steps_deg[-1])) + 1
        return k * k + self.check_directions + len(self.dark.temperatures_c)


#: The camera family's fits (one: OpenCV's camera model, calibration.camera)
CAMERA_METHODS = ("opencv",)
#: The simulated webcam's design (drivers/sim/camera_optics.py: f = 2.4 mm on 3 µm pixels, 800 px, on 640×480):
#: a horizontal field of view of 2·atan(320/800)
CAMERA_DESIGN_FOV_DEG = 43.6


class CameraGridProcedure(_Strict):
    """The camera sun sensor's bench calibration (seed 001 digest §7 item 4): zenith rings × azimuths over the whole
    frame out to its corners (:func:`calibration.camera.camera_grid` on the design camera), each set through the
    table's kinematics, `repeats` frames each, after an auto-exposure at the boresight that puts the Sun's peak at
    `auto_exposure.target_peak_fraction` of full scale (60–70 % by default)."""

    horizontal_fov_deg: float = Field(CAMERA_DESIGN_FOV_DEG, gt=1, lt=170)  # the design's, for the grid
    width_px: int = Field(640, ge=16, le=8192)
    height_px: int = Field(480, ge=16, le=8192)
    rings: int = Field(8, ge=3, le=40)  # zenith rings besides the boresight
    azimuths: int = Field(16, ge=4, le=72)  # equally spaced azimuths per ring (the frame's corners are added)
    margin_radii: float = Field(2.0, ge=0.5, le=20)  # the spots stay this many disc radii inside the frame
    repeats: int = Field(2, ge=1, le=100)
    auto_exposure: AutoExposure = AutoExposure(start_ms=2.0, target_peak_fraction=0.65, tolerance=0.08,
                                               min_ms=0.1, max_ms=500.0)

    def points(self) -> int:
        """The grid's directions at most: the boresight and every ring at every azimuth and corner azimuth."""
        return 1 + self.rings * (self.azimuths + 4)


#: The setpoints the CSS head's driver accepts (drivers/css_sensor.py DEFAULT_SETPOINT_RANGE_C): a campaign asking
#: for others is refused when it is read, not when the plate is set in the middle of a run
CSS_PLATE_RANGE_C = DEFAULT_SETPOINT_RANGE_C


class CssSweepProcedure(_Strict):
    """A coarse-sun-sensor head's bench calibration (seed 000 digest §8.3 items 7–8, 10): a plan that sweeps each
    face through its field. For each face, rings of incidence around its normal from 0 to `field_deg` every
    `step_deg` at up to `around` azimuths about the normal (fewer at the centre; directions two faces share measured
    once: :mod:`calibration.css.sweep`), every channel read at each; each direction set through the table's
    kinematics (the whole sphere: faces other than +z face the source at zeniths beyond 90°). At each of the head's
    thermal-plate temperatures `temperatures_c` (none: no thermal control) the dark readings with the shutter
    closed, then the full sweep at the first temperature and a reduced one (rings every `reduced_step_deg` ×
    `reduced_around`) at the others, enough for the temperature coefficients; `check_directions` directions spread
    over the sphere (Halton), measured at the first temperature and never fitted."""

    field_deg: float = Field(88.0, gt=5, le=90)
    step_deg: float = Field(5.0, ge=0.5, le=45)
    around: int = Field(8, ge=3, le=72)
    repeats: int = Field(2, ge=1, le=100)
    temperatures_c: tuple[float, ...] = Field((25.0, 10.0, 40.0), max_length=20)
    tolerance_c: float = Field(0.2, gt=0, le=5)
    dark_repeats: int = Field(8, ge=1, le=100)
    reduced_step_deg: float = Field(30.0, ge=1, le=90)
    reduced_around: int = Field(4, ge=3, le=72)
    check_directions: int = Field(24, ge=0, le=500)

    @field_validator("temperatures_c")
    @classmethod
    def _temperatures(cls, v):
        low, high = CSS_PLATE_RANGE_C
        if any(not low <= t <= high for t in v):
            span = f"{low:g}…{high:g}".replace("-", "−")
            raise ValueError(f"the head's thermal plate is set within {span} °C (its driver's range)")
        if len(set(v)) != len(v):
            raise ValueError("a temperature is listed twice")
        return v

    def points(self) -> int:
        """The plan's points: the full sweep, the check directions, a reduced sweep at every further temperature and
        one dark point per temperature (the ambient one without thermal control)."""
        from calibration.css.sweep import sweep_size_bound, sweep_vectors

        bound = sweep_size_bound(self.field_deg, self.step_deg, self.around)
        if bound > MAX_POINTS_PER_SENSOR:
            return bound  # beyond the cap anyway: not worth computing
        temperatures = max(1, len(self.temperatures_c))
        reduced = len(sweep_vectors(self.field_deg, self.reduced_step_deg, self.reduced_around, edge=False))
        return (len(sweep_vectors(self.field_deg, self.step_deg, self.around)) + self.check_directions
                + (temperatures - 1) * reduced + temperatures)


#: The horizon family's fit (one: the crossing model of calibration.horizon.bench_fit)
HORIZON_METHODS = ("crossings",)
#: The sensor's measurement range (seed 004 Table 1-1): roll ±33°, pitch ±17°
HORIZON_ROLL_RANGE_DEG = 33.0
HORIZON_PITCH_RANGE_DEG = 17.0


class HorizonGridProcedure(_Strict):
    """A scanning horizon sensor's bench calibration in front of an IR Earth simulator (seed 004): the disc heated and
    settled, the cover opened, then for each disc radius (`disc_radii_deg`, or by default the Earth's angular radius at
    each of `altitudes_km`, seed 004 eq. 2.3) the iris set and a grid of roll × pitch over ±`roll_range_deg` ×
    ±`pitch_range_deg` every `roll_step_deg` × `pitch_step_deg` (the sensor's range, seed 004 Table 1-1: roll ±33°,
    pitch ±17°), each (roll, pitch) set through the table's kinematics as the disc centre's body direction, `repeats`
    scans each; and `check_points` poses per radius spread over the range (Halton), never fitted. The cover is closed
    at the end."""

    altitudes_km: tuple[float, ...] = Field((400.0, 500.0, 700.0), min_length=1, max_length=20)
    disc_radii_deg: tuple[float, ...] | None = Field(None, min_length=1, max_length=20)
    roll_range_deg: float = Field(HORIZON_ROLL_RANGE_DEG, ge=0, le=60)
    pitch_range_deg: float = Field(HORIZON_PITCH_RANGE_DEG, ge=0, le=45)
    roll_step_deg: float = Field(11.0, gt=0, le=60)
    pitch_step_deg: float = Field(8.5, gt=0, le=45)
    repeats: int = Field(4, ge=1, le=100)
    check_points: int = Field(4, ge=0, le=100)
    tolerance_deg: float = Field(0.02, gt=0, le=1)

    @field_validator("altitudes_km")
    @classmethod
    def _altitudes(cls, v):
        if any(not 100.0 <= h <= 40000.0 for h in v):
            raise ValueError("an altitude lies within 100…40000 km")
        if len(set(v)) != len(v):
            raise ValueError("an altitude is listed twice")
        return v

    @field_validator("disc_radii_deg")
    @classmethod
    def _radii(cls, v):
        if v is not None:
            if any(not 1.0 <= r <= 80.0 for r in v):
                raise ValueError("a disc radius lies within 1…80°")
            if len(set(v)) != len(v):
                raise ValueError("a disc radius is listed twice")
        return v

    @model_validator(mode="after")
    def _grid_within_the_cones(self):
        for name, span, step in (("roll", self.roll_range_deg, self.roll_step_deg),
                                 ("pitch", self.pitch_range_deg, self.pitch_step_deg)):
            if abs(2 * span / step - round(2 * span / step)) > 1e-9:
                raise ValueError(f"the {name} step must divide the {name} span, so the grid reaches ±{span:g}° "
                                 f"exactly: {2 * span:g}° / {step:g}° is not whole")
        from calibration.horizon.scan import crossing_phases

        rolls, pitches = self.rolls_deg(), self.pitches_deg()
        roll, pitch = (a.ravel() for a in np.meshgrid(rolls, pitches))
        for radius in self.radii_deg():
            for cone in (1, 2):
                out, _ = crossing_phases(roll, pitch, radius, cone=cone)
                missed = np.isnan(out)
                if missed.any():
                    i = int(np.flatnonzero(missed)[0])
                    raise ValueError(f"at roll {roll[i]:g}°, pitch {pitch[i]:g}° cone {cone} of the design sensor "
                                     f"(γ = 70°) does not cross a disc of radius {radius:.3f}°: narrow the grid or "
                                     "change the disc radius")
        return self

    def radii_deg(self) -> tuple[float, ...]:
        """The disc radii the plan sets [°]: `disc_radii_deg`, else the Earth's angular radius at each altitude (seed
        004 eq. 2.3, H_eq = 0), rounded to 1e-4°."""
        if self.disc_radii_deg is not None:
            return tuple(float(r) for r in self.disc_radii_deg)
        from calibration.horizon.scan import earth_angular_radius_deg

        return tuple(round(float(earth_angular_radius_deg(h)), 4) for h in self.altitudes_km)

    def rolls_deg(self):
        n = int(round(2 * self.roll_range_deg / self.roll_step_deg)) + 1
        return np.linspace(-self.roll_range_deg, self.roll_range_deg, n)

    def pitches_deg(self):
        n = int(round(2 * self.pitch_range_deg / self.pitch_step_deg)) + 1
        return np.linspace(-self.pitch_range_deg, self.pitch_range_deg, n)

    def points(self) -> int:
        """The grid and the check points at every radius."""
        return len(self.radii_deg()) * (len(self.rolls_deg()) * len(self.pitches_deg()) + self.check_points)


class Alignment(_Strict):
    """Caliper readings of the bench alignment (seed 003 §4.1), checked before anything moves.

    l1/l2: table edge to the rotation mechanism / to the simulator aperture; h1/h2: table to the simulator
    aperture / to the sensor window; distance: sensor to simulator. Tolerances: 0.5 mm, 0.5 mm, 5 mm.
    """

    l1_mm: float
    l2_mm: float
    h1_mm: float
    h2_mm: float
    distance_mm: float


class Campaign(_Strict):
    """A campaign: a procedure run on one sensor or on a fleet (a flight batch is ten)."""

    name: str = Field(min_length=1)
    plan: Literal["seed003", "grid", "physical", "qd-grid", "qd-physical", "qd-dark", "camera-grid",
                  "css-sweep", "horizon-grid"] = "seed003"
    operator: str = "unknown"
    sensors: tuple[str, ...] = Field(("SIM-0001",), min_length=1, max_length=MAX_SENSORS)
    frames: Literal["roi", "full", "none"] = "roi"
    seed003: Seed003Procedure = Seed003Procedure()
    grid: GridProcedure = GridProcedure()
    physical: PhysicalProcedure = PhysicalProcedure()
    qd_grid: QdGridProcedure = QdGridProcedure()
    qd_physical: QdPhysicalProcedure = QdPhysicalProcedure()
    qd_dark: QdDarkSweep = QdDarkSweep()
    camera_grid: CameraGridProcedure = CameraGridProcedure()
    css_sweep: CssSweepProcedure = CssSweepProcedure()
    horizon_grid: HorizonGridProcedure = HorizonGridProcedure()
    alignment: Alignment | None = None
    # the fits at the run's end; None: every method of the sensor family (a CSS head: the kelly law and the spline,
    # bench.families.css.DEFAULT_METHODS, each law being a full fit with its held-out folds)
    methods: tuple[str, ...] | None = None

    @field_validator("methods")
    @classmethod
    def _methods(cls, v, info):
        if v is not None:
            plan = info.data.get("plan", "seed003")
            known = (QD_METHODS if plan.startswith("qd-") else CAMERA_METHODS if plan.startswith("camera-")
                     else CSS_METHODS if plan.startswith("css-") else HORIZON_METHODS if plan.startswith("horizon-")
                     else tuple(METHODS))
            unknown = [m for m in v if m not in known]
            if unknown:
                raise ValueError(f"unknown method(s) {unknown}; known for the {plan} plan: {list(known)}")
        return v

    @model_validator(mode="after")
    def _unique_sensors(self):
        if len(set(self.sensors)) != len(self.sensors):
            raise ValueError("`sensors` lists a sensor twice")
        return self

    @model_validator(mode="after")
    def _points_within_the_cap(self):
        # counted from the fields, before any plan is expanded, so a huge request costs nothing
        points = self.planned_points()
        if points > MAX_POINTS_PER_SENSOR:
            raise ValueError(f"the {self.plan} plan would measure {points} points per sensor; the limit is "
                             f"{MAX_POINTS_PER_SENSOR} (a seed 003 run has 80): use fewer azimuths or zeniths")
        return self

    def planned_points(self) -> int:
        """Points per sensor the plan will measure at most, from its fields alone."""
        if self.plan == "seed003":
            p = self.seed003
            return len(p.azimuths_deg) * (1 + 2 * p.tilt_stage + len(p.zenith_stage_deg))
        if self.plan == "grid":
            return len(self.grid.azimuths_deg) * len(self.grid.zenith_stage_deg)
        if self.plan == "qd-grid":
            return self.qd_grid.points()
        if self.plan == "qd-physical":
            return self.qd_physical.points()
        if self.plan == "qd-dark":
            return len(self.qd_dark.temperatures_c)
        if self.plan == "camera-grid":
            return self.camera_grid.points()
        if self.plan == "css-sweep":
            return self.css_sweep.points()
        if self.plan == "horizon-grid":
            return self.horizon_grid.points()
        return self.physical.max_points


def load_campaign_file(path) -> Campaign:
    """Read and validate a campaign YAML file."""
    document = read_yaml(path, CampaignFileError)
    if not isinstance(document, dict):
        raise CampaignFileError(f"{path}: expected a mapping at the top level")
    try:
        return Campaign.model_validate(document)
    except ValidationError as exc:
        raise CampaignFileError(f"{path}: {field_problems(exc)}") from None
