"""The thesis' horizon locators on a sampled pulse (seed 004 §2-2, eqs. 2.1–2.2; §4-4, §4-5).

A pulse is the detector's level sampled at phases δ_j (uniform step, ascending, one revolution or a window of one)
for one cone, or a stack (n_cones, N) of them. It is high on the Earth and low on the sky.

* **Normalised constant locator** (eq. 2.1): δ* where α/α_max = C1 (C1 = 0.5 for the thesis' 50 % obscuration).
* **Normalised integrated locator** (eq. 2.2): δ* where ∫ α/α_max dδ = C2, integrated from the sky side of the edge
  (C2 in degrees of phase; the thesis gives no value).
* **Crossing rule**: ``"first-sample"`` reports the phase of the first sample past the level, as the thesis' scripts
  did — a bias of up to one sample, always in the direction of the scan (0–0.0036° at 10⁻⁵ s, 0–3.6° at 10⁻² s;
  digest §5.3). ``"interpolate"`` puts the crossing between the two samples that straddle the level by linear
  interpolation, which leaves only the curvature of the pulse over one step.
* **Pre-filter**: a centred moving average (symmetric, so it does not move an edge that is symmetric about its
  midpoint; the thesis filtered its PSG pulses without saying how, §4-5).

* **Edge locators** (one window holding one edge, :func:`locate_edge`): eq. 2.1 normalised by the whole pulse's peak
  (the thesis') or by the edge's own level just inside the disc (:func:`local_reference`), eq. 2.2 likewise, the
  steepest slope (:func:`inflection_locator`) and the foot of a two-level line (:func:`two_level_locator`). All but
  the first are blind to the crossing's radiance scale, which weather changes by ~2 %/K.

The edge leaving the Earth (falling, Earth → sky) is ``out``; the one coming back (rising) is ``in``
(:mod:`calibration.horizon` conventions). Phases are in degrees, in [0, 360) when `period_deg` wraps them.
"""

from __future__ import annotations

import numpy as np

CROSSING_RULES = ("interpolate", "first-sample")
NORMALISATIONS = ("max", "range")


def _phase_and_pulse(phase_deg, pulse):
    phase = np.asarray(phase_deg, float)
    values = np.asarray(pulse, float)
    if phase.ndim != 1 or phase.size < 3:
        raise ValueError("phase_deg must be a 1-D array of at least 3 samples")
    if values.shape[-1] != phase.size:
        raise ValueError(f"the pulse's last axis ({values.shape[-1]}) must match the phases ({phase.size})")
    step = np.diff(phase)
    if np.any(step <= 0) or not np.allclose(step, step[0], rtol=1e-6, atol=1e-9):
        raise ValueError("phase_deg must be uniformly spaced and increasing")
    if not np.all(np.isfinite(values)):
        raise ValueError("the pulse holds NaN or infinite samples")
    return phase, values, float(step[0])


def moving_average(pulse, window: int, circular: bool = True) -> np.ndarray:
    """Centred moving average of `window` samples (odd) along the last axis: the pre-filter of seed 004 §4-5.

    ``circular`` wraps the ends (a whole revolution is periodic); otherwise the ends are averaged over the samples
    that exist. A symmetric window leaves the phase of an edge that is odd about its midpoint unchanged.
    """
    values = np.asarray(pulse, float)
    if int(window) != window or window < 1 or window % 2 == 0:
        raise ValueError(f"the moving-average window must be an odd positive number of samples, got {window!r}")
    if window == 1:
        return values.copy()
    half = window // 2
    if circular:
        padded = np.concatenate([values[..., -half:], values, values[..., :half]], axis=-1)
        kernel = np.ones(window) / window
        return np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), -1, padded)
    ones = np.ones(values.shape[-1])
    kernel = np.ones(window)
    total = np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="same"), -1, values)
    return total / np.convolve(ones, kernel, mode="same")


def normalise(pulse, reference: str = "max") -> np.ndarray:
    """α/α_max of seed 004 eq. 2.1 (``reference="max"``: the sky at zero radiance, as PSG's pulse), or
    (α − α_min)/(α_max − α_min) (``"range"``: a detector with an offset, as on the bench), along the last axis."""
    values = np.asarray(pulse, float)
    if reference not in NORMALISATIONS:
        raise ValueError(f"reference must be one of {NORMALISATIONS}, got {reference!r}")
    top = values.max(axis=-1, keepdims=True)
    bottom = values.min(axis=-1, keepdims=True) if reference == "range" else 0.0
    span = top - bottom
    if np.any(span <= 0):
        raise ValueError("the pulse is flat (or not positive): no Earth in view to normalise by")
    return (values - bottom) / span


