"""A scanning horizon sensor's own errors from bench scans in front of an Earth simulator (seed 004 §2-3).

On the bench the table sets the disc centre's direction in the table's frame from a commanded roll φ and pitch θ,
``n_t = (−sin θ, sin φ cos θ, cos φ cos θ)`` (the package conventions, :func:`calibration.horizon.scan.nadir_in_body`);
the Earth simulator's iris sets the disc radius ρ. What the sensor reports differs from the ideal sensor of the
thesis by its own errors, the parameters fitted here (:data:`PARAMETERS`):

* ``gamma1_deg``, ``gamma2_deg``: the cones' half-angles γ_k (seed 004 eq. 2.5; the design's 70°);
* ``phase_offset1_deg``, ``phase_offset2_deg``: o_k, what cone k reports minus the scan's geometric phase (the index
  mark's angle, each fixed mirror's azimuth, the detector's delay): δ_reported = δ + o_k;
* ``radius_bias_deg``: Δρ, the threshold bias — the locator's threshold off 50 % (seed 004 eq. 2.1, C1 ≠ 0.5) and
  any blur beyond the design's IFOV make the sensor see a disc of radius ρ + Δρ, on top of the IFOV's own curvature
  bias below;
* ``mount_roll_deg``, ``mount_yaw_deg``: the sensor body's orientation on the table — a rigid rotation composed with
  the table's, never added to its angles: M = R_x(φ_m)·R_z(ψ_m)·R_y(θ_m) (active rotations; its columns are the body
  axes in the table's frame), the disc centre in the body frame ``n_b = Mᵀ n_t`` (seed 004 eq. 2.6's composition).

The mount's pitch θ_m is not fitted: a turn of the body about its own Y_s, the scan's spin axis, turns each cone's
scan along itself — R_y(θ)·S_k(δ) = S_k(δ + θ) (seed 004 eq. 2.5) —, so it is a phase offset common to both cones,
exactly, whatever the plan (δ_reported = δ + o_k − θ_m). The fit holds it at the value it is given (default 0, the
fixture's pitch folded into the phase offsets, :meth:`HorizonSensorParameters.folded`), and the phase offsets it
reports are then the sensor's pitch zero on this fixture. Only a pitch error applied inside the table's roll (an error
of the table's own pitch, n = R_x(−φ)·R_y(−θ − Δθ)·ẑ) would be told from a phase offset, by the 1/cos φ of the chord's
centre (c = atan2(n_x, n_z), tan c = −tan θ / cos φ); the table's kinematics are the bench's, not fitted here.

Each cone reports the disc's edge where S_k(δ)·n_b = cos(ρ − b(ρ, α) + Δρ) (seed 004 eq. 2.7 corrected,
:func:`calibration.horizon.scan.crossing_phases_for_nadir`; :func:`model_disc_radius_deg`). b is the IFOV's known
curvature bias: the sensor's normalised constant-threshold locator (seed 004 eq. 2.1, C1 = 0.5) fires where half of
its top-hat IFOV of half-angle α covers the disc (seed 004 §2-4-2), and on a convex limb that is with the boresight
inside the disc by b = ρ − d_½(ρ, α) ≈ cot ρ · α²/6 (0.0047° at ρ = 67.9°, α = 2°;
:func:`calibration.horizon.ifov.locator_radius_bias_deg`, from the exact overlap of the two caps). It changes with ρ
(0.0056° at 64.3°, 0.0042° at 70.2°), so left to Δρ it would read as a cone angle when the plan spans several radii.
α is the design's (:attr:`HorizonSensorParameters.ifov_half_angle_deg`, IDENTIFY's 2° by default, or the bench
data's), never fitted; α = 0 is the bare boresight model. :func:`fit_horizon_bench` fits the parameters by
weighted least squares (:func:`scipy.optimize.least_squares`, a robust soft-L1 pass that names the outliers, then a
plain pass without them) to every edge's phase, weighted by the repeat scatter of its cone and edge; the covariance is
scaled by the χ²/dof against that scatter when the model misses by more than the noise. Identifiability is said in
words: the condition number of the scaled Jacobian and the pairs of parameters that trade.

Held out: each disc radius left out in turn (refit on the others, scored on it), and check points never fitted; for
both, the roll and pitch the calibrated sensor reports (solved from its crossings, :func:`solve_roll_pitch`, and
turned into the table's frame through the fitted mount) against the table's, beside those of the nominal sensor.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from scipy.optimize import least_squares

from ..errors import BenchDataError, FitError, InsufficientDataError
from .ifov import locator_radius_bias_deg
from .scan import (
    THESIS_GAMMA_DEG,
    THESIS_IFOV_HALF_ANGLE_DEG,
    crossing_phases_for_nadir,
    nadir_in_body,
    roll_pitch_of_nadir,
)

#: The fitted parameters, in the order of every vector and matrix [°].
PARAMETERS = ("gamma1_deg", "gamma2_deg", "phase_offset1_deg", "phase_offset2_deg", "radius_bias_deg",
              "mount_roll_deg", "mount_yaw_deg")
#: Every parameter of a sensor, the mount's pitch (given, never fitted: a common phase offset) last.
ALL_PARAMETERS = PARAMETERS + ("mount_pitch_deg",)
#: A residual beyond this many σ after the robust pass is an outlier, named and left out of the final pass.
OUTLIER_SIGMA = 5.0
#: The soft-L1 loss's scale, in σ: residuals beyond it weigh less in the robust pass.
ROBUST_SCALE_SIGMA = 3.0
#: |correlation| above this between two fitted parameters is worth a word.
CORRELATION_WARNING = 0.95
#: A condition number (of the Jacobian, columns scaled to unit norm) above this is worth a word.
CONDITION_WARNING = 1e3
#: Above this the plan does not determine the parameters at all (1σ of degrees or more): no fit, an error saying why.
CONDITION_LIMIT = 1e5
#: χ²/dof against the repeat scatter above this: the model misses by more than the noise.
CHI2_WARNING = 2.0
#: Held-out figures worse than this × the fitted ones are worth a word.
HELDOUT_WORSE = 3.0
#: The smallest noise an edge is weighted with [°] (a simulator without noise repeats itself exactly).
MIN_SIGMA_DEG = 1e-5
#: Rows within this of each other in roll, pitch and radius [°] are repeats of one pose.
POSE_TOLERANCE_DEG = 1e-3
#: Edges of a cone: the falling edge (Earth → space) and the rising one (space → Earth).
EDGES = ("out", "in")
#: The locator's threshold the IFOV's curvature bias is taken at (seed 004 eq. 2.1, the design's C1 = 0.5; a
#: threshold off it is Δρ's)
LOCATOR_LEVEL = 0.5

# why two parameters trade, when they do (the pair's names sorted)
_SPAN_ROLL = "span roll over the sensor's range (seed 004 Table 1-1: ±33°)"
_TRADES = {
    ("phase_offset1_deg", "phase_offset2_deg"): "both offsets move the chords' common centre; " + _SPAN_ROLL,
    ("mount_yaw_deg", "phase_offset1_deg"): "a mount yaw moves the chord's centre by ψ sin φ, an offset by o: "
    + _SPAN_ROLL,
    ("mount_yaw_deg", "phase_offset2_deg"): "a mount yaw moves the chord's centre by ψ sin φ, an offset by o: "
    + _SPAN_ROLL,
    ("gamma1_deg", "radius_bias_deg"): "a cone angle and the threshold bias both widen the chord; measure at disc "
    "radii further apart",
    ("gamma2_deg", "radius_bias_deg"): "a cone angle and the threshold bias both widen the chord; measure at disc "
    "radii further apart",
    ("gamma1_deg", "gamma2_deg"): "both cone angles widen the chords alike; measure at disc radii further apart and "
    + _SPAN_ROLL,
    ("gamma1_deg", "mount_roll_deg"): "a mount roll shifts the chords between the cones like unequal cone angles; "
    + _SPAN_ROLL,
    ("gamma2_deg", "mount_roll_deg"): "a mount roll shifts the chords between the cones like unequal cone angles; "
    + _SPAN_ROLL,
    ("mount_roll_deg", "radius_bias_deg"): "a mount roll tips one cone toward the disc, like a larger disc, and the "
    "other away; measure both cones and " + _SPAN_ROLL,
}


@dataclass(frozen=True)
class HorizonSensorParameters:
    """A horizon sensor's own errors (module docstring), all in degrees; the defaults are the nominal sensor of seed
    004 §3-5 (γ = 70°) on a perfect mount. `ifov_half_angle_deg` is the design's IFOV half-angle α, known and never
    fitted (not one of :data:`ALL_PARAMETERS`): the crossing model's curvature bias b(ρ, α); 0 leaves it out."""

    gamma1_deg: float = THESIS_GAMMA_DEG
    gamma2_deg: float = THESIS_GAMMA_DEG
    phase_offset1_deg: float = 0.0
    phase_offset2_deg: float = 0.0
    radius_bias_deg: float = 0.0
    mount_roll_deg: float = 0.0
    mount_yaw_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    ifov_half_angle_deg: float = THESIS_IFOV_HALF_ANGLE_DEG

    def vector(self) -> np.ndarray:
        """The fitted parameters in :data:`PARAMETERS` order (the mount's pitch is not one)."""
        return np.array([getattr(self, n) for n in PARAMETERS], float)

    def with_vector(self, values) -> HorizonSensorParameters:
        """These parameters with the fitted ones replaced by `values` (:data:`PARAMETERS` order)."""
        return replace(self, **{n: float(v) for n, v in zip(PARAMETERS, values)})

    def folded(self) -> HorizonSensorParameters:
        """The same sensor with the mount's pitch folded into the phase offsets, o_k − θ_m, and θ_m = 0: the
        reported phases are the same at every pose (module docstring), so this is what a bench fit can recover."""
        return replace(self, phase_offset1_deg=self.phase_offset1_deg - self.mount_pitch_deg,
                       phase_offset2_deg=self.phase_offset2_deg - self.mount_pitch_deg, mount_pitch_deg=0.0)

    def gamma_deg(self, cone) -> np.ndarray:
        """γ_k of each cone in `cone` (1 or 2) [°]."""
        return np.where(np.asarray(cone) == 1, self.gamma1_deg, self.gamma2_deg)

    def phase_offset_deg(self, cone) -> np.ndarray:
        """o_k of each cone in `cone` [°]."""
        return np.where(np.asarray(cone) == 1, self.phase_offset1_deg, self.phase_offset2_deg)

    def to_dict(self) -> dict:
        return {n: getattr(self, n) for n in ALL_PARAMETERS}


