"""The LUTs of seed 000 ch. 5.3.5: Table C.3's elevation LUT, the two-face azimuth LUT, and their C header."""

import itertools
import subprocess

import numpy as np
import pytest
from ccompiler import c_compiler

from calibration.css import lut
from calibration.css.karel import azimuth_from_codes, elevation_from_codes
from calibration.css.quantiser import TABLES, quantise

# Table C.3 "LUT tabulka pro určení elevace", row by row: elevation (±, face 5 / face 6) and the code's bits
TABLE_C3 = [
    (0, "10011"), (2.5, "10010"), (7.5, "10001"), (12.5, "10000"), (17.5, "01111"), (22.5, "01110"),
    (27.5, "01101"), (32.5, "01100"), (37.5, "01011"), (42.5, "01010"), (47.5, "01001"), (52.5, "01000"),
    (57.5, "00111"), (62.5, "00110"), (67.5, "00101"), (72.5, "00100"), (77.5, "00011"), (82.5, "00010"),
    (87.5, "00001"), (90, "00000"),
]
X = -1  # a face not processed ('xxxxx')


def _six(**faces):
    codes = [X] * 6
    for name, code in faces.items():
        codes[int(name[1]) - 1] = code
    return codes


def test_the_elevation_lut_is_table_c3_entry_by_entry():
    el = lut.build_elevation_lut()
    assert el.shape == (20,) == (lut.ELEVATION_ENTRIES,)
    for elevation, bits in TABLE_C3:
        code = int(bits, 2)
        assert el[code] == elevation, bits
        assert lut.lookup_elevation(_six(f5=code)) == elevation  # face 5: +
        assert lut.lookup_elevation(_six(f6=code)) == -elevation  # face 6: −
    assert sorted(int(b, 2) for _, b in TABLE_C3) == list(range(20))  # C.3 covers every code once


def test_the_azimuth_lut_has_fewer_than_1024_entries_addressed_by_two_codes():
    az = lut.build_azimuth_lut()
    assert az.size == lut.AZIMUTH_ENTRIES == 628 < 1024
    reachable = np.isfinite(az)
    assert reachable.sum() == 400  # 20 codes of the 1/3 face × 20 of the 2/4 face
    addresses = np.arange(az.size)
    np.testing.assert_array_equal(reachable, ((addresses >> 5) <= 19) & ((addresses & 31) <= 19))
    assert lut.azimuth_address(4, 19) == 0b00100_10011
    # the thesis' rule (D.5) uses the 2/4 face's code only: ψ = 90° − bin centre (Table C.3's numbers)
    for c13 in range(20):
        for elevation, bits in TABLE_C3:
            assert az[lut.azimuth_address(c13, int(bits, 2))] == elevation
    with pytest.raises(ValueError):
        lut.azimuth_address(20, 0)


def _all_code_sets():
    """Every combination of processed side faces (each of 1–4 in or out) with every reachable code pair, and
    every elevation case, as six-code rows."""
    rows = []
    for picked in itertools.product([False, True], repeat=4):
        for a, b in itertools.product(range(20), repeat=2):
            codes = [X] * 6
            # the first processed of 1/3 carries a, the first of 2/4 carries b, the other one a code of its own
            for f, on in enumerate(picked):
                if on:
                    codes[f] = a if f in (0, 2) else b
            if picked[0] and picked[2]:
                codes[2] = (a + 7) % 20
            if picked[1] and picked[3]:
                codes[3] = (b + 3) % 20
            rows.append(codes)
    for five, six, c in itertools.product([False, True], [False, True], range(20)):
        codes = [0, 4, X, X, X, X]
        codes[4] = c if five else X
        codes[5] = (19 - c) if six else X
        rows.append(codes)
    return np.array(rows)


def test_lookup_through_the_luts_gives_the_rules_for_every_reachable_code_pair():
    codes = _all_code_sets()
    az, el = lut.lookup(codes)
    np.testing.assert_array_equal(az, azimuth_from_codes(codes))
    np.testing.assert_array_equal(el, elevation_from_codes(codes))
    listing_az, listing_el = lut.lookup(codes, listing=True)  # dark faces steering, as the listing has it
    np.testing.assert_array_equal(listing_az, azimuth_from_codes(codes, listing=True))
    np.testing.assert_array_equal(listing_el, elevation_from_codes(codes, listing=True))
    assert np.any(listing_az != az)
    assert np.all(np.isfinite(az)) and np.all((az >= 0) & (az <= 360))
    # 31 (11111) is the on-board "not processed" and reads like −1
    onboard = np.where(codes == X, 31, codes)
    np.testing.assert_array_equal(lut.lookup_azimuth(onboard), az)
    np.testing.assert_array_equal(lut.lookup_elevation(onboard), el)


