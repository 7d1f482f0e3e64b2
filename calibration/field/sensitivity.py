"""Seed 001's sensitivity study (digest §4.2.1–4.2.3, Table 3), redone with the least-squares locator.

The thesis fed its chain with injected errors swept over a square and read the largest position error off its
figures 30–31; Table 3 gives 73 km / 1.75° (inclinometer ±0.5° plus 0.1° of glue), 16 km / 0.35° (±0.1°) and
1 km / 0.02° (arcminute sensors). It also claimed that only the azimuth error matters and a constant zenith
error does not; the digest's re-simulation found the opposite. Here a noise-free track (given, e.g. from the
field simulator, or made with :func:`simulated_track`) is perturbed and located with
:func:`calibration.field.locate.locate` (level given), and the fix is compared with the truth:

(a) a constant bias b in the sensor's azimuth φ: for a level sensor a turn about the vertical, which only the
    heading can absorb: the fitted heading moves by +b (this module's convention, φ = ψ − A on a level mount, so
    φ + b reads as heading ψ + b), the position not at all;
(b) a constant bias in the sensor's zenith θ: the site moves towards or away from the Sun, ≈ 111 km per degree;
(c) a tilt error: the roll/pitch given to the locator wrong by (Δρ, Δπ) over the square [−e, e]², the
    thesis' figure-30 input; a wrong local vertical moves the fix by ≈ 111 km per degree of tilt;
(d) random direction noise (σ per component), several draws: the RMS error against the stated 1-σ.

Squares are sampled on a `square_points` × `square_points` grid (the error is nearly linear in the input, so the
largest is at a corner); the reported figure is the largest position distance [km] and the largest |heading
error| [°] over the square, like the thesis' maxima.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..geometry import direction_vector, zenith_azimuth_from_vector
from .locate import locate, tangent_basis
from .sky import Atmosphere, Mount, Site, sun_position, utc_seconds

#: Seed 001's site (§4.1): Písek, South Bohemia.
PISEK = Site(49.3052028, 14.1633511, 378.0)

#: Seed 001 Table 3 (§4.2.3): configuration, the input error the thesis' figures used (tilt square [°], direction
#: square of Fig. 31 [°]), and its maximum position [km] and orientation [°] deviations.
TABLE3 = (
    ("test rig, inclinometer ±0.5° (+0.1° glue)", 0.6, 0.685, 73.0, 1.75),
    ("test rig, inclinometer ±0.1°", 0.1, 0.138, 16.0, 0.35),
    ("best sensors (arcminutes)", 0.016, 0.016, 1.0, 0.02),
)


@dataclass(frozen=True)
class SensitivityCase:
    """One injected error and what the locator made of it.

    Attributes
    ----------
    kind : str
        ``"azimuth bias"``, ``"zenith bias"``, ``"tilt square"``, ``"direction square"`` or ``"noise"``.
    input_deg : float
        The bias, the square's half side, or the noise σ per component [°].
    position_error_km : float
        Distance of the fix from the truth (largest over a square; RMS over noise draws) [km].
    heading_error_deg : float
        Fitted minus true heading (signed for a bias; largest |.| over a square; RMS over noise draws) [°].
    north_km, east_km : float
        The fix's offset from the truth (biases only; NaN otherwise) [km].
    stated_sigma_km : float
        Mean 1-σ semi-major axis the locator stated [km].
    n_fits : int
        Fits behind the figure.
    """

    kind: str
    input_deg: float
    position_error_km: float
    heading_error_deg: float
    north_km: float = float("nan")
    east_km: float = float("nan")
    stated_sigma_km: float = float("nan")
    n_fits: int = 1


@dataclass(frozen=True)
class Table3Row:
    """Seed 001 Table 3 against this study (maximum over the square)."""

    configuration: str
    tilt_square_deg: float
    direction_square_deg: float
    thesis_km: float
    thesis_heading_deg: float
    tilt_km: float
    tilt_heading_deg: float
    direction_km: float
    direction_heading_deg: float


@dataclass(frozen=True)
class SensitivityStudy:
    """The sensitivity study's cases and its headline figures.

    Attributes
    ----------
    cases : tuple of SensitivityCase
    km_per_deg_zenith : float
        Position shift per degree of constant zenith bias (least-squares slope through zero) [km/°].
    heading_per_deg_azimuth : float
        Heading shift per degree of constant azimuth bias [°/°] (+1: the heading absorbs the bias).
    km_per_deg_azimuth : float
        Largest position shift per degree of constant azimuth bias [km/°].
    km_per_deg_tilt : float
        Position shift per degree of tilt error along one axis (the mean of the roll-only and pitch-only cases
        at the largest tilt) [km/°].
    table3 : tuple of Table3Row
    track : str
        What track the study ran on.
    """

    cases: tuple[SensitivityCase, ...]
    km_per_deg_zenith: float
    heading_per_deg_azimuth: float
    km_per_deg_azimuth: float
    km_per_deg_tilt: float
    table3: tuple[Table3Row, ...]
    track: str

    def of_kind(self, kind: str) -> tuple[SensitivityCase, ...]:
        return tuple(c for c in self.cases if c.kind == kind)

    def table(self) -> str:
        """The cases and the Table 3 comparison as plain text."""
        lines = [f"Sensitivity of the least-squares fix (seed 001 §4.2), track: {self.track}",
                 f"{'injected error':<18}{'input [°]':>10}{'position [km]':>15}{'heading [°]':>13}"
                 f"{'north [km]':>12}{'east [km]':>11}{'1σ [km]':>9}"]
        for c in self.cases:
            lines.append(f"{c.kind:<18}{c.input_deg:>10.4g}{c.position_error_km:>15.3f}{c.heading_error_deg:>+13.4f}"
                         f"{c.north_km:>12.3f}{c.east_km:>11.3f}{c.stated_sigma_km:>9.3f}")
        lines += [f"zenith bias: {self.km_per_deg_zenith:.1f} km per degree; azimuth bias: heading shift "
                  f"{self.heading_per_deg_azimuth:+.4f}°/°, position {self.km_per_deg_azimuth:.3f} km/°; "
                  f"tilt: {self.km_per_deg_tilt:.1f} km per degree along one axis",
                  "", "Seed 001 Table 3 against this study (maxima over the input-error square):",
                  f"{'configuration':<44}{'thesis':>16}{'ours: tilt square':>26}{'ours: direction square':>28}"]
        for r in self.table3:
            lines.append(f"{r.configuration:<44}{r.thesis_km:>7.0f} km {r.thesis_heading_deg:>5.2f}°"
                         f"   ±{r.tilt_square_deg:<5.3g}{r.tilt_km:>7.1f} km {r.tilt_heading_deg:>6.3f}°"
                         f"   ±{r.direction_square_deg:<5.3g}{r.direction_km:>7.1f} km "
                         f"{r.direction_heading_deg:>6.3f}°")
        return "\n".join(lines)


def simulated_track(site: Site = PISEK, start="2013-04-18T08:00:00", hours: float = 2.0, step_s: float = 60.0,
                    mount: Mount = Mount(), atmosphere: Atmosphere = Atmosphere(delta_t_s=67.0)):
    """A noise-free track of a sensor on `mount` at `site` by the calibration's own SPA (the locator's model):
    times [Unix s] and the Sun's θ, φ in the sensor frame [°]. Tests use the field simulator instead."""
    t0 = float(utc_seconds(start)[0]) if not isinstance(start, int | float) else float(start)
    t = t0 + np.arange(0.0, hours * 3600.0 + 0.5 * step_s, step_s)
    d = sun_position(t, site, atmosphere).enu()
    th, ph = zenith_azimuth_from_vector(d @ mount.matrix())
    return t, th, ph


