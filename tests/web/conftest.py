import pytest
from inprocess import api_client, qd_bench_service


@pytest.fixture
def client(service):
    with api_client(service) as c:
        yield c


@pytest.fixture
def qd_service(tmp_path):
    """A started bench service on the simulated QD bench (examples/bench-sim-qd.yaml) at time scale 0."""
    with qd_bench_service(tmp_path) as service:
        yield service


@pytest.fixture
def qd_client(qd_service):
    with api_client(qd_service) as c:
        yield c
