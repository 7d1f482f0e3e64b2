import pytest

from inprocess import api_client


@pytest.fixture
def client(service):
    with api_client(service) as c:
        yield c
