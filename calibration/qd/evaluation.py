"""Calibrate a QD sun sensor from bench data: dark current, every method, scored held out between the nodes.

:func:`calibrate_qd` is the QD family's counterpart of :func:`calibration.evaluation.calibrate`:

1. **Dark current** (seed 002 §2.1) from the dark rows (:func:`~calibration.qd.dark.fit_dark`); a dark row more
   than :data:`OUTLIER_SIGMAS` robust sigmas off the fit is rejected and named, and the fit repeated.
2. **Photocurrents** I − I^d(t) of the light rows; a row whose photocurrents sum to ≤ 0 is rejected, and so
   is a saturated one: a current at the design's ADC full scale, or (full scale unknown) at a channel's
   maximum that :data:`CLIP_REPEATS` or more readings share exactly (a clip level, not a measurement).
3. **Repeats**: rows of one direction ((α, β) within :data:`DIRECTION_TOLERANCE_DEG`, so a table's read-back
   jitter of 1′ still groups them) are compared by their quadrant shares; with three or more, a row farther
   than :data:`OUTLIER_SIGMAS` × the pooled repeat scatter from its direction's median is rejected and named
   (a glint). The direction's point is the mean of its kept rows (check points never join a node).
4. **Outlying directions**: a robust (soft-L1) fit of the physical model; a direction whose share residual
   exceeds :data:`OUTLIER_SIGMAS` × 1.4826 × the larger of the median residual and the median of its eight
   nearest neighbours' is an outlier (a spike, not the smooth misfit a model can have at the edge of the
   field); of its readings, those that agree with the model are kept and the others rejected and named. If
   more than :data:`SCREEN_MAX_SHARE` of the directions would go, the model is not trusted to judge them
   (a wrong quadrant layout, a sensor unlike the model) and nothing is rejected, with a warning.
5. **Every method** (``geometric`` eq. 2.2, ``polynomial`` eq. 2.3 with its order chosen by held-out error,
   ``physical``) is fitted to the node directions and scored in degrees of angular error at the nodes and
   **held out between the nodes**, since the thesis warns the error between nodes may exceed the error at
   them (§5.3):

   * the off-node check points, when the data have them (never fitted);
   * leave-lines-out cross-validation: the interior grid columns (α lines) are split into
     :data:`FOLDS` interleaved folds, each left out whole in turn and predicted from the rest; the same for
     the rows (β lines). Without a recognisable grid, an interleaved checkerboard of interior cells.

   A method's held-out figure is the worst of these by maximum error. The polynomial's order is chosen
   inside each fold on that fold's training points (nested), so its held-out score is not flattered.
6. **χ²/dof** against the repeat scatter: each method's angles for every kept row give the pooled scatter of
   one reading [°, per axis]; χ² = Σ n_i Δ_i² / σ² over the node directions, per 2N − p degrees of freedom.
7. The **default method** is the one with the smallest held-out maximum error; warnings say in words what
   looks wrong. Each method's calibration document (:mod:`calibration.qd.document`) is in its report.

References
----------
seed 002, §2.1, eqs. 2.1–2.3, §3.1, §5.2–5.3 (max errors over ±40°; the warning about points between the
polynomial's nodes); digest §4 and §8 (validation on points between the grid nodes); research note
anchors-sunsensors §6 (robust fits, held-out accuracy).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..data import chained_groups
from ..errors import CalibrationError, InsufficientDataError
from .angles import angle_between_projections_deg
from .dark import NO_DARK, DarkFit, fit_dark, subtract_dark
from .data import QdBenchData
from .design import DEFAULT_QD, QdDesign
from .document import geometric_parts, physical_parts, polynomial_parts, qd_document
from .geometric import angles_from_spot, fit_geometric
from .physical import fit_physical, invert_physical, predict_shares
from .polynomial import DEFAULT_CANDIDATES, select_polynomial
from .spot import quadrant_fractions, spot_position, spot_ratios

#: Methods in the order they are reported.
METHODS = ("physical", "polynomial", "geometric")
#: A row or direction farther than this many robust sigmas from the rest is an outlier.
OUTLIER_SIGMAS = 6.0
#: If the physical model would reject more than this share of the directions, it is not trusted to judge them.
SCREEN_MAX_SHARE = 0.05
#: Shares closer than this never make an outlier, whatever the scatter (exact synthetic data have none).
OUTLIER_FLOOR_SHARE = 1e-6
#: χ²/dof above this (a residual 3× the repeat scatter) says the model does not describe the data.
CHI2_WARNING = 9.0
#: Interleaved folds per axis of the leave-lines-out cross-validation.
FOLDS = 3
#: Share of the points that must lie on grid lines (:func:`grid_lines`) for the data to count as a grid.
GRID_SHARE = 0.8
#: Rows of one direction: (α, β) within this of each other [°] (more than the thesis' 1′ table steps).
DIRECTION_TOLERANCE_DEG = 0.03
#: A channel's maximum shared exactly by this many readings is taken as the ADC's clip level.
CLIP_REPEATS = 3


@dataclass(frozen=True)
class AngularMetrics:
    """Angular error of predicted Sun directions against the true ones.

    Attributes
    ----------
    n_points : int
        Points scored.
    n_failed : int
        Points the method gave no direction for (counted here, left out of the figures below).
    max_deg, rms_deg, p99_deg : float
        Largest, RMS and 99th-percentile angle between the true and the predicted direction [°].
    rms_alpha_deg, rms_beta_deg : float
        RMS of the α and β errors [°].
    """

    n_points: int
    n_failed: int
    max_deg: float
    rms_deg: float
    p99_deg: float
    rms_alpha_deg: float
    rms_beta_deg: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def angular_metrics(alpha_true, beta_true, alpha_deg, beta_deg) -> AngularMetrics:
    """Angular-error figures of predicted (α, β) against the truth [°].

    References
    ----------
    seed 002, §5.2–5.3 (maximum error over the field); seed 003, eq. 13 (angle between directions).
    """
    at, bt = np.asarray(alpha_true, float).ravel(), np.asarray(beta_true, float).ravel()
    a, b = np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    if not ok.any():
        nan = float("nan")
        return AngularMetrics(int(at.size), int(at.size), nan, nan, nan, nan, nan)
    err = angle_between_projections_deg(at[ok], bt[ok], a[ok], b[ok])
    return AngularMetrics(int(at.size), int((~ok).sum()), float(err.max()), float(np.sqrt(np.mean(err**2))),
                          float(np.percentile(err, 99)), float(np.sqrt(np.mean((a[ok] - at[ok]) ** 2))),
                          float(np.sqrt(np.mean((b[ok] - bt[ok]) ** 2))))


@dataclass(frozen=True)
class RejectedRow:
    """A reading left out of the calibration, and why.

    Attributes
    ----------
    row_id : int
        The row's name (:attr:`QdBenchData.row_id`).
    alpha_deg, beta_deg : float
        Its direction (NaN for a dark row) [°].
    reason : str
    """

    row_id: int
    alpha_deg: float
    beta_deg: float
    reason: str

    def to_dict(self) -> dict:
        return {"row": self.row_id, "alpha_deg": None if np.isnan(self.alpha_deg) else self.alpha_deg,
                "beta_deg": None if np.isnan(self.beta_deg) else self.beta_deg, "reason": self.reason}

    def describe(self) -> str:
        where = "" if np.isnan(self.alpha_deg) else f" (α {self.alpha_deg:.3f}°, β {self.beta_deg:.3f}°)"
        return f"row {self.row_id}{where}: {self.reason}"


def grid_lines(values, *, tolerance_deg: float = 0.1, min_members: int = 3) -> np.ndarray:
    """Index of the grid line (cluster of equal values within `tolerance_deg`) each value lies on, −1 for none.

    Lines are numbered in increasing value; a cluster of fewer than `min_members` values is no line.

    References
    ----------
    digest §4 (a grid over ±40° on both axes).
    """
    v = np.asarray(values, float).ravel()
    cluster = np.zeros(v.size, int)
    if v.size:
        order, group = chained_groups(v, tolerance_deg)
        cluster[order] = group
    counts = np.bincount(cluster) if v.size else np.zeros(0, int)
    keep = np.flatnonzero(counts >= min_members)
    index = np.full(counts.size, -1)
    index[keep] = np.arange(keep.size)
    return index[cluster]


def heldout_schemes(alpha_deg, beta_deg, *, folds: int = FOLDS) -> dict:
    """Leave-lines-out held-out schemes: group labels (−1: never left out) per scheme name.

    ``"columns"``: interior α lines in `folds` interleaved folds (line i in fold i mod folds); ``"rows"``: the
    same for β lines. A scheme needs three interior lines and :data:`GRID_SHARE` of the points on lines; when
    neither axis has them (no grid), a ``"checkerboard"`` of the points' rank cells (interior cells only) is
    used instead.

    References
    ----------
    seed 002, §5.3 (errors between the polynomial's nodes); digest §4 and §8 (hold-out points between nodes).
    """
    a, b = np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()
    out = {}
    for name, values in (("columns", a), ("rows", b)):
        line = grid_lines(values)
        n = line.max() + 1 if line.size else 0
        if n - 2 >= max(folds, 3) and np.mean(line >= 0) >= GRID_SHARE:
            interior = (line > 0) & (line < n - 1)
            out[name] = np.where(interior, (line - 1) % folds, -1)
    if not out and a.size >= 4 * folds:
        bins = max(int(round(np.sqrt(a.size))), 4)
        ia = np.minimum((np.argsort(np.argsort(a)) * bins) // a.size, bins - 1)
        ib = np.minimum((np.argsort(np.argsort(b)) * bins) // b.size, bins - 1)
        interior = (ia > 0) & (ia < bins - 1) & (ib > 0) & (ib < bins - 1)
        out["checkerboard"] = np.where(interior, (ia + 2 * ib) % folds, -1)
    return out


# --- the methods, each as fit / predict / parameter count / document parts ----------------------------------


@dataclass(frozen=True)
class _Fitted:
    method: str
    model: object
    n_params: int
    details: dict = field(default_factory=dict)


def _fit_method(method: str, alpha, beta, photo, design: QdDesign, *, initial=None, offsets="auto",
                candidates=DEFAULT_CANDIDATES, folds: int = FOLDS) -> _Fitted:
    if method == "geometric":
        xc, yc = spot_position(photo, design.eq21_length_m, design.layout)  # seed 002 eq. 2.1
        fit = fit_geometric(xc, yc, alpha, beta, initial=initial)  # eq. 2.2
        return _Fitted(method, fit, len(fit.free), {"statements": fit.statements})
    if method == "polynomial":
        u, v = spot_ratios(photo, design.layout)  # eq. 2.1
        schemes = list(heldout_schemes(alpha, beta, folds=folds).values())
        if not schemes:
            raise InsufficientDataError("too few points to choose the polynomial's order held out")
        selection = select_polynomial(u, v, alpha, beta, schemes, candidates=candidates)  # eq. 2.3
        return _Fitted(method, selection.model, 2 * selection.model.n_terms,
                       {"order_rule": selection.rule, "order_table": selection.table,
                        "condition_number": selection.model.condition_number})
    if method == "physical":
        fit = fit_physical(alpha, beta, photo, design=design, initial=initial,
                           offsets=initial.offsets if initial is not None else offsets)
        return _Fitted(method, fit, len(fit.free), {"statements": fit.statements, "offsets": fit.parameters.offsets,
                                                    "cos_law_rms": fit.cos_law_rms, "notes": list(fit.notes)})
    raise ValueError(f"unknown QD method {method!r}; the methods are {METHODS}")


def _predict(fitted: _Fitted, photo, design: QdDesign) -> tuple[np.ndarray, np.ndarray]:
    if fitted.method == "geometric":
        xc, yc = spot_position(photo, design.eq21_length_m, design.layout, invalid="nan")
        return angles_from_spot(xc, yc, fitted.model.parameters)
    if fitted.method == "polynomial":
        return fitted.model.evaluate(*spot_ratios(photo, design.layout, invalid="nan"))
    alpha, beta, _ = invert_physical(photo, fitted.model.parameters)
    return alpha, beta


def _initial_of(fitted: _Fitted):
    return fitted.model.parameters if fitted.method in ("geometric", "physical") else None


def _document(fitted: _Fitted, dark: DarkFit, design: QdDesign, sensor_id, metrics: dict) -> dict:
    model = fitted.model
    if fitted.method == "geometric":
        params, extra = geometric_parts(model.parameters, model.sd, design.eq21_length_m, design.layout)
        corr, notes = (model.free, model.correlation), model.statements
    elif fitted.method == "polynomial":
        params, extra = polynomial_parts(model, design.layout)
        corr, notes = None, [fitted.details["order_rule"]]
    else:
        params, extra = physical_parts(model.parameters, model.sd)
        corr, notes = (model.free, model.correlation), list(model.statements) + list(model.notes)
    return qd_document(fitted.method, params, extra, dark=dark, design=design, sensor_id=sensor_id,
                       correlation=corr, metrics=metrics, notes=notes)


# --- reports ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class QdMethodReport:
    """One method fitted to the node directions and scored.

    Attributes
    ----------
    method : str
    model : object or None
        :class:`~calibration.qd.geometric.GeometricFit`, :class:`~calibration.qd.polynomial.PolynomialModel`
        or :class:`~calibration.qd.physical.PhysicalFit` fitted to all node directions; None if it failed.
    document : dict or None
        Its calibration document.
    at_nodes : AngularMetrics or None
    heldout : AngularMetrics or None
        The worst (by maximum error) of the held-out schemes: what the method is judged by.
    heldout_scheme : str or None
        Which one it is ("check", "columns", "rows" or "checkerboard").
    heldout_by_scheme : dict of str to AngularMetrics
    chi2_dof : float or None
        Against the repeat scatter (None without repeats).
    error : str or None
        Why the method could not be fitted or scored.
    details : dict
        Method-specific: correlation statements, the polynomial's order table, the physical model's notes.
    """

    method: str
    model: object
    document: dict | None
    at_nodes: AngularMetrics | None
    heldout: AngularMetrics | None
    heldout_scheme: str | None = None
    heldout_by_scheme: dict = field(default_factory=dict)
    chi2_dof: float | None = None
    error: str | None = None
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        plain = lambda m: None if m is None else m.to_dict()  # noqa: E731
        return {"method": self.method, "error": self.error, "at_nodes": plain(self.at_nodes),
                "heldout": plain(self.heldout), "heldout_scheme": self.heldout_scheme,
                "heldout_by_scheme": {k: plain(v) for k, v in self.heldout_by_scheme.items()},
                "chi2_dof": self.chi2_dof}


@dataclass(frozen=True)
class QdDirections:
    """The points every method is fitted to and scored on: one per bench direction.

    Attributes
    ----------
    alpha_deg, beta_deg : ndarray, shape (M,)
    photocurrents_a : ndarray, shape (M, 4)
        Mean dark-corrected currents of the direction's kept rows [A].
    check : ndarray of bool
        Off-node check points.
    members : list of ndarray
        Indices (into the data) of each direction's kept rows.
    """

    alpha_deg: np.ndarray
    beta_deg: np.ndarray
    photocurrents_a: np.ndarray
    check: np.ndarray
    members: list

    def __len__(self) -> int:
        return self.alpha_deg.size

    @property
    def n_rows(self) -> np.ndarray:
        return np.array([m.size for m in self.members])

    def subset(self, mask) -> QdDirections:
        idx = np.flatnonzero(mask)
        return QdDirections(self.alpha_deg[idx], self.beta_deg[idx], self.photocurrents_a[idx], self.check[idx],
                            [self.members[i] for i in idx])


@dataclass(frozen=True)
class QdCalibrationOutcome:
    """Everything :func:`calibrate_qd` found.

    Attributes
    ----------
    dark : DarkFit
    reports : list of QdMethodReport
    chosen : QdMethodReport
        Smallest held-out maximum error.
    directions : QdDirections
        The clean directions (nodes and check points) the methods saw.
    rejected : list of RejectedRow
    warnings : list of str
    repeat_scatter_share : float or None
        Pooled scatter of one reading's quadrant share between repeats [unitless].
    """

    dark: DarkFit
    reports: list
    chosen: QdMethodReport
    directions: QdDirections
    rejected: list
    warnings: list
    repeat_scatter_share: float | None

    @property
    def document(self) -> dict:
        """The chosen method's calibration document."""
        return self.chosen.document

    def report(self, method: str) -> QdMethodReport:
        for r in self.reports:
            if r.method == method:
                return r
        raise KeyError(method)

    def to_dict(self) -> dict:
        return {"chosen": self.chosen.method, "dark": self.dark.to_dict(),
                "reports": [r.to_dict() for r in self.reports], "rejected": [r.to_dict() for r in self.rejected],
                "warnings": list(self.warnings), "repeat_scatter_share": self.repeat_scatter_share}


# --- the steps ----------------------------------------------------------------------------------------------


def _robust_sigma(values) -> float:
    values = np.asarray(values, float)
    return float(1.4826 * np.median(np.abs(values))) if values.size else float("nan")


def _fit_dark_robust(data: QdBenchData, rejected: list) -> DarkFit:
    dark = np.flatnonzero(data.dark)
    if dark.size == 0:
        return NO_DARK
    t, cur = data.temperature_c[dark], data.currents_a[dark]
    fit = fit_dark(t, cur)
    if dark.size >= 6 and fit.kind != "constant":
        res = cur - fit.current(t)
        sigma = np.array([_robust_sigma(res[:, k]) for k in range(4)])
        score = np.max(np.abs(res) / np.where(sigma > 0, sigma, np.inf), axis=1)
        bad = score > OUTLIER_SIGMAS
        if bad.any() and (~bad).sum() >= 3:
            for i in np.flatnonzero(bad):
                rejected.append(RejectedRow(int(data.row_id[dark[i]]), np.nan, np.nan,
                                            f"dark reading {score[i]:.1f} robust sigmas off the {fit.kind} "
                                            "dark-current fit"))
            fit = fit_dark(t[~bad], cur[~bad])
    return fit


def direction_groups(alpha_deg, beta_deg, *, tolerance_deg: float = DIRECTION_TOLERANCE_DEG) -> np.ndarray:
    """Group label of each reading: readings within `tolerance_deg` in both α and β of a group's first share it.

    References
    ----------
    seed 002, §4 (readings at known table angles; digest §8: repeat passes).
    """
    a, b = np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()
    labels = np.full(a.size, -1)
    centres_a, centres_b = [], []
    for i in np.lexsort((b, a)):
        if centres_a:
            near = np.flatnonzero((np.abs(np.asarray(centres_a) - a[i]) <= tolerance_deg)
                                  & (np.abs(np.asarray(centres_b) - b[i]) <= tolerance_deg))
            if near.size:
                labels[i] = near[0]
                continue
        labels[i] = len(centres_a)
        centres_a.append(a[i])
        centres_b.append(b[i])
    return labels


def saturated_rows(currents_a, full_scale_a: float | None = None) -> np.ndarray:
    """Readings with a saturated channel (module docstring, step 2).

    References
    ----------
    seed 002, §1.3 (the sensor's ADC converts the currents); digest §8 (ADC quantisation, saturation).
    """
    cur = np.asarray(currents_a, float)
    if full_scale_a is not None:
        return np.any(cur >= full_scale_a, axis=1)
    out = np.zeros(cur.shape[0], bool)
    for k in range(4):
        top = cur[:, k].max() if cur.shape[0] else 0.0
        at_top = cur[:, k] == top
        if at_top.sum() >= CLIP_REPEATS and top > 0:
            out |= at_top
    return out


def _directions(data: QdBenchData, alpha: np.ndarray, beta: np.ndarray, photo: np.ndarray, light: np.ndarray,
                rejected: list) -> tuple[QdDirections, float | None]:
    idx = np.flatnonzero(light)
    group = np.full(idx.size, -1)
    for flag in (False, True):  # check points never share a direction with nodes
        part = data.check[idx] == flag
        if part.any():
            group[part] = direction_groups(alpha[idx[part]], beta[idx[part]]) + (group.max() + 1)
    shares = quadrant_fractions(photo[idx])
    members = [idx[group == g] for g in range(group.max() + 1)] if idx.size else []
    local = [np.flatnonzero(group == g) for g in range(len(members))]
    # the repeat scatter from the differences between readings of one direction: var(x_i − x_j) = 2σ², with no
    # reading compared with a centre it helped to place (a median of 3 is one of them: its deviation is 0)
    differences = []
    for loc in local:
        if loc.size >= 2:
            i, j = np.triu_indices(loc.size, 1)
            differences.append(shares[loc][i] - shares[loc][j])
    scatter = _robust_sigma(np.concatenate(differences).ravel()) / np.sqrt(2.0) if differences else None
    keep_members = []
    for g, loc in enumerate(local):
        mem = members[g]
        if loc.size >= 3 and scatter is not None:
            own = shares[loc]
            others = np.array([np.median(np.delete(own, k, axis=0), axis=0) for k in range(loc.size)])
            # a reading against the median of the others: its own noise and theirs (≈ σ²/(n − 1) for a mean)
            dist = np.max(np.abs(own - others), axis=1) / np.sqrt(1.0 + 1.0 / (loc.size - 1))
            limit = max(OUTLIER_SIGMAS * scatter, OUTLIER_FLOOR_SHARE)
            bad = dist > limit
            if bad.any() and (~bad).sum() >= 2:
                for i in np.flatnonzero(bad):
                    rejected.append(RejectedRow(
                        int(data.row_id[mem[i]]), float(alpha[mem[i]]), float(beta[mem[i]]),
                        f"its quadrant shares lie {dist[i] / scatter:.1f} repeat sigmas from the other "
                        f"{int((~bad).sum())} readings of its direction (glint or stray light)"))
                mem = mem[~bad]
        keep_members.append(mem)
    photo_mean = np.array([photo[m].mean(axis=0) for m in keep_members]).reshape(-1, 4)
    mean_a = np.array([alpha[m].mean() for m in members])  # the direction: its readings' mean (all of them)
    mean_b = np.array([beta[m].mean() for m in members])
    first = np.array([m[0] for m in members], int)
    return QdDirections(mean_a, mean_b, photo_mean, data.check[first], keep_members), scatter


def _screen_directions(points: QdDirections, photo: np.ndarray, design: QdDesign, data: QdBenchData,
                       rejected: list, warnings: list) -> QdDirections:
    """Step 4 of the module docstring: a robust physical fit; isolated spikes of its residual are rejected.

    In a rejected direction with several readings, the readings that agree with the model are kept (a glint
    in one of two repeats costs that reading only). Only fitted (node) directions are screened: a check
    direction is held out, and dropping it for disagreeing with a model would let the model choose the points it
    is scored on (a check direction gets only the model-free repeat test of :func:`_directions`).
    """
    nodes = ~points.check
    if nodes.sum() < 12:
        return points
    try:
        fit = fit_physical(points.alpha_deg[nodes], points.beta_deg[nodes], points.photocurrents_a[nodes],
                           design=design, loss="soft_l1")
    except CalibrationError:
        return points
    model = predict_shares(points.alpha_deg, points.beta_deg, fit.parameters)
    resid = np.sqrt(np.mean((model - quadrant_fractions(points.photocurrents_a)) ** 2, axis=1))
    base = float(np.median(resid[nodes]))
    pos = np.stack([points.alpha_deg, points.beta_deg], axis=1)
    dist = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    np.fill_diagonal(dist, np.inf)
    near = np.argsort(dist, axis=1)[:, :8]
    local = np.maximum(np.median(resid[near], axis=1), base)
    limit = np.maximum(OUTLIER_SIGMAS * 1.4826 * local, OUTLIER_FLOOR_SHARE)
    bad = (resid > limit) & nodes
    if not bad.any():
        return points
    if bad.mean() > SCREEN_MAX_SHARE:
        warnings.append(f"the physical model disagrees with {int(bad.sum())} of {len(points)} directions far beyond "
                        "their neighbours' residual: it was not used to reject outliers. Check the quadrant layout "
                        "and the design (diaphragm, gap), or look for stray light")
        return points
    keep = np.ones(len(points), bool)
    members = list(points.members)
    current = points.photocurrents_a.copy()
    for i in np.flatnonzero(bad):
        rows = points.members[i]
        row_resid = np.sqrt(np.mean((quadrant_fractions(photo[rows]) - model[i]) ** 2, axis=1))
        good = row_resid <= limit[i]
        for j, r in zip(rows[~good], row_resid[~good]):
            rejected.append(RejectedRow(int(data.row_id[j]), float(points.alpha_deg[i]), float(points.beta_deg[i]),
                                        f"its quadrant shares disagree with the physical model by {r:.2e}, "
                                        f"{r / local[i]:.0f}× the residual of the neighbouring directions "
                                        "(glint or a bad reading)"))
        if good.any():
            members[i] = rows[good]
            current[i] = photo[rows[good]].mean(axis=0)
        else:
            keep[i] = False
    cleaned = QdDirections(points.alpha_deg, points.beta_deg, current, points.check, members)
    return cleaned.subset(keep)


def _chi2(fitted: _Fitted, points: QdDirections, photo: np.ndarray, design: QdDesign, pred_a, pred_b) -> float | None:
    nodes = np.flatnonzero(~points.check)
    groups = [points.members[i] for i in nodes if points.members[i].size >= 2]
    if not groups:
        return None
    rows = np.concatenate(groups)
    ra, rb = _predict(fitted, photo[rows], design)
    ss_a = ss_b = 0.0
    dof_rep = 0
    start = 0
    for g in groups:
        sa, sb = ra[start:start + g.size], rb[start:start + g.size]
        start += g.size
        ss_a += float(np.nansum((sa - np.nanmean(sa)) ** 2))
        ss_b += float(np.nansum((sb - np.nanmean(sb)) ** 2))
        dof_rep += g.size - 1
    var_a, var_b = ss_a / dof_rep, ss_b / dof_rep
    if not (var_a > 0 and var_b > 0):
        return None
    n = points.n_rows[nodes]
    da = pred_a[nodes] - points.alpha_deg[nodes]
    db = pred_b[nodes] - points.beta_deg[nodes]
    ok = np.isfinite(da) & np.isfinite(db)
    chi2 = float(np.sum(n[ok] * (da[ok] ** 2 / var_a + db[ok] ** 2 / var_b)))
    return chi2 / max(2 * int(ok.sum()) - fitted.n_params, 1)


def _evaluate(method: str, points: QdDirections, photo: np.ndarray, dark: DarkFit, design: QdDesign, sensor_id,
              folds: int, candidates) -> QdMethodReport:
    nodes = ~points.check
    a, b, cur = points.alpha_deg, points.beta_deg, points.photocurrents_a
    try:
        fitted = _fit_method(method, a[nodes], b[nodes], cur[nodes], design, candidates=candidates, folds=folds)
    except CalibrationError as exc:
        return QdMethodReport(method, None, None, None, None, error=str(exc))
    pred_a, pred_b = _predict(fitted, cur, design)
    at_nodes = angular_metrics(a[nodes], b[nodes], pred_a[nodes], pred_b[nodes])
    by_scheme, problems = {}, []
    if points.check.any():
        chk = points.check
        by_scheme["check"] = angular_metrics(a[chk], b[chk], pred_a[chk], pred_b[chk])
    na, nb, ncur = a[nodes], b[nodes], cur[nodes]
    for name, labels in heldout_schemes(na, nb, folds=folds).items():
        ha, hb = np.full(na.size, np.nan), np.full(na.size, np.nan)
        try:
            for label in np.unique(labels[labels >= 0]):
                out = labels == label
                fold = _fit_method(method, na[~out], nb[~out], ncur[~out], design, initial=_initial_of(fitted),
                                   candidates=candidates, folds=folds)
                ha[out], hb[out] = _predict(fold, ncur[out], design)
        except CalibrationError as exc:
            problems.append(f"{name}: {exc}")
            continue
        scored = labels >= 0
        by_scheme[name] = angular_metrics(na[scored], nb[scored], ha[scored], hb[scored])
    heldout, scheme = None, None
    if by_scheme:
        scheme = max(by_scheme, key=lambda k: (by_scheme[k].max_deg if np.isfinite(by_scheme[k].max_deg) else np.inf))
        heldout = by_scheme[scheme]
    chi2 = _chi2(fitted, points, photo, design, pred_a, pred_b)
    metrics = {"at_nodes": at_nodes.to_dict(), "heldout": None if heldout is None else heldout.to_dict(),
               "heldout_scheme": scheme, "heldout_by_scheme": {k: v.to_dict() for k, v in by_scheme.items()},
               "chi2_dof": chi2}
    document = _document(fitted, dark, design, sensor_id, metrics)
    error = None if heldout is not None else ("no held-out figure: " + "; ".join(problems) if problems
                                              else "no held-out figure: no check points and no grid lines to leave out")
    return QdMethodReport(method, fitted.model, document, at_nodes, heldout, scheme, by_scheme, chi2, error,
                          dict(fitted.details))


def choose_method(reports: list) -> QdMethodReport:
    """The report with the smallest held-out maximum error (the at-node one when none could be held out).

    References
    ----------
    seed 002, §5.2–5.3 (methods compared by their maximum error over the field).
    """
    usable = [r for r in reports if r.model is not None]
    if not usable:
        raise CalibrationError("no QD method could be fitted: " + "; ".join(f"{r.method}: {r.error}" for r in reports))
    held = [r for r in usable if r.heldout is not None and np.isfinite(r.heldout.max_deg)]
    if held:
        return min(held, key=lambda r: (r.heldout.n_failed, r.heldout.max_deg))
    return min(usable, key=lambda r: r.at_nodes.max_deg)


def calibrate_qd(data: QdBenchData, methods=None, *, design: QdDesign = DEFAULT_QD, folds: int = FOLDS,
                 polynomial_candidates=DEFAULT_CANDIDATES) -> QdCalibrationOutcome:
    """Calibrate a QD sun sensor from its bench data (module docstring, steps 1–7).

    Parameters
    ----------
    data : QdBenchData
        Dark rows, node rows and (optionally) check rows, with repeats.
    methods : sequence of str, optional
        Default every method of :data:`METHODS`.
    design : QdDesign
        Nominal design (diaphragm radius, L of eq. 2.1, layout).
    folds : int
        Interleaved folds per axis of the leave-lines-out cross-validation.
    polynomial_candidates : sequence
        Term sets the polynomial's order is chosen from.

    Returns
    -------
    QdCalibrationOutcome

    References
    ----------
    seed 002, §2.1, §3.1, eqs. 2.1–2.3, §5.2–5.3.
    """
    methods = tuple(methods or METHODS)
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        raise ValueError(f"unknown QD methods {unknown}; the methods are {METHODS}")
    rejected: list = []
    warnings: list = []
    dark = _fit_dark_robust(data, rejected)
    photo = subtract_dark(data.currents_a, data.temperature_c, dark)  # seed 002 §2.1
    alpha, beta = data.projection_deg
    light = ~data.dark
    sums = photo.sum(axis=1)
    for i in np.flatnonzero(light & ~(sums > 0)):
        rejected.append(RejectedRow(int(data.row_id[i]), float(alpha[i]), float(beta[i]),
                                    f"its photocurrents sum to {sums[i]:.3e} A after the dark current: no light"))
    light &= sums > 0
    clipped = saturated_rows(data.currents_a, design.full_scale_a) & light
    for i in np.flatnonzero(clipped):
        rejected.append(RejectedRow(int(data.row_id[i]), float(alpha[i]), float(beta[i]),
                                    "a channel is saturated (at the ADC's full scale)"))
    light &= ~clipped
    if (light & ~data.check).sum() < 8:
        raise InsufficientDataError(f"a QD calibration needs light readings at 8 directions at least, the data have "
                                    f"{int((light & ~data.check).sum())} usable light rows")
    points, scatter = _directions(data, alpha, beta, photo, light, rejected)
    points = _screen_directions(points, photo, design, data, rejected, warnings)
    if (~points.check).sum() < 8:
        raise InsufficientDataError(f"only {int((~points.check).sum())} node directions are left after the outliers")
    reports = [_evaluate(m, points, photo, dark, design, data.sensor_id, folds, polynomial_candidates) for m in methods]
    chosen = choose_method(reports)
    warnings += _warnings(chosen, reports, dark, points, rejected, scatter, data)
    return QdCalibrationOutcome(dark, reports, chosen, points, rejected, warnings, scatter)


def _warnings(chosen: QdMethodReport, reports: list, dark: DarkFit, points: QdDirections, rejected: list,
              scatter, data: QdBenchData) -> list[str]:
    out = []
    if dark.kind == "none":
        out.append("no dark readings (light off): the dark current is not subtracted; it biases the spot toward the "
                   "quadrants with more dark current, most at high temperature (seed 002 §2.1)")
    elif dark.kind == "constant":
        out.append(dark.note)
    else:
        t_light = data.temperature_c[~data.dark]
        lo, hi = dark.temperature_range_c
        if t_light.size and (t_light.min() < lo - 1.0 or t_light.max() > hi + 1.0):
            out.append(f"light readings span {t_light.min():.1f}…{t_light.max():.1f} °C but the dark current was "
                       f"measured over {lo:.1f}…{hi:.1f} °C only: it is extrapolated")
    if rejected:
        out.append(f"{len(rejected)} row(s) rejected: " + "; ".join(r.describe() for r in rejected[:5])
                   + (" …" if len(rejected) > 5 else ""))
    if scatter is None:
        out.append("no direction has repeated readings, so no residual can be compared with the noise; repeat "
                   "each direction to let the calibration check itself")
    elif chosen.chi2_dof is not None and chosen.chi2_dof > CHI2_WARNING:
        out.append(f"the residual of {chosen.method} is {np.sqrt(chosen.chi2_dof):.1f}× the repeat scatter "
                   f"(χ²/dof = {chosen.chi2_dof:.1f}): the calibration does not describe these data to their "
                   "noise. Likely causes: the table's pointing (1′ in the thesis, not in the repeat scatter), "
                   "reflections inside the housing at the edge of the field (the thesis' suspicion, §5.2), a dark "
                   "current drifting between the dark run and the light run, or a sensor unlike the model")
    if not points.check.any():
        out.append("no off-node check points: held-out figures come from leaving grid lines out only; add points "
                   "between the nodes (the thesis warns the error there may exceed the error at them, §5.3)")
    h, n = chosen.heldout, chosen.at_nodes
    if h is not None and n is not None and h.max_deg > 3 * max(n.max_deg, 1e-4) and h.max_deg > 0.05:
        out.append(f"{chosen.method} does {h.max_deg / n.max_deg:.0f}× worse between the nodes "
                   f"({h.max_deg:.3f}° max, {chosen.heldout_scheme}) than at them ({n.max_deg:.3f}°): use a "
                   "finer grid")
    if h is not None and h.n_failed:
        out.append(f"{chosen.method} gave no direction for {h.n_failed} held-out point(s): the spot left the QD's "
                   "centre there (the field is wider than the sensor's)")
    for statement in chosen.details.get("statements", []):
        out.append(f"{chosen.method}: {statement}")
    cos_rms = chosen.details.get("cos_law_rms")
    if cos_rms is not None and cos_rms > 0.02:
        out.append(f"the photocurrent sums depart from the cos law by {100 * cos_rms:.1f} % RMS: the lamp drifted, "
                   "its beam is not uniform, or stray light reaches the QD")
    failed = [r for r in reports if r.model is None]
    for r in failed:
        out.append(f"{r.method} could not be fitted: {r.error}")
    return out
