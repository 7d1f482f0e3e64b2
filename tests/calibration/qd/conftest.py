"""Shared QD bench data, simulated once per session by the independent generators of qd_simulation."""

import numpy as np
import pytest
from qd_simulation import GLINT_ROW, SENSOR, brute_force_currents, grid, measure

from calibration.qd.data import QdBenchData


@pytest.fixture(scope="session")
def physical_grid():
    """Noise-free brute-force photocurrents over a ±40° grid (5° nodes) and the centres of its cells."""
    a_nodes, b_nodes = grid(40.0, 5.0)
    mids = np.arange(-37.5, 37.6, 5.0)
    a_mid, b_mid = (m.ravel() for m in np.meshgrid(mids, mids, indexing="ij"))
    alpha = np.concatenate([a_nodes, a_mid])
    beta = np.concatenate([b_nodes, b_mid])
    check = np.concatenate([np.zeros(a_nodes.size, bool), np.ones(a_mid.size, bool)])
    return {"alpha_deg": alpha, "beta_deg": beta, "check": check,
            "photocurrents_a": brute_force_currents(alpha, beta, SENSOR, seed=1)}


@pytest.fixture(scope="session")
def bench_data(physical_grid):
    """A bench run: two passes over nodes and check points at 18–32 °C, a dark run at −10…50 °C, one glint."""
    rng = np.random.default_rng(42)
    g = physical_grid
    n = g["alpha_deg"].size
    alpha, beta, currents, temps, check, repeat, dark = [], [], [], [], [], [], []
    for rep in range(2):
        t = rng.uniform(18.0, 32.0, n)
        currents.append(measure(g["photocurrents_a"], t, SENSOR, rng))
        alpha.append(g["alpha_deg"]), beta.append(g["beta_deg"]), temps.append(t), check.append(g["check"])
        repeat.append(np.full(n, rep)), dark.append(np.zeros(n, bool))
    td = np.repeat(np.linspace(-10.0, 50.0, 13), 3)
    currents.append(measure(np.zeros((td.size, 4)), td, SENSOR, rng))
    alpha.append(np.full(td.size, np.nan)), beta.append(np.full(td.size, np.nan)), temps.append(td)
    check.append(np.zeros(td.size, bool)), repeat.append(np.zeros(td.size, int)), dark.append(np.ones(td.size, bool))
    cur = np.concatenate(currents)
    cur[GLINT_ROW] *= [1.0, 1.25, 1.0, 1.0]  # a glint on quadrant 2 of one reading
    return QdBenchData.from_projection(np.concatenate(alpha), np.concatenate(beta), cur, np.concatenate(temps),
                                       repeat=np.concatenate(repeat), dark=np.concatenate(dark),
                                       check=np.concatenate(check), sensor_id="QD-SIM-7")


@pytest.fixture(scope="session")
def outcome(bench_data):
    from calibration.qd.evaluation import calibrate_qd

    return calibrate_qd(bench_data)
