"""The dashboard pages on the simulated bench: each page, its JS module, plotly.js served locally (no CDN),
the read-only fit route the result plots draw, and the event stream's ?token= for the browser's EventSource."""

import re
import time
import typing
from html.parser import HTMLParser

import annotated_types
import numpy as np
import pytest
from inprocess import AUTH, TOKEN, api_client

from bench.campaign import (
    CameraGridProcedure,
    Campaign,
    CssSweepProcedure,
    PhysicalProcedure,
    QdDarkSweep,
    QdGridProcedure,
    QdPhysicalProcedure,
    Seed003Procedure,
)
from calibration.models import METHODS
from calibration.models.physical import FITTED
from web.routes.pages import PAGES, STATIC_DIR

SMALL = Campaign(name="small", frames="none", seed003=Seed003Procedure(
    azimuth_step_deg=90.0, repeats=1, centre_repeats=1, tilt_stage=False)).model_dump(mode="json")

# page → its JS module, and whether it draws with plotly
MODULES = {"/": ("bench.js", False), "/launch": ("launch.js", False), "/run": ("run.js", True),
           "/results": ("results.js", True), "/fleet": ("fleet.js", False), "/field": ("field.js", True)}
EXTERNAL_URL = re.compile(r"(?:https?:)?//[a-z0-9.-]+\.[a-z]{2,}", re.IGNORECASE)
XML_NAMESPACE = re.compile(r'\sxmlns(?::\w+)?="[^"]*"')


def _local_assets(html: str) -> list[str]:
    return re.findall(r'(?:src|href)="(/static/[^"]+)"', html)


def _imports(js: str) -> list[str]:
    return [f"/static/{name.removeprefix('./')}" for name in re.findall(r'from\s+"(\./[^"]+)"', js)]


def test_every_page_is_html_with_its_module_and_plotly_where_it_plots(client):
    assert set(PAGES) == set(MODULES)
    for path, (module, plots) in MODULES.items():
        response = client.get(path)  # the pages hold no data: no token needed
        assert response.status_code == 200, path
        assert response.headers["content-type"].startswith("text/html")
        html = response.text
        assert f'<script type="module" src="/static/{module}"></script>' in html, path
        assert ('src="/static/plotly.min.js"' in html) == plots, path
        assert 'id="token-form"' in html and 'id="message"' in html
        for asset in _local_assets(html):
            assert client.get(asset).status_code == 200, (path, asset)
    assert client.get("/results", params={"run": 1}).status_code == 200
    assert client.get("/fleet", params={"campaign": 1}).status_code == 200


def test_no_served_html_or_js_refers_to_another_host(client):
    seen, todo = set(), [*MODULES]
    while todo:
        url = todo.pop()
        if url in seen or url == "/static/plotly.min.js":  # plotly's own bundle: checked for what it is below
            continue
        seen.add(url)
        response = client.get(url)
        assert response.status_code == 200, url
        # an XML namespace (the favicon's xmlns="http://www.w3.org/2000/svg") names, it is never fetched
        text = XML_NAMESPACE.sub("", response.text)
        assert not EXTERNAL_URL.search(text), (url, EXTERNAL_URL.search(text).group())
        todo += _local_assets(response.text) if url in MODULES else _imports(response.text)
    assert {f"/static/{m}" for m, _ in MODULES.values()} | {"/static/common.js", "/static/style.css"} <= seen
    # every file shipped in web/static is a page or is reached from one (nothing stale), and was checked
    shipped = {p.name for p in STATIC_DIR.iterdir() if p.is_file()}
    assert {n for n in shipped if n.endswith(".html")} == set(PAGES.values())
    assert {f"/static/{n}" for n in shipped if not n.endswith(".html")} <= seen


#: an id a script looks up: a selector in a string literal ("#run-title", "#metrics tbody"; a colour, "#d62728",
#: is none) or a plot's element, named "…-plot" (Plotly.react("spot-plot" …), currentsPlot("currents-plot" …))
_ID_SELECTOR = re.compile(r"""["'`]#([A-Za-z][\w-]*)""")
_PLOT_ID = re.compile(r"""["']([A-Za-z][\w-]*-plot)["']""")
_COLOUR = re.compile(r"[0-9a-fA-F]{3}(?:[0-9a-fA-F]{3})?")


