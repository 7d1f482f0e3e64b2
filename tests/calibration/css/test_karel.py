"""seed 000's azimuth/elevation algorithm (listing D.5, ch. 6) against what the thesis prints.

Every expected number is the thesis' (the ch. 6 printout and matrices, Table C.3) or worked by hand from the
listing's tables and rules; inputs that the thesis does not give are reconstructed, and say so.
"""

import numpy as np
import pytest

from calibration.css import head
from calibration.css.karel import (
    INTENDED_D5_INPUTS,
    LISTING_D5_INPUTS,
    TVIS_EARTH_C,
    azimuth_from_codes,
    code_matrix,
    codes_from_matrix,
    elevation_from_codes,
    karel_attitude,
    thesis_to_body,
)
from calibration.css.quantiser import TABLES

# listing D.5 lines 29–48, as MATLAB runs them: `epd3=1,42*10^-6;` assigns 1 (decimal comma)
TPS_D5 = [9.64, -209, -270, -243, -191, -254]
EPD_D5_LITERAL = [1.03e-6, 5.9e-6, 1.0, 0.97e-60, 3.3e-7, 5.6e-6]
EPD_D5_INTENDED = [1.03e-6, 5.9e-6, 1.42e-6, 0.97e-60, 3.3e-7, 5.6e-6]
BPW_D5 = [2.54e-4, 1.12e-3, 8e-4, 1.29e-40, 8e-5, 1.09e-3]

# Table C.1: incidence [°] and I_EPD,sun [A]
C1_ANGLE = np.arange(0, 91, 5.0)
C1_EPD_SUN = np.array([6.18e-06, 6.16e-06, 6.10e-06, 6.00e-06, 5.87e-06, 5.49e-06, 4.76e-06, 3.89e-06, 3.09e-06,
                       2.29e-06, 1.42e-06, 6.84e-07, 3.09e-07, 1.99e-07, 1.19e-07, 6.40e-08, 3.09e-08, 9.55e-09, 0.0])


def test_the_thesis_face_order_is_head_faces():
    # ch. 5.3.1: 1 faces the observer [0, 0], 2 the next counter-clockwise [90, 0], 3 and 4 opposite, 5 top, 6 bottom
    assert head.FACES == ("px", "py", "mx", "my", "pz", "mz")
    zen, az = head.vector_angles(head.normal_matrix())
    t_az, t_el = head.thesis_az_el(zen, az)
    np.testing.assert_allclose(t_el, [0, 0, 0, 0, 90, -90], atol=1e-12)
    np.testing.assert_allclose(t_az[:4], [0, 90, 180, 270], atol=1e-12)


def test_the_listings_inputs_are_kept_as_written():
    assert list(LISTING_D5_INPUTS["tps_c"]) == TPS_D5 and list(INTENDED_D5_INPUTS["tps_c"]) == TPS_D5
    assert list(LISTING_D5_INPUTS["epd_a"]) == EPD_D5_LITERAL
    assert list(INTENDED_D5_INPUTS["epd_a"]) == EPD_D5_INTENDED
    assert list(LISTING_D5_INPUTS["bpw_a"]) == BPW_D5 == list(INTENDED_D5_INPUTS["bpw_a"])
    assert TVIS_EARTH_C == -202.4


@pytest.mark.parametrize("epd", [EPD_D5_LITERAL, EPD_D5_INTENDED], ids=["epd3=1 (listing)", "epd3=1.42uA"])
def test_the_d5_example_gives_the_ch6_printout(epd):
    r = karel_attitude(TPS_D5, epd, BPW_D5)
    # "Výsledný produkt může vypadat například takto:" (end of ch. 6)
    assert (r.ELsunEPD, r.ELsunBPW) == (-67.5, -67.5)
    assert (r.ELalbedoEPD, r.ELalbedoBPW, r.ELalbedoTPS) == (2.5, 2.5, 2.5)
    assert (r.AZsunEPD, r.AZsunBPW) == (107.5, 107.5)
    assert (r.AZalbedoEPD, r.AZalbedoBPW, r.AZalbedoTPS) == (0, 0, 0)
    assert r.sun_error_free and r.sun_errors == ()
    assert r.messages("cs") == ["Poloha slunce není počítána s chybou."]
    assert r.messages() == ["The Sun position is computed without error."]
    # worked by hand: Earth on faces 1 (TPS 9.64 °C) and 5 (−191 °C); 2, 3, 4, 6 are below −202.4 °C
    assert r.earth_faces == (1, 5) == r.earth_lit_faces
    # EPDalbedo: face 1 1.03 µA → 00100 (1.012 < x ≤ 1.046), face 5 0.33 µA → 10010 (0.311 < x ≤ 0.356)
    assert r.EPDalbedo == ("0xxx1x", "0xxx0x", "1xxx0x", "0xxx1x", "0xxx0x")
    assert r.BPWalbedo == r.EPDalbedo == r.TPSalbedo  # 2.54e-4 → 00100, 8e-5 → 10010; 9.64 °C → 00100, −191 → 10010
    # Sun: face 2 5.9 µA → 00100, face 6 5.6 µA → 00101; BPW face 2 1.12 mA 00100, 3 0.8 mA 00111, 6 1.09 mA 00101
    assert r.BPWsun == ("x00xx0", "x00xx0", "x11xx1", "x01xx0", "x01xx1")
    assert r.sun_faces_bpw == (2, 6, 3)


