"""The 5-bit incidence-angle quantiser of seed 000 (ch. 5.3.4, listing D.6) and its inverse (Table C.3).

Each detector's output is mapped to a 1-D incidence-angle code in 5° bins (seed 000 ch. 5.3.4, digest §5.6).
Five tables t0 > t1 ≥ … > t18 exist, one per listing D.6 function:

=============  ===============  =====================  ===============================================
table          D.6 function     input                  listing's internal scaling
=============  ===============  =====================  ===============================================
``epd_albedo``  ``kvaepdalb``    EPD-365 current [A]     ``Iepdalbedo = x*10^6``  (µA)
``epd_sun``     ``kvaepdsun``    EPD-365 current [A]     ``Iepdsun = x*10^6``     (µA)
``bpw_albedo``  ``kvabpwalb``    BPW 21 current [A]      ``Ibpwalbedo = x*10^4``  (10⁻⁴ A)
``bpw_sun``     ``kvabpwsun``    BPW 21 current [A]      ``Ibpwsun = x*10^3``     (mA)
``tps``         ``kvatps``       TPS 230 seen temp. [°C] none
=============  ===============  =====================  ===============================================

The rule of every function (listing D.6)::

    code 0 if x > t0;   code k (1 … 18) if t_k < x ≤ t_(k−1);   code 19 if x ≤ t18

Code k (1 … 18) is the incidence bin [5(k−1)°, 5k°]; code 0 is direct (0°) incidence, code 19 (``10011``) is 90°,
"not lit". A code is an int here and the thesis' 5-character bit string (``'00100'``, MSB first) where the
listing has one; a face that was not processed is ``'xxxxx'`` (:data:`NOT_PROCESSED`, −1 as an int).

Thresholds are held in SI units (amperes, °C): each is the double nearest to the listing's decimal digits times
the listing's scale (``1.076`` µA → ``1.076e-6``), so a reading typed as a printed threshold compares equal to it
and falls on the documented side of the strict ``>`` (the listing's own ``x*10^6`` can move such an exact-edge
reading by one ulp into the neighbouring bin; nothing else differs).

The inverse of a code is the bin centre: incidence 5k − 2.5° (code 0 → 0°, code 19 → 90°), and the thesis'
``elevace()``/``azimut()`` — not listed, reconstructed from Table C.3 and the printed runs (digest §5.7) — are
90° minus that incidence: the angle of the source above the face's plane.

:func:`thresholds_from_response` is the thesis' future work (e) (ch. 7): a table built from a measured
(calibrated) response curve, at any angular step.

References
----------
seed 000, ch. 5.3.4, listing D.6 (D.6.1–D.6.5), Table C.1, Table C.3, ch. 7 (e); digest §5.6, §5.7, §9 item 15.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

#: Bits per face code (seed 000 ch. 5.3.4)
CODE_BITS = 5
#: Angular resolution of the thesis' tables [°]
STEP_DEG = 5.0
#: Number of thresholds of a thesis table (t0 … t18, one every 5° from 0° to 90°)
N_THRESHOLDS = 19
#: The code of a face that reads "not lit" (90°): ``10011``
DARK_CODE = 19
#: The int of a face that was not processed (the listing's ``'xxxxx'`` column)
NOT_PROCESSED = -1
#: Its on-board form: the unused code ``11111`` the thesis proposes for it (seed 000 ch. 6)
NOT_PROCESSED_ONBOARD = 31


@dataclass(frozen=True)
class QuantiserTable:
    """One of the five threshold tables of listing D.6.

    Attributes
    ----------
    name : str
        ``epd_albedo``, ``epd_sun``, ``bpw_albedo``, ``bpw_sun`` or ``tps``.
    function : str
        The listing's function name (``kvaepdalb`` …).
    unit : str
        ``"A"`` (photodiode current) or ``"degC"`` (TPS seen temperature).
    listing_scale : float
        What the listing multiplies the input by before comparing (1e6, 1e4, 1e3 or 1).
    thresholds : tuple of float
        t0 … t18 in SI units (A or °C), non-increasing.
    """

    name: str
    function: str
    unit: str
    listing_scale: float
    thresholds: tuple[float, ...]

    @property
    def listing_thresholds(self) -> np.ndarray:
        """t0 … t18 in the listing's scaled units (µA, 10⁻⁴ A, mA or °C)."""
        return np.asarray(self.thresholds) * self.listing_scale


# seed 000, listing D.6.1 `kvaepdalb` (µA in the listing)
EPD_ALBEDO = QuantiserTable("epd_albedo", "kvaepdalb", "A", 1e6, (
    1.08e-6, 1.076e-6, 1.068e-6, 1.046e-6, 1.012e-6, 0.9704e-6, 0.9232e-6, 0.874e-6, 0.824e-6, 0.779e-6,
    0.733e-6, 0.682e-6, 0.627e-6, 0.571e-6, 0.514e-6, 0.459e-6, 0.405e-6, 0.356e-6, 0.311e-6))