def level_crossings(phase_deg, pulse, level, rule: str = "interpolate", period_deg: float | None = 360.0):
    """All phases where a 1-D `pulse` crosses `level`: ``(falling (k,), rising (m,))`` [°] (seed 004 eq. 2.1).

    `rule` is ``"interpolate"`` (linear between the straddling samples) or ``"first-sample"`` (the thesis: the
    first sample past the level). With `period_deg` (default a revolution) the last sample is followed by the first
    one period later, and phases are wrapped into [0, period); with None the pulse is an open window.
    """
    phase, values, step = _phase_and_pulse(phase_deg, pulse)
    if values.ndim != 1:
        raise ValueError("level_crossings takes one pulse (N,)")
    if rule not in CROSSING_RULES:
        raise ValueError(f"rule must be one of {CROSSING_RULES}, got {rule!r}")
    if period_deg is not None:
        nxt_values = np.roll(values, -1)
        nxt_phase = np.append(phase[1:], phase[0] + period_deg)
    else:
        nxt_values, nxt_phase = values[1:], phase[1:]
        values, phase = values[:-1], phase[:-1]
    above, nxt_above = values >= level, nxt_values >= level
    out = []
    for mask in (above & ~nxt_above, ~above & nxt_above):
        idx = np.nonzero(mask)[0]
        if rule == "first-sample":
            at = nxt_phase[idx]
        else:
            frac = (level - values[idx]) / (nxt_values[idx] - values[idx])
            at = phase[idx] + frac * (nxt_phase[idx] - phase[idx])
        out.append(np.mod(at, period_deg) if period_deg is not None else at)
    return out[0], out[1]


def _single(crossings: np.ndarray, which: str) -> float:
    if crossings.size == 0:
        return np.nan
    if crossings.size > 1:
        raise ValueError(f"the pulse crosses the level {crossings.size} times {which}: filter it first "
                         "(moving_average) or look at level_crossings")
    return float(crossings[0])


def constant_locator(phase_deg, pulse, c1: float = 0.5, rule: str = "interpolate", reference: str = "max",
                     period_deg: float | None = 360.0):
    """The normalised constant-radiance locator of seed 004 eq. 2.1: the phases ``(out, in)`` [°] where α/α_max = C1.

    `pulse` is one cone (N,) or a stack (n_cones, N); the result is two floats or two arrays (n_cones,), NaN where
    the pulse has no such edge. More than one crossing of the same sense raises (noise: pre-filter first).
    """
    if not 0.0 < c1 < 1.0:
        raise ValueError(f"C1 must lie strictly between 0 and 1, got {c1!r}")
    phase, values, _ = _phase_and_pulse(phase_deg, pulse)
    norm = normalise(values, reference)
    flat = norm.reshape(-1, phase.size)
    outs, ins = [], []
    for row in flat:
        falling, rising = level_crossings(phase, row, c1, rule, period_deg)
        outs.append(_single(falling, "falling"))
        ins.append(_single(rising, "rising"))
    if norm.ndim == 1:
        return outs[0], ins[0]
    shape = norm.shape[:-1]
    return np.reshape(outs, shape), np.reshape(ins, shape)


def integrated_locator(phase_deg, pulse, c2_deg: float, start_level: float = 0.0, reference: str = "max"):
    """The normalised integrated-radiance locator of seed 004 eq. 2.2: the phases ``(out, in)`` [°] where the integral
    of α/α_max from the sky side of each edge reaches C2 [° of phase].

    For the rising edge the integral starts at the last sample at or below `start_level` (the sky: 0 for a clean
    pulse, a noise floor otherwise — the tail the floor cuts off is lost from the integral) before the edge and runs
    forwards; for the falling edge it starts at the first such sample after the edge and runs backwards (the same
    construction mirrored). Trapezoidal sums, linear interpolation inside the step. One pulse
    (N,) over one revolution (wrapped); NaN where an edge is missing. For a straight edge blurred by a top-hat disc
    of radius α swept square-on, the boresight sits on the edge at C2 = 2α/(3π) (the disc's mean depth beyond a chord
    through its centre).
    """
    if c2_deg <= 0:
        raise ValueError(f"C2 must be positive (degrees of phase), got {c2_deg!r}")
    phase, values, step = _phase_and_pulse(phase_deg, pulse)
    if values.ndim != 1:
        raise ValueError("integrated_locator takes one pulse (N,)")
    norm = normalise(values, reference)
    n = phase.size
    below = norm <= start_level
    result = []
    for direction in (-1, +1):  # falling edge (integrate backwards from the sky after it), rising edge (forwards)
        seq = norm[::direction] if direction == 1 else norm[::-1]
        ph = phase if direction == 1 else -phase[::-1]
        low = below if direction == 1 else below[::-1]
        # the first sky sample that is followed by Earth (in the integration direction)
        starts = np.nonzero(low & ~np.roll(low, -1))[0]
        if starts.size == 0:
            result.append(np.nan)
            continue
        i0 = int(starts[0])
        order = (i0 + np.arange(n)) % n
        y = seq[order]
        x = ph[i0] + step * np.arange(n)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * step)])
        k = int(np.searchsorted(cum, c2_deg))
        if k == 0 or k >= n:
            result.append(np.nan)
            continue
        # inside step k-1..k the integrand is linear: solve the quadratic for the exact trapezoid, or linearly
        y0, y1 = y[k - 1], y[k]
        need = c2_deg - cum[k - 1]
        slope = (y1 - y0) / step
        if abs(slope) < 1e-15:
            dx = need / y0
        else:
            dx = (-y0 + np.sqrt(max(y0 * y0 + 2.0 * slope * need, 0.0))) / slope
        at = x[k - 1] + dx
        result.append(float(np.mod(at if direction == 1 else -at, 360.0)))
    return result[0], result[1]