def perturb_directions(zenith_deg, azimuth_deg, sigma_deg: float, rng: np.random.Generator):
    """The directions turned by random small angles: a 2-D Gaussian with σ per component in the tangent plane
    (the vector error is then Rayleigh, RMS σ√2) [°]."""
    n = direction_vector(zenith_deg, azimuth_deg)
    e1, e2 = tangent_basis(n)
    g = rng.normal(0.0, np.radians(sigma_deg), (n.shape[0], 2))
    v = g[:, :1] * e1 + g[:, 1:] * e2
    angle = np.linalg.norm(v, axis=1, keepdims=True)
    unit = np.divide(v, angle, out=np.zeros_like(v), where=angle > 0)
    return zenith_azimuth_from_vector(np.cos(angle) * n + np.sin(angle) * unit)


def sensitivity_study(times_s=None, zenith_deg=None, azimuth_deg=None, *, site: Site = PISEK,
                      mount: Mount = Mount(), atmosphere: Atmosphere = Atmosphere(delta_t_s=67.0),
                      azimuth_biases=(0.1, 0.5, 1.0), zenith_biases=(0.1, 0.5, 1.0),
                      tilt_squares=(0.6, 0.1, 0.016), direction_squares=(0.685, 0.138, 0.016),
                      square_points: int = 3, noise_levels=(0.01, 0.1), noise_draws: int = 5,
                      seed: int = 0) -> SensitivityStudy:
    """Inject seed 001's errors into a noise-free track and locate it (see the module docstring).

    Parameters
    ----------
    times_s, zenith_deg, azimuth_deg : arrays or None
        The true (noise-free) track: Unix seconds and the Sun's θ, φ in the sensor frame [°]; None: a 2 h
        track at Písek on 18 Apr 2013 08–10 UTC, one sample a minute (:func:`simulated_track`).
    site, mount, atmosphere :
        The truth behind the track (the mount's roll and pitch are also what the locator is given).
    azimuth_biases, zenith_biases : sequence of float
        Constant biases added to φ and to θ [°].
    tilt_squares : sequence of float
        Half sides e of the tilt-error squares (Δρ, Δπ) ∈ [−e, e]² [°] (Table 3: 0.6, 0.1, 0.016).
    direction_squares : sequence of float
        Half sides of the direction-bias squares (Δφ, Δθ) ∈ [−e, e]² [°] (the thesis' Fig. 31 inputs).
    square_points : int
        Grid points per side of a square (odd, ≥ 2; 3: corners, edge midpoints, centre).
    noise_levels : sequence of float
        Direction noise σ per component [°].
    noise_draws : int
        Draws per noise level.
    seed : int
        Of the noise generator.

    Returns
    -------
    SensitivityStudy

    References
    ----------
    seed 001 §4.2.1–4.2.3, Table 3, Figs. 30–31; digest 001 §4.2.2 (the zenith/azimuth re-simulation).
    """
    if times_s is None:
        times_s, zenith_deg, azimuth_deg = simulated_track(site=site, mount=mount, atmosphere=atmosphere)
        track = "Písek, 2013-04-18 08:00–10:00 UTC, 60 s, calibration's own SPA"
    else:
        track = f"{len(times_s)} samples over {(np.max(times_s) - np.min(times_s)) / 3600:.2f} h (given)"
    t = np.asarray(times_s, dtype=float)
    th0 = np.asarray(zenith_deg, dtype=float)
    ph0 = np.asarray(azimuth_deg, dtype=float)

    def fix(th, ph, roll=0.0, pitch=0.0):
        given = Mount(0.0, mount.roll_deg + roll, mount.pitch_deg + pitch)
        f = locate(t, th, ph, altitude_m=site.altitude_m, atmosphere=atmosphere, mount=given,
                   initial_site=site, initial_heading_deg=mount.heading_deg)
        north, east, dist = f.error_km(site.latitude_deg, site.longitude_deg)
        dpsi = (f.heading_deg - mount.heading_deg + 180.0) % 360.0 - 180.0
        return dist, dpsi, north, east, f.ellipse.semi_major_km

    cases: list[SensitivityCase] = []
    for b in azimuth_biases:
        dist, dpsi, north, east, sig = fix(th0, ph0 + b)
        cases.append(SensitivityCase("azimuth bias", float(b), dist, dpsi, north, east))
    for b in zenith_biases:
        dist, dpsi, north, east, sig = fix(th0 + b, ph0)
        cases.append(SensitivityCase("zenith bias", float(b), dist, dpsi, north, east))
    axis_tilt = []
    for e in tilt_squares:
        grid = np.linspace(-e, e, square_points)
        results = [fix(th0, ph0, roll=r, pitch=p) for r, p in itertools.product(grid, grid)]
        cases.append(SensitivityCase("tilt square", float(e), max(r[0] for r in results),
                                     max(abs(r[1]) for r in results), n_fits=len(results)))
        if e == max(tilt_squares):
            axis_tilt = [fix(th0, ph0, roll=e)[0] / e, fix(th0, ph0, pitch=e)[0] / e]
    for e in direction_squares:
        grid = np.linspace(-e, e, square_points)
        results = [fix(th0 + dz, ph0 + da) for da, dz in itertools.product(grid, grid)]
        cases.append(SensitivityCase("direction square", float(e), max(r[0] for r in results),
                                     max(abs(r[1]) for r in results), n_fits=len(results)))
    rng = np.random.default_rng(seed)
    for s in noise_levels:
        results = [fix(*perturb_directions(th0, ph0, s, rng)) for _ in range(noise_draws)]
        d = np.array([r[0] for r in results])
        h = np.array([r[1] for r in results])
        cases.append(SensitivityCase("noise", float(s), float(np.sqrt(np.mean(d**2))), float(np.sqrt(np.mean(h**2))),
                                     stated_sigma_km=float(np.mean([r[4] for r in results])), n_fits=noise_draws))

    def slope(kind, value):
        cs = [c for c in cases if c.kind == kind]
        b = np.array([c.input_deg for c in cs])
        y = np.array([value(c) for c in cs])
        return float(np.sum(b * y) / np.sum(b * b)) if cs else float("nan")

    az = [c for c in cases if c.kind == "azimuth bias"]
    table3 = []
    by = {(c.kind, c.input_deg): c for c in cases}
    for name, tilt, direction, km, deg in TABLE3:
        tc, dc = by.get(("tilt square", tilt)), by.get(("direction square", direction))
        table3.append(Table3Row(name, tilt, direction, km, deg,
                                tc.position_error_km if tc else float("nan"),
                                tc.heading_error_deg if tc else float("nan"),
                                dc.position_error_km if dc else float("nan"),
                                dc.heading_error_deg if dc else float("nan")))
    return SensitivityStudy(
        cases=tuple(cases), km_per_deg_zenith=slope("zenith bias", lambda c: c.position_error_km),
        heading_per_deg_azimuth=slope("azimuth bias", lambda c: c.heading_error_deg),
        km_per_deg_azimuth=max((c.position_error_km / c.input_deg for c in az), default=float("nan")),
        km_per_deg_tilt=float(np.mean(axis_tilt)) if axis_tilt else float("nan"), table3=tuple(table3),
        track=track)

