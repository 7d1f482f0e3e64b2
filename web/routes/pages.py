"""The dashboard: plain HTML pages and their small JS modules from ``web/static``, and plotly.js from the
installed ``plotly`` package (served locally: the bench PCs are often offline, so no CDN).

The pages hold no data and need no token (but for the banner of a simulated bench: simulated, and at what
time scale); every API call they make sends the token the operator pasted (kept in the browser's localStorage).
"""

from __future__ import annotations

import html
from importlib import resources
from pathlib import Path

from fastapi import APIRouter, FastAPI, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles

from ..family import bench_info

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"

LAYOUT = Path(__file__).resolve().parent.parent / "templates" / "layout.html"

#: URL path → page file in STATIC_DIR (the page's <main>; the head, the navigation and the token form are
#: the layout's, written once)
PAGES = {"/": "bench.html", "/launch": "launch.html", "/run": "run.html", "/results": "results.html",
         "/fleet": "fleet.html", "/field": "field.html"}
TITLES = {"/": "Bench", "/launch": "Campaign launcher", "/run": "Live run", "/results": "Results", "/fleet": "Fleet",
          "/field": "Field data"}
PLOTS = {"/run", "/results", "/field"}  # the pages that load plotly.js

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


def _wall(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 60} min {seconds % 60} s" if seconds >= 60 else f"{seconds} s"


def bench_banner(bench: dict | None) -> str:
    """The banner every page shows on a simulated bench (none on a real one): that it is simulated, and how its
    time runs against the wall clock (:meth:`bench.service.BenchService.bench_info`)."""
    if not bench or not bench.get("simulated"):
        return ""
    scale = bench.get("time_scale")
    if scale is None:
        pace = "its time scale is unknown"
    elif scale == 0:
        pace = "time scale 0: every wait is skipped, so a run takes as long as the computer needs"
    elif scale == 1:
        pace = "time scale 1: its time runs as the wall clock's"
    else:
        pace = (f"time scale {scale:g}: its time runs {scale:g}× as fast as the wall clock (a bench hour takes "
                f"{_wall(3600 / scale)} of wall time)")
    attribute = "" if scale is None else f"{scale:g}"
    return (f'  <p id="bench-banner" class="sim-banner" role="note" data-time-scale="{attribute}">'
            f"<b>Simulated bench</b>: nothing real moves, lights or measures; {html.escape(pace)}.</p>\n")


def bench_attributes(bench: dict | None) -> str:
    """The bench's sensor family on the page's <body> (``data-family``, ``data-plans``, ``data-frames``), so the
    launcher offers the family's plans and the live pages show its readings before any API call (no token)."""
    if not bench or not bench.get("family"):
        return ""
    values = {"family": bench["family"], "plans": " ".join(bench.get("plans") or ()),
              "frames": "true" if bench.get("has_frames") else "false"}
    return "".join(f' data-{name}="{html.escape(value, quote=True)}"' for name, value in values.items())


def render_page(path: str, bench: dict | None = None) -> str:
    """The page at `path`: its <main> in the layout, its own link marked, its scripts in the head, the simulated
    bench's banner when `bench` (its :meth:`~bench.service.BenchService.bench_info` with its family,
    :func:`web.family.bench_info`) says so, and the bench's family on its <body>."""
    name = PAGES[path].removesuffix(".html")
    scripts = ('  <script src="/static/plotly.min.js"></script>\n' if path in PLOTS else "")
    scripts += f'  <script type="module" src="/static/{name}.js"></script>\n'
    main = (STATIC_DIR / PAGES[path]).read_text(encoding="utf-8").split("\n", 1)[1]  # drop the first comment line
    page = LAYOUT.read_text(encoding="utf-8").format(title=TITLES[path], scripts=scripts, main=main,
                                                     banner=bench_banner(bench),
                                                     bench_attributes=bench_attributes(bench))
    return page.replace(f'<a href="{path}">', f'<a href="{path}" class="here">', 1)


def _page_route(path: str):
    def page(request: Request):
        return HTMLResponse(render_page(path, bench_info(request.app.state.service)),
                            headers={"Cache-Control": "no-cache"})
    page.__name__ = f"page_{PAGES[path].removesuffix('.html')}"
    return page


for _path, _file in PAGES.items():
    router.add_api_route(_path, _page_route(_path), methods=["GET"], name=f"page-{_file}")


def install(app: FastAPI) -> None:
    """Add the pages, plotly.js, then the other static files (the explicit routes win over the mount)."""
    app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
