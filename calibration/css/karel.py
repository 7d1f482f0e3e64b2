"""The azimuth/elevation algorithm of seed 000 (Karel 2013, listing D.5) as a pure function.

Inputs are one reading of the cube's 18 detectors in the thesis' face order 1 … 6, which is
:data:`calibration.css.head.FACES` (``px, py, mx, my, pz, mz``: face n is ``FACES[n - 1]``):

- six TPS 230 seen temperatures [°C],
- six EPD-365 currents [A],
- six BPW 21 currents [A].

The algorithm (seed 000 ch. 5.3.3–5.3.5 and ch. 6; listing D.5; digest §5.5–§5.8, §6.5):

1. Earth faces from the TPS: the two warmest of faces 1–4 and the warmer of 5/6, each only if its seen
   temperature is above ``TvisEarth`` = −202.4 °C (the TPS sees Earth at 90° at −202.4 °C, the Sun at best at
   −234.1 °C, ch. 5.2). The 3rd/4th of 1–4 and the cooler of 5/6 are the "other" faces; any of them above
   ``TvisEarth`` is also Earth-lit and is checked for the Sun error (step 5).
2. On the Earth faces the EPD, BPW and TPS readings are quantised with the albedo tables (``kvaepdalb``,
   ``kvabpwalb``, ``kvatps``) into the ``EPDalbedo``, ``BPWalbedo``, ``TPSalbedo`` matrices.
3. Sun faces: the three strongest EPD (BPW) currents among the faces that are not Earth-lit, quantised with the
   Sun tables (``kvaepdsun``, ``kvabpwsun``) into ``EPDsun`` (``BPWsun``). They are not split 2 + 1 as Earth's are.
4. Each matrix (5 bit rows × 6 face columns, ``x`` where a face was not processed) gives an elevation and an
   azimuth by the rules of :func:`elevation_from_codes` and :func:`azimuth_from_codes` (ch. 6, D.5 lines 792–1042).
5. The Sun-error verdict (ch. 6, D.5 lines 1048–1102): for each Earth-lit face not used for the Earth fix, its TPS
   code (Earth) is compared with its EPD code read with the *Sun* table; a smaller TPS code prints "the error is at
   most", otherwise "at least", followed by ``azimut`` of the TPS code (90° − its bin centre, not the incidence).

This is the *intended* computation, written with ``argsort``; comments marked ``LISTING:`` say where listing D.5
(or the ch. 6 excerpts of it) does something else. The MATLAB test inputs of D.5 are
:data:`LISTING_D5_INPUTS`; with them this gives the output printed at the end of ch. 6.

Model limits of the thesis' scheme (digest §5.4 ⚠): the elevation from face 5/6 alone is exact to the
quantisation (±2.5°); the azimuth from one side face (az = 90° − incidence on face 2 in the first quadrant) is
exact only at el = 0, since in general cos(i₂) = cos(el)·sin(az). A face that is selected but dark reads code 19
and counts as processed: e.g. Sun on faces 3 and 5 only, with a dark face 1 picked as the third, gives az = 0.

References
----------
seed 000, ch. 5.2, 5.3.1–5.3.5, ch. 6 (excerpts and printed results), appendix D.5, D.6, Table C.3;
digest §5.1–§5.8, §6.5, §8.4 item 11, §9 items 13–17.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from . import head
from .quantiser import (
    BPW_ALBEDO,
    BPW_SUN,
    CODE_BITS,
    DARK_CODE,
    EPD_ALBEDO,
    EPD_SUN,
    NOT_PROCESSED,
    NOT_PROCESSED_ONBOARD,
    TPS,
    code_angle_deg,
    code_bits,
    code_from_bits,
    quantise,
    table_thresholds,
)

#: D.5 line 51 ``TvisEarth=-202.4`` "Temperature of vision Earth angle 90°" [°C] (ch. 5.2, D.4)
TVIS_EARTH_C = -202.4

#: The test inputs hard-coded in listing D.5 (lines 29–48), as MATLAB evaluates them. Thesis face order 1 … 6.
LISTING_D5_INPUTS: dict[str, tuple[float, ...]] = {
    "tps_c": (9.64, -209.0, -270.0, -243.0, -191.0, -254.0),
    # LISTING: line 38 `epd3=1,42*10^-6;` has a decimal comma: MATLAB assigns epd3 = 1 and evaluates 42*10^-6
    # as a separate statement, so the script runs with 1 A on face 3. Lines 39 and 46 give face 4
    # `0.97*10^-60` and `1.29*10^-40`: exponents that are typos or stand-ins for a dark face (kept as written).
    "epd_a": (1.03e-6, 5.9e-6, 1.0, 0.97e-60, 3.3e-7, 5.6e-6),
    "bpw_a": (2.54e-4, 1.12e-3, 8e-4, 1.29e-40, 8e-5, 1.09e-3),
}

#: The same with the value D.5 line 38 means on face 3: epd3 = 1.42 µA
INTENDED_D5_INPUTS: dict[str, tuple[float, ...]] = {
    **LISTING_D5_INPUTS,
    "epd_a": (1.03e-6, 5.9e-6, 1.42e-6, 0.97e-60, 3.3e-7, 5.6e-6),
}

_FACE_ORDER_NOTE = "thesis face order 1 … 6 = calibration.css.head.FACES"


def _face_codes(codes) -> np.ndarray:
    c = np.asarray(codes)
    if c.dtype.kind in "USO":
        c = np.asarray(code_from_bits(c))
    c = c.astype(int)
    if c.shape[-1:] != (6,):
        raise ValueError(f"codes need a last axis of six faces ({_FACE_ORDER_NOTE})")
    return c


def _selected(c: np.ndarray, listing: bool = False) -> np.ndarray:
    # the listing's `pom~=('xxxxx')`: the face's column was written; on board the unused 11111 means "not".
    # LISTING: a face picked among the three strongest but dark (code 19, "90°: not lit") is processed too, and the
    # azimuth rules test face 1 before face 3, so the Sun on face 3 alone beside a dark face 1 reads as on face 1
    # (az 47.5° for 132.5°). Ch. 5.3.3 says what a dark face is for: "faces that are not lit read as 90°; this tells
    # how many faces, and which, are lit" — the intended rules see only lit faces (`listing=True`: the literal one).
    selected = (c != NOT_PROCESSED) & (c != NOT_PROCESSED_ONBOARD)
    return selected if listing else selected & (c != DARK_CODE)


def elevation_from_codes(codes, *, listing: bool = False) -> np.ndarray:
    """Elevation [°] from six face codes by the rule of seed 000 listing D.5 (lines 792–857; Table C.3).

    EL = +elevace(code of face 5) if face 5 was processed, else −elevace(code of face 6) if face 6 was, else 0.

    Parameters
    ----------
    codes : array_like, shape (..., 6)
        Codes in thesis face order 1 … 6 (calibration.css.head.FACES); ints with :data:`~.quantiser.NOT_PROCESSED`
        (−1) or 31 for a face not processed, or bit strings with ``'xxxxx'``.
    listing : bool
        Count a processed face at code 19 (dark) as the listing does (:func:`_selected`); by default it is not lit.
    """
    c = _face_codes(codes)
    sel = _selected(c, listing)
    # LISTING: lines 839 and 853 call elevace() on a column, `elevace(BPWalbedo(1:5,6))`, without the transpose
    # the other calls have; codes here are ints, so there is nothing to transpose.
    up = code_angle_deg(np.where(sel[..., 4], c[..., 4], 0))
    down = -code_angle_deg(np.where(sel[..., 5], c[..., 5], 0))
    return np.where(sel[..., 4], up, np.where(sel[..., 5], down, 0.0))


def azimuth_from_codes(codes, *, listing: bool = False) -> np.ndarray:
    """Azimuth [°] in [0, 360] from six face codes by the rule of seed 000 listing D.5 (lines 859–1042).

    With ψ_f = azimut(code of face f) = 90° − its bin centre::

        face 1 processed:  ψ_2 if 2 processed, elif 4: 360 − ψ_4, else 0
        elif face 3:       180 − ψ_2 if 2 processed, elif 4: ψ_4 + 180, else 180
        else:              90 if 2 processed, else 270

    The code of face 1 or 3 is not used. Note 360 − ψ_4 is 360 (not 0) for ψ_4 = 0, as in the listing.

    Parameters
    ----------
    codes : array_like, shape (..., 6)
        As for :func:`elevation_from_codes`.
    listing : bool
        As for :func:`elevation_from_codes`.
    """
    c = _face_codes(codes)
    sel = _selected(c, listing)
    psi2 = code_angle_deg(np.where(sel[..., 1], c[..., 1], 0))
    psi4 = code_angle_deg(np.where(sel[..., 3], c[..., 3], 0))
    # LISTING: lines 914, 917 and the EPDalbedo/BPWalbedo blocks (934–1005) read columns without the transpose
    # (`pom1=(EPDalbedo(1:5,1));` compared with the row 'xxxxx'); MATLAB of 2013 stops there with "Matrix
    # dimensions must agree" (later versions broadcast to the same answer), so the script that printed the ch. 6
    # results had them (or the printed listing lost its apostrophes). Ints here: nothing to transpose.
    via1 = np.where(sel[..., 1], psi2, np.where(sel[..., 3], 360.0 - psi4, 0.0))
    via3 = np.where(sel[..., 1], 180.0 - psi2, np.where(sel[..., 3], psi4 + 180.0, 180.0))
    neither = np.where(sel[..., 1], 90.0, 270.0)
    return np.where(sel[..., 0], via1, np.where(sel[..., 2], via3, neither))


def code_matrix(codes) -> tuple[str, ...]:
    """The listing's 5×6 char matrix of six face codes: five rows (bits MSB → LSB), a column per face, ``x``
    where a face was not processed (seed 000 ch. 6, Tab. 6.1). ``[4, -1, …]`` → ``('0x…', '0x…', '1x…', …)``."""
    c = _face_codes(codes)
    if c.ndim != 1:
        raise ValueError("code_matrix() takes one reading's six codes")
    cols = [str(code_bits(np.int64(k))) for k in c]
    return tuple("".join(col[r] for col in cols) for r in range(CODE_BITS))


def codes_from_matrix(rows: Sequence[str]) -> np.ndarray:
    """Six int codes of a printed 5×6 matrix (rows of six characters, as ch. 6 prints them)."""
    rows = [str(r).strip() for r in rows]
    if len(rows) != CODE_BITS or any(len(r) != 6 for r in rows):
        raise ValueError("a code matrix is five rows of six characters")
    return np.array([code_from_bits("".join(r[f] for r in rows)) for f in range(6)], int)


@dataclass(frozen=True)
class SunError:
    """One line of the Sun-error verdict (seed 000 ch. 6, D.5 lines 1058–1102).

    Attributes
    ----------
    face : int
        Thesis face number (1 … 6) that is Earth-lit but not used for the Earth fix.
    bound : str
        ``"at most"`` (TPS code < EPD-as-Sun code, the listing's "Chyba činí maximálně") or ``"at least"``
        (otherwise, "Chyba činí minimálně").
    value_deg : float
        azimut(TPS code): 90° − the bin centre of the Earth incidence on that face [°] (digest §5.8 ⚠: not the
        incidence the text talks about).
    tps_code, epd_code : int
        The face's TPS code (``kvatps``) and its EPD code read with the Sun table (``kvaepdsun``).
    """

    face: int
    bound: str
    value_deg: float
    tps_code: int
    epd_code: int

    def message_cs(self) -> str:
        """The listing's printout, one line (D.5 lines 1062–1065 / 1067–1070)."""
        word = "maximálně" if self.bound == "at most" else "minimálně"
        return f"Poloha slunce je počítána s chybou na straně. {self.face} Chyba činí {word}: {self.value_deg:.4f}"

    def message(self) -> str:
        """The printout in English."""
        return (f"The Sun position is computed with an error on side {self.face}. "
                f"The error is {self.bound} {self.value_deg:.4f}")


@dataclass(frozen=True)
class KarelResult:
    """The output of :func:`karel_attitude` (seed 000 listing D.5; names as the ch. 6 printout has them).

    Angles are the thesis' [azimuth, elevation] in degrees (ch. 5.3.1): az from face 1 (+X) towards face 2 (+Y),
    el from the side faces' plane towards face 5 (+Z); :meth:`sun_zenith_azimuth` gives the body frame's.

    Attributes
    ----------
    ELsunEPD, ELsunBPW, AZsunEPD, AZsunBPW : float
        The Sun from the EPD and from the BPW [°].
    ELalbedoEPD, ELalbedoBPW, ELalbedoTPS, AZalbedoEPD, AZalbedoBPW, AZalbedoTPS : float
        The Earth from each detector type [°].
    EPDsun, EPDalbedo, BPWsun, BPWalbedo, TPSalbedo : tuple of str
        The listing's 5×6 code matrices: five rows (bits MSB → LSB), one character per face 1 … 6, ``x`` where the
        face was not processed.
    earth_faces : tuple of int
        Thesis face numbers used for the Earth fix, in the listing's order tpspos1, tpspos2 (faces 1–4), tpspos3
        (face 5/6); only those above ``TvisEarth``.
    earth_lit_faces : tuple of int
        Every face above ``TvisEarth`` (the Earth faces and the ones checked for the Sun error), ascending.
    sun_faces_epd, sun_faces_bpw : tuple of int
        The faces the Sun was found on, strongest first.
    sun_errors : tuple of SunError
        The Sun-error verdict; empty means "Poloha slunce není počítána s chybou." (without error).
    """

    ELsunEPD: float
    ELsunBPW: float
    ELalbedoEPD: float
    ELalbedoBPW: float
    ELalbedoTPS: float
    AZsunEPD: float
    AZsunBPW: float
    AZalbedoEPD: float
    AZalbedoBPW: float
    AZalbedoTPS: float
    EPDsun: tuple[str, ...]
    EPDalbedo: tuple[str, ...]
    BPWsun: tuple[str, ...]
    BPWalbedo: tuple[str, ...]
    TPSalbedo: tuple[str, ...]
    earth_faces: tuple[int, ...]
    earth_lit_faces: tuple[int, ...]
    sun_faces_epd: tuple[int, ...]
    sun_faces_bpw: tuple[int, ...]
    sun_errors: tuple[SunError, ...]

    @property
    def sun_error_free(self) -> bool:
        """True when the listing prints "Poloha slunce není počítána s chybou." (no Earth-lit face left over)."""
        return not self.sun_errors

    def messages(self, language: str = "en") -> list[str]:
        """The Sun-error printout of D.5 lines 1054–1102, in English (``"en"``) or the listing's Czech (``"cs"``)."""
        if language not in ("en", "cs"):
            raise ValueError("language is 'en' or 'cs'")
        if not self.sun_errors:
            return ["Poloha slunce není počítána s chybou." if language == "cs"
                    else "The Sun position is computed without error."]
        return [e.message_cs() if language == "cs" else e.message() for e in self.sun_errors]

    def codes(self, matrix: str) -> np.ndarray:
        """Six int codes of a matrix (``"EPDsun"`` …), −1 where not processed."""
        if matrix not in ("EPDsun", "EPDalbedo", "BPWsun", "BPWalbedo", "TPSalbedo"):
            raise ValueError(f"no code matrix {matrix!r}")
        return codes_from_matrix(getattr(self, matrix))

    def sun_az_el(self, detector: str = "epd") -> tuple[float, float]:
        """The Sun's thesis (azimuth, elevation) [°] from ``"epd"`` or ``"bpw"``."""
        key = {"epd": "EPD", "bpw": "BPW"}.get(detector)
        if key is None:
            raise ValueError("the Sun comes from 'epd' or 'bpw'")
        return getattr(self, f"AZsun{key}"), getattr(self, f"ELsun{key}")

    def earth_az_el(self, detector: str = "tps") -> tuple[float, float]:
        """The Earth's thesis (azimuth, elevation) [°] from ``"tps"``, ``"epd"`` or ``"bpw"``."""
        key = {"epd": "EPD", "bpw": "BPW", "tps": "TPS"}.get(detector)
        if key is None:
            raise ValueError("the Earth comes from 'tps', 'epd' or 'bpw'")
        return getattr(self, f"AZalbedo{key}"), getattr(self, f"ELalbedo{key}")

    def sun_zenith_azimuth(self, detector: str = "epd") -> tuple[float, float]:
        """Body-frame (zenith, azimuth) [°] of the Sun (calibration/css/head.from_thesis_az_el; DESIGN.md frame)."""
        return _zenith_azimuth(*self.sun_az_el(detector))

    def earth_zenith_azimuth(self, detector: str = "tps") -> tuple[float, float]:
        """Body-frame (zenith, azimuth) [°] of the Earth's direction (head.from_thesis_az_el)."""
        return _zenith_azimuth(*self.earth_az_el(detector))

    def sun_vector(self, detector: str = "epd") -> np.ndarray:
        """Body-frame unit vector towards the Sun (head.sun_vectors)."""
        return head.sun_vectors(*self.sun_zenith_azimuth(detector))

    def earth_vector(self, detector: str = "tps") -> np.ndarray:
        """Body-frame unit vector towards the Earth (head.sun_vectors of its zenith and azimuth)."""
        return head.sun_vectors(*self.earth_zenith_azimuth(detector))


def _zenith_azimuth(az_deg: float, el_deg: float) -> tuple[float, float]:
    zenith, azimuth = head.from_thesis_az_el(az_deg, el_deg)
    return float(zenith), float(azimuth)


def thesis_to_body(az_deg, el_deg) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame (zenith, azimuth) [°] of the algorithm's thesis az/el (seed 000 ch. 5.3.1; head.from_thesis_az_el).

    Vectorised; az 360 becomes 0.
    """
    return head.from_thesis_az_el(az_deg, el_deg)


def _reading(values, name: str) -> np.ndarray:
    v = np.asarray(values, float)
    if v.shape != (6,):
        raise ValueError(f"{name} needs six values in {_FACE_ORDER_NOTE} (got shape {v.shape})")
    if not np.all(np.isfinite(v)):
        # LISTING: a NaN matches nothing in the DO-WHILE position searches, which then run past the array's end
        raise ValueError(f"{name} must be finite")
    return v


def _descending(values: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """`faces` (0-based) ordered by their value, largest first; ties keep the lower face first.

    LISTING: D.5 sorts the values, then recovers each one's face with a DO-WHILE search for the first equal entry
    and erases the found entry with 0 (lines 66–124, 146–204, 473–531) so a repeated value finds the next face.
    The 0 sentinel collides with a real 0 reading (a TPS at 0 °C, a dark photodiode at 0 A): the search for it
    then finds an already-erased face again, and that face is used twice while another is lost. A stable argsort
    gives the same order (MATLAB's sort keeps equal values in index order) without the collision.
    """
    return faces[np.argsort(-values[faces], kind="stable")]


def karel_attitude(tps_c, epd_a, bpw_a, *, tvis_earth_c: float = TVIS_EARTH_C,
                   tables: Mapping[str, Sequence[float]] | None = None, listing: bool = False) -> KarelResult:
    """Sun and Earth azimuth/elevation from one cube reading: seed 000's algorithm (listing D.5, ch. 6).

    Parameters
    ----------
    tps_c : array_like, shape (6,)
        TPS 230 seen temperatures [°C], thesis face order 1 … 6 (= calibration.css.head.FACES).
    epd_a : array_like, shape (6,)
        EPD-365 currents [A], same order.
    bpw_a : array_like, shape (6,)
        BPW 21 currents [A], same order.
    tvis_earth_c : float
        ``TvisEarth`` [°C]: a face whose TPS reads above it sees Earth (D.5 line 51: −202.4).
    tables : mapping, optional
        Calibrated thresholds by table name (``epd_albedo``, ``epd_sun``, ``bpw_albedo``, ``bpw_sun``, ``tps``),
        e.g. from :func:`~.quantiser.thresholds_from_response`, 19 each (5° bins); listing D.6's otherwise.
    listing : bool
        Let a dark face (code 19) picked among the three strongest steer the azimuth rules as the listing does
        (:func:`_selected`); by default only lit faces do, as ch. 5.3.3 intends.

    Returns
    -------
    KarelResult
    """
    tps = _reading(tps_c, "tps_c")
    epd = _reading(epd_a, "epd_a")
    bpw = _reading(bpw_a, "bpw_a")
    t = {name: table_thresholds(tables, name) for name in (EPD_ALBEDO.name, EPD_SUN.name, BPW_ALBEDO.name,
                                                          BPW_SUN.name, TPS.name)}
    for name, th in t.items():
        if th.size != 19:
            raise ValueError(f"table {name!r} needs 19 thresholds (5° bins, 5-bit codes); got {th.size}")

    # --- Selecting the sides facing the Earth from TPS sensors (D.5 lines 53–124) -----------------------------
    order14 = _descending(tps, np.arange(4))         # tpspos1, tpspos2, tpspos4, tpspos5
    order56 = _descending(tps, np.arange(4, 6))      # tpspos3, tpspos6
    fix = (order14[0], order14[1], order56[0])       # tpspos1, tpspos2, tpspos3
    others = (order14[2], order14[3], order56[1])    # tpspos4, tpspos5, tpspos6
    # LISTING: the position searches scan all six faces (`tps(i)` for i = 1, 2, …), not only 1–4 or 5–6; with the
    # erased-by-0 sentinel a 0 °C reading on face 5/6 can be found on an erased face of 1–4 (see _descending).
    lit = tps > tvis_earth_c
    # LISTING: faces are kept with `tpsA(tpspos) > TvisEarth` (lines 217–305) but their positions are zeroed only
    # with `tpsA(tpspos) < TvisEarth` (lines 396–413): a reading of exactly −202.4 °C is neither, and its column is
    # then written with the quantised 0 of the unfilled `earthepd` (code 19). Here such a face is not Earth-lit.
    earth_faces = [int(f) for f in fix if lit[f]]
    extra_faces = [int(f) for f in others if lit[f]]

    # --- Filling earthepd/earthbpw and quantisation of the Earth (D.5 lines 210–305, 533–613, 736–774) --------
    # LISTING: the 18 `if (tpsposj==epdposm)` blocks per detector only look up each Earth face's own reading
    # (earthepd(j) = epd(tpsposj)), which is what is indexed here.
    # LISTING: line 540 reads `tpsa(tpspos1)` where every other line has `tpsA`; MATLAB is case-sensitive, so the
    # script stops with "Undefined function or variable 'tpsa'" whenever tpspos1 == bpwpos1 (the warmest side face
    # also has the strongest BPW current); `&&` skips it otherwise, as in the D.5 example. Intended: tpsA.
    # LISTING: ch. 6 calls the albedo functions `kvaepdalbedo`/`kvabpwalbedo`; D.5/D.6 call `kvaepdalb`/`kvabpwalb`.
    epd_alb = np.full(6, NOT_PROCESSED)
    bpw_alb = np.full(6, NOT_PROCESSED)
    tps_alb = np.full(6, NOT_PROCESSED)
    for f in earth_faces:
        epd_alb[f] = quantise(epd[f], t["epd_albedo"])
        bpw_alb[f] = quantise(bpw[f], t["bpw_albedo"])
        tps_alb[f] = quantise(tps[f], t["tps"])

    # --- Selecting the sides facing the Sun (D.5 lines 317–454 EPD, 624–722 BPW) -----------------------------
    # Every Earth-lit face (the three of the fix and any of tpspos4–6 above TvisEarth) is out of the Sun search.
    candidates = np.flatnonzero(~lit)
    # LISTING: the 2nd and 3rd EPD searches (lines 435–437, 447–449) test `epdpos1sun~=tpspos4…6` instead of
    # `epdpos2sun`/`epdpos3sun`, so they do not exclude the extra Earth faces (the BPW searches, lines 703–717, are
    # right). With fewer than three faces left (four or more Earth-lit faces) the value searched for is an erased
    # 0, which re-finds a face already taken or runs past the array's end; here the Sun simply gets fewer faces.
    sun_epd = _descending(epd, candidates)[:3]
    sun_bpw = _descending(bpw, candidates)[:3]
    epd_sun = np.full(6, NOT_PROCESSED)
    bpw_sun = np.full(6, NOT_PROCESSED)
    epd_sun[sun_epd] = quantise(epd[sun_epd], t["epd_sun"])
    # LISTING: the ch. 6 excerpt writes `BPWsun(1:5,bpwpow3sun)`; D.5 line 750 has the right `bpwpos3sun`.
    # LISTING: the matrices are assigned a 1×5 row into a 5×1 column, `EPDsun(1:5,epdpos1sun)=kvaepdsun(…)`, which
    # MATLAB allows for vectors of equal length; codes are ints here.
    bpw_sun[sun_bpw] = quantise(bpw[sun_bpw], t["bpw_sun"])

    # --- Determining of azimuth and elevation of the Sun and the Earth (D.5 lines 788–1046) -------------------
    # LISTING: D.5 names the Sun elevations `ELSunEPD`/`ELSunBPW` (capital S, lines 796–815); the ch. 6 excerpt
    # and printout have `ELsunEPD`/`ELsunBPW`, which are used here.
    stacked = np.stack([epd_sun, bpw_sun, epd_alb, bpw_alb, tps_alb])
    el = elevation_from_codes(stacked, listing=listing)
    az = azimuth_from_codes(stacked, listing=listing)

    # --- Decision about correct calculation of the Sun position (D.5 lines 1048–1102) --------------------------
    # LISTING: only two cases have a branch: tpspos4 alone, and tpspos4 with tpspos5 (both with tpspos6 == 0).
    # With tpspos6 Earth-lit (both faces 5 and 6 see Earth) nothing at all is printed, not even "without error";
    # here every left-over Earth-lit face, tpspos6 included, gets the same test. (tpspos5 without tpspos4 cannot
    # occur: tpspos4 is the warmer of the two.)
    # LISTING: the check quantises `epdA(tpspos)`, the EPD vector the Sun searches erase with 0; an Earth-lit face
    # is never a Sun face here, so its own reading is used. The decision uses the EPD only, though the ch. 6 prose
    # illustrates it with the BPW.
    errors = []
    for f in extra_faces:
        tc = int(quantise(tps[f], t["tps"]))
        ec = int(quantise(epd[f], t["epd_sun"]))
        # `str2num(help1) < str2num(help2)` compares the bit strings as decimal numbers: same order as the codes.
        # The code prints "at most" when the TPS code is the smaller; ch. 5.3.3 calls that case a correct Sun fix
        # and the ch. 6 prose labels the two cases the other way round (digest §5.8 ⚠): the code is followed.
        bound = "at most" if tc < ec else "at least"
        # LISTING: in the two-face branch the "at least" message for the second face prints `disp (tpspos4)`
        # (line 1098) instead of tpspos5; the face reported here is the one tested.
        errors.append(SunError(face=f + 1, bound=bound, value_deg=float(code_angle_deg(tc)), tps_code=tc,
                               epd_code=ec))

    return KarelResult(
        ELsunEPD=float(el[0]), ELsunBPW=float(el[1]), ELalbedoEPD=float(el[2]), ELalbedoBPW=float(el[3]),
        ELalbedoTPS=float(el[4]),
        AZsunEPD=float(az[0]), AZsunBPW=float(az[1]), AZalbedoEPD=float(az[2]), AZalbedoBPW=float(az[3]),
        AZalbedoTPS=float(az[4]),
        EPDsun=code_matrix(epd_sun), EPDalbedo=code_matrix(epd_alb), BPWsun=code_matrix(bpw_sun),
        BPWalbedo=code_matrix(bpw_alb), TPSalbedo=code_matrix(tps_alb),
        earth_faces=tuple(f + 1 for f in earth_faces),
        earth_lit_faces=tuple(int(f) + 1 for f in np.flatnonzero(lit)),
        sun_faces_epd=tuple(int(f) + 1 for f in sun_epd),
        sun_faces_bpw=tuple(int(f) + 1 for f in sun_bpw),
        sun_errors=tuple(errors),
    )
