"""The web app in-process (Starlette's TestClient) around a bench service, with the tests' token and host."""

from fastapi.testclient import TestClient

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