def test_what_the_decimal_comma_changes_in_the_d5_example():
    literal = karel_attitude(TPS_D5, EPD_D5_LITERAL, BPW_D5)
    intended = karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5)
    # only face 3's EPD Sun code: 1 A is above t0 (00000); 1.42 µA is t10 itself, so 01011 (50–55°)
    assert literal.EPDsun == ("x00xx0", "x00xx0", "x10xx1", "x00xx0", "x00xx1")
    assert intended.EPDsun == ("x00xx0", "x01xx0", "x10xx1", "x01xx0", "x01xx1")
    assert literal.sun_faces_epd == (3, 2, 6) and intended.sun_faces_epd == (2, 6, 3)
    # the printed numbers use face 3 only to pick the quadrant (face 3 + face 2: 180 − azimut(00100)); all equal
    for field in ("ELsunEPD", "AZsunEPD", "ELalbedoEPD", "AZalbedoEPD", "EPDalbedo", "BPWsun", "sun_errors"):
        assert getattr(literal, field) == getattr(intended, field), field


def test_the_ch6_epd_matrices_three_earth_faces():
    # ch. 6 prints EPDalbedo on faces 1, 3, 5 and EPDsun on faces 2, 4, 6 from a run whose inputs it does not give.
    # Reconstruction: D.5's inputs with face 3 Earth-lit at a grazing angle (TPS −195 °C, EPD 0.30 µA): the Sun
    # columns are then D.5's epd2, epd4, epd6 exactly.
    tps = [9.64, -209, -195, -243, -191, -254]
    epd = [1.03e-6, 5.9e-6, 3.0e-7, 0.97e-60, 3.3e-7, 5.6e-6]
    r = karel_attitude(tps, epd, BPW_D5)
    assert r.EPDalbedo == ("0x1x1x", "0x0x0x", "1x0x0x", "0x1x1x", "0x1x0x")
    assert r.EPDsun == ("x0x1x0", "x0x0x0", "x1x0x1", "x0x1x0", "x0x1x1")
    # "poloha Země je počítána ze stěn 1,3 a 5 … poloha Slunce je určena ze stěn 2,4 a 6"
    assert r.earth_faces == (1, 3, 5) and sorted(r.sun_faces_epd) == [2, 4, 6]
    assert r.sun_error_free


FOUR_EARTH_TPS = [9.64, -50.0, -75.0, -243, -191, -254]


@pytest.mark.parametrize(("epd3", "bound", "word"), [
    (1.0, "at least", "minimálně"),       # the listing's epd3: EPD Sun code 00000 < TPS code 01011
    (1.42e-6, "at least", "minimálně"),   # equal codes (01011): not smaller, "at least"
    (3.0e-7, "at most", "maximálně"),     # 0.30 µA → 01101: the TPS code is the smaller, "at most"
])
def test_the_ch6_bpw_matrices_and_the_side_3_error(epd3, bound, word):
    # ch. 6 "Příklad výstupních vektorů v případě ozáření čtyř stěn satelitu od Země": BPWsun on faces 4, 6,
    # BPWalbedo on 1, 2, 5, face 3 also Earth-lit, and "chyba na straně 3 … 37.5000". Reconstruction: D.5's
    # inputs with faces 2 and 3 Earth-lit, face 3's TPS in the 50–55° bin (azimut = 37.5).
    epd = list(EPD_D5_INTENDED)
    epd[2] = epd3
    r = karel_attitude(FOUR_EARTH_TPS, epd, BPW_D5)
    assert r.BPWsun == ("xxx1x0", "xxx0x0", "xxx0x1", "xxx1x0", "xxx1x1")
    assert r.BPWalbedo == ("00xx1x", "00xx0x", "10xx0x", "00xx1x", "00xx0x")
    assert r.earth_faces == (1, 2, 5) and r.earth_lit_faces == (1, 2, 3, 5)
    assert sorted(r.sun_faces_bpw) == [4, 6] and sorted(r.sun_faces_epd) == [4, 6]
    (error,) = r.sun_errors
    assert (error.face, error.bound, error.value_deg) == (3, bound, 37.5)
    line = r.messages("cs")[0]
    for part in ("Poloha slunce je počítána s chybou na straně.", "3", f"Chyba činí {word}:", "37.5000"):
        assert part in line
    assert not r.sun_error_free


