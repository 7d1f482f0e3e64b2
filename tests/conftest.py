"""Fixtures shared by the tests of the bench service and of the web API around it."""

import pytest

from bench.benchfile import BenchFile
from bench.catalogue import Catalogue
from bench.service import BenchService


@pytest.fixture
def service(tmp_path):
    """A started bench service on the default simulated bench at time scale 0, its catalogue in tmp_path."""
    svc = BenchService(BenchFile(), Catalogue(tmp_path / "c.sqlite"), time_scale=0.0, status_period_s=0.05).start()
    yield svc
    svc.close()
    svc.catalogue.close()
