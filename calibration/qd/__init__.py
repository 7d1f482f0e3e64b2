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
``data``         :class:`~.data.QdBenchData`, one row per reading
``evaluation``   :func:`~.evaluation.calibrate_qd`: dark, outliers, each method held out between nodes, the choice
``document``     the JSON calibration document and :func:`~.document.apply_document` from it alone
``export``       the C header of a document
``reference``    the thesis' published parameters and coefficients (reference only)
===============  ===========================================================================================

Conventions: quadrant k is column k−1 of an (N, 4) current array, in amperes, laid out as eq. 2.1 implies
(Q1 (−x, −y), Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y)) unless a layout says otherwise; tan α = s_x/s_z and
tan β = s_y/s_z in the CMOS family's body frame; angles in degrees, lengths in metres.

Import from the modules themselves (``from calibration.qd.evaluation import calibrate_qd``): the package
re-exports nothing, so importing one module (``calibration.mount`` needs only ``angles``) loads no other.
"""