def test_lookup_gives_the_printed_d5_result():
    # the ch. 6 run: EPDsun on faces 2 (00100), 3 (00000, the epd3 = 1 A run) and 6 (00101)
    az, el = lut.lookup([X, 0b00100, 0b00000, X, X, 0b00101])
    assert (az, el) == (107.5, -67.5)
    # EPDalbedo on faces 1 (00100) and 5 (10010)
    assert lut.lookup([0b00100, X, X, X, 0b10010, X]) == (0.0, 2.5)
    # the thesis' quadrant cases (ch. 5.3.2): one side face gives 0/90/180/270; none gives 270 as D.5 has it
    assert [float(lut.lookup_azimuth(c)) for c in (_six(f1=5), _six(f2=5), _six(f3=5), _six(f4=5), _six())] == [
        0, 90, 180, 270, 270]


MAIN = r"""
#include <stdio.h>
#include "css.h"

int main(void) {
    int c[6];
    double x;
    char kind;
    while (scanf(" %c", &kind) == 1) {
        if (kind == 'c') {
            if (scanf("%d %d %d %d %d %d", &c[0], &c[1], &c[2], &c[3], &c[4], &c[5]) != 6) return 2;
            uint8_t codes[6];
            for (int f = 0; f < 6; ++f) codes[f] = (uint8_t)(c[f] < 0 ? SBCSS_NOT_PROCESSED : c[f]);
            int16_t az = 0, el = 0;
            int ok = sbcss_az_el(codes, &az, &el);
            printf("%d %d %d\n", ok, az, el);
        } else {
            if (scanf("%lf", &x) != 1) return 2;
            printf("%d %d %d %d %d\n", sbcss_quantise(x, SBCSS_T_EPD_ALBEDO), sbcss_quantise(x, SBCSS_T_EPD_SUN),
                   sbcss_quantise(x, SBCSS_T_BPW_ALBEDO), sbcss_quantise(x, SBCSS_T_BPW_SUN),
                   sbcss_quantise(x, SBCSS_T_TPS));
        }
    }
    return 0;
}
"""


def test_the_c_header_compiles_and_gives_what_lookup_and_quantise_give(tmp_path):
    compiler = c_compiler()
    header = lut.c_header(provenance={"run": "test */ run"})
    assert "static const int16_t SBCSS_ELEVATION_DECIDEG[SBCSS_ELEVATION_ENTRIES]" in header
    (tmp_path / "css.h").write_text(header)
    (tmp_path / "main.c").write_text(MAIN)
    exe = tmp_path / "css"
    build = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-o", str(exe),
                            str(tmp_path / "main.c")], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    codes = _all_code_sets()
    bad = np.array([[X, 4, 25, X, X, X], [X, X, X, X, 20, X]])  # codes out of range: no answer
    # readings on and around every threshold of the five tables
    t = np.concatenate([TABLES[n].thresholds for n in TABLES])
    x = np.concatenate([t, np.nextafter(t, np.inf), np.nextafter(t, -np.inf), [0.0, -300.0, 1.0, 40.0]])
    text = "".join("c " + " ".join(str(v) for v in row) + "\n" for row in np.vstack([codes, bad]))
    text += "".join(f"x {float(v)!r}\n" for v in x)
    run = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
    got = np.array([line.split() for line in run.stdout.splitlines()[:len(codes) + 2]], dtype=int)
    az, el = lut.lookup(codes)
    np.testing.assert_array_equal(got[:-2, 0], 1)
    np.testing.assert_array_equal(got[:-2, 1], np.rint(az * 10).astype(int))
    np.testing.assert_array_equal(got[:-2, 2], np.rint(el * 10).astype(int))
    np.testing.assert_array_equal(got[-2:, 0], 0)
    q = np.array([line.split() for line in run.stdout.splitlines()[len(codes) + 2:]], dtype=int)
    expected = np.stack([quantise(x, n) for n in ("epd_albedo", "epd_sun", "bpw_albedo", "bpw_sun", "tps")], axis=1)
    np.testing.assert_array_equal(q, expected)


def test_the_header_takes_calibrated_tables_and_refuses_broken_luts():
    calibrated = np.linspace(1e-6, 0.0, 19)
    header = lut.c_header(tables={"epd_sun": calibrated})
    assert "SBCSS_T_EPD_SUN[SBCSS_N_THRESHOLDS] = {1e-06, " in header
    el = lut.build_elevation_lut()
    el[3] = np.nan
    with pytest.raises(ValueError):
        lut.c_header(elevation_lut=el)
    with pytest.raises(ValueError):
        lut.c_header(tables={"uv": calibrated})
    with pytest.raises(ValueError):
        lut.c_header(tables={"tps": calibrated[:10]})