# --- Locators on one edge window (seed 004 §2-2 and its future-work item 3: a locator that cuts the atmosphere's
# error). A window holds one edge: sky at one end, the Earth's disc at the other, sampled uniformly in phase.

EDGES = ("out", "in")
EDGE_METHODS = ("peak-threshold", "local-threshold", "local-integrated", "inflection", "two-level")


def _rising(phase_deg, pulse, edge: str):
    """The window as a rising edge: x ascending from the sky into the Earth, and the sign that maps x back to phase
    (an ``"out"`` edge, Earth → sky along the scan, is mirrored)."""
    if edge not in EDGES:
        raise ValueError(f"edge must be one of {EDGES}, got {edge!r}")
    phase, values, step = _phase_and_pulse(phase_deg, pulse)
    if values.ndim != 1:
        raise ValueError("an edge locator takes one window (N,)")
    if edge == "in":
        return phase, values, step, 1.0
    return -phase[::-1], values[::-1], step, -1.0


def _first_up_crossing(x, y, level: float) -> float:
    """The x where y first reaches `level` coming from the sky (x ascending), by linear interpolation."""
    at = np.nonzero(y >= level)[0]
    if at.size == 0 or at[0] == 0:
        raise ValueError("the window does not hold the edge: it must start on the sky below the level and reach it")
    k = int(at[0])
    return float(x[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (x[k] - x[k - 1]))


def _local_peak(x, y, start: float, depth_deg: float) -> float:
    """The pulse's maximum from `start` to `depth_deg` further into the Earth (the interpolated end included)."""
    end = start + depth_deg
    if end > x[-1]:
        raise ValueError(f"the window must reach {depth_deg}° into the Earth beyond the edge for the local reference")
    inside = y[(x >= start) & (x <= end)]
    return float(max(np.max(inside, initial=-np.inf), np.interp(end, x, y), np.interp(start, x, y)))


def local_reference(phase_deg, pulse, edge: str = "in", c1: float = 0.5, depth_deg: float = 5.0,
                    passes: int = 6) -> tuple[float, float]:
    """The pulse's own level just inside the disc for one edge window: ``(reference, crossing)`` — the maximum of the
    pulse within `depth_deg` [° of phase] Earth-side of the C1 crossing, and that crossing [°], found together by
    fixed-point passes (the crossing moves with the reference). The per-crossing α_max of seed 004 eq. 2.1: it
    follows the crossing's own atmosphere instead of the disc's brightest point, which lies far from the horizon."""
    if not 0.0 < c1 < 1.0:
        raise ValueError(f"C1 must lie strictly between 0 and 1, got {c1!r}")
    x, y, _, sign = _rising(phase_deg, pulse, edge)
    reference = float(y.max())
    at = _first_up_crossing(x, y, c1 * reference)
    for _ in range(passes):
        reference = _local_peak(x, y, at, depth_deg)
        at = _first_up_crossing(x, y, c1 * reference)
    return reference, sign * at


def threshold_edge_locator(phase_deg, pulse, edge: str = "in", c1: float = 0.5, peak: float | None = None,
                           depth_deg: float = 5.0) -> float:
    """Seed 004 eq. 2.1 on one edge window: the phase [°] where α/α_ref = C1, interpolated. α_ref is `peak` (the
    whole pulse's maximum, as the thesis normalised) or, when None, the pulse's local level (:func:`local_reference`),
    which makes the locator blind to the crossing's overall radiance scale."""
    if not 0.0 < c1 < 1.0:
        raise ValueError(f"C1 must lie strictly between 0 and 1, got {c1!r}")
    if peak is None:
        return local_reference(phase_deg, pulse, edge, c1, depth_deg)[1]
    if not peak > 0:
        raise ValueError(f"the normalising peak must be positive, got {peak!r}")
    x, y, _, sign = _rising(phase_deg, pulse, edge)
    return sign * _first_up_crossing(x, y, c1 * float(peak))


def integrated_edge_locator(phase_deg, pulse, c2_deg: float, edge: str = "in", peak: float | None = None,
                            depth_deg: float = 5.0) -> float:
    """Seed 004 eq. 2.2 on one edge window: the phase [°] where ∫ α/α_ref dδ, from the window's sky end towards the
    Earth, reaches C2 [° of phase] (trapezoids, exact inside the step). α_ref is `peak` or the local level of
    :func:`local_reference` (C1 = 0.5)."""
    if not c2_deg > 0:
        raise ValueError(f"C2 must be positive (degrees of phase), got {c2_deg!r}")
    reference = peak if peak is not None else local_reference(phase_deg, pulse, edge, 0.5, depth_deg)[0]
    x, y, step, sign = _rising(phase_deg, pulse, edge)
    y = y / reference
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * step)])
    k = int(np.searchsorted(cum, c2_deg))
    if k == 0 or k >= x.size:
        raise ValueError("the window's integral does not reach C2: widen the window into the Earth")
    y0, y1, need = y[k - 1], y[k], c2_deg - cum[k - 1]
    slope = (y1 - y0) / step
    dx = need / y0 if abs(slope) < 1e-15 else (-y0 + np.sqrt(max(y0 * y0 + 2.0 * slope * need, 0.0))) / slope
    return sign * float(x[k - 1] + dx)


