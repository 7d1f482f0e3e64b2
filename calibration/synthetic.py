"""Synthetic bench data from a sensor with known build errors, on the seed 003 measurement grid.

Used by the demo and by the tests that check a fit recovers what was put in.
"""

from __future__ import annotations

import numpy as np

from .data import BenchData
from .design import DEFAULT_SENSOR, SensorDesign
from .pinhole import PinholeBuild, spot_from_direction
from .procedure import (
    SEED003_AZIMUTH_STEP_DEG,
    SEED003_CENTRE_REPEATS,
    SEED003_REPEATS,
    SEED003_ZENITH_MAX_DEG,
    SEED003_ZENITH_STEP_DEG,
    grid_azimuths_deg,
    grid_zeniths_deg,
)

#: A sensor with realistic build errors: pinhole off-centre, 1.05 mm air gap over 0.5 mm of cover glass,
#: detector tilted ~0.3° and rotated 1.4° in-plane (the magnitudes of seed 003 §4.4–4.5 and the research
#: note's refraction study).
EXAMPLE_BUILD = PinholeBuild(x0_px=325.8, y0_px=233.4, gap_mm=1.05, glass_mm=0.5, glass_index=1.52,
                             tilt_x_deg=0.22, tilt_y_deg=-0.21, rotation_deg=1.4)


def seed003_grid(*, azimuth_step_deg: float = SEED003_AZIMUTH_STEP_DEG, zenith_max_deg: float = SEED003_ZENITH_MAX_DEG,
                 zenith_step_deg: float = SEED003_ZENITH_STEP_DEG, repeats: int = SEED003_REPEATS,
                 centre_repeats: int = SEED003_CENTRE_REPEATS):
    """Bench directions of the seed 003 procedure, in measurement order.

    Stage 1 (centre): every azimuth at normal incidence, `centre_repeats` frames each. Stage 2 (grid): zenith
    0…`zenith_max_deg` in `zenith_step_deg` steps as the outer loop, every azimuth inside it, `repeats` frames
    each (the optimised order of seed 003 §4.2).

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray
        [°], one entry per frame.
    repeat : ndarray of int
        Frame index at its direction.

    References
    ----------
    seed 003, §4.2 (8 azimuths × 5 frames; 8 azimuths × 0–60° in 10° steps × 4 frames).
    """
    azimuths = grid_azimuths_deg(azimuth_step_deg)  # the grid of calibration.procedure
    zeniths = grid_zeniths_deg(zenith_max_deg, zenith_step_deg)
    rows = [(0.0, a, k) for a in azimuths for k in range(centre_repeats)]
    rows += [(z, a, k) for z in zeniths for a in azimuths for k in range(repeats)]
    z, a, k = (np.array(c) for c in zip(*rows))
    return z.astype(float), a.astype(float), k.astype(int)


def synthetic_bench_data(build: PinholeBuild = EXAMPLE_BUILD, *, zenith_deg=None, azimuth_deg=None,
                         noise_px: float = 0.02, seed: int = 0, design: SensorDesign = DEFAULT_SENSOR,
                         sensor_id: str = "SIM-0001") -> BenchData:
    """Spot centres a sensor of known build would give, with Gaussian centroid noise.

    Parameters
    ----------
    build : PinholeBuild
        The truth.
    zenith_deg, azimuth_deg : array_like, optional
        Directions [°]; default the seed 003 grid (:func:`seed003_grid`).
    noise_px : float
        Standard deviation of the centroid noise on each axis [px].
    seed : int
        Seed of the random generator (the data are reproducible).
    """
    repeat = None
    if zenith_deg is None:
        zenith_deg, azimuth_deg, repeat = seed003_grid()
    x, y = spot_from_direction(zenith_deg, azimuth_deg, build, design.pixel_pitch_mm)
    rng = np.random.default_rng(seed)
    x = x + rng.normal(0.0, noise_px, np.shape(x))
    y = y + rng.normal(0.0, noise_px, np.shape(y))
    return BenchData(zenith_deg, azimuth_deg, x, y, repeat=repeat, sensor_id=sensor_id)
