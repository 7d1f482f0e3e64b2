"""The API's documentation at ``/docs`` without a CDN, and the favicon.

FastAPI's own ``/docs`` loads Swagger UI from a CDN, which a bench PC off the network cannot reach. Here the
page is FastAPI's (:func:`fastapi.openapi.docs.get_swagger_ui_html`) with Swagger UI's files served by this app
from the installed ``fastapi-offline`` package, which ships Swagger UI 5 (FastAPI's OpenAPI 3.1 schema needs
5; the ``swagger-ui-bundle`` package ships 4.15, which refuses it). Only its static files are used.

The page starts Swagger UI with an inline script; its Content-Security-Policy allows that one script by its
hash, and nothing else inline.
"""

from __future__ import annotations

import base64
import hashlib
import re
from importlib import resources
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse

from ..guard import CONTENT_SECURITY_POLICY

router = APIRouter(include_in_schema=False)

#: Swagger UI's files, as this app serves them → their names in the package
SWAGGER_FILES = {"swagger-ui-bundle.js": "text/javascript", "swagger-ui.css": "text/css"}
SWAGGER_PREFIX = "/static/swagger-ui/"
FAVICON = Path(__file__).resolve().parent.parent / "static" / "favicon.svg"

_INLINE_SCRIPT = re.compile(r"<script>(.*?)</script>", re.DOTALL)


def swagger_ui_dir() -> Path:
    """Swagger UI's dist files as the ``fastapi-offline`` package ships them."""
    return Path(str(resources.files("fastapi_offline") / "static"))


def inline_script_hashes(html: str) -> list[str]:
    """CSP source expressions (``'sha256-…'``) for each inline script of `html`."""
    return [f"'sha256-{base64.b64encode(hashlib.sha256(body.encode()).digest()).decode()}'"
            for body in _INLINE_SCRIPT.findall(html)]


@router.get("/docs")
def swagger_ui(request: Request):
    app = request.app
    page = get_swagger_ui_html(openapi_url=app.openapi_url, title=f"{app.title} · API",
                               swagger_js_url=SWAGGER_PREFIX + "swagger-ui-bundle.js",
                               swagger_css_url=SWAGGER_PREFIX + "swagger-ui.css",
                               swagger_favicon_url="/static/favicon.svg")
    html = page.body.decode()
    policy = CONTENT_SECURITY_POLICY.replace("script-src 'self'",
                                             "script-src 'self' " + " ".join(inline_script_hashes(html)))
    return HTMLResponse(html, headers={"Content-Security-Policy": policy, "Cache-Control": "no-cache"})


@router.get(SWAGGER_PREFIX + "{name}")
def swagger_ui_file(name: str):
    if name not in SWAGGER_FILES:
        raise HTTPException(404, f"no {name} here")
    try:
        path = swagger_ui_dir() / name
    except ModuleNotFoundError:
        path = None
    if path is None or not path.is_file():
        raise HTTPException(404, f"{name} not found: install the fastapi-offline package (pip install -e .)")
    return FileResponse(path, media_type=SWAGGER_FILES[name], headers={"Cache-Control": "max-age=86400"})


@router.get("/favicon.ico")
def favicon():
    """Browsers ask for /favicon.ico whatever the page says: the same icon as the pages link."""
    return FileResponse(FAVICON, media_type="image/svg+xml", headers={"Cache-Control": "max-age=86400"})
