"""The QD family: pure numerics of the quadrant-photodiode pinhole sun sensor (seed 002).

===============  ===========================================================================================
module           what it holds
===============  ===========================================================================================
``design``       the sensor's nominal design (diaphragm, pinhole height, gap, L of eq. 2.1, quadrant layout)
``angles``       the thesis' projection angles (α, β) ↔ the body frame's zenith and azimuth
``dark``         dark current per quadrant against temperature: the thesis' line, an exponential if clearly
                 better (§2.1); subtraction
``spot``         eq. 2.1: spot position (ratios, metres) from the four photocurrents
``geometric``    eq. 2.2 forward and inverse; its six-parameter least-squares fit with covariance
``polynomial``   eq. 2.3: 2-D polynomials on normalised coordinates; term sets; order by held-out error
``overlap``      exact area of a round spot on each quadrant of a QD with a dead cross
``physical``     the physical model (overlap, gains, offsets, d, φ) fitted to the shares; its inversion
(the tables' kinematics, (α, β) → table angles and back, are calibration.mount: every family uses them)
``data``         :class:`QdBenchData`, one row per reading
``evaluation``   :func:`calibrate_qd`: dark, outliers, every method held out between the nodes, the choice
``document``     the JSON calibration document and :func:`apply_document` from it alone
``export``       the C header of a document
``reference``    the thesis' published parameters and coefficients (reference only)
===============  ===========================================================================================

Conventions: quadrant k is column k−1 of an (N, 4) current array, in amperes, laid out as eq. 2.1 implies
(Q1 (−x, −y), Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y)) unless a layout says otherwise; tan α = s_x/s_z and
tan β = s_y/s_z in the CMOS family's body frame; angles in degrees, lengths in metres.
"""

from __future__ import annotations

from .angles import projection_angles, zenith_azimuth_from_projection
from .dark import DarkFit, fit_dark, subtract_dark
from .data import QdBenchData
from .design import DEFAULT_QD, QdDesign, quadrant_layout
from .document import QD_FORMAT_VERSION, apply_document, qd_document, validate_document
from .evaluation import METHODS, QdCalibrationOutcome, QdMethodReport, calibrate_qd
from .export import c_header
from .geometric import GeometricParameters, angles_from_spot, fit_geometric, spot_from_angles
from .physical import PhysicalParameters, fit_physical, invert_physical
from .polynomial import fit_polynomial, select_polynomial, term_set
from .spot import spot_position, spot_ratios

__all__ = [
    "DEFAULT_QD", "METHODS", "QD_FORMAT_VERSION", "DarkFit", "GeometricParameters", "PhysicalParameters",
    "QdBenchData", "QdCalibrationOutcome", "QdDesign", "QdMethodReport", "angles_from_spot", "apply_document",
    "c_header", "calibrate_qd", "fit_dark", "fit_geometric", "fit_physical", "fit_polynomial", "invert_physical",
    "projection_angles", "qd_document",
    "quadrant_layout", "select_polynomial", "spot_from_angles", "spot_position", "spot_ratios", "subtract_dark",
    "term_set", "validate_document", "zenith_azimuth_from_projection",
]