def inflection_locator(phase_deg, pulse, edge: str = "in", fit_half_width: int = 2) -> float:
    """The phase [°] of the edge's steepest slope: the maximum of the centred difference, refined by a least-squares
    parabola through it and `fit_half_width` samples each side. Independent of the pulse's scale and offset (a
    derivative locator; seed 004 §2-2 lists the constant and integrated ones)."""
    x, y, step, sign = _rising(phase_deg, pulse, edge)
    slope = np.gradient(y, step)
    k = int(np.argmax(slope))
    m = int(fit_half_width)
    if m < 1 or k - m < 0 or k + m >= x.size:
        raise ValueError("the steepest slope lies too near the window's end to refine: widen the window")
    u = np.arange(-m, m + 1, dtype=float)
    c2, c1, _ = np.polyfit(u, slope[k - m:k + m + 1], 2)
    if c2 >= 0:
        raise ValueError("the slope has no maximum inside the window")
    return sign * float(x[k] + np.clip(-c1 / (2.0 * c2), -m, m) * step)


def two_level_locator(phase_deg, pulse, edge: str = "in", levels: tuple[float, float] = (0.3, 0.7),
                      peak: float | None = None, depth_deg: float = 5.0) -> float:
    """The edge's foot [°]: the line through the crossings of two normalised levels (α_ref = `peak` or the local
    level of :func:`local_reference`) extrapolated to zero radiance — a two-threshold locator that keeps the edge's
    slope, so a steeper or shallower limb moves it less than one threshold (seed 004 eq. 2.1 twice)."""
    low, high = levels
    if not 0.0 < low < high < 1.0:
        raise ValueError(f"levels must satisfy 0 < low < high < 1, got {levels!r}")
    reference = peak if peak is not None else local_reference(phase_deg, pulse, edge, 0.5, depth_deg)[0]
    x, y, _, sign = _rising(phase_deg, pulse, edge)
    x_low, x_high = _first_up_crossing(x, y, low * reference), _first_up_crossing(x, y, high * reference)
    return sign * float(x_low - low * (x_high - x_low) / (high - low))


def locate_edge(method: str, phase_deg, pulse, edge: str = "in", peak: float | None = None, **options) -> float:
    """One edge window's crossing phase [°] by a named method (:data:`EDGE_METHODS`): ``"peak-threshold"`` (eq. 2.1
    normalised by the whole pulse's `peak`, the thesis' locator), ``"local-threshold"`` (eq. 2.1 normalised by the
    edge's own level), ``"local-integrated"`` (eq. 2.2 likewise; option ``c2_deg``), ``"inflection"``,
    ``"two-level"``. Other `options` go to the method."""
    if method == "peak-threshold":
        if peak is None:
            raise ValueError("the peak-threshold locator needs the whole pulse's peak")
        return threshold_edge_locator(phase_deg, pulse, edge, peak=peak, **options)
    if method == "local-threshold":
        return threshold_edge_locator(phase_deg, pulse, edge, **options)
    if method == "local-integrated":
        return integrated_edge_locator(phase_deg, pulse, edge=edge, **options)
    if method == "inflection":
        return inflection_locator(phase_deg, pulse, edge, **options)
    if method == "two-level":
        return two_level_locator(phase_deg, pulse, edge, **options)
    raise ValueError(f"unknown edge locator {method!r}; known: {EDGE_METHODS}")