# seed 000, listing D.6.2 `kvaepdsun` (µA); t18 is a floor of 0.112 pA, not Table C.1's I(90°) = 0
EPD_SUN = QuantiserTable("epd_sun", "kvaepdsun", "A", 1e6, (
    6.18e-6, 6.16e-6, 6.1e-6, 6.0e-6, 5.87e-6, 5.49e-6, 4.76e-6, 3.89e-6, 3.09e-6, 2.29e-6,
    1.42e-6, 0.684e-6, 0.309e-6, 0.199e-6, 0.119e-6, 0.064e-6, 0.0309e-6, 0.00955e-6, 0.000112e-6))

# seed 000, listing D.6.3 `kvabpwalb` (10⁻⁴ A); t0 = t1 = 2.66: the 0–5° bin (code 1) is empty
BPW_ALBEDO = QuantiserTable("bpw_albedo", "kvabpwalb", "A", 1e4, (
    2.66e-4, 2.66e-4, 2.64e-4, 2.58e-4, 2.5e-4, 2.4e-4, 2.28e-4, 2.16e-4, 2.04e-4, 1.92e-4,
    1.81e-4, 1.69e-4, 1.55e-4, 1.41e-4, 1.27e-4, 1.13e-4, 1e-4, 0.879e-4, 0.77e-4))

# seed 000, listing D.6.4 `kvabpwsun` (mA); t6 = 0.898 mA where Table C.1 prints 8.68E-04 (a typo in C.1,
# digest §3.5 ⚠); t18 is a floor of 20 nA, not I(90°) = 0
BPW_SUN = QuantiserTable("bpw_sun", "kvabpwsun", "A", 1e3, (
    1.17e-3, 1.16e-3, 1.15e-3, 1.13e-3, 1.11e-3, 1.04e-3, 0.898e-3, 0.734e-3, 0.583e-3, 0.432e-3,
    0.267e-3, 0.129e-3, 0.0583e-3, 0.0375e-3, 0.0224e-3, 0.0121e-3, 0.00583e-3, 0.0018e-3, 0.00002e-3))

# seed 000, listing D.6.5 `kvatps` (°C): the D.4 curve H(i) at i = 1, 6, …, 91; t18 = −205.7 °C is not
# TvisEarth = −202.4 °C (digest §9 item 15)
TPS = QuantiserTable("tps", "kvatps", "degC", 1.0, (
    13.7843, 13.5158, 12.7568, 10.8241, 6.7586, 0.1875, -8.6975, -19.8899, -33.5573, -49.3000,
    -66.1502, -83.3928, -100.9151, -118.6173, -136.3827, -154.0849, -171.6072, -188.8498, -205.7000))

#: The five tables of listing D.6 by name
TABLES: dict[str, QuantiserTable] = {t.name: t for t in (EPD_ALBEDO, EPD_SUN, BPW_ALBEDO, BPW_SUN, TPS)}