def script_ids(client, module: str) -> dict[str, set[str]]:
    """Every element id the page script `module` (``/static/run.js``) and the modules it imports look up, with
    the modules that do."""
    ids, todo, seen = {}, [module], set()
    while todo:
        url = todo.pop()
        if url in seen:
            continue
        seen.add(url)
        js = client.get(url).text
        for found in _ID_SELECTOR.findall(js) + _PLOT_ID.findall(js):
            if not _COLOUR.fullmatch(found):
                ids.setdefault(found, set()).add(url)
        todo += _imports(js)
    return ids


def page_ids(html: str) -> set[str]:
    return set(re.findall(r'\sid="([^"]+)"', html))


def test_every_element_a_page_script_looks_up_is_on_its_page(client):
    """A script that looks up an element its page lacks fails on the operator's screen, not here: each id a
    page's modules name (common.js and, on /results, results-qd.js included) is an element of the page."""
    for path, (module, _) in MODULES.items():
        referenced = script_ids(client, f"/static/{module}")
        assert referenced, path
        missing = {i: where for i, where in referenced.items() if i not in page_ids(client.get(path).text)}
        assert not missing, (path, missing)


def test_plotly_is_served_locally_from_the_plotly_package(client):
    response = client.get("/static/plotly.min.js")
    assert response.status_code == 200
    assert "javascript" in response.headers["content-type"]
    head = response.text[:2000]
    assert "plotly.js" in head and len(response.content) > 1_000_000
    assert "newPlot" in response.text


def test_static_files_cannot_escape_their_folder(client):
    assert client.get("/static/nonexistent.js").status_code == 404
    assert client.get("/static/../app.py").status_code == 404
    assert client.get("/static/%2e%2e/app.py").status_code == 404


def test_the_pages_are_not_in_the_api_schema(client):
    paths = client.get("/openapi.json").json()["paths"]
    assert not {"/", "/launch", "/run", "/results", "/fleet", "/static/plotly.min.js"} & set(paths)