NOMINAL = HorizonSensorParameters()


def _rotation(axis: int, angle_deg) -> np.ndarray:
    """The active right-handed rotation about axis 0/1/2 by `angle_deg` [°], (3, 3)."""
    a = np.radians(float(angle_deg))
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.eye(3)
    out[i, i] = out[j, j] = c
    out[i, j], out[j, i] = -s, s
    return out


def mount_rotation(parameters: HorizonSensorParameters) -> np.ndarray:
    """M = R_x(φ_m)·R_z(ψ_m)·R_y(θ_m), active rotations: the columns are the sensor body's axes in the table's frame
    (module docstring; R_y(θ)·R_x(φ) is seed 004 eq. 2.6's body → orbit with the orthogonal R_x), shape (3, 3)."""
    return (_rotation(0, parameters.mount_roll_deg) @ _rotation(2, parameters.mount_yaw_deg)
            @ _rotation(1, parameters.mount_pitch_deg))


def mount_from_rotation(matrix) -> tuple[float, float, float]:
    """(φ_m, ψ_m, θ_m) [°] of a mount rotation M (columns: the body axes in the table's frame), M = R_x(φ_m)·R_z(ψ_m)·
    R_y(θ_m) (:func:`mount_rotation` inverted; |ψ_m| < 90°)."""
    m = np.asarray(matrix, float)
    yaw = np.arcsin(np.clip(-m[0, 1], -1.0, 1.0))
    roll = np.arctan2(m[2, 1], m[1, 1])
    pitch = np.arctan2(m[0, 2], m[0, 0])
    return float(np.degrees(roll)), float(np.degrees(yaw)), float(np.degrees(pitch))


def mount_offsets_from_tilts(tilt_x_deg: float, tilt_y_deg: float) -> tuple[float, float, float]:
    """The mount (φ_m, ψ_m, θ_m) [°] of a fixture tilt given as seed 003's boresight tipped toward body azimuth 0° by α
    (`tilt_x_deg`) and toward 90° by β (`tilt_y_deg`), the rotation R_y(α)·R_x(−β) (seed 003 eqs. 14–15): to first
    order (−β, 0, α), with a yaw of order αβ."""
    return mount_from_rotation(_rotation(1, tilt_x_deg) @ _rotation(0, -float(tilt_y_deg)))


