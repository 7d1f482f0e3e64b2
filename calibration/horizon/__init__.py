"""The scanning Earth-horizon sensor (seed 004): cone-scan geometry, horizon crossings on a spherical and on the
WGS84 Earth, the field of view's partial obscuration, the atmosphere's limb radiance, locators, roll and pitch from
crossing times, the thesis' error tables, and the bench calibration of a sensor's own errors.

Conventions (shared by every module of the package, the simulators and the bench; seed 004 §1-3, §2-3):

* Body (sensor) frame: X_s the flight direction, Y_s the spin axis of cone 1, Z_s towards nadir. Orbit frame:
  X_r along track, Z_r towards the Earth's centre (geocentric nadir), Y_r completing the right-handed set.
* Roll φ about X, pitch θ about Y; body → orbit is ``R_y(−θ) · R_x(−φ)`` (seed 004 eq. 2.6, with the orthogonal
  R_x the printed one is not), so the nadir in the body frame is ``n_b = (−sin θ, sin φ cos θ, cos φ cos θ)``.
* Cone k (k = 1, 2, s_1 = +1, s_2 = −1) scans ``S_k(δ) = (sin δ sin γ_k, s_k cos γ_k, cos δ sin γ_k)``: the half-cone
  γ_k from the spin axis ±Y_s, the phase δ from Z_s towards X_s (seed 004 eq. 2.5; cone 2's axis −Y_s and the phase
  running the same way are the STK model's, digest §2.5 — unconfirmed against hardware). δ = 360° · t / T.
* A crossing is where the scan meets the horizon: ``S_k(δ) · n_b = cos ρ`` (seed 004 eq. 2.7 as corrected in
  :mod:`.scan`). Along increasing phase the scan leaves the Earth at ``δ_out`` (Earth → space, the falling edge:
  0.1845 s at 505 km, the thesis' "entry" of Table 4-2) and comes back onto it at ``δ_in`` (space → Earth, the rising
  edge); both are reported as phases in [0, 360) from the scan's reference (its index mark at δ = 0).
* Angles in degrees at every public boundary (``_deg``), lengths in km (``_km``), times in s (``_s``).
"""
