"""Fixtures shared by the tests of the engine, the bench service and the web API around it."""

import pytest

from bench.benchfile import BenchFile
from bench.catalogue import Catalogue
from bench.runner import open_session
from bench.service import BenchService
from drivers.sim.bench import SimBenchConfig


@pytest.fixture
def service(tmp_path):
    """A started bench service on the default simulated bench at time scale 0, its catalogue in tmp_path."""
    svc = BenchService(BenchFile(), Catalogue(tmp_path / "c.sqlite"), time_scale=0.0, status_period_s=0.05).start()
    yield svc
    svc.close()
    svc.catalogue.close()


@pytest.fixture
def session(tmp_path):
    """An open session on the default simulated bench (seed 5) at time scale 0, its catalogue in tmp_path."""
    catalogue = Catalogue(tmp_path / "catalogue.sqlite")
    s = open_session(BenchFile(simulation=SimBenchConfig(time_scale=0.0, seed=5)), catalogue)
    yield s
    s.close()
    catalogue.close()
