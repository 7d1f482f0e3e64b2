"""The thesis' alternative model: Sun angles as 2-D polynomials of the spot coordinates (seed 002 eq. 2.3).

.. math:: α = \\sum_{(i,j) ∈ T} K_α(i,j)\\, u^i v^j, \\qquad β = \\sum_{(i,j) ∈ T} K_β(i,j)\\, u^i v^j

The thesis' term set T is ambiguous (digest §2.4, §5.3, §7 item 1): eq. 2.3 literally sums i, j = 0…4 (25
terms, up to x⁴y⁴), the text says "fourth degree", and the printed coefficients look like MATLAB's
``poly45`` less its last term. All three are available (:func:`term_set`): ``"total"`` (i + j ≤ n),
``"polyij"`` (MATLAB polyIJ: i ≤ I, j ≤ J, i + j ≤ max(I, J)) and ``"tensor"`` (i, j ≤ n).

The coordinates are normalised before the powers are taken, u = (x − c_x)/s_x and v = (y − c_y)/s_y with the
centre and half-range of the fitted data (stored with the coefficients): the thesis' SI coefficients span
10¹…10¹⁶, a badly conditioned basis. The model is linear in its coefficients and is fitted by linear least
squares (``numpy.linalg.lstsq``), both angles on one design matrix, whose condition number is
reported. The order is chosen by held-out error (:func:`select_polynomial`), since the thesis itself warns
that between the nodes the error may exceed the error at them.

References
----------
seed 002, eq. 2.3 and §5.3 (the p_ij table; warning about points between the nodes); digest §5.3, §7 item 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InsufficientDataError
from .angles import angle_between_projections_deg

#: Term-set kinds of :func:`term_set`.
TERM_KINDS = ("total", "polyij", "tensor")


def term_set(kind: str = "total", degree=4) -> tuple[tuple[int, int], ...]:
    """Exponents (i, j) of the monomials u^i v^j of a 2-D polynomial, in MATLAB's order.

    Parameters
    ----------
    kind : {"total", "polyij", "tensor"}
        ``"total"``: i + j ≤ n; ``"polyij"``: MATLAB Curve Fitting Toolbox polyIJ, i ≤ I, j ≤ J and
        i + j ≤ max(I, J) (``poly45`` has 20 terms); ``"tensor"``: i, j ≤ n (eq. 2.3 read literally, 25 terms
        for n = 4).
    degree : int or (int, int)
        n, or (I, J) for ``"polyij"``.

    Returns
    -------
    terms : tuple of (i, j)
        Ordered by total degree, then by falling power of u (p00, p10, p01, p20, p11, p02, …).

    References
    ----------
    seed 002, eq. 2.3 and §5.3; digest §5.3 (poly45) and §7 item 1.
    """
    if kind == "polyij":
        ix, jy = (degree, degree) if np.isscalar(degree) else tuple(int(v) for v in degree)
        top = max(ix, jy)
        keep = lambda i, j: i <= ix and j <= jy and i + j <= top  # noqa: E731
    elif kind == "total":
        ix = jy = top = int(degree)
        keep = lambda i, j: i + j <= top  # noqa: E731
    elif kind == "tensor":
        ix = jy = int(degree)
        top = 2 * ix
        keep = lambda i, j: i <= ix and j <= jy  # noqa: E731
    else:
        raise ValueError(f"`kind` must be one of {TERM_KINDS}, got {kind!r}")
    if min(ix, jy) < 0:
        raise ValueError(f"`degree` must be non-negative, got {degree!r}")
    return tuple((t - j, j) for t in range(top + 1) for j in range(t + 1) if keep(t - j, j))


def design_matrix(u, v, terms) -> np.ndarray:
    """Columns u^i v^j for each (i, j) of `terms`, shape (N, len(terms)).

    References
    ----------
    seed 002, eq. 2.3.
    """
    u = np.asarray(u, dtype=float).ravel()
    v = np.asarray(v, dtype=float).ravel()
    top = max(max(i, j) for i, j in terms)
    pu = np.stack([u**k for k in range(top + 1)], axis=1)
    pv = np.stack([v**k for k in range(top + 1)], axis=1)
    return np.stack([pu[:, i] * pv[:, j] for i, j in terms], axis=1)


@dataclass(frozen=True)
class PolynomialModel:
    """Eq. 2.3 fitted: two coefficient sets on normalised coordinates.

    Attributes
    ----------
    terms : tuple of (i, j)
    kind : str
    degree : int or tuple
    center : (float, float)
        (c_x, c_y) subtracted from the input coordinates [input unit].
    scale : (float, float)
        (s_x, s_y) the centred coordinates are divided by [input unit].
    coef_alpha, coef_beta : ndarray, shape (len(terms),)
        K_α and K_β on the normalised coordinates [°].
    sd_alpha, sd_beta : ndarray
        Their 1σ (s² (VᵀV)⁻¹ with s² the residual variance of each angle) [°].
    condition_number : float
        Of the normalised design matrix (2-norm).
    residual_rms_deg : float
        RMS of the fitted angle residuals over both angles [°].
    """

    terms: tuple
    kind: str
    degree: object
    center: tuple
    scale: tuple
    coef_alpha: np.ndarray
    coef_beta: np.ndarray
    sd_alpha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sd_beta: np.ndarray = field(default_factory=lambda: np.zeros(0))
    condition_number: float = float("nan")
    residual_rms_deg: float = float("nan")

    def normalise(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) = ((x − c_x)/s_x, (y − c_y)/s_y)."""
        return ((np.asarray(x, dtype=float) - self.center[0]) / self.scale[0],
                (np.asarray(y, dtype=float) - self.center[1]) / self.scale[1])

    def evaluate(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(α, β) [°] at spot coordinates (x, y), of the input's shape (seed 002 eq. 2.3)."""
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        u, v = self.normalise(*np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float)))
        m = design_matrix(u, v, self.terms)
        return (m @ self.coef_alpha).reshape(shape), (m @ self.coef_beta).reshape(shape)

    @property
    def n_terms(self) -> int:
        return len(self.terms)


