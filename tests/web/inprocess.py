"""The web app in-process (Starlette's TestClient) around a bench service, with the tests' token and host; and a
bench service on the simulated QD bench (seed 002's quadrant photodiode), camera bench (seed 001's camera) or CSS
bench (seed 000's coarse-sun-sensor head)."""

import contextlib
from pathlib import Path

from fastapi.testclient import TestClient

from bench.benchfile import load_bench_file
from bench.catalogue import Catalogue
from bench.service import BenchService
from web.app import create_app
from web.settings import WebSettings

TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


#: The Host header of Starlette's TestClient (http://testserver): the app answers only its own names (web/guard.py),
#: so the tests' settings add this one, as a lab would add the bench PC's name
TEST_HOST = "testserver"


def settings_for_tests(**settings) -> WebSettings:
    """The tests' WebSettings: their token, a short keep-alive and the TestClient's host; `settings` override."""
    return WebSettings(**{"token": TOKEN, "sse_keepalive_s": 0.2, "allowed_hosts": (TEST_HOST,), **settings})


def api_client(service, **settings) -> TestClient:
    """A client of the app around `service`; `settings` override the tests' WebSettings."""
    return TestClient(create_app(service, settings=settings_for_tests(**settings)))


#: The simulated QD bench of seed 002 (README: sunbench serve --bench examples/bench-sim-qd.yaml)
QD_BENCH = Path(__file__).resolve().parents[2] / "examples" / "bench-sim-qd.yaml"


#: The simulated camera bench of seed 001 (README: sunbench serve --bench examples/bench-sim-camera.yaml)
CAMERA_BENCH = QD_BENCH.parent / "bench-sim-camera.yaml"


#: The simulated CSS bench of seed 000 (README: sunbench serve --bench examples/bench-sim-css.yaml)
CSS_BENCH = QD_BENCH.parent / "bench-sim-css.yaml"


@contextlib.contextmanager
def bench_file_service(bench: Path, catalogue: Path):
    """A started bench service on the simulated bench of the bench file `bench` at time scale 0, its catalogue at
    `catalogue`."""
    service = BenchService(load_bench_file(bench), Catalogue(catalogue), time_scale=0.0, status_period_s=0.05).start()
    try:
        yield service
    finally:
        service.close()
        service.catalogue.close()


def qd_bench_service(folder: Path):
    """A started bench service on the simulated QD bench at time scale 0, its catalogue in `folder`."""
    return bench_file_service(QD_BENCH, folder / "qd.sqlite")


def camera_bench_service(folder: Path):
    """A started bench service on the simulated camera bench at time scale 0, its catalogue in `folder`."""
    return bench_file_service(CAMERA_BENCH, folder / "camera.sqlite")


def css_bench_service(folder: Path):
    """A started bench service on the simulated CSS bench at time scale 0, its catalogue in `folder`."""
    return bench_file_service(CSS_BENCH, folder / "css.sqlite")