def body_nadir(roll_deg, pitch_deg, parameters: HorizonSensorParameters = NOMINAL) -> np.ndarray:
    """The disc centre in the sensor's body frame, n_b = Mᵀ n_t, when the table sets roll φ and pitch θ [°]
    (n_t of seed 004 eq. 2.6; M of :func:`mount_rotation`), shape (…, 3)."""
    return nadir_in_body(roll_deg, pitch_deg) @ mount_rotation(parameters)  # row vectors: n_tᵀ M = (Mᵀ n_t)ᵀ


def table_roll_pitch(body_roll_deg, body_pitch_deg, parameters: HorizonSensorParameters = NOMINAL):
    """The roll and pitch in the table's frame [°] of a disc centre the sensor sees at body roll and pitch:
    n_t = M n_b (:func:`body_nadir` inverted), then θ = −asin n_x, φ = atan2(n_y, n_z) (seed 004 eqs. 2.25–2.26 with
    atan2)."""
    n_body = nadir_in_body(body_roll_deg, body_pitch_deg)
    return roll_pitch_of_nadir(np.einsum("ij,...j->...i", mount_rotation(parameters), n_body))


@lru_cache(maxsize=4096)
def _curvature_bias_deg(disc_radius_deg: float, ifov_half_angle_deg: float) -> float:
    return float(locator_radius_bias_deg(disc_radius_deg, ifov_half_angle_deg, LOCATOR_LEVEL))


def ifov_curvature_bias_deg(disc_radius_deg, ifov_half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG) -> np.ndarray:
    """b(ρ, α) [°]: how far inside a disc of angular radius ρ the boresight is when half of a top-hat IFOV of
    half-angle α covers it — where the normalised constant-threshold locator (seed 004 eq. 2.1, C1 = 0.5) fires on
    a convex limb (seed 004 §2-4-2; :func:`calibration.horizon.ifov.locator_radius_bias_deg`, the exact cap overlap;
    ≈ cot ρ · α²/6). 0 for α = 0. Cached per (ρ, α): a fit asks for the same few radii many times."""
    rho = np.asarray(disc_radius_deg, float)
    alpha = float(ifov_half_angle_deg)
    if alpha == 0.0:
        return np.zeros_like(rho)
    if not 0.0 < alpha < 10.0:
        raise ValueError(f"the IFOV half-angle must lie in [0, 10)°, got {ifov_half_angle_deg!r}")
    values, index = np.unique(rho, return_inverse=True)
    bias = np.array([_curvature_bias_deg(float(v), alpha) if np.isfinite(v) else np.nan for v in values])
    return bias[index].reshape(rho.shape)


def model_disc_radius_deg(disc_radius_deg, parameters: HorizonSensorParameters = NOMINAL) -> np.ndarray:
    """The angular radius [°] of the circle about the disc's centre on which the sensor reports the disc's edge:
    ρ − b(ρ, α) + Δρ — the IFOV's curvature bias (:func:`ifov_curvature_bias_deg`, α the parameters' known
    `ifov_half_angle_deg`) and the fitted threshold bias Δρ (module docstring; seed 004 §2-4-2, eq. 2.1)."""
    rho = np.asarray(disc_radius_deg, float)
    return rho - ifov_curvature_bias_deg(rho, parameters.ifov_half_angle_deg) + parameters.radius_bias_deg


def predicted_phases(roll_deg, pitch_deg, disc_radius_deg, cone, parameters: HorizonSensorParameters = NOMINAL):
    """The phases [°, in [0, 360)] cone `cone` reports for the disc's falling and rising edges, ``(phase_out,
    phase_in)``, when the table sets roll φ, pitch θ and the iris radius ρ: the crossings of
    S_k(δ)·n_b = cos(ρ − b(ρ, α) + Δρ) with γ_k (seed 004 eqs. 2.5–2.7 corrected,
    :func:`calibration.horizon.scan.crossing_phases_for_nadir`; b the IFOV's curvature bias of seed 004 §2-4-2 at
    C1 = 0.5, :func:`model_disc_radius_deg`) plus the cone's phase offset o_k. NaN where the cone does not cross the
    disc's edge."""
    cone = np.asarray(cone)
    n_b = body_nadir(roll_deg, pitch_deg, parameters)
    rho = model_disc_radius_deg(disc_radius_deg, parameters)
    out, in_ = crossing_phases_for_nadir(n_b, rho, parameters.gamma_deg(cone), cone)
    offset = parameters.phase_offset_deg(cone)
    return np.mod(out + offset, 360.0), np.mod(in_ + offset, 360.0)


def wrap_deg(angle) -> np.ndarray:
    """An angle difference wrapped to [−180, 180) [°]."""
    return np.mod(np.asarray(angle, float) + 180.0, 360.0) - 180.0