def _thresholds(table) -> np.ndarray:
    if isinstance(table, str):
        if table not in TABLES:
            raise ValueError(f"no quantiser table {table!r} (tables: {', '.join(TABLES)})")
        table = TABLES[table]
    if isinstance(table, QuantiserTable):
        table = table.thresholds
    t = np.asarray(table, float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError("thresholds must be a non-empty 1-D sequence t0, t1, …")
    if np.any(np.diff(t) > 0):
        raise ValueError("thresholds must be non-increasing (t0 ≥ t1 ≥ …)")
    return t


def quantise(x, table) -> np.ndarray:
    """Incidence-angle code of detector readings (seed 000, listing D.6; ch. 5.3.4).

    code 0 if x > t0; k if t_k < x ≤ t_(k−1); len(t) (19 for the thesis' tables) if x ≤ t_last.

    Parameters
    ----------
    x : array_like
        Readings in the table's SI unit: current [A] for the photodiode tables, seen temperature [°C] for ``tps``.
    table : str, QuantiserTable or sequence of float
        A table name of :data:`TABLES`, a table, or thresholds t0 ≥ t1 ≥ … in the unit of `x`.

    Returns
    -------
    numpy.ndarray of int
        Codes, the shape of `x` (a 0-d array for a scalar).
    """
    t = _thresholds(table)
    x = np.asarray(x, float)
    if np.any(np.isnan(x)):
        raise ValueError("quantise() got NaN: a reading is needed for every face")  # D.6 leaves y unassigned
    # the number of thresholds ≥ x: 0 above t0, k for t_k < x ≤ t_(k−1), len(t) at or below the last
    return t.size - np.searchsorted(t[::-1], x, side="left")


def code_bits(code, width: int = CODE_BITS):
    """The thesis' bit string of a code, MSB first: 4 → ``'00100'``; :data:`NOT_PROCESSED` → ``'xxxxx'``.

    Vectorised: an array of codes gives an array of strings (seed 000 ch. 5.3.4, listing D.6 returns the
    ASCII codes 48/49 of these characters).
    """
    c = np.asarray(code)
    if not np.issubdtype(c.dtype, np.integer):
        raise TypeError("codes are ints")
    if np.any((c >= 2 ** width) | (c < NOT_PROCESSED)):
        raise ValueError(f"a code does not fit {width} bits")
    out = np.vectorize(lambda k: "x" * width if k == NOT_PROCESSED else format(int(k), f"0{width}b"),
                       otypes=[object])(c)
    return str(out) if out.ndim == 0 else out.astype(str)


def code_from_bits(bits):
    """The int code of a thesis bit string: ``'00100'`` → 4, ``'xxxxx'`` → :data:`NOT_PROCESSED` (vectorised).

    seed 000 ch. 5.3.4 (the MATLAB matrices hold these characters; ``str2num`` of them orders as the code does).
    """
    def one(s: str) -> int:
        s = str(s)
        if set(s) == {"x"}:
            return NOT_PROCESSED
        if not s or set(s) - {"0", "1"}:
            raise ValueError(f"not a code bit string: {s!r}")
        return int(s, 2)

    b = np.asarray(bits, dtype=object)
    out = np.vectorize(one, otypes=[int])(b)
    return int(out) if out.ndim == 0 else out


def _as_code(code) -> np.ndarray:
    c = np.asarray(code)
    if c.dtype.kind in "USO":
        c = np.asarray(code_from_bits(c))
    return c.astype(int)


def code_incidence_deg(code, step_deg: float = STEP_DEG) -> np.ndarray:
    """Incidence angle [°] a code stands for: its bin centre (seed 000 ch. 5.3.4, Table C.3).

    Code 0 → 0°, code k (1 … n) → step·k − step/2, the last code (19 at 5°) → 90°. `code` may be ints or bit
    strings; :data:`NOT_PROCESSED` gives NaN.
    """
    c = _as_code(code)
    last = _last_code(step_deg)
    if np.any((c > last) | (c < NOT_PROCESSED)):
        raise ValueError(f"a code is outside 0 … {last} at a {step_deg}° step")
    inc = np.where(c == 0, 0.0, np.where(c == last, 90.0, step_deg * c - step_deg / 2.0))
    return np.where(c == NOT_PROCESSED, np.nan, inc)


def code_angle_deg(code, step_deg: float = STEP_DEG) -> np.ndarray:
    """The thesis' ``elevace()``/``azimut()`` of a code: 90° − the bin-centre incidence [°].

    The angle of the source above the face's plane (seed 000 Table C.3; the functions themselves are not listed,
    digest §5.7 reconstructs them): ``00000`` → 90, ``00001`` → 87.5, …, ``10010`` → 2.5, ``10011`` → 0.
    """
    return 90.0 - code_incidence_deg(code, step_deg)


def elevace(code) -> np.ndarray:
    """seed 000 D.5's ``elevace()``: 90° − bin centre of a 5° code (Table C.3); ints or bit strings."""
    return code_angle_deg(code)


def azimut(code) -> np.ndarray:
    """seed 000 D.5's ``azimut()``: the same angle as :func:`elevace` (the printed runs show it, digest §5.7)."""
    return code_angle_deg(code)


def incidence_code(incidence_deg, step_deg: float = STEP_DEG) -> np.ndarray:
    """The code a noise-free detector with a strictly decreasing response gives at an exact incidence [°].

    With x = R(i) strictly decreasing and t_k = R(step·k), t_k < x ≤ t_(k−1) ⇔ step(k−1) ≤ i < step·k, so the
    code is floor(i/step) + 1, and 19 (at 5°) from 90° on (seed 000 ch. 5.3.4, listing D.6). Code 0 (x > t0)
    needs a reading brighter than the table's 0° value, which no incidence gives: 0° itself is code 1.
    """
    i = np.asarray(incidence_deg, float)
    if np.any(np.isnan(i)):
        raise ValueError("incidence_code() got NaN")
    last = _last_code(step_deg)
    return np.clip(np.floor(i / step_deg).astype(int) + 1, 1, last)


def _last_code(step_deg: float) -> int:
    n = 90.0 / step_deg
    if step_deg <= 0 or abs(n - round(n)) > 1e-9:
        raise ValueError(f"the step must divide 90° (got {step_deg})")
    return int(round(n)) + 1


def kvaepdalb(x):
    """seed 000 listing D.6.1: bit-string code of EPD currents [A] lit by Earth albedo (vectorised)."""
    return code_bits(quantise(x, EPD_ALBEDO))


def kvaepdsun(x):
    """seed 000 listing D.6.2: bit-string code of EPD currents [A] lit by the Sun (vectorised)."""
    return code_bits(quantise(x, EPD_SUN))


def kvabpwalb(x):
    """seed 000 listing D.6.3: bit-string code of BPW currents [A] lit by Earth albedo (vectorised)."""
    return code_bits(quantise(x, BPW_ALBEDO))


def kvabpwsun(x):
    """seed 000 listing D.6.4: bit-string code of BPW currents [A] lit by the Sun (vectorised)."""
    return code_bits(quantise(x, BPW_SUN))


def kvatps(x):
    """seed 000 listing D.6.5: bit-string code of TPS seen temperatures [°C] (vectorised)."""
    return code_bits(quantise(x, TPS))


# ch. 6 names the albedo functions `kvaepdalbedo` / `kvabpwalbedo`; the listings D.5 and D.6 define and call
# `kvaepdalb` / `kvabpwalb` (digest §9 item 16). Both names work here.
kvaepdalbedo = kvaepdalb
kvabpwalbedo = kvabpwalb


def thresholds_from_response(angles_deg, values, step_deg: float = STEP_DEG, *, floor: float | None = None,
                             method: str = "linear") -> np.ndarray:
    """A quantiser table t0, t1, … from a measured (calibrated) response curve (seed 000 ch. 7, future work (e)).

    t_k is the response at incidence step·k for k = 0 … 90/step: the upper-angle edge of bin k, as the thesis
    built its tables from Table C.1 (ch. 5.3.4). The thesis' own EPD/BPW tables are this with Table C.1's
    columns, and its TPS table is this with the D.4 curve H read with H(1) at 0° (H(i) at i = 1, 6, …, 91).

    Parameters
    ----------
    angles_deg : array_like
        Incidence angles [°] of the measured curve, strictly increasing, covering 0 … 90°.
    values : array_like
        The response at those angles (current [A], seen temperature [°C] …), decreasing with the angle.
    step_deg : float
        Bin width [°]; must divide 90 (5° gives the thesis' 19 thresholds; 3° is the finest that fits 5 bits).
    floor : float, optional
        Thresholds below it are raised to it: a dark floor, so that a dark reading is "not lit" and not the
        last bin. The listing's Sun tables have one (EPD 0.112 pA, BPW 20 nA) where Table C.1 gives I(90°) = 0.
    method : {"linear", "pchip"}
        Interpolation between the measured angles (``pchip`` is MATLAB's, the thesis' interpolant).

    Returns
    -------
    numpy.ndarray
        t0 … t_(90/step), made non-increasing (a running minimum) so that :func:`quantise` can use them.
    """
    a = np.asarray(angles_deg, float)
    v = np.asarray(values, float)
    if a.ndim != 1 or a.shape != v.shape or a.size < 2:
        raise ValueError("angles_deg and values must be 1-D of the same length (at least 2)")
    if np.any(np.diff(a) <= 0):
        raise ValueError("angles_deg must be strictly increasing")
    if not np.all(np.isfinite(v)):
        raise ValueError("values must be finite")
    n = _last_code(step_deg) - 1
    edges = step_deg * np.arange(n + 1)
    if a[0] > 0.0 or a[-1] < 90.0:
        raise ValueError(f"the response must cover 0 … 90° (got {a[0]} … {a[-1]}°)")
    if method == "linear":
        t = np.interp(edges, a, v)
    elif method == "pchip":
        t = PchipInterpolator(a, v)(edges)
    else:
        raise ValueError(f"method must be 'linear' or 'pchip' (got {method!r})")
    t = np.minimum.accumulate(t)
    if floor is not None:
        t = np.maximum(t, floor)
    return t


def unique_vector(codes) -> int:
    """The 30-bit unique vector of six face codes, face 1 in the top bits (seed 000 ch. 5.3.4).

    `codes`: six codes in thesis face order 1 … 6 (calibration/css/head.FACES); a face not processed becomes
    ``11111`` (:data:`NOT_PROCESSED_ONBOARD`, ch. 6).
    """
    c = [int(k) for k in np.asarray(_as_code(codes)).ravel()]
    if len(c) != 6:
        raise ValueError("a unique vector takes six codes")
    value = 0
    for k in c:
        k = NOT_PROCESSED_ONBOARD if k == NOT_PROCESSED else k
        if not 0 <= k < 2 ** CODE_BITS:
            raise ValueError(f"code {k} does not fit {CODE_BITS} bits")
        value = (value << CODE_BITS) | k
    return value


def table_thresholds(tables: Mapping[str, Sequence[float]] | None, name: str) -> np.ndarray:
    """The thresholds of table `name`: from `tables` when it has one (a calibrated table), else listing D.6's."""
    if tables is not None and name in tables:
        return _thresholds(tables[name])
    return _thresholds(name)