def normalisation(x, y) -> tuple[tuple[float, float], tuple[float, float]]:
    """Centre (mid-range) and half-range of the coordinates, so the normalised data span [−1, 1].

    References
    ----------
    digest §5.3 (fit in scaled coordinates and store the scaling with the coefficients).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    center = (float((x.max() + x.min()) / 2), float((y.max() + y.min()) / 2))
    scale = (float((x.max() - x.min()) / 2) or 1.0, float((y.max() - y.min()) / 2) or 1.0)
    return center, scale


def fit_polynomial(x, y, alpha_deg, beta_deg, *, kind: str = "total", degree=4, normalise=None) -> PolynomialModel:
    """Fit eq. 2.3 by linear least squares on normalised coordinates.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Spot coordinates (eq. 2.1's x_c, y_c or its ratios) [any unit].
    alpha_deg, beta_deg : array_like, shape (N,)
        Known Sun angles [°].
    kind, degree
        Term set (:func:`term_set`).
    normalise : ((c_x, c_y), (s_x, s_y)), optional
        Default: :func:`normalisation` of `x`, `y`.

    Returns
    -------
    PolynomialModel

    References
    ----------
    seed 002, eq. 2.3 (linear in its coefficients, so plain linear least squares suffices; digest §2.5).
    """
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    targets = np.stack([np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()], axis=1)
    if not (x.size == y.size == targets.shape[0]):
        raise InsufficientDataError("x, y, alpha and beta must have the same length")
    terms = term_set(kind, degree)
    if x.size < len(terms):
        raise InsufficientDataError(f"a {kind} polynomial of degree {degree} has {len(terms)} terms; it needs that "
                                    f"many points at least, got {x.size}")
    center, scale = normalise or normalisation(x, y)
    u, v = (x - center[0]) / scale[0], (y - center[1]) / scale[1]
    m = design_matrix(u, v, terms)
    coef, _, rank, sv = np.linalg.lstsq(m, targets, rcond=None)  # gelsd: its singular values give the condition
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    resid = targets - m @ coef
    dof = x.size - len(terms)
    if dof > 0 and rank == len(terms):
        s2 = np.sum(resid**2, axis=0) / dof
        diag = np.diag(np.linalg.solve(m.T @ m, np.eye(len(terms))))  # (MᵀM)⁻¹: normalised, so well enough posed
        sd = np.sqrt(np.outer(np.abs(diag), s2))
    else:
        sd = np.full(coef.shape, np.nan)
    return PolynomialModel(terms, kind, degree, center, scale, coef[:, 0], coef[:, 1], sd[:, 0], sd[:, 1], cond,
                           float(np.sqrt(np.mean(resid**2))))


#: Candidate term sets of :func:`select_polynomial`: total degree 1…8, MATLAB poly45/poly54, eq. 2.3 literally.
DEFAULT_CANDIDATES = tuple([("total", n) for n in range(1, 9)] + [("polyij", (4, 5)), ("polyij", (5, 4)),
                                                                   ("tensor", 4)])


@dataclass(frozen=True)
class OrderSelection:
    """How :func:`select_polynomial` chose its term set.

    Attributes
    ----------
    model : PolynomialModel
        The chosen term set fitted to all the data.
    table : list of dict
        Per candidate: kind, degree, n_terms, held-out RMS and max angular error [°], condition number.
    rule : str
        The rule, in words.
    """

    model: PolynomialModel
    table: list
    rule: str


def heldout_angles(x, y, alpha_deg, beta_deg, groups, *, kind: str, degree) -> tuple[np.ndarray, np.ndarray]:
    """(α, β) [°] of each point from a polynomial fitted without its group (NaN where a group cannot be left out).

    `groups` labels the points (−1: never left out); each label ≥ 0 is left out in turn. The normalisation is
    the full data's, so every fold shares the basis.

    References
    ----------
    seed 002, §5.3 (the error between the polynomial's nodes); research note anchors-sunsensors §6.
    """
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    a, b = np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()
    groups = np.asarray(groups).ravel()
    (cx, cy), (sx, sy) = normalisation(x, y)
    terms = term_set(kind, degree)
    m = design_matrix((x - cx) / sx, (y - cy) / sy, terms)
    targets = np.stack([a, b], axis=1)
    out_a, out_b = np.full(x.size, np.nan), np.full(x.size, np.nan)
    for label in np.unique(groups[groups >= 0]):
        out = groups == label
        if int((~out).sum()) < len(terms):
            continue
        coef, _, rank, _ = np.linalg.lstsq(m[~out], targets[~out], rcond=None)
        if rank < len(terms):
            continue
        pred = m[out] @ coef
        out_a[out], out_b[out] = pred[:, 0], pred[:, 1]
    return out_a, out_b


def _schemes(groups) -> list[np.ndarray]:
    if isinstance(groups, (list, tuple)):
        return [np.asarray(g).ravel() for g in groups]
    return [np.asarray(groups).ravel()]


def select_polynomial(x, y, alpha_deg, beta_deg, groups, *, candidates=DEFAULT_CANDIDATES,
                      tolerance: float = 0.05) -> OrderSelection:
    """Choose the term set by held-out angular error and fit it to all the data.

    Rule: each candidate is scored by the RMS angular error of the points predicted with their group left out,
    for each held-out scheme in `groups` (one label array, or several, e.g. whole grid columns and whole grid
    rows: :func:`calibration.qd.evaluation.heldout_schemes`), the worse scheme counting; the chosen one is the
    candidate with the fewest terms whose score is within `tolerance` (5 %) of the best, so a bigger basis must
    earn its terms between the nodes. A candidate needs fewer terms than half the points of any fold's fit,
    else it is skipped.

    References
    ----------
    seed 002, eq. 2.3 and §5.3 (the warning about errors between nodes).
    """
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    a, b = np.asarray(alpha_deg, float).ravel(), np.asarray(beta_deg, float).ravel()
    schemes = [g for g in _schemes(groups) if np.unique(g[g >= 0]).size >= 2]
    if not schemes:
        raise InsufficientDataError("choosing the polynomial's order needs a held-out scheme of two groups at least")
    smallest_fit = min(int(np.sum(g != label)) for g in schemes for label in np.unique(g[g >= 0]))
    table = []
    for kind, degree in candidates:
        n_terms = len(term_set(kind, degree))
        if 2 * n_terms > smallest_fit:
            continue
        rms, worst = [], []
        for g in schemes:
            ha, hb = heldout_angles(x, y, a, b, g, kind=kind, degree=degree)
            ok = np.isfinite(ha) & np.isfinite(hb)
            if ok.any():
                err = angle_between_projections_deg(a[ok], b[ok], ha[ok], hb[ok])
                rms.append(float(np.sqrt(np.mean(err**2))))
                worst.append(float(err.max()))
        if not rms:
            continue
        full = fit_polynomial(x, y, a, b, kind=kind, degree=degree)
        table.append({"kind": kind, "degree": degree, "n_terms": n_terms, "heldout_rms_deg": max(rms),
                      "heldout_max_deg": max(worst), "condition_number": full.condition_number, "_model": full})
    if not table:
        raise InsufficientDataError("no polynomial term set is small enough for these data")
    best = min(r["heldout_rms_deg"] for r in table)
    good = [r for r in table if r["heldout_rms_deg"] <= best * (1.0 + tolerance)]
    chosen = min(good, key=lambda r: (r["n_terms"], r["heldout_rms_deg"]))
    model = chosen["_model"]
    for r in table:
        r.pop("_model")
        r["chosen"] = r is chosen
    rule = (f"fewest terms with a held-out RMS within {100 * tolerance:g} % of the best ({best:.4f}°): "
            f"{model.kind} {model.degree} ({model.n_terms} terms)")
    return OrderSelection(model, table, rule)