def test_an_earth_lit_face_6_is_checked_too():
    # both 5 and 6 see Earth: the listing has no branch for tpspos6 and prints nothing; here it is checked.
    # Face 6: TPS −195 °C → 10010 (18), EPD 5.6 µA as Sun → 00101 (5): not smaller → at least azimut(10010) = 2.5
    r = karel_attitude([9.64, -209, -270, -243, -191, -195], EPD_D5_INTENDED, BPW_D5)
    assert r.earth_faces == (1, 5) and r.earth_lit_faces == (1, 5, 6)
    assert [(e.face, e.bound, e.value_deg) for e in r.sun_errors] == [(6, "at least", 2.5)]
    # the Sun from faces 2, 3, 4: no face 5/6 → EL 0; faces 3 + 2 → 180 − azimut(00100) = 107.5
    assert (r.ELsunEPD, r.AZsunEPD) == (0, 107.5)


def test_five_earth_lit_faces_leave_one_sun_face():
    # the listing's Sun searches would look for an erased 0 past the candidates; here the Sun gets face 6 only
    r = karel_attitude([9.0, 8.0, 7.0, 6.0, 5.0, -260.0], EPD_D5_INTENDED, BPW_D5)
    assert r.earth_faces == (1, 2, 5) and r.sun_faces_epd == (6,) == r.sun_faces_bpw
    assert r.ELsunEPD == -67.5  # face 6 5.6 µA → 00101
    assert r.AZsunEPD == 270  # no side face: the rule's else branch
    # faces 3 (7 °C → 00100, 1.42 µA → 01011) and 4 (6 °C → 00101, ~0 A → 10011): both "at most"
    assert [(e.face, e.bound, e.value_deg) for e in r.sun_errors] == [(3, "at most", 72.5), (4, "at most", 67.5)]


def test_a_0_degree_reading_does_not_hit_the_listings_erase_sentinel():
    # the listing erases found TPS entries with 0 °C; face 2 at 0 °C would then be found on face 1 again
    r = karel_attitude([9.64, 0.0, -270, -243, -191, -254], EPD_D5_INTENDED, BPW_D5)
    assert r.earth_faces == (1, 2, 5)
    # TPS 0 °C → 00110 (−8.6975 < 0 ≤ 0.1875): faces 1 + 2 → azimut(00110) = 62.5
    assert r.AZalbedoTPS == 62.5
    # EPD 5.9 µA is above the albedo table's t0 → 00000 → 90
    assert r.AZalbedoEPD == 90


def test_the_warmest_side_face_with_the_strongest_bpw_runs():
    # D.5 line 540 `tpsa(tpspos1)` stops MATLAB when tpspos1 == bpwpos1; the intended tpsA is used here
    bpw = [1.12e-3, 2.54e-4, 8e-4, 1.29e-40, 8e-5, 1.09e-3]
    r = karel_attitude(TPS_D5, EPD_D5_INTENDED, bpw)
    assert r.BPWalbedo[0][0] + "".join(row[0] for row in r.BPWalbedo[1:]) == "00000"  # 1.12 mA > 2.66e-4
    assert r.AZalbedoBPW == 0 and r.ELalbedoBPW == 2.5


def test_exactly_tvis_earth_is_not_earth_and_tvis_earth_is_a_parameter():
    tps = [9.64, -202.4, -270, -243, -191, -254]
    r = karel_attitude(tps, EPD_D5_INTENDED, BPW_D5)
    assert r.earth_faces == (1, 5) and r.EPDalbedo[0][1] == "x"
    r = karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5, tvis_earth_c=-215.0)
    assert r.earth_faces == (1, 2, 5)
    # calibrated tables by name; the listing's own give the printed result
    tables = {name: t.thresholds for name, t in TABLES.items()}
    assert karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5, tables=tables) == karel_attitude(
        TPS_D5, EPD_D5_INTENDED, BPW_D5)
    with pytest.raises(ValueError, match="19 thresholds"):
        karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5, tables={"tps": [1.0, 0.0]})


def test_inputs_are_checked():
    with pytest.raises(ValueError, match="six"):
        karel_attitude(TPS_D5[:5], EPD_D5_INTENDED, BPW_D5)
    with pytest.raises(ValueError, match="finite"):
        karel_attitude(TPS_D5, [np.nan] * 6, BPW_D5)