# --- the data -------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HorizonBenchData:
    """Horizon bench data: one row per cone of one scan (revolution).

    Attributes
    ----------
    roll_deg, pitch_deg : ndarray (N,)
        What the table set, in its own frame (the disc centre at n_t(φ, θ)) [°].
    cone : ndarray of int (N,)
        1 or 2.
    phase_out_deg, phase_in_deg : ndarray (N,)
        The reported phases of the falling (Earth → space) and rising (space → Earth) edges, 360° · t / T [°]; NaN
        where the module found no edge.
    disc_radius_deg : ndarray (N,)
        The disc radius the Earth simulator reported [°].
    scan : ndarray of int (N,)
        Which revolution a row belongs to: both cones' rows of one scan share it (default: every row its own).
    repeat : ndarray of int (N,)
    check : ndarray of bool (N,)
        Check rows: never fitted, only scored.
    sensor_id : str or None
    row_id : ndarray of int (N,)
        The rows' names in error messages (a file's data row, a catalogue's reading).
    ifov_half_angle_deg : float or None
        The sensor's IFOV half-angle α [°] as its IDENTIFY reports it (the crossing model's curvature bias, module
        docstring); None: not recorded, the fit's start (the design's 2°) is taken.
    """

    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    cone: np.ndarray
    phase_out_deg: np.ndarray
    phase_in_deg: np.ndarray
    disc_radius_deg: np.ndarray
    scan: np.ndarray | None = None
    repeat: np.ndarray | None = None
    check: np.ndarray | None = None
    sensor_id: str | None = None
    row_id: np.ndarray | None = None
    ifov_half_angle_deg: float | None = None

    def __post_init__(self) -> None:
        if self.ifov_half_angle_deg is not None:
            alpha = self.ifov_half_angle_deg
            if isinstance(alpha, bool) or not isinstance(alpha, (int, float, np.number)) \
                    or not 0.0 <= float(alpha) < 10.0:
                raise BenchDataError(f"the IFOV half-angle must be a number in [0, 10)°, got {alpha!r}",
                                     column="ifov_half_angle_deg")
            object.__setattr__(self, "ifov_half_angle_deg", float(alpha))
        numbers = ("roll_deg", "pitch_deg", "phase_out_deg", "phase_in_deg", "disc_radius_deg")
        for name in numbers:
            object.__setattr__(self, name, np.atleast_1d(np.asarray(getattr(self, name), float)))
        n = self.roll_deg.size
        object.__setattr__(self, "cone", np.atleast_1d(np.asarray(self.cone)).astype(int))
        defaults = {"scan": np.arange(n), "repeat": np.zeros(n, int), "check": np.zeros(n, bool),
                    "row_id": np.arange(n)}
        for name, default in defaults.items():
            value = getattr(self, name)
            value = default if value is None else np.atleast_1d(np.asarray(value))
            object.__setattr__(self, name, value.astype(bool if name == "check" else int))
        for name in numbers + ("cone", *defaults):
            if getattr(self, name).shape != (n,):
                raise BenchDataError(f"{name} has {getattr(self, name).size} values, roll_deg {n}", column=name)
        for name in ("roll_deg", "pitch_deg", "disc_radius_deg"):
            _refuse(~np.isfinite(getattr(self, name)), name, "must be a finite number")
        _refuse(~np.isin(self.cone, (1, 2)), "cone", "a cone is 1 or 2")
        _refuse(np.abs(self.roll_deg) >= 90.0, "roll_deg", "a roll lies within ±90°")
        _refuse(np.abs(self.pitch_deg) >= 90.0, "pitch_deg", "a pitch lies within ±90°")
        _refuse((self.disc_radius_deg <= 0.0) | (self.disc_radius_deg >= 90.0), "disc_radius_deg",
                "a disc radius lies in (0, 90)°")
        for name in ("phase_out_deg", "phase_in_deg"):
            _refuse(np.isinf(getattr(self, name)), name, "must be finite (NaN: no edge)")
            object.__setattr__(self, name, np.mod(getattr(self, name), 360.0))
        pairs = {}
        for i, key in enumerate(zip(self.scan.tolist(), self.cone.tolist())):
            if key in pairs:
                raise BenchDataError(f"scan {key[0]} has two rows of cone {key[1]}", row=i, column="cone")
            pairs[key] = i

    def __len__(self) -> int:
        return int(self.roll_deg.size)

    def subset(self, mask) -> HorizonBenchData:
        """The rows where `mask` (boolean or indices)."""
        take = lambda a: a[mask]  # noqa: E731
        return replace(self, **{n: take(getattr(self, n)) for n in (
            "roll_deg", "pitch_deg", "cone", "phase_out_deg", "phase_in_deg", "disc_radius_deg", "scan", "repeat",
            "check", "row_id")})

    def phases(self) -> np.ndarray:
        """(N, 2): the falling and rising edges' phases [°]."""
        return np.column_stack([self.phase_out_deg, self.phase_in_deg])

    def pose_groups(self) -> np.ndarray:
        """A group index per row: rows of one pose (roll, pitch, radius within :data:`POSE_TOLERANCE_DEG`), one cone
        and one kind (fitted or check) are repeats."""
        q = lambda a: np.round(np.asarray(a) / POSE_TOLERANCE_DEG).astype(np.int64)  # noqa: E731
        keys = np.column_stack([q(self.roll_deg), q(self.pitch_deg), q(self.disc_radius_deg), self.cone,
                                self.check.astype(int)])
        return np.unique(keys, axis=0, return_inverse=True)[1].ravel()

    def radii(self) -> np.ndarray:
        """The distinct disc radii [°] (within :data:`POSE_TOLERANCE_DEG`)."""
        return np.unique(np.round(self.disc_radius_deg / POSE_TOLERANCE_DEG)) * POSE_TOLERANCE_DEG


def _refuse(bad, column: str, message: str) -> None:
    bad = np.asarray(bad)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise BenchDataError(f"{message}", row=i, column=column)


# --- the noise --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EdgeNoise:
    """The noise of each cone's edges [°] (1σ of one reported phase).

    Attributes
    ----------
    sigma_deg : dict of (cone, edge) to float
    dof : dict of (cone, edge) to int
        The repeat scatter's degrees of freedom (0: not from repeats).
    source : str
        "repeats" (the pooled scatter of repeated scans at a pose) or "residuals" (no repeats: the fit's residuals).
    """

    sigma_deg: dict
    dof: dict
    source: str

    def per_row(self, cone) -> np.ndarray:
        """(N, 2): the σ of each row's out and in edges."""
        cone = np.asarray(cone)
        return np.column_stack([np.where(cone == 1, self.sigma_deg[(1, e)], self.sigma_deg[(2, e)]) for e in EDGES])

    def to_dict(self) -> dict:
        return {f"cone{c}_{e}": {"sigma_deg": self.sigma_deg[(c, e)], "dof": self.dof[(c, e)]}
                for c in (1, 2) for e in EDGES}


