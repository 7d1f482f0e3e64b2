"""Which bench directions to measure, in which order, and when to stop: the experiment design of the
physical calibration.

The physical model (:mod:`calibration.models.physical`) has nine build parameters; the seed 003 grid
(§4.2: the centre stage, then 8 azimuths × zenith 0–60° in 10° steps, 4 frames each, 80 poses) measures far
more directions than they need. Here the directions are chosen by the information they carry about those
parameters:

* the Jacobian of the spot centre [px] with respect to the build parameters, at a nominal build, by
  central differences of :func:`calibration.pinhole.spot_from_vectors` (:func:`spot_jacobian`);
* a greedy D-optimal selection from a candidate grid over the field of view (:func:`greedy_d_optimal`):
  each step adds the candidate that most increases log det of the Fisher information, so every prefix of
  the selection is itself a good design and the run can stop after any batch;
* a few check directions spread over the field and never fitted (:func:`check_directions`), which score
  the calibration where it was not fitted;
* the order of the chosen poses that shortens the table's travel (:func:`order_tour`): a nearest-neighbour
  tour improved by 2-opt, each move costing the slower of the two axes' trapezoidal moves;
* the stopping rule (:func:`stopping_decision`): every parameter's 1σ below its target and the check
  directions' vector RMS below its target.

Everything is pure: numbers in, numbers out, no I/O.

References
----------
A. C. Atkinson, A. N. Donev, R. D. Tobias, *Optimum Experimental Designs, with SAS*, Oxford 2007:
ch. 10–11 (D-optimality, the determinant of the information matrix), ch. 12 (sequential construction,
the greedy forward algorithm), ch. 17 (non-linear models: designs at a nominal parameter value, "locally
optimal"). K. Chaloner, I. Verdinelli, "Bayesian experimental design: a review", Statist. Sci. 10 (1995)
273–304 (the weak prior that makes log det finite before the design determines every parameter).
S. Lin, B. W. Kernighan, Oper. Res. 21 (1973) 498–516, and G. A. Croes, Oper. Res. 6 (1958) 791–812
(2-opt). Seed 003 §4.2 (the grid this design replaces) and eq. 13 (angular error).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .data import BenchData
from .design import DEFAULT_SENSOR, SensorDesign
from .errors import CalibrationError
from .geometry import angular_error_deg, direction_vector
from .models.physical import FITTED, PhysicalCalibration
from .pinhole import PinholeBuild, direction_from_spot, spot_from_vectors

#: Central-difference steps of the build parameters, in their units (px, mm, °, unitless). The model is
#: smooth; these are ~1e-6 of each parameter's range, far above rounding and far below curvature.
JACOBIAN_STEPS = {"x0_px": 1e-3, "y0_px": 1e-3, "gap_mm": 1e-6, "glass_mm": 1e-6, "glass_index": 1e-6,
                  "tilt_x_deg": 1e-4, "tilt_y_deg": 1e-4, "rotation_deg": 1e-4, "aperture_c": 1e-7,
                  "aperture_s": 1e-7}

#: Prior spread of each build parameter before any measurement, in its units: the weak prior of the
#: Bayesian D-criterion (Chaloner & Verdinelli 1995 §2.1). Generous build tolerances, so the prior only
#: makes log det finite at the first picks and never competes with the measurements.
PRIOR_SIGMA = {"x0_px": 20.0, "y0_px": 20.0, "gap_mm": 0.5, "glass_mm": 0.5, "glass_index": 0.3,
               "tilt_x_deg": 2.0, "tilt_y_deg": 2.0, "rotation_deg": 5.0, "aperture_c": 0.02, "aperture_s": 0.02}


def nominal_build(design: SensorDesign = DEFAULT_SENSOR) -> PinholeBuild:
    """The build a designer knows before any measurement: the pinhole over the detector's centre at the nominal
    height, no glass, no tilt, no rotation, a round hole.

    References
    ----------
    seed 003, §3.1 (L = 1.37 mm, 640×480 px) and eq. 6.
    """
    x0, y0 = design.centre_px
    return PinholeBuild(x0_px=x0, y0_px=y0, gap_mm=design.pinhole_height_mm, glass_mm=0.0)


# -- information ------------------------------------------------------------------------------------------
def spot_jacobian(zenith_deg, azimuth_deg, build: PinholeBuild, pixel_pitch_mm: float,
                  names=FITTED) -> np.ndarray:
    """Derivatives of the spot centre with respect to the build parameters, by central differences.

    Parameters
    ----------
    zenith_deg, azimuth_deg : array_like, shape (n,)
        Sun directions in the body frame [°].
    build : PinholeBuild
        Where the derivatives are taken (the nominal build: a locally optimal design, Atkinson et al. ch. 17).
    pixel_pitch_mm : float
        [mm].
    names : sequence of str
        Parameters, default those the physical model fits (:data:`calibration.models.physical.FITTED`).

    Returns
    -------
    jacobian : ndarray, shape (n, 2, p)
        ∂(x_px, y_px)/∂parameter [px per unit of the parameter].
    """
    s = direction_vector(np.atleast_1d(zenith_deg), np.atleast_1d(azimuth_deg))
    columns = []
    for name in names:
        h = JACOBIAN_STEPS[name]
        value = getattr(build, name)
        up = spot_from_vectors(s, dataclasses.replace(build, **{name: value + h}), pixel_pitch_mm)
        try:
            down, span = spot_from_vectors(s, dataclasses.replace(build, **{name: value - h}), pixel_pitch_mm), 2 * h
        except ValueError:  # at a bound (no glass: thickness 0): one-sided
            down, span = spot_from_vectors(s, build, pixel_pitch_mm), h
        columns.append(np.stack([(up[0] - down[0]) / span, (up[1] - down[1]) / span], axis=-1))
    return np.stack(columns, axis=-1)


def prior_information(names=FITTED) -> np.ndarray:
    """Information of the weak prior, diag(1 / σ_prior²) [1 / unit²] (Chaloner & Verdinelli 1995 §2.1)."""
    return np.diag([1.0 / PRIOR_SIGMA[n] ** 2 for n in names])


def information_matrix(jacobian: np.ndarray, noise_px: float, prior: np.ndarray | None = None) -> np.ndarray:
    """Fisher information of the build parameters from spot centres with Gaussian noise.

    .. math:: M = \\sum_i J_i^T J_i / σ^2 \\; (+ M_0)

    Parameters
    ----------
    jacobian : ndarray, shape (n, 2, p)
        :func:`spot_jacobian` of the measured directions [px / unit].
    noise_px : float
        Standard deviation of one direction's spot centre on each axis [px].
    prior : ndarray, shape (p, p), optional
        Prior information M₀ [1 / unit²].

    References
    ----------
    Atkinson, Donev & Tobias 2007, §10.2 (information matrix of a non-linear model, eq. 17.9).
    """
    j = np.asarray(jacobian, dtype=float).reshape(-1, jacobian.shape[-1])
    m = j.T @ j / noise_px**2
    return m if prior is None else m + prior


def log_det_information(jacobian: np.ndarray, noise_px: float, prior: np.ndarray | None = None) -> float:
    """log det M: the D-criterion of a design (larger is better; −inf when a parameter is undetermined).

    References
    ----------
    Atkinson, Donev & Tobias 2007, §10.1 (D-optimality).
    """
    sign, value = np.linalg.slogdet(information_matrix(jacobian, noise_px, prior))
    return float(value) if sign > 0 else -math.inf


def greedy_d_optimal(jacobian: np.ndarray, n: int, *, noise_px: float = 0.02, prior: np.ndarray | None = None,
                     start=()) -> np.ndarray:
    """Choose `n` candidates one at a time, each the one that most increases log det of the information.

    The gain of candidate c is log det(I₂ + J_c M⁻¹ J_cᵀ / σ²) (the matrix determinant lemma), so each step
    costs one p×p inverse. Every candidate is taken at most once (one table pose; its repeated frames are
    the pose's `repeats`). Every prefix of the answer is the greedy design of its own size, so a sequential
    run may stop after any batch.

    Parameters
    ----------
    jacobian : ndarray, shape (m, 2, p)
        :func:`spot_jacobian` of the candidates [px / unit].
    n : int
        How many to choose, `start` included (at most m).
    noise_px : float
        Centroid noise of one pose [px]; it only scales M against the prior.
    prior : ndarray, shape (p, p), optional
        Prior information; default :func:`prior_information` of the physical model's parameters when p
        matches them, else 1e-6 × I.
    start : sequence of int
        Candidates taken first, in this order (e.g. normal incidence, where the table already is).

    Returns
    -------
    chosen : ndarray of int, shape (n,)
        Candidate indices in the order chosen.

    References
    ----------
    Atkinson, Donev & Tobias 2007, §12.4 (sequential construction of D-optimal designs: add the point of
    largest variance of prediction, d(x) = J_x M⁻¹ J_xᵀ); Chaloner & Verdinelli 1995 §2.1 (the prior term).
    """
    jacobian = np.asarray(jacobian, dtype=float)
    m_candidates, _, p = jacobian.shape
    if not 0 < n <= m_candidates:
        raise CalibrationError(f"greedy_d_optimal: cannot choose {n} of {m_candidates} candidates")
    if prior is None:
        prior = prior_information() if p == len(FITTED) else 1e-6 * np.eye(p)
    scaled = jacobian / noise_px
    info = prior.astype(float).copy()
    chosen: list[int] = []
    available = np.ones(m_candidates, dtype=bool)
    for index in start:
        chosen.append(int(index))
        available[index] = False
        info += scaled[index].T @ scaled[index]
    while len(chosen) < n:
        inverse = np.linalg.inv(info)
        # d(c) = J_c M⁻¹ J_cᵀ (2×2 per candidate); gain = log det(I + d)
        d = np.einsum("cip,pq,cjq->cij", scaled, inverse, scaled)
        gain = np.log((1.0 + d[:, 0, 0]) * (1.0 + d[:, 1, 1]) - d[:, 0, 1] * d[:, 1, 0])
        gain[~available] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        available[best] = False
        info += scaled[best].T @ scaled[best]
    return np.array(chosen, dtype=int)


# -- where the bench may look ------------------------------------------------------------------------------
def spot_inside(zenith_deg, azimuth_deg, build: PinholeBuild, design: SensorDesign = DEFAULT_SENSOR, *,
                margin_px: float = 24.0) -> np.ndarray:
    """True where the nominal spot lies at least `margin_px` inside the detector.

    The margin absorbs the build's unknown offset (a few px), the spot's radius (~6 px with its blur) and
    the bench's stage-to-body mapping (eq. 8 moves the zenith by up to ~1°, ~10 px at 60°): a spot that
    touches the edge has a biased centre and is not fitted.
    """
    x, y = spot_from_vectors(direction_vector(zenith_deg, azimuth_deg), build, design.pixel_pitch_mm)
    return ((x >= margin_px) & (x <= design.width_px - 1 - margin_px)
            & (y >= margin_px) & (y <= design.height_px - 1 - margin_px))


def candidate_directions(build: PinholeBuild | None = None, design: SensorDesign = DEFAULT_SENSOR, *,
                         zenith_max_deg: float = 60.0, zenith_step_deg: float = 5.0,
                         azimuth_step_deg: float = 15.0, margin_px: float = 24.0):
    """The candidate grid over the field of view: normal incidence first, then every zenith step
    (`zenith_step_deg` … `zenith_max_deg`) × every azimuth step, keeping the directions whose nominal spot
    lies inside the detector (:func:`spot_inside`).

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray
        [°]; index 0 is normal incidence (zenith 0, azimuth 0).

    References
    ----------
    seed 003, §4.2 (zenith 0–60°, the 120° field of view of eq. 2).
    """
    build = build or nominal_build(design)
    zeniths = np.arange(zenith_step_deg, zenith_max_deg + 1e-9, zenith_step_deg)
    azimuths = np.arange(0.0, 360.0 - 1e-9, azimuth_step_deg)
    z, a = (g.ravel() for g in np.meshgrid(zeniths, azimuths, indexing="ij"))
    keep = spot_inside(z, a, build, design, margin_px=margin_px)
    return np.concatenate([[0.0], z[keep]]), np.concatenate([[0.0], a[keep]])


def check_directions(n: int, build: PinholeBuild | None = None, design: SensorDesign = DEFAULT_SENSOR, *,
                     zenith_max_deg: float = 55.0, margin_px: float = 24.0, round_deg: float = 0.1):
    """`n` directions spread evenly over the field (equal solid angle per direction), away from the grid.

    A golden-angle spiral on the spherical cap θ ≤ `zenith_max_deg`: direction k at cos θ_k = 1 − (k + ½)/n ·
    (1 − cos θ_max), φ_k = k × 137.508°. Its azimuths never repeat and fall between the candidate grid's, so
    the check scores the calibration between the fitted directions. A direction whose nominal spot is too
    close to the edge is brought in along its azimuth until it is inside.

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray, shape (n,)
        [°], rounded to `round_deg`.

    References
    ----------
    R. Swinbank, R. J. Purser, "Fibonacci grids", Q. J. R. Meteorol. Soc. 132 (2006) 1769–1793 (the golden
    spiral as a near-uniform point set on the sphere).
    """
    if n < 1:
        raise CalibrationError("check_directions: n must be at least 1")
    build = build or nominal_build(design)
    k = np.arange(n)
    cos_max = np.cos(np.radians(zenith_max_deg))
    zenith = np.degrees(np.arccos(1.0 - (k + 0.5) / n * (1.0 - cos_max)))
    azimuth = np.mod(k * (360.0 * (1.0 - 1.0 / ((1.0 + 5.0**0.5) / 2.0))) + 7.0, 360.0)  # golden angle, off the grid
    zenith, azimuth = np.round(zenith / round_deg) * round_deg, np.round(azimuth / round_deg) * round_deg
    for i in range(n):
        while zenith[i] > 0 and not spot_inside(zenith[i], azimuth[i], build, design, margin_px=margin_px):
            zenith[i] = round(zenith[i] - 1.0, 6)
    return zenith, np.mod(azimuth, 360.0)


# -- table travel ------------------------------------------------------------------------------------------
def trapezoid_move_s(distance_deg, rate_deg_s: float, accel_deg_s2: float):
    """Duration of a rest-to-rest move with a trapezoidal (or, when short, triangular) velocity profile [s].

    .. math:: t = |d| / v + v / a \\;(|d| ≥ v^2/a), \\qquad t = 2 \\sqrt{|d| / a} \\;\\text{otherwise}

    Parameters
    ----------
    distance_deg : numeric
        [°].
    rate_deg_s, accel_deg_s2 : float
        Top speed [°/s] and acceleration [°/s²] of the axis.
    """
    d = np.abs(np.asarray(distance_deg, dtype=float))
    return np.where(d >= rate_deg_s**2 / accel_deg_s2, d / rate_deg_s + rate_deg_s / accel_deg_s2,
                    2.0 * np.sqrt(d / accel_deg_s2))


def move_time_s(a, b, rates_deg_s=(10.0, 10.0), accels_deg_s2=(20.0, 20.0), settle_s: float = 0.0):
    """Time to move the table from pose `a` to pose `b` (azimuth, zenith stage) [s]: both axes move at once,
    so the slower one sets it; a move adds `settle_s`, staying put costs nothing.

    Parameters
    ----------
    a, b : array_like, shape (..., 2)
        Poses (azimuth_deg, zenith_stage_deg) [°].
    rates_deg_s, accels_deg_s2 : (float, float)
        Speed [°/s] and acceleration [°/s²] of the azimuth and the zenith axis.
    settle_s : float
        Settling after a move [s].
    """
    delta = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
    t = np.maximum(trapezoid_move_s(delta[..., 0], rates_deg_s[0], accels_deg_s2[0]),
                   trapezoid_move_s(delta[..., 1], rates_deg_s[1], accels_deg_s2[1]))
    return np.where(np.any(delta != 0, axis=-1), t + settle_s, 0.0)


def tour_time_s(poses, order, start=(0.0, 0.0), **speeds) -> float:
    """Travel time of visiting `poses` in `order`, from `start` (an open path: the run does not come back) [s]."""
    path = np.vstack([np.asarray(start, dtype=float)[None, :], np.asarray(poses, dtype=float)[np.asarray(order)]])
    return float(np.sum(move_time_s(path[:-1], path[1:], **speeds)))


def order_tour(poses, start=(0.0, 0.0), *, rates_deg_s=(10.0, 10.0), accels_deg_s2=(20.0, 20.0),
               settle_s: float = 0.0, max_sweeps: int = 50) -> np.ndarray:
    """An order of the poses that shortens the table's travel from `start`: nearest neighbour, then 2-opt.

    The cost of a move is :func:`move_time_s` (the slower axis's trapezoidal move), so a zenith move hidden
    under a longer azimuth move is free. 2-opt reverses a stretch of the path whenever that shortens it,
    until no reversal helps or `max_sweeps` passes have been made; the result is never longer than the
    nearest-neighbour path, which in turn is compared with the given order and the shorter kept.

    Parameters
    ----------
    poses : array_like, shape (n, 2)
        (azimuth_deg, zenith_stage_deg) [°].
    start : (float, float)
        Where the table is.
    rates_deg_s, accels_deg_s2, settle_s
        As :func:`move_time_s`.
    max_sweeps : int
        Cap on the 2-opt passes.

    Returns
    -------
    order : ndarray of int, shape (n,)

    References
    ----------
    Croes 1958 (2-opt); Lin & Kernighan 1973 §2 (nearest neighbour and r-opt improvement).
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 2)
    n = len(poses)
    if n <= 1:
        return np.arange(n)
    speeds = {"rates_deg_s": rates_deg_s, "accels_deg_s2": accels_deg_s2, "settle_s": settle_s}
    nodes = np.vstack([np.asarray(start, dtype=float)[None, :], poses])  # node 0 is the start
    cost = move_time_s(nodes[:, None, :], nodes[None, :, :], **speeds)
    # nearest neighbour from the start
    path, left = [0], set(range(1, n + 1))
    while left:
        here = path[-1]
        nxt = min(left, key=lambda j: (cost[here, j], j))
        path.append(nxt)
        left.remove(nxt)
    path = np.array(path)

    def length(p):
        return float(cost[p[:-1], p[1:]].sum())

    # 2-opt on an open path with a fixed first node: reverse path[i..j], 1 ≤ i < j ≤ n
    for _ in range(max_sweeps):
        improved = False
        for i in range(1, n):
            for j in range(i + 1, n + 1):
                before = cost[path[i - 1], path[i]] + (cost[path[j], path[j + 1]] if j < n else 0.0)
                after = cost[path[i - 1], path[j]] + (cost[path[i], path[j + 1]] if j < n else 0.0)
                if after < before - 1e-12:
                    path[i:j + 1] = path[i:j + 1][::-1].copy()
                    improved = True
        if not improved:
            break
    given = np.arange(n + 1)
    best = path if length(path) <= length(given) else given
    return best[1:] - 1


# -- the whole design --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ExperimentDesign:
    """The directions of a physical calibration run.

    Attributes
    ----------
    zenith_deg, azimuth_deg : ndarray, shape (n,)
        Fit directions in the order of the greedy D-optimal choice [°] (index 0: normal incidence).
    batches : tuple of (int, int)
        Half-open index ranges of the fit directions measured together; a run may stop after any batch.
    check_zenith_deg, check_azimuth_deg : ndarray
        Check directions, measured with the first batch and never fitted [°].
    log_det : tuple of float
        log det of the information after each batch (the design's D-criterion, at the nominal build).
    """

    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    batches: tuple
    check_zenith_deg: np.ndarray
    check_azimuth_deg: np.ndarray
    log_det: tuple = ()

    @property
    def n_fit(self) -> int:
        return int(self.zenith_deg.size)

    @property
    def n_check(self) -> int:
        return int(self.check_zenith_deg.size)


def design_experiment(*, first_batch: int = 16, batch_size: int = 8, max_batches: int = 3, n_check: int = 8,
                      noise_px: float = 0.02, build: PinholeBuild | None = None,
                      design: SensorDesign = DEFAULT_SENSOR, zenith_max_deg: float = 60.0,
                      zenith_step_deg: float = 5.0, azimuth_step_deg: float = 15.0,
                      margin_px: float = 24.0) -> ExperimentDesign:
    """Choose the fit directions (greedy D-optimal, normal incidence first), split them into batches, and add
    the check directions.

    Parameters
    ----------
    first_batch : int
        Fit directions of the first batch (the physical model has 9 parameters; twice as many pins them
        with room for the residuals to estimate the noise).
    batch_size : int
        Fit directions of every later batch.
    max_batches : int
        Cap on the batches: at most ``first_batch + (max_batches − 1) × batch_size`` fit directions.
    n_check : int
        Check directions.
    noise_px : float
        Centroid noise of one pose's mean [px] (scales the information against the prior).
    build : PinholeBuild, optional
        Nominal build at which the information is computed; default :func:`nominal_build`.
    zenith_max_deg, zenith_step_deg, azimuth_step_deg, margin_px
        The candidate grid (:func:`candidate_directions`).

    References
    ----------
    Atkinson, Donev & Tobias 2007, ch. 12 and 17 (sequential, locally D-optimal designs); seed 003 §4.2 (the
    80-pose grid it replaces).
    """
    if first_batch < len(FITTED) + 1 or batch_size < 1 or max_batches < 1:
        raise CalibrationError(f"design_experiment: the first batch needs at least {len(FITTED) + 1} directions "
                               "and every batch one")
    build = build or nominal_build(design)
    zenith, azimuth = candidate_directions(build, design, zenith_max_deg=zenith_max_deg,
                                           zenith_step_deg=zenith_step_deg, azimuth_step_deg=azimuth_step_deg,
                                           margin_px=margin_px)
    n = min(first_batch + (max_batches - 1) * batch_size, zenith.size)
    jacobian = spot_jacobian(zenith, azimuth, build, design.pixel_pitch_mm)
    chosen = greedy_d_optimal(jacobian, n, noise_px=noise_px, start=(0,))
    ends = [min(first_batch, n)]
    while ends[-1] < n:
        ends.append(min(ends[-1] + batch_size, n))
    batches = tuple(zip([0] + ends[:-1], ends))
    prior = prior_information()
    log_det = tuple(log_det_information(jacobian[chosen[:end]], noise_px, prior) for _, end in batches)
    check_z, check_a = check_directions(n_check, build, design, zenith_max_deg=min(55.0, zenith_max_deg),
                                        margin_px=margin_px)
    return ExperimentDesign(zenith[chosen], azimuth[chosen], batches, check_z, check_a, log_det)


# -- when to stop ------------------------------------------------------------------------------------------
def parameter_targets(budget_deg: float = 0.01, build: PinholeBuild | None = None,
                      design: SensorDesign = DEFAULT_SENSOR, *, zenith_max_deg: float = 60.0,
                      names=FITTED) -> dict[str, float]:
    """The 1σ each build parameter may keep so that, alone, it moves the directions of the field by no more
    than `budget_deg` RMS.

    The sensitivity of parameter i is the RMS angular error (eq. 13) over a grid of field directions when the
    calibration's value is off by a small δ and the spot stays where the true build put it; the target is
    `budget_deg` / sensitivity, in the parameter's unit. RMS, like the accuracy the check directions measure.
    Each parameter is taken alone: strongly correlated ones (the air gap and the glass thickness trade off
    against each other) move the field less together than either does alone, which the check directions see.

    Parameters
    ----------
    budget_deg : float
        RMS pointing error one parameter's 1σ may cause at most [°]; the default is half the default check
        target of 0.02°.
    build : PinholeBuild, optional
        Where the sensitivities are taken; default :func:`nominal_build`.

    Returns
    -------
    targets : dict of str to float
        Parameter name → largest acceptable 1σ [its unit].

    References
    ----------
    seed 003, eq. 13 (angular error).
    """
    build = build or nominal_build(design)
    zenith, azimuth = (g.ravel() for g in np.meshgrid(np.linspace(5.0, zenith_max_deg, 12),
                                                      np.arange(0.0, 360.0, 15.0), indexing="ij"))
    keep = spot_inside(zenith, azimuth, build, design, margin_px=0.0)
    zenith, azimuth = zenith[keep], azimuth[keep]
    x, y = spot_from_vectors(direction_vector(zenith, azimuth), build, design.pixel_pitch_mm)
    targets = {}
    for name in names:
        h = 100 * JACOBIAN_STEPS[name]
        wrong = dataclasses.replace(build, **{name: getattr(build, name) + h})
        error = angular_error_deg(zenith, azimuth, *direction_from_spot(x, y, wrong, design.pixel_pitch_mm))
        targets[name] = float(budget_deg * h / max(float(np.sqrt(np.mean(error**2))), 1e-300))
    return targets


@dataclass(frozen=True)
class StopDecision:
    """The stopping rule's verdict after a batch.

    Attributes
    ----------
    stop : bool
        Every parameter's 1σ is below its target and the check directions' vector RMS is at most its target.
    reasons : tuple of str
        What is not met yet (empty when `stop`), or why no fit could be made.
    n_fit_directions, n_check_directions : int
        Directions fitted and scored.
    check_rms_deg : float
        Vector RMS of the check directions (eq. 13) [°]; NaN without a fit or checks.
    check_max_deg : float
        Largest check error [°].
    sigmas : dict of str to float
        1σ of every fitted parameter [its unit].
    targets : dict of str to float
        The targets it was compared with.
    calibration : PhysicalCalibration or None
        The fit the decision is about.
    """

    stop: bool
    reasons: tuple
    n_fit_directions: int
    n_check_directions: int
    check_rms_deg: float = float("nan")
    check_max_deg: float = float("nan")
    sigmas: dict = field(default_factory=dict)
    targets: dict = field(default_factory=dict)
    calibration: PhysicalCalibration | None = field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict:
        """JSON-able summary (without the calibration object)."""
        return {"stop": self.stop, "reasons": list(self.reasons), "n_fit_directions": self.n_fit_directions,
                "n_check_directions": self.n_check_directions,
                "check_rms_deg": None if not np.isfinite(self.check_rms_deg) else self.check_rms_deg,
                "check_max_deg": None if not np.isfinite(self.check_max_deg) else self.check_max_deg,
                "sigmas": dict(self.sigmas), "targets": dict(self.targets)}

    def summary(self) -> str:
        """One sentence for the run's log."""
        head = (f"{self.n_fit_directions} directions fitted, {self.n_check_directions} checked: check RMS "
                f"{self.check_rms_deg:.4f}° (max {self.check_max_deg:.4f}°)" if np.isfinite(self.check_rms_deg)
                else f"{self.n_fit_directions} directions fitted, {self.n_check_directions} checked")
        if self.stop:
            return f"{head}; every target met: stop"
        return f"{head}; go on: " + "; ".join(self.reasons)


def stopping_decision(fit_data: BenchData, check_data: BenchData | None, *, check_rms_target_deg: float = 0.02,
                      targets: dict[str, float] | None = None, min_check_directions: int = 3,
                      design: SensorDesign = DEFAULT_SENSOR) -> StopDecision:
    """Fit the physical model to the fit directions, score it on the check directions, decide whether to stop.

    Stop when both hold:

    * every fitted parameter's 1σ (from the fit's covariance σ² (JᵀJ)⁻¹) is at most its target
      (default :func:`parameter_targets`);
    * the vector RMS (eq. 13) of at least `min_check_directions` check directions, which the fit never saw, is
      at most `check_rms_target_deg`.

    The repeats of each direction are averaged before fitting and scoring (seed 003 §4.3). A fit that cannot
    be made (too few directions, no convergence) is a decision to go on, with the reason.

    Parameters
    ----------
    fit_data : BenchData
        Frames of the fit directions (true body directions, spot centres).
    check_data : BenchData or None
        Frames of the check directions.
    check_rms_target_deg : float
        [°].
    targets : dict of str to float, optional
        Largest 1σ of each parameter [its unit]; a parameter without a target is not checked.
    min_check_directions : int
        Fewer scored check directions never stop a run.
    design : SensorDesign
        Pixel pitch and nominal height for the fit.

    References
    ----------
    Atkinson, Donev & Tobias 2007, §12.4 (stopping a sequential design once the parameters are known well
    enough); seed 003 eqs. 12–13 and §4.3.
    """
    targets = parameter_targets(design=design) if targets is None else dict(targets)
    fit_means = fit_data.direction_means() if len(fit_data) else fit_data
    n_fit = len(fit_means)
    check_means = check_data.direction_means() if check_data is not None and len(check_data) else None
    n_check = 0 if check_means is None else len(check_means)
    if n_fit < PhysicalCalibration.min_points:
        return StopDecision(False, (f"no fit yet ({n_fit} directions with a usable spot, "
                                    f"{PhysicalCalibration.min_points} needed)",), n_fit, n_check, targets=targets)
    try:
        calibration = PhysicalCalibration.fit(fit_means, design)
    except CalibrationError as exc:
        return StopDecision(False, (f"no fit yet ({exc})",), n_fit, n_check, targets=targets)
    sigmas = dict(calibration.uncertainties)
    reasons = [f"σ({name}) = {sigmas[name]:.3g} > {target:.3g}" for name, target in targets.items()
               if name in sigmas and not sigmas[name] <= target]
    rms = worst = float("nan")
    if check_means is not None:
        errors = angular_error_deg(check_means.zenith_deg, check_means.azimuth_deg,
                                   *calibration.apply(check_means.x_px, check_means.y_px))
        rms, worst = float(np.sqrt(np.mean(errors**2))), float(errors.max())
    if n_check < min_check_directions:
        reasons.append(f"only {n_check} check direction(s) scored, {min_check_directions} needed")
    elif not rms <= check_rms_target_deg:
        reasons.append(f"check RMS {rms:.4f}° > {check_rms_target_deg}°")
    return StopDecision(not reasons, tuple(reasons), n_fit, n_check, rms, worst, sigmas, targets, calibration)
