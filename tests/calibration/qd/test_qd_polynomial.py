"""Eq. 2.3: term sets, fits on normalised coordinates, order chosen by error between the nodes."""

import numpy as np
import pytest
from qd_simulation import grid, separable_currents, thesis_spots

from calibration.errors import InsufficientDataError
from calibration.qd.evaluation import heldout_schemes
from calibration.qd.polynomial import fit_polynomial, select_polynomial, term_set
from calibration.qd.reference import THESIS_POLYNOMIAL
from calibration.qd.spot import spot_position

LENGTH = 3e-3


def test_term_sets():
    assert len(term_set("total", 4)) == 15
    assert len(term_set("tensor", 4)) == 25  # eq. 2.3 read literally, up to x⁴y⁴
    poly45 = term_set("polyij", (4, 5))
    assert len(poly45) == 20
    # the thesis' printed table is MATLAB poly45 in its order, less its last term p05 (digest §5.3)
    assert tuple(THESIS_POLYNOMIAL) == poly45[:-1] and poly45[-1] == (0, 5)
    assert term_set("total", 2) == ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
    with pytest.raises(ValueError):
        term_set("chebyshev", 3)


def _thesis_bench(seed, step=5.0, noise_a=1e-10):
    a, b = grid(40.0, step)
    cur = separable_currents(*thesis_spots(a, b), LENGTH, total_a=1e-6)
    cur = cur + np.random.default_rng(seed).normal(0.0, noise_a, cur.shape)
    x, y = spot_position(cur, LENGTH)
    return a, b, x, y


def test_normalisation_keeps_the_basis_well_conditioned():
    a, b, x, y = _thesis_bench(0)
    scaled = fit_polynomial(x, y, a, b, kind="polyij", degree=(4, 5))
    raw = fit_polynomial(x, y, a, b, kind="polyij", degree=(4, 5), normalise=((0.0, 0.0), (1.0, 1.0)))
    print(f"\npoly45 condition number: normalised {scaled.condition_number:.3g}, in metres {raw.condition_number:.3g}")
    assert scaled.condition_number < 1e4
    assert raw.condition_number > 1e12  # the thesis' SI coefficients spanned 10¹…10¹⁶
    assert np.all(np.isfinite(scaled.coef_alpha)) and np.all(np.isfinite(scaled.sd_beta))
    # the model evaluates where it was fitted to its residual
    pa, pb = scaled.evaluate(x, y)
    assert np.sqrt(np.mean(np.concatenate([pa - a, pb - b]) ** 2)) == pytest.approx(scaled.residual_rms_deg)


def test_order_chosen_by_error_between_the_nodes():
    a, b, x, y = _thesis_bench(1)
    schemes = list(heldout_schemes(a, b).values())
    assert len(schemes) == 2  # whole interior columns, whole interior rows
    sel = select_polynomial(x, y, a, b, schemes)
    table = {(r["kind"], str(r["degree"])): r for r in sel.table}
    chosen = next(r for r in sel.table if r["chosen"])
    best = min(r["heldout_rms_deg"] for r in sel.table)
    print("\n" + "\n".join(f"{r['kind']:>7} {str(r['degree']):>7} {r['n_terms']:3d} terms: held-out RMS "
                           f"{r['heldout_rms_deg']:.4f}° max {r['heldout_max_deg']:.4f}°, "
                           f"cond {r['condition_number']:.3g}"
                           + ("  <- chosen" if r["chosen"] else "") for r in sel.table))
    assert chosen["heldout_rms_deg"] <= 1.05 * best
    assert 3 <= sel.model.n_terms <= 45 and sel.model.kind in ("total", "polyij", "tensor")
    # the rule: the fewest terms within 5 % of the best, and the model returned is that candidate's
    assert chosen["n_terms"] == min(r["n_terms"] for r in sel.table if r["heldout_rms_deg"] <= 1.05 * best)
    assert (sel.model.kind, sel.model.degree, sel.model.n_terms) == (chosen["kind"], chosen["degree"],
                                                                     chosen["n_terms"])
    assert sum(r["chosen"] for r in sel.table) == 1
    # a plane cannot follow arctan over ±40°: it is far worse between the nodes
    assert table[("total", "1")]["heldout_rms_deg"] > 10 * chosen["heldout_rms_deg"]
    # coefficients finite, conditioning reported
    assert np.all(np.isfinite(sel.model.coef_alpha)) and np.isfinite(sel.model.condition_number)
    # held out, the chosen model does no better than at the nodes
    assert chosen["heldout_rms_deg"] >= 0.9 * sel.model.residual_rms_deg


def test_too_many_terms_for_the_points_refused():
    a, b, x, y = _thesis_bench(2, step=20.0)  # 25 points
    with pytest.raises(InsufficientDataError):
        fit_polynomial(x, y, a, b, kind="total", degree=8)  # 45 terms
