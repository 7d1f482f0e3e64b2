"""Look-up tables of seed 000 (ch. 5.3.5, Table C.3): elevation by one face's code, azimuth by two side faces' codes.

The thesis meant the on-board computer to read azimuth and elevation from memory instead of running the rules of
listing D.5 (ch. 5.3.5, ch. 7 (b)): a full 30-bit unique vector would address 2³⁰ words, three faces 2¹⁵, and
splitting the table, because elevation always comes from one face (5 or 6) and azimuth from two (one of 1/3, one of
2/4), leaves 20 elevation entries and fewer than 2¹⁰ azimuth entries, the cube's symmetry giving the rest.

- **Elevation LUT** (Table C.3): 20 entries indexed by the code of face 5 (+el) or face 6 (−el);
  entry k = elevace(k) = 90° − bin centre: ``10011`` → ±0, ``10010`` → ±2.5, …, ``00001`` → ±87.5, ``00000`` → ±90.
- **Azimuth LUT**: addressed by ``(code of face 1|3) << 5 | (code of face 2|4)``; an entry is the azimuth inside
  the quadrant, measured from the 1/3 face's normal towards the 2/4 face's (the value the D.5 rules give for faces
  1 and 2). Codes run 0 … 19, so the highest address is 19·32 + 19 = 627: 628 entries (< 1024), of which the
  20 × 20 = 400 with both low 5-bit codes ≤ 19 are reachable (unreachable ones are NaN, −1 in C). The quadrant is
  then applied by symmetry: faces (1,2) ψ, (3,2) 180 − ψ, (3,4) 180 + ψ, (1,4) 360 − ψ; with one side face only,
  0/90/180/270; with none, 270 — all as listing D.5 decides. Under the thesis' rule an entry depends on the 2/4
  face's code alone; the address keeps both codes so that a calibrated table can use both.

Both are generated from the implemented rules (:func:`calibration.css.karel.elevation_from_codes`,
:func:`calibration.css.karel.azimuth_from_codes`), and :func:`c_header` renders them, with the listing D.6
thresholds and a lookup function, as C for a microcontroller (angles in tenths of a degree as ``int16_t``).

References
----------
seed 000, ch. 5.3.4–5.3.5, ch. 6, ch. 7 (b), Table C.3, listing D.5 (lines 788–1046); digest §5.6, §5.7, §8.3 item 9.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..export import c_array, comment_safe
from .karel import _selected, azimuth_from_codes, elevation_from_codes
from .quantiser import CODE_BITS, DARK_CODE, NOT_PROCESSED, NOT_PROCESSED_ONBOARD, TABLES, QuantiserTable

#: Entries of the elevation LUT (codes 0 … 19; Table C.3)
ELEVATION_ENTRIES = DARK_CODE + 1
#: Entries of the azimuth LUT: addresses 0 … (19 << 5 | 19) = 627
AZIMUTH_ENTRIES = (DARK_CODE << CODE_BITS | DARK_CODE) + 1


def azimuth_address(code_13, code_24) -> np.ndarray:
    """Azimuth-LUT address of the codes of the 1/3 face and of the 2/4 face: ``code_13 << 5 | code_24``
    (seed 000 ch. 5.3.5: two side faces' 5-bit codes, 2¹⁰ addresses). Vectorised."""
    a = np.asarray(code_13)
    b = np.asarray(code_24)
    if np.any((a < 0) | (a > DARK_CODE) | (b < 0) | (b > DARK_CODE)):
        raise ValueError(f"side-face codes are 0 … {DARK_CODE}")
    return (a.astype(int) << CODE_BITS) | b.astype(int)


def build_elevation_lut() -> np.ndarray:
    """The elevation LUT of seed 000 Table C.3: 20 values [°] indexed by code, from the D.5 rule for face 5.

    ``lut[code]`` is the elevation when face 5 carries `code`; face 6 gives its negative.
    """
    codes = np.full((ELEVATION_ENTRIES, 6), NOT_PROCESSED)
    codes[:, 4] = np.arange(ELEVATION_ENTRIES)
    return elevation_from_codes(codes)


def build_azimuth_lut() -> np.ndarray:
    """The azimuth LUT (seed 000 ch. 5.3.5): in-quadrant azimuth [°] by :func:`azimuth_address`, NaN unreachable.

    Entry (c13, c24) is what the D.5 rule gives with face 1 at code c13 and face 2 at code c24, dark codes included
    (the listing's rule: whether a dark face steers is the lookup's choice, :func:`lookup_azimuth`).
    """
    lut = np.full(AZIMUTH_ENTRIES, np.nan)
    c13, c24 = (g.ravel() for g in np.meshgrid(np.arange(DARK_CODE + 1), np.arange(DARK_CODE + 1), indexing="ij"))
    codes = np.full((c13.size, 6), NOT_PROCESSED)
    codes[:, 0], codes[:, 1] = c13, c24
    lut[azimuth_address(c13, c24)] = azimuth_from_codes(codes, listing=True)
    return lut


def _codes(codes) -> np.ndarray:
    c = np.asarray(codes)
    if not np.issubdtype(c.dtype, np.integer) or c.shape[-1:] != (6,):
        raise ValueError("codes: ints with a last axis of six faces (thesis order 1 … 6 = head.FACES)")
    return c.astype(int)


def _processed(c: np.ndarray, listing: bool = False) -> np.ndarray:
    # a dark face (code 19) is not lit and steers nothing, unless `listing` (calibration.css.karel._selected)
    return _selected(c, listing)


def lookup_elevation(codes, lut: np.ndarray | None = None, *, listing: bool = False) -> np.ndarray:
    """Elevation [°] of six face codes through the elevation LUT (seed 000 Table C.3).

    +lut[code of face 5] if face 5 was processed, else −lut[code of face 6] if face 6 was, else 0.
    `codes`: ints, shape (..., 6), thesis face order; −1 or 31 where a face was not processed; a face at code 19 (dark)
    counts as not lit unless `listing` (:func:`calibration.css.karel.elevation_from_codes`).
    """
    c = _codes(codes)
    lut = build_elevation_lut() if lut is None else np.asarray(lut, float)
    sel = _processed(c, listing)
    c5 = np.where(sel[..., 4], c[..., 4], 0)
    c6 = np.where(sel[..., 5], c[..., 5], 0)
    return np.where(sel[..., 4], lut[c5], np.where(sel[..., 5], -lut[c6], 0.0))


def lookup_azimuth(codes, lut: np.ndarray | None = None, *, listing: bool = False) -> np.ndarray:
    """Azimuth [°] of six face codes through the azimuth LUT and the cube's symmetry (seed 000 ch. 5.3.5).

    The 1/3 face is face 1 if processed, else face 3; the 2/4 face is face 2 if processed, else face 4 (the
    order of listing D.5). With both, ψ = lut[address] is placed in its quadrant: (1,2) ψ, (1,4) 360 − ψ,
    (3,2) 180 − ψ, (3,4) 180 + ψ. With one side face only: 0 (1), 180 (3), 90 (2), 270 (4); with none, 270.
    `codes` as for :func:`lookup_elevation`.
    """
    c = _codes(codes)
    lut = build_azimuth_lut() if lut is None else np.asarray(lut, float)
    sel = _processed(c, listing)
    has13 = sel[..., 0] | sel[..., 2]
    has24 = sel[..., 1] | sel[..., 3]
    c13 = np.where(sel[..., 0], c[..., 0], np.where(sel[..., 2], c[..., 2], 0))
    c24 = np.where(sel[..., 1], c[..., 1], np.where(sel[..., 3], c[..., 3], 0))
    psi = lut[azimuth_address(c13, c24)]
    two = np.where(sel[..., 0], np.where(sel[..., 1], psi, 360.0 - psi),
                   np.where(sel[..., 1], 180.0 - psi, 180.0 + psi))
    one = np.where(has13, np.where(sel[..., 0], 0.0, 180.0), np.where(sel[..., 1], 90.0, 270.0))
    return np.where(has13 & has24, two, one)


def lookup(codes, elevation_lut: np.ndarray | None = None, azimuth_lut: np.ndarray | None = None, *,
           listing: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth, elevation) [°] of six face codes through the two LUTs (seed 000 ch. 5.3.5, Table C.3)."""
    return (lookup_azimuth(codes, azimuth_lut, listing=listing),
            lookup_elevation(codes, elevation_lut, listing=listing))


def _decideg(values) -> list[int]:
    v = np.asarray(values, float)
    out = np.where(np.isnan(v), -1, np.rint(np.nan_to_num(v) * 10.0)).astype(int)
    if np.any(out > 3600) or np.any(out < -1):
        raise ValueError("LUT angles must lie in 0 … 360°")
    return [int(x) for x in out]


def _c_rows(values: Sequence[int], per_line: int = 20) -> str:
    rows = [", ".join(str(v) for v in values[i:i + per_line]) for i in range(0, len(values), per_line)]
    return "{\n    " + ",\n    ".join(rows) + "}"


_LOOKUP_C = """\
/* Quantise one reading with a table of SBCSS_N_THRESHOLDS thresholds t0 >= t1 >= ... (listing D.6):
   0 if x > t0, k if t_k < x <= t_(k-1), SBCSS_N_THRESHOLDS if x <= the last. */
static inline uint8_t sbcss_quantise(double x, const double t[SBCSS_N_THRESHOLDS]) {
    uint8_t k = 0;
    while (k < SBCSS_N_THRESHOLDS && x <= t[k]) ++k;
    return k;
}

/* a face steers the rules when it was processed and is lit: code 19 reads 90 deg, not lit (ch. 5.3.3) */
static inline int sbcss_processed(uint8_t c) { return c != SBCSS_NOT_PROCESSED && c != SBCSS_N_THRESHOLDS; }

/* Azimuth and elevation in tenths of a degree from six face codes (faces 1..6; SBCSS_NOT_PROCESSED where a face
   was not processed), as listing D.5 decides them. Returns 1, or 0 when a processed code is out of range. */
static inline int sbcss_az_el(const uint8_t codes[6], int16_t *az_decideg, int16_t *el_decideg) {
    for (int f = 0; f < 6; ++f)
        if (sbcss_processed(codes[f]) && codes[f] >= SBCSS_ELEVATION_ENTRIES) return 0;
    if (sbcss_processed(codes[4])) *el_decideg = SBCSS_ELEVATION_DECIDEG[codes[4]];
    else if (sbcss_processed(codes[5])) *el_decideg = (int16_t)-SBCSS_ELEVATION_DECIDEG[codes[5]];
    else *el_decideg = 0;
    int f13 = sbcss_processed(codes[0]) ? 0 : (sbcss_processed(codes[2]) ? 2 : -1);
    int f24 = sbcss_processed(codes[1]) ? 1 : (sbcss_processed(codes[3]) ? 3 : -1);
    if (f13 >= 0 && f24 >= 0) {
        int16_t psi = SBCSS_AZIMUTH_DECIDEG[(codes[f13] << SBCSS_CODE_BITS) | codes[f24]];
        if (psi < 0) return 0;
        if (f13 == 0) *az_decideg = (int16_t)(f24 == 1 ? psi : 3600 - psi);
        else *az_decideg = (int16_t)(f24 == 1 ? 1800 - psi : 1800 + psi);
    } else if (f13 >= 0) {
        *az_decideg = f13 == 0 ? 0 : 1800;
    } else {
        *az_decideg = f24 == 1 ? 900 : 2700;
    }
    return 1;
}
"""


def c_header(elevation_lut: np.ndarray | None = None, azimuth_lut: np.ndarray | None = None, *,
             tables: Mapping[str, QuantiserTable | Sequence[float]] | None = None,
             provenance: Mapping[str, object] | None = None) -> str:
    """The LUTs and quantiser tables as a C99 header for the cube's microcontroller (seed 000 ch. 5.3.5, ch. 7 (b)).

    Defines ``SBCSS_ELEVATION_DECIDEG[20]`` and ``SBCSS_AZIMUTH_DECIDEG[628]`` (tenths of a degree, −1 unreachable),
    one ``static const double SBCSS_T_<TABLE>[19]`` per quantiser table (amperes, °C; the listing's D.6 tables
    unless `tables` gives calibrated ones), ``sbcss_quantise(x, table)`` and ``sbcss_az_el(codes, &az, &el)``, which
    gives what :func:`lookup` gives. `provenance` lines go into the header's comment.
    """
    el = build_elevation_lut() if elevation_lut is None else np.asarray(elevation_lut, float)
    az = build_azimuth_lut() if azimuth_lut is None else np.asarray(azimuth_lut, float)
    if el.shape != (ELEVATION_ENTRIES,) or az.shape != (AZIMUTH_ENTRIES,):
        raise ValueError(f"LUTs of {ELEVATION_ENTRIES} and {AZIMUTH_ENTRIES} entries expected")
    if np.any(np.isnan(el)):
        raise ValueError("the elevation LUT has no unreachable entries")
    thresholds = {name: np.asarray(t.thresholds) for name, t in TABLES.items()}
    for name, t in (tables or {}).items():
        if name not in thresholds:
            raise ValueError(f"no quantiser table {name!r} (tables: {', '.join(thresholds)})")
        thresholds[name] = np.asarray(t.thresholds if isinstance(t, QuantiserTable) else t, float)
    n = {t.size for t in thresholds.values()}
    if n != {DARK_CODE}:
        raise ValueError(f"every quantiser table needs {DARK_CODE} thresholds (5° bins)")
    comment = "".join(f"\n   {key}: {comment_safe(value)}" for key, value in (provenance or {}).items()
                      if value is not None)
    units = {"tps": "degC"}
    lines = [
        "/* sunbench CSS look-up tables: seed 000 (Karel 2013) ch. 5.3.5, Table C.3, listings D.5-D.6.",
        "   Generated by `sunbench`; do not edit. Face codes are 5-bit incidence bins (code k = 5(k-1)..5k deg,",
        "   0 = direct, 19 = not lit); faces 1..6 = +X, +Y, -X, -Y, +Z, -Z. Angles in tenths of a degree:",
        "   azimuth from face 1 towards face 2, elevation towards face 5." + comment + " */",
        "#ifndef SUNBENCH_CSS_LUT_H",
        "#define SUNBENCH_CSS_LUT_H",
        "",
        "#include <stdint.h>",
        "",
        f"#define SBCSS_CODE_BITS {CODE_BITS}",
        f"#define SBCSS_NOT_PROCESSED {NOT_PROCESSED_ONBOARD}  /* the unused code 11111 (ch. 6) */",
        f"#define SBCSS_N_THRESHOLDS {DARK_CODE}",
        f"#define SBCSS_ELEVATION_ENTRIES {ELEVATION_ENTRIES}",
        f"#define SBCSS_AZIMUTH_ENTRIES {AZIMUTH_ENTRIES}",
        "",
        "/* Table C.3: elevation of the code of face 5 (+) or face 6 (-) */",
        f"static const int16_t SBCSS_ELEVATION_DECIDEG[SBCSS_ELEVATION_ENTRIES] = {_c_rows(_decideg(el))};",
        "",
        "/* in-quadrant azimuth by (code of face 1|3) << 5 | (code of face 2|4); -1: unreachable address */",
        f"static const int16_t SBCSS_AZIMUTH_DECIDEG[SBCSS_AZIMUTH_ENTRIES] = {_c_rows(_decideg(az), 32)};",
        "",
    ]
    for name, t in thresholds.items():
        lines.append(f"/* quantiser table {name} ({units.get(name, 'A')}) */")
        lines.append(f"static const double SBCSS_T_{name.upper()}[SBCSS_N_THRESHOLDS] = {c_array(t)};")
    lines += ["", _LOOKUP_C, "#endif /* SUNBENCH_CSS_LUT_H */", ""]
    return "\n".join(lines)