def repeat_scatter(data: HorizonBenchData) -> EdgeNoise:
    """Each cone's and edge's noise from the scatter of repeated scans at one pose (seed 004 §2-3: one scan, one
    crossing per edge), pooled over the poses: Σ(δ − δ̄)² / Σ(n − 1), a deviation beyond 5 robust σ (1.4826 × the
    median absolute deviation) left out as a glitch. Where no pose has repeats, the source is "residuals" and the σ
    a placeholder of 1 until the fit's residuals replace it."""
    groups = data.pose_groups()
    phases = data.phases()
    sigma, dof = {}, {}
    for cone in (1, 2):
        for k, edge in enumerate(EDGES):
            rows = (data.cone == cone) & np.isfinite(phases[:, k])
            if not rows.any():
                sigma[(cone, edge)], dof[(cone, edge)] = 1.0, 0
                continue
            g, v = groups[rows], phases[rows, k]
            # the circular mean of each group (an edge near 0°/360° wraps)
            ref = np.zeros(groups.max() + 1)
            ref[g] = v
            dev = wrap_deg(v - ref[g])
            counts = np.bincount(g, minlength=groups.max() + 1)
            mean = np.bincount(g, weights=dev, minlength=groups.max() + 1) / np.maximum(counts, 1)
            dev = dev - mean[g]
            many = counts[g] > 1
            if not many.any():
                sigma[(cone, edge)], dof[(cone, edge)] = 1.0, 0
                continue
            robust = 1.4826 * np.median(np.abs(dev[many])) * np.sqrt(np.mean(counts[g][many] / (counts[g][many] - 1)))
            keep = many & (np.abs(dev) <= 5.0 * max(robust, MIN_SIGMA_DEG))
            n_kept = np.bincount(g[keep], minlength=counts.size)
            mean_kept = np.bincount(g[keep], weights=dev[keep], minlength=counts.size) / np.maximum(n_kept, 1)
            ss = np.sum((dev[keep] - mean_kept[g[keep]]) ** 2)
            d = int(np.sum(np.maximum(n_kept - 1, 0)))
            sigma[(cone, edge)] = max(float(np.sqrt(ss / d)) if d else 1.0, MIN_SIGMA_DEG)
            dof[(cone, edge)] = d
    source = "repeats" if any(dof.values()) else "residuals"
    if source == "repeats":  # an edge without repeats borrows the pooled σ of the others
        known = [sigma[k] for k in sigma if dof[k]]
        pooled = float(np.sqrt(np.mean(np.square(known))))
        sigma = {k: (s if dof[k] else pooled) for k, s in sigma.items()}
    return EdgeNoise(sigma, dof, source)