def test_the_body_frame_directions():
    r = karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5)
    # thesis [107.5, −67.5] → zenith 90 + 67.5, azimuth 107.5; Earth [0, 2.5] → zenith 87.5
    assert r.sun_zenith_azimuth() == (157.5, 107.5) == r.sun_zenith_azimuth("bpw")
    assert r.earth_zenith_azimuth() == (87.5, 0.0)
    el, az = np.radians(-67.5), np.radians(107.5)
    np.testing.assert_allclose(r.sun_vector(), [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)],
                               atol=1e-12)
    np.testing.assert_allclose(r.earth_vector("epd"), [np.cos(np.radians(2.5)), 0, np.sin(np.radians(2.5))],
                               atol=1e-12)
    zen, azi = thesis_to_body([360.0, 90.0], [0.0, 90.0])
    np.testing.assert_allclose(zen, [90, 0]) and np.testing.assert_allclose(azi, [0, 90])
    with pytest.raises(ValueError):
        r.sun_az_el("tps")


def test_matrices_and_codes_round_trip():
    printed = ("x0x1x0", "x0x0x0", "x1x0x1", "x0x1x0", "x0x1x1")  # ch. 6 EPDsun
    codes = codes_from_matrix(printed)
    np.testing.assert_array_equal(codes, [-1, 4, -1, 19, -1, 5])
    assert code_matrix(codes) == printed
    r = karel_attitude(TPS_D5, EPD_D5_INTENDED, BPW_D5)
    np.testing.assert_array_equal(r.codes("EPDalbedo"), [4, -1, -1, -1, 18, -1])
    # that matrix through the rules: faces 2, 4, 6, neither 1 nor 3 → 90 (face 2 processed); −azimut(00101)
    assert (float(azimuth_from_codes(codes)), float(elevation_from_codes(codes))) == (90.0, -67.5)


# ---------------------------------------------------------------------------------------------------------------
# geometry (digest §5.4 ⚠): a Sun-only sky, currents from Table C.1's EPD column, TPS seeing space
# ---------------------------------------------------------------------------------------------------------------

NORMALS_1_TO_6 = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def _sun(az_deg, el_deg, listing=False):
    az, el = np.radians(az_deg), np.radians(el_deg)
    s = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    inc = np.degrees(np.arccos(np.clip(NORMALS_1_TO_6 @ s, -1, 1)))
    current = np.where(inc < 90, np.interp(np.minimum(inc, 90), C1_ANGLE, C1_EPD_SUN), 0.0)
    return karel_attitude(np.full(6, -270.0), current, current * (1.17e-3 / 6.18e-6), listing=listing)


def test_azimuth_from_one_side_face_is_exact_only_at_el_0():
    # digest §5.4: true az 30°, el 40° → incidence on face 2 67.5° → the thesis' az 22.5° (7.5° off)
    r = _sun(30.0, 40.0)
    assert r.AZsunEPD == 22.5
    assert abs(r.ELsunEPD - 40.0) <= 2.5
    # at el 60°: incidence 75.5° on face 2 → bin 75–80° → 12.5° (digest: 14.5° before quantisation)
    assert _sun(30.0, 60.0).AZsunEPD == 12.5
    # at el = 0 the azimuth is exact to the quantisation (first quadrant: faces 1 and 2)
    for az in np.arange(0.5, 90.0, 0.5):
        assert abs(_sun(az, 0.0).AZsunEPD - az) <= 2.5 + 1e-9, az


@pytest.mark.parametrize("az", [30.0, 120.0, 210.0, 300.0])
def test_elevation_from_face_5_or_6_is_exact_to_the_quantisation(az):
    for el in np.arange(-89.5, 90.0, 0.5):
        r = _sun(az, el)
        assert abs(r.ELsunEPD - el) <= 2.5 + 1e-9, (az, el, r.ELsunEPD)


def test_a_dark_face_picked_as_the_third_sun_face_steers_the_listing_not_the_intended_rules():
    # Sun at az 132°, el 0: face 2 lit at 42°, face 3 at 48°, the third strongest is a dark 0 A, the lowest such
    # face (1). In the listing face 1 processed takes the rule's first branch: azimut(01001) = 47.5 instead of
    # 180 − 47.5 = 132.5; read as ch. 5.3.3 intends (a dark face reads 90°: not lit) the rules take face 3's branch
    r = _sun(132.0, 0.0)
    assert r.sun_faces_epd == (2, 3, 1)
    assert r.AZsunEPD == 132.5
    assert _sun(132.0, 0.0, listing=True).AZsunEPD == 47.5
    assert _sun(132.0, 1.0, listing=True).AZsunEPD == 132.5  # with face 5 lit a little: faces 2, 3, 5
