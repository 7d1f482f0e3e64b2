"""The dashboard: plain HTML pages and their small JS modules from ``web/static``, and plotly.js from the
installed ``plotly`` package (served locally: the bench PCs are often offline, so no CDN).

The pages hold no data and need no token; every API call they make sends the token the operator pasted
(kept in the browser's localStorage).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from fastapi import APIRouter, FastAPI, HTTPException
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"

LAYOUT = Path(__file__).resolve().parent.parent / "templates" / "layout.html"

#: URL path → page file in STATIC_DIR (the page's <main>; the head, the navigation and the token form are
#: the layout's, written once)
PAGES = {"/": "bench.html", "/launch": "launch.html", "/run": "run.html", "/results": "results.html",
         "/fleet": "fleet.html"}
TITLES = {"/": "Bench", "/launch": "Campaign launcher", "/run": "Live run", "/results": "Results", "/fleet": "Fleet"}
PLOTS = {"/run", "/results"}  # the pages that load plotly.js

router = APIRouter(include_in_schema=False)


def plotly_js_path() -> Path:
    """``plotly.min.js`` as shipped by the plotly Python package."""
    return Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))


@router.get("/static/plotly.min.js")
def plotly_js():
    try:
        path = plotly_js_path()
    except ModuleNotFoundError:
        path = None
    if path is None or not path.is_file():
        raise HTTPException(404, "plotly.min.js not found: install the plotly package (pip install plotly)")
    return FileResponse(path, media_type="text/javascript", headers={"Cache-Control": "max-age=86400"})


def render_page(path: str) -> str:
    """The page at `path`: its <main> in the layout, its own link marked, its scripts in the head."""
    name = PAGES[path].removesuffix(".html")
    scripts = ('  <script src="/static/plotly.min.js"></script>\n' if path in PLOTS else "")
    scripts += f'  <script type="module" src="/static/{name}.js"></script>\n'
    main = (STATIC_DIR / PAGES[path]).read_text(encoding="utf-8").split("\n", 1)[1]  # drop the first comment line
    html = LAYOUT.read_text(encoding="utf-8").format(title=TITLES[path], scripts=scripts, main=main)
    return html.replace(f'<a href="{path}">', f'<a href="{path}" class="here">', 1)


def _page_route(path: str):
    def page():
        return HTMLResponse(render_page(path), headers={"Cache-Control": "no-cache"})
    page.__name__ = f"page_{PAGES[path].removesuffix('.html')}"
    return page


for _path, _file in PAGES.items():
    router.add_api_route(_path, _page_route(_path), methods=["GET"], name=f"page-{_file}")


def install(app: FastAPI) -> None:
    """Add the pages, plotly.js, then the other static files (the explicit routes win over the mount)."""
    app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