# --- roll and pitch of the calibrated sensor -------------------------------------------------------------------------
def solve_roll_pitch(data: HorizonBenchData, parameters: HorizonSensorParameters = NOMINAL, *,
                     iterations: int = 30) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each scan's roll and pitch in the sensor's body frame [°] from its reported crossings, the sensor described by
    `parameters` (γ_k, o_k, ρ − b(ρ, α) + Δρ; no mount: what the sensor itself would report).

    Gauss–Newton on the crossing equations of every edge the scan has (seed 004 eq. 2.7 corrected: two crossings with
    ρ known determine roll and pitch, four over-determine them), started from the chord centre's pitch (tan c =
    −tan θ / cos φ at φ = 0) and zero roll.

    Returns
    -------
    scans : ndarray of int
        The scan ids, sorted.
    roll_deg, pitch_deg : ndarray
        NaN for a scan with fewer than two edges or that did not converge.
    """
    scans, index = np.unique(data.scan, return_inverse=True)
    n = scans.size
    phases = data.phases() - parameters.phase_offset_deg(data.cone)[:, None]
    found = np.isfinite(phases)
    # start: the chord's centre c = −θ at zero roll; the chord runs from the rising edge (c − w) to the falling one
    # (c + w)
    half = np.mod(phases[:, 0] - phases[:, 1], 360.0) / 2.0
    centre = np.where(found.all(axis=1), wrap_deg(phases[:, 1] + half), np.nan)
    sums = np.bincount(index, weights=np.nan_to_num(centre), minlength=n)
    counts = np.bincount(index, weights=np.isfinite(centre).astype(float), minlength=n)
    roll = np.zeros(n)
    pitch = np.where(counts > 0, -sums / np.maximum(counts, 1), 0.0)
    rho = model_disc_radius_deg(data.disc_radius_deg, parameters)
    gamma = parameters.gamma_deg(data.cone)

    def model(r, p):
        out, in_ = crossing_phases_for_nadir(nadir_in_body(r[index], p[index]), rho, gamma, data.cone)
        return np.column_stack([out, in_])

    step = 1e-4
    converged = np.zeros(n, bool)
    for _ in range(iterations):
        f = model(roll, pitch)
        residual = wrap_deg(phases - f)
        jr = wrap_deg(model(roll + step, pitch) - f) / step
        jp = wrap_deg(model(roll, pitch + step) - f) / step
        use = found & np.isfinite(residual) & np.isfinite(jr) & np.isfinite(jp)
        r, a, b = (np.where(use, x, 0.0) for x in (residual, jr, jp))
        saa = np.bincount(index, (a * a).sum(1), n)
        sab = np.bincount(index, (a * b).sum(1), n)
        sbb = np.bincount(index, (b * b).sum(1), n)
        sar = np.bincount(index, (a * r).sum(1), n)
        sbr = np.bincount(index, (b * r).sum(1), n)
        det = saa * sbb - sab * sab
        ok = np.abs(det) > 1e-12
        d_roll = np.where(ok, (sbb * sar - sab * sbr) / np.where(ok, det, 1.0), 0.0)
        d_pitch = np.where(ok, (saa * sbr - sab * sar) / np.where(ok, det, 1.0), 0.0)
        d_roll, d_pitch = np.clip(d_roll, -10.0, 10.0), np.clip(d_pitch, -10.0, 10.0)  # a bounded step
        roll, pitch = roll + d_roll, pitch + d_pitch
        converged = ok & (np.abs(d_roll) < 1e-7) & (np.abs(d_pitch) < 1e-7)
        if converged.all():
            break
    edges = np.bincount(index, found.sum(1), n)
    good = converged & (edges >= 2)
    return scans, np.where(good, roll, np.nan), np.where(good, pitch, np.nan)


@dataclass(frozen=True)
class AttitudeErrors:
    """Roll and pitch the sensor reports (through `parameters`, in the table's frame) against the table's [°].

    Attributes
    ----------
    n_scans : int
        Scans scored; `n_failed` more had no solution.
    roll_rms_deg, roll_max_deg, pitch_rms_deg, pitch_max_deg : float
        RMS and largest |error|; NaN without scans.
    roll_mean_deg, pitch_mean_deg : float
        The mean error (a bias the calibration leaves).
    """

    n_scans: int
    n_failed: int
    roll_rms_deg: float
    roll_max_deg: float
    roll_mean_deg: float
    pitch_rms_deg: float
    pitch_max_deg: float
    pitch_mean_deg: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def attitude_errors(data: HorizonBenchData, parameters: HorizonSensorParameters = NOMINAL) -> AttitudeErrors:
    """The roll and pitch errors of a sensor described by `parameters` on the scans of `data`: each scan's body roll
    and pitch (:func:`solve_roll_pitch`) turned into the table's frame through the mount (:func:`table_roll_pitch`)
    and compared with what the table set."""
    scans, roll, pitch = solve_roll_pitch(data, parameters)
    first = np.unique(data.scan, return_index=True)[1]
    table_roll, table_pitch = table_roll_pitch(np.nan_to_num(roll), np.nan_to_num(pitch), parameters)
    ok = np.isfinite(roll) & np.isfinite(pitch)
    e_roll = wrap_deg(table_roll - data.roll_deg[first])[ok]
    e_pitch = (table_pitch - data.pitch_deg[first])[ok]

    def stats(e):
        if not e.size:
            return float("nan"), float("nan"), float("nan")
        return float(np.sqrt(np.mean(e ** 2))), float(np.max(np.abs(e))), float(np.mean(e))

    r, p = stats(e_roll), stats(e_pitch)
    return AttitudeErrors(int(ok.sum()), int((~ok).sum()), r[0], r[1], r[2], p[0], p[1], p[2])


# --- the fit ----------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RejectedEdge:
    """An edge left out of the fit: its row, cone, which edge, the pose and the residual."""

    row_id: int
    cone: int
    edge: str
    roll_deg: float
    pitch_deg: float
    disc_radius_deg: float
    residual_deg: float
    reason: str

    def describe(self) -> str:
        return (f"row {self.row_id} cone {self.cone} {self.edge} edge (roll {self.roll_deg:.2f}°, pitch "
                f"{self.pitch_deg:.2f}°, ρ {self.disc_radius_deg:.3f}°): {self.reason}")

    def to_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class HorizonBenchFit:
    """What :func:`fit_horizon_bench` found (the document: :mod:`calibration.horizon.bench_document`).

    Attributes
    ----------
    parameters : HorizonSensorParameters
    free : tuple of str
        The fitted parameters (a cone without an edge found keeps its γ and offset where the fit started, the
        nominal ones by default: :func:`cones_with_edges`).
    sd : dict of str to float
        1σ of each fitted parameter [°], from `covariance`.
    covariance : ndarray (F, F)
        Of the free parameters, (JᵀWJ)⁻¹ × `uncertainty_scale`.
    correlation : ndarray (F, F)
    condition_number : float
        Of the weighted Jacobian with its columns scaled to unit norm.
    trades : list of str
        The parameter pairs that trade, in words.
    chi2_dof : float
        Σ(residual/σ)² / dof against the noise (`noise`): ≈ 1 when the model explains the data to the noise.
    dof : int
    uncertainty_scale : float
        max(1, χ²/dof): the covariance's scale (a misfit beyond the noise widens the stated 1σ).
    noise : EdgeNoise
    rms_deg : float
        RMS phase residual of the fitted edges [°].
    n_scans, n_edges, n_missing : int
        Fitted scans, edges fitted, edges the module did not find (NaN).
    rejected : list of RejectedEdge
    heldout : dict or None
        ``radius_out``: one entry per disc radius left out; ``check``: the check scans (calibrated, nominal);
        ``at_nodes``: the fitted scans (calibrated, nominal).
    warnings : list of str
    radii_deg, roll_span_deg, pitch_span_deg : the plan's extent
    """

    parameters: HorizonSensorParameters
    free: tuple
    sd: dict
    covariance: np.ndarray
    correlation: np.ndarray
    condition_number: float
    trades: list
    chi2_dof: float
    dof: int
    uncertainty_scale: float
    noise: EdgeNoise
    rms_deg: float
    n_scans: int
    n_edges: int
    n_missing: int
    rejected: list = field(default_factory=list)
    heldout: dict | None = None
    warnings: list = field(default_factory=list)
    radii_deg: tuple = ()
    roll_span_deg: tuple = ()
    pitch_span_deg: tuple = ()
    sensor_id: str | None = None


#: The parameters only a cone's own scans determine
_CONE_PARAMETERS = {1: ("gamma1_deg", "phase_offset1_deg"), 2: ("gamma2_deg", "phase_offset2_deg")}


def cones_with_edges(data: HorizonBenchData) -> tuple:
    """The cones (1, 2) of which `data` holds at least one edge found (a finite phase). A cone without scans, or whose
    detector found no edge in any of them (a dead detector, a pulse saturated all run: its rows' phases are all NaN),
    has nothing to determine its own parameters γ_k and o_k (seed 004 eqs. 2.5–2.7: only cone k's crossings
    depend on them)."""
    found = np.isfinite(data.phases()).any(axis=1)
    return tuple(c for c in (1, 2) if np.any(found & (data.cone == c)))


def _free_parameters(data: HorizonBenchData) -> tuple:
    """The parameters the data can fit: a cone without an edge found keeps its γ and offset where the fit starts."""
    cones = cones_with_edges(data)
    fixed = {n for cone, names in _CONE_PARAMETERS.items() if cone not in cones for n in names}
    return tuple(n for n in PARAMETERS if n not in fixed)


def _residuals(x, free, base: HorizonSensorParameters, data, observed, sigma, use):
    values = base.vector()
    values[[PARAMETERS.index(n) for n in free]] = x
    parameters = base.with_vector(values)
    out, in_ = predicted_phases(data.roll_deg, data.pitch_deg, data.disc_radius_deg, data.cone, parameters)
    r = wrap_deg(observed - np.column_stack([out, in_]))
    r = np.where(np.isfinite(r), r, 180.0)  # the model lost the crossing: as far off as a phase can be
    return (r / sigma)[use]


def _solve(data, free, start: HorizonSensorParameters, noise: EdgeNoise, use, loss: str):
    observed = data.phases()
    sigma = noise.per_row(data.cone)
    x0 = start.vector()[[PARAMETERS.index(n) for n in free]]
    # the Jacobian's steps are scipy's default, √ε·max(1, |x|) [°]: a step relative to the value alone (diff_step)
    # shrinks to nothing for a parameter near 0 (Δρ, the mount), below the phases' rounding
    result = least_squares(_residuals, x0, args=(free, start, data, observed, sigma, use), method="trf", loss=loss,
                           f_scale=ROBUST_SCALE_SIGMA, x_scale=0.01, xtol=1e-12, ftol=1e-12, gtol=1e-12,
                           max_nfev=500)
    values = start.vector()
    values[[PARAMETERS.index(n) for n in free]] = result.x
    return start.with_vector(values), result


def _fit_core(data, free, start, noise, use):
    """The robust pass, the outliers, the plain pass: (parameters, result, use, outliers)."""
    robust, _ = _solve(data, free, start, noise, use, "soft_l1")
    r = np.full(use.shape, np.nan)
    r[use] = _residuals(robust.vector()[[PARAMETERS.index(n) for n in free]], free, robust, data, data.phases(),
                        noise.per_row(data.cone), use)
    outliers = use & (np.abs(r) > OUTLIER_SIGMA)
    use = use & ~outliers
    parameters, result = _solve(data, free, robust, noise, use, "linear")
    return parameters, result, use, outliers


def _phase_scores(data, parameters, noise) -> dict:
    out, in_ = predicted_phases(data.roll_deg, data.pitch_deg, data.disc_radius_deg, data.cone, parameters)
    r = wrap_deg(data.phases() - np.column_stack([out, in_]))
    ok = np.isfinite(r)
    if not ok.any():
        return {"n_edges": 0, "phase_rms_deg": None, "phase_rms_sigma": None}
    return {"n_edges": int(ok.sum()), "phase_rms_deg": float(np.sqrt(np.mean(r[ok] ** 2))),
            "phase_rms_sigma": float(np.sqrt(np.mean((r / noise.per_row(data.cone))[ok] ** 2)))}


def fit_horizon_bench(data: HorizonBenchData, *, start: HorizonSensorParameters = NOMINAL,
                      heldout: bool = True) -> HorizonBenchFit:
    """Fit a horizon sensor's own errors (:data:`PARAMETERS`) to bench scans (module docstring).

    Parameters
    ----------
    data : HorizonBenchData
        Check rows are scored, never fitted.
    start : HorizonSensorParameters
        Where the fit starts (the nominal sensor by default); its `ifov_half_angle_deg` is the IFOV's α of the
        crossing model unless `data` records one.
    heldout : bool
        Also leave each disc radius out in turn and score the check rows (off: the fit alone, for Monte Carlo).

    Returns
    -------
    HorizonBenchFit

    Raises
    ------
    InsufficientDataError
        Fewer edges than parameters, or every pose alike.
    FitError
        The least squares did not converge, or the plan does not determine the parameters (the scaled Jacobian's
        condition number above :data:`CONDITION_LIMIT`); the message names the parameters it hardly separates.

    References
    ----------
    seed 004 eqs. 2.3–2.7 (the crossing model), eq. 2.1 with C1 = 0.5 and §2-4-2 (the threshold locator on the
    IFOV's obscuration: the curvature bias b(ρ, α), known; Δρ the free bias on top of it); research note
    anchors-sunsensors §6 (covariance, held-out accuracy).
    """
    if data.ifov_half_angle_deg is not None:
        start = replace(start, ifov_half_angle_deg=data.ifov_half_angle_deg)
    fitted = data.subset(~data.check)
    if not len(fitted):
        raise InsufficientDataError("no fitted rows (every row is a check row)")
    free = _free_parameters(fitted)
    noise = repeat_scatter(fitted)
    found = np.isfinite(fitted.phases())
    if found.sum() <= len(free):
        raise InsufficientDataError(f"{int(found.sum())} edges cannot fit {len(free)} parameters")
    if np.ptp(fitted.roll_deg) < 1.0 and np.ptp(fitted.pitch_deg) < 1.0:
        raise InsufficientDataError("every fitted scan is at one pose: the mount and the phase offsets need roll and "
                                    "pitch spread over the sensor's range")
    parameters, result, use, outliers = _fit_core(fitted, free, start, noise, found)
    if not result.success:
        raise FitError(f"the horizon sensor's fit did not converge ({result.message}); "
                       + _weakest(free, result.jac))
    residual = result.fun
    dof = int(use.sum()) - len(free)
    if noise.source == "residuals":  # no repeats: the residuals are the noise (χ²/dof = 1 by construction)
        raw = residual * noise.per_row(fitted.cone)[use]
        s = max(float(np.sqrt(np.sum(raw ** 2) / max(dof, 1))), MIN_SIGMA_DEG)
        noise = EdgeNoise({k: s for k in noise.sigma_deg}, noise.dof, "residuals")
        parameters, result, use, outliers = _fit_core(fitted, free, parameters, noise, found)
        residual = result.fun
        dof = int(use.sum()) - len(free)
    chi2_dof = float(np.sum(residual ** 2) / max(dof, 1))
    scale = max(1.0, chi2_dof)
    jac = result.jac
    norms = np.linalg.norm(jac, axis=0)
    if np.any(norms == 0):
        dead = [free[i] for i in np.flatnonzero(norms == 0)]
        raise InsufficientDataError(f"the data do not constrain {', '.join(dead)}")
    singular = np.linalg.svd(jac / norms, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    if condition > CONDITION_LIMIT:
        raise FitError("the horizon sensor's parameters are not determined; " + _weakest(free, jac))
    covariance = np.linalg.pinv(jac.T @ jac) * scale
    sd_values = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    correlation = covariance / np.outer(sd_values, sd_values)
    trades = _trades(free, correlation)
    raw_residual = wrap_deg(fitted.phases() - np.column_stack(predicted_phases(
        fitted.roll_deg, fitted.pitch_deg, fitted.disc_radius_deg, fitted.cone, parameters)))
    rejected = _rejected(fitted, outliers, raw_residual, noise)
    fit = HorizonBenchFit(
        parameters=parameters, free=free, sd=dict(zip(free, sd_values.tolist())), covariance=covariance,
        correlation=correlation, condition_number=condition, trades=trades, chi2_dof=chi2_dof, dof=dof,
        uncertainty_scale=scale, noise=noise, rms_deg=float(np.sqrt(np.mean(raw_residual[use] ** 2))),
        n_scans=int(np.unique(fitted.scan).size), n_edges=int(use.sum()), n_missing=int((~found).sum()),
        rejected=rejected, radii_deg=tuple(fitted.radii().tolist()),
        roll_span_deg=(float(fitted.roll_deg.min()), float(fitted.roll_deg.max())),
        pitch_span_deg=(float(fitted.pitch_deg.min()), float(fitted.pitch_deg.max())), sensor_id=data.sensor_id)
    scores = _heldout(data, fit, noise) if heldout else None
    return replace(fit, heldout=scores, warnings=_warnings(data, fit, scores))


def _weakest(free, jac) -> str:
    """The parameters the data determine least, in words (the smallest singular vector of the scaled Jacobian)."""
    norms = np.linalg.norm(jac, axis=0)
    _, singular, vt = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), full_matrices=False)
    weights = np.abs(vt[-1])
    names = [free[i] for i in np.argsort(weights)[::-1] if weights[i] > 0.3]
    condition = singular[0] / singular[-1] if singular[-1] > 0 else float("inf")
    return (f"the plan hardly separates {' and '.join(names)} (condition number {condition:.3g}): spread roll, pitch "
            "and the disc radius over the sensor's range, with both cones")


def _rejected(data, outliers, residual, noise) -> list:
    out = []
    sigma = noise.per_row(data.cone)
    for i, k in zip(*np.nonzero(outliers)):
        out.append(RejectedEdge(int(data.row_id[i]), int(data.cone[i]), EDGES[k], float(data.roll_deg[i]),
                                float(data.pitch_deg[i]), float(data.disc_radius_deg[i]), float(residual[i, k]),
                                f"{residual[i, k]:+.4f}° off the fit ({abs(residual[i, k]) / sigma[i, k]:.0f} σ, more "
                                f"than {OUTLIER_SIGMA:g} σ)"))
    return out


def _trades(free, correlation) -> list:
    out = []
    for i in range(len(free)):
        for j in range(i + 1, len(free)):
            c = correlation[i, j]
            if abs(c) > CORRELATION_WARNING:
                pair = tuple(sorted((free[i], free[j])))
                why = _TRADES.get(pair, "the plan does not separate them")
                out.append(f"{free[i]} and {free[j]} trade (correlation {c:+.3f}): {why}")
    return out


def _heldout(data: HorizonBenchData, fit: HorizonBenchFit, noise: EdgeNoise) -> dict:
    """Leave-one-radius-out, the check scans and the fitted scans (module docstring)."""
    fitted = data.subset(~data.check)
    radius_out = []
    radii = fitted.radii()
    if radii.size >= 2:
        for radius in radii:
            left = np.abs(fitted.disc_radius_deg - radius) < POSE_TOLERANCE_DEG
            rest = fitted.subset(~left)
            found = np.isfinite(rest.phases())
            free = _free_parameters(rest)
            try:
                parameters, result, _, _ = _fit_core(rest, free, fit.parameters, noise, found)
            except (ValueError, np.linalg.LinAlgError):
                parameters = None
            entry = {"disc_radius_deg": float(radius), "n_scans": int(np.unique(fitted.scan[left]).size)}
            if parameters is not None:
                scored = fitted.subset(left)
                entry.update(_phase_scores(scored, parameters, noise))
                entry["calibrated"] = attitude_errors(scored, parameters).to_dict()
                entry["parameters"] = parameters.to_dict()
            radius_out.append(entry)
    check = data.subset(data.check)
    return {
        "radius_out": radius_out,
        "check": None if not len(check) else {**_phase_scores(check, fit.parameters, noise),
                                              "calibrated": attitude_errors(check, fit.parameters).to_dict(),
                                              "nominal": attitude_errors(check, NOMINAL).to_dict()},
        "at_nodes": {**_phase_scores(fitted, fit.parameters, noise),
                     "calibrated": attitude_errors(fitted, fit.parameters).to_dict(),
                     "nominal": attitude_errors(fitted, NOMINAL).to_dict()},
    }


def _warnings(data: HorizonBenchData, fit: HorizonBenchFit, scores: dict | None) -> list:
    out = []
    fitted = data.subset(~data.check)
    cones = cones_with_edges(fitted)
    for c in (1, 2):
        if c in cones:
            continue
        scans = int(np.unique(fitted.scan[fitted.cone == c]).size)
        why = f"no scans of cone {c}" if not scans else (
            f"cone {c} found no edge in any of its {scans} scans (a dead detector, or its pulse saturated all run)")
        out.append(f"{why}: its cone angle gamma{c}_deg and phase offset phase_offset{c}_deg are not fitted (kept at "
                   f"{float(fit.parameters.gamma_deg(c)):g}° and {float(fit.parameters.phase_offset_deg(c)):g}°)")
    if fit.noise.source == "residuals":
        out.append("no repeated scans at a pose: the noise is taken from the fit's residuals, so χ²/dof says nothing "
                   "of the model's misfit; measure `repeats` ≥ 2")
    if fit.chi2_dof > CHI2_WARNING:
        out.append(f"χ²/dof {fit.chi2_dof:.1f} against the repeat scatter: the crossing model misses by more than the "
                   "noise (a source off the table's axes, a disc that is not round, an IFOV blur that changes with "
                   f"the crossing's angle); the stated 1σ are widened by √{fit.chi2_dof:.1f}")
    if fit.condition_number > CONDITION_WARNING:
        out.append(f"condition number {fit.condition_number:.3g}: the plan separates the parameters poorly")
    out.extend(fit.trades)
    if len(fit.radii_deg) < 2:
        out.append("a single disc radius: the cone angles and the threshold bias are told apart only by the roll and "
                   "pitch spread; measure at several radii (several altitudes)")
    span = fit.roll_span_deg[1] - fit.roll_span_deg[0] if fit.roll_span_deg else 0.0
    if span < 20.0:
        out.append(f"roll spans {span:.1f}°: the mount's yaw (it moves the chord's centre by ψ sin φ) and roll and the "
                   "cones' difference are told from the phase offsets and the cone angles by roll; " + _SPAN_ROLL)
    lost = fit.n_missing - int(np.sum(~np.isin(fitted.cone, cones))) * len(EDGES)  # beyond a cone without any, said
    if lost:
        out.append(f"{lost} edge(s) not found by the module (left out)")
    if fit.rejected:
        out.append(f"{len(fit.rejected)} edge(s) rejected as outliers (> {OUTLIER_SIGMA:g} σ)")
    if scores is not None:
        nodes = scores["at_nodes"]
        for entry in scores["radius_out"]:
            if entry.get("phase_rms_deg") is not None and nodes["phase_rms_deg"] and \
                    entry["phase_rms_deg"] > HELDOUT_WORSE * nodes["phase_rms_deg"]:
                out.append(f"with the disc radius {entry['disc_radius_deg']:.3f}° left out, its phases miss by "
                           f"{entry['phase_rms_deg']:.4f}° RMS, {entry['phase_rms_deg'] / nodes['phase_rms_deg']:.1f}× "
                           "the fitted residual: the radius dependence (Δρ, γ) is not well determined")
        if scores["check"] is None:
            out.append("no check rows: held-out figures come from leaving disc radii out only")
    return out
