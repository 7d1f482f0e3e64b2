"""The web app in-process (Starlette's TestClient) around a bench service, with the tests' token."""

from fastapi.testclient import TestClient

from web.app import create_app
from web.settings import WebSettings

TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


def api_client(service, **settings) -> TestClient:
    """A client of the app around `service`; `settings` override the tests' WebSettings."""
    return TestClient(create_app(service, settings=WebSettings(token=TOKEN, sse_keepalive_s=0.2, **settings)))
