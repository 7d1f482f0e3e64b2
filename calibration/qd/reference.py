"""The thesis' published numbers, as documented constants: reference data, not test oracles.

* :data:`THESIS_GEOMETRIC` — the six parameters of eq. 2.2 found by the "main" calibration (§5.2), with the
  decimal commas of the original read as points. The lengths mean something only with the thesis' L of
  eq. 2.1, which is not given (digest §2.3).
* :data:`THESIS_POLYNOMIAL` — the 19 coefficients p_ij (multiplying x^i y^j) printed for the "alternative"
  model (§5.3). Only one set is printed though eq. 2.3 needs two, it is unlabelled (its magnitudes suggest β
  in degrees of x, y in metres), and its terms are MATLAB ``poly45``'s less p05 (digest §5.3): evaluated, it
  does not reproduce the geometric model, so it must not be used to check a polynomial fit.

References
----------
seed 002, §5.2, §5.3, §5.4; digest §5.2–5.4 and §7 item 1.
"""

from __future__ import annotations

from types import MappingProxyType

from .geometric import GeometricParameters

#: Seed 002 §5.2 (verbatim: x⁰ = −5,17e−05 м, y⁰ = 5,20e−04 м, α⁰ = 8,60e−03°, β⁰ = −0,15°,
#: d = 8,17e−04 м, φ⁰ = 5,14e−04°).
THESIS_GEOMETRIC = GeometricParameters(x0_m=-5.17e-05, y0_m=5.20e-04, alpha0_deg=8.60e-03, beta0_deg=-0.15,
                                       phi0_deg=5.14e-04, d_m=8.17e-04)

#: Seed 002 §5.3: p_ij by (i, j), in the printed order (p00, p10, p01, …, p14); p05 is not printed.
THESIS_POLYNOMIAL = MappingProxyType({
    (0, 0): 24.64, (1, 0): 454.8, (0, 1): -5.514e04,
    (2, 0): -1.405e07, (1, 1): -2.668e06, (0, 2): -2.568e07,
    (3, 0): -7.778e08, (2, 1): 3.412e10, (1, 2): 6.618e08, (0, 3): 4.027e09,
    (4, 0): 4.024e12, (3, 1): 3.016e12, (2, 2): 1.92e13, (1, 3): -1.608e12, (0, 4): 1.869e13,
    (4, 1): -2.736e16, (3, 2): 2.181e14, (2, 3): -1.182e16, (1, 4): 1.147e14,
})