# -- the event stream's token as a query parameter ----------------------------------------------------------
def _first_event(response, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    for line in response.iter_lines():
        if line.startswith(("event: ", ":")):
            return line
        assert time.monotonic() < deadline
    raise AssertionError("the stream ended")


def test_the_event_stream_takes_the_token_as_a_query_parameter(client):
    with client.stream("GET", "/api/events", params={"token": TOKEN}) as response:
        assert response.status_code == 200 and response.headers["content-type"].startswith("text/event-stream")
        assert _first_event(response)


@pytest.mark.parametrize("params", [{}, {"token": "wrong-token-0123456789"}, {"token": ""}],
                         ids=["none", "wrong", "empty"])
def test_the_event_stream_refuses_a_missing_or_wrong_query_token(client, params):
    response = client.get("/api/events", params=params)
    assert response.status_code == 401 and response.headers["www-authenticate"] == "Bearer"


def test_a_header_token_wins_over_the_query_token(client):
    wrong = {"Authorization": "Bearer wrong-token-0123456789"}
    assert client.get("/api/events", params={"token": TOKEN}, headers=wrong).status_code == 401
    with client.stream("GET", "/api/events", params={"token": "wrong-token-0123456789"}, headers=AUTH) as response:
        assert response.status_code == 200


def test_the_query_token_opens_nothing_but_the_event_stream(client):
    assert client.get("/api/status", params={"token": TOKEN}).status_code == 401
    assert client.post("/api/source/lamp", params={"token": TOKEN}, json={"on": True}).status_code == 401


def test_with_public_read_the_event_stream_needs_no_token(service):
    with api_client(service, public_read=True) as client, client.stream("GET", "/api/events") as response:
        assert response.status_code == 200
        assert _first_event(response)


# -- the fit route the result plots use ---------------------------------------------------------------------
def _finished_run(client, timeout_s=60.0) -> int:
    assert client.post("/api/campaigns", json=SMALL, headers=AUTH).status_code == 202
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        runs = client.get("/api/runs", headers=AUTH).json()["data"]
        # a run is marked completed only once every calibration is stored (they are stored one by one)
        if runs and runs[0]["status"] == "completed":
            return runs[0]["id"]
        time.sleep(0.05)
    raise AssertionError("the campaign did not finish")


def test_the_fit_route_gives_radius_and_residuals_of_each_method(client):
    run_id = _finished_run(client)
    points = client.get(f"/api/runs/{run_id}/points", headers=AUTH).json()["data"]
    calibrations = client.get(f"/api/runs/{run_id}/calibrations", headers=AUTH).json()["data"]
    chosen = next(c["method"] for c in calibrations if c["chosen"])

    fit = client.get(f"/api/runs/{run_id}/fit", headers=AUTH).json()
    assert fit["method"] == chosen and fit["chosen"] and fit["count"] == len(points) == 32
    assert 0 < fit["x0_px"] < 640 and 0 < fit["y0_px"] < 480
    for p, q in zip(fit["data"], points, strict=True):
        assert (p["id"], p["zenith_deg"], p["x_px"]) == (q["id"], q["zenith_deg"], q["x_px"])
        radius = ((p["x_px"] - fit["x0_px"]) ** 2 + (p["y_px"] - fit["y0_px"]) ** 2) ** 0.5
        assert p["radius_px"] == pytest.approx(radius)
    errors = [p["error_deg"] for p in fit["data"]]
    assert all(e is not None and 0 <= e < 2.0 for e in errors)  # a calibrated sensor: within a couple of degrees
    normal = [p for p in fit["data"] if p["zenith_deg"] == 0]
    outer = [p for p in fit["data"] if p["zenith_deg"] >= 50]
    assert max(p["radius_px"] for p in normal) < min(p["radius_px"] for p in outer)  # θ grows with r
    # eq. 10 about the fitted centre: off the axis, the spot's azimuth is the bench's plus one offset (eq. 11's
    # b0: the detector's axes against the bench's zero, and its in-plane rotation), the same for every point
    offsets = np.array([(p["azimuth_spot_deg"] - p["azimuth_deg"] + 180) % 360 - 180 for p in outer])
    assert np.ptp(offsets) < 2

    for method in METHODS:
        other = client.get(f"/api/runs/{run_id}/fit", params={"method": method}, headers=AUTH)
        assert other.status_code == 200 and other.json()["method"] == method


def test_the_fit_route_refusals(client):
    assert client.get("/api/runs/1/fit").status_code == 401
    assert client.get("/api/runs/99/fit", headers=AUTH).status_code == 404
    run_id = _finished_run(client)
    response = client.get(f"/api/runs/{run_id}/fit", params={"method": "nonsense"}, headers=AUTH)
    assert response.status_code == 404 and "no nonsense calibration" in response.json()["detail"]


# -- the launcher's form is the campaign model's ------------------------------------------------------------
class _Form(HTMLParser):
    """The launcher's plan options, and its inputs by the plan of the fieldset around them (None outside)."""

    def __init__(self):
        super().__init__()
        self.plan, self.options, self.inputs, self.selects = None, [], {}, set()
        self._select = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "fieldset":
            self.plan = attrs["data-plan"]
            self.inputs.setdefault(self.plan, {})
        elif tag == "select":
            self._select = attrs["name"]
            self.selects.add(attrs["name"])
        elif tag == "option" and self._select == "plan":
            self.options.append(attrs["value"])
        elif tag == "input" and "name" in attrs:
            inputs = self.inputs.setdefault(self.plan, {})
            assert attrs["name"] not in inputs, f"{attrs['name']} twice in fieldset {self.plan}"
            inputs[attrs["name"]] = attrs

    def handle_endtag(self, tag):
        if tag == "fieldset":
            self.plan = None
        elif tag == "select":
            self._select = None


def _launch_form(client) -> _Form:
    form = _Form()
    form.feed(client.get("/launch").text)
    return form


def _limits(field) -> tuple[float | None, float | None]:
    """(lower, upper) bounds of a model field, inclusive or not: an input's min and max."""
    low = high = None
    for m in field.metadata:
        if isinstance(m, (annotated_types.Ge, annotated_types.Gt)):
            low = getattr(m, "ge", None) if isinstance(m, annotated_types.Ge) else m.gt
        if isinstance(m, (annotated_types.Le, annotated_types.Lt)):
            high = getattr(m, "le", None) if isinstance(m, annotated_types.Le) else m.lt
    return low, high


def test_the_launcher_offers_every_familys_plans(client):
    # the page holds every plan's fieldset; launch.js keeps those of the bench's family (its <body data-plans>)
    form = _launch_form(client)
    assert form.options == ["seed003", "physical", "qd-grid", "qd-physical", "qd-dark", "camera-grid", "css-sweep",
                            "horizon-grid"]
    assert set(form.options) <= set(typing.get_args(Campaign.model_fields["plan"].annotation))
    # one fieldset per plan, named as the plan (its data-field names Campaign's field: qd_grid for qd-grid)
    assert set(form.inputs) == {None, "seed003", "physical", "qd-grid", "qd-physical", "qd-dark", "camera-grid",
                                "css-sweep", "horizon-grid"}
    assert {"name", "operator", "sensors"} <= set(form.inputs[None]) and {"plan", "frames"} <= form.selects


@pytest.mark.parametrize("plan, model", [("seed003", Seed003Procedure), ("physical", PhysicalProcedure),
                                         ("qd-grid", QdGridProcedure), ("qd-physical", QdPhysicalProcedure),
                                         ("qd-dark", QdDarkSweep), ("camera-grid", CameraGridProcedure),
                                         ("css-sweep", CssSweepProcedure)])
def test_every_field_of_the_launcher_has_the_models_default_and_limits(client, plan, model):
    inputs = _launch_form(client).inputs[plan]
    targets = {name.split(".", 1)[1] for name in inputs if name.startswith("parameter_targets.")}
    if plan == "physical":  # one optional 1σ target per fitted parameter, blank by default
        assert targets == set(FITTED)
        assert all("value" not in inputs[f"parameter_targets.{t}"]
                   and "required" not in inputs[f"parameter_targets.{t}"]
                   and inputs[f"parameter_targets.{t}"]["min"] == "0" for t in targets)
    fields = {name for name in inputs if "." not in name}
    assert fields <= set(model.model_fields), fields - set(model.model_fields)
    wanted = {"seed003": {"azimuth_step_deg", "zenith_stage_deg", "repeats", "centre_repeats", "tilt_stage"},
              "physical": {"first_batch", "batch_size", "max_batches", "check_directions", "repeats",
                           "check_rms_target_deg", "parameter_budget_deg", "zenith_max_deg", "zenith_step_deg",
                           "azimuth_step_deg", "edge_margin_px"},
              "qd-grid": {"field_deg", "step_deg", "repeats", "check_points", "temperature_c"},  # + dark.* (test_qd.py)
              "qd-physical": {"field_deg", "steps_deg", "check_directions", "repeats", "check_max_target_deg",
                              "check_rms_target_deg", "temperature_c"},
              "qd-dark": {"temperatures_c", "repeats", "tolerance_c"},
              "camera-grid": {"horizontal_fov_deg", "width_px", "height_px", "rings", "azimuths", "margin_radii",
                              "repeats"},
              "css-sweep": set(CssSweepProcedure.model_fields)}[plan]
    assert fields == wanted
    for name in fields:
        attrs, field = inputs[name], model.model_fields[name]
        if attrs.get("type") == "checkbox":
            assert ("checked" in attrs) == field.default, name
        elif "data-list" in attrs:
            assert [float(v) for v in attrs["value"].split(",")] == list(field.default), name
        else:
            assert attrs["type"] == "number" and "required" in attrs, name
            assert float(attrs["value"]) == field.default, name
            low, high = _limits(field)
            assert (float(attrs["min"]), float(attrs["max"])) == (low, high), name
            assert attrs["step"] == ("1" if field.annotation is int else "any"), name
