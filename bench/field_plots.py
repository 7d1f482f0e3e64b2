"""The field figures as HTML files (plotly, its script written once beside them): seed 003's figs. 5.1–5.5 — the
measured and the computed zenith and azimuth against time and their errors, clear and cloudy readings apart —
and the located site with its uncertainty ellipse on plain latitude/longitude axes (no map)."""

from __future__ import annotations

from pathlib import Path

#: Colours of the three kinds of reading.
CLEAR, CLOUD, OUTSIDE = "#1f77b4", "#ff7f0e", "#bbbbbb"


def _kinds(comparison: dict) -> list[str]:
    return ["outside" if not fov else "cloud" if cloud else "clear"
            for fov, cloud in zip(comparison["in_fov"], comparison["cloud"])]


def write_comparison_plots(document: dict, path: Path) -> Path:
    """Figs. 5.1–5.5 of seed 003 for an :func:`~bench.field_analysis.analysis_document`, as one HTML file."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    c = document["comparison"]
    t = c["time_utc"]
    kinds = _kinds(c)
    rows = [("zenith [°] (fig. 5.1)", "measured_zenith_deg", "sun_zenith_deg"),
            ("zenith error [°] (fig. 5.2)", "zenith_error_deg", None),
            ("azimuth [°] (fig. 5.3)", "measured_azimuth_deg", "sun_azimuth_deg"),
            ("azimuth error [°] (fig. 5.4)", "azimuth_error_deg", None),
            ("vector error [°] (fig. 5.5)", "vector_error_deg", None)]
    fig = make_subplots(rows=len(rows), cols=1, shared_xaxes=True, subplot_titles=[r[0] for r in rows],
                        vertical_spacing=0.04)
    for i, (_, measured, sun) in enumerate(rows, start=1):
        if sun is not None:
            fig.add_trace(go.Scatter(x=t, y=c[sun], mode="lines", name="SPA", line={"color": "#d62728"},
                                     showlegend=i == 1), row=i, col=1)
        for kind, colour in (("clear", CLEAR), ("cloud", CLOUD), ("outside", OUTSIDE)):
            pick = [k == kind for k in kinds]
            fig.add_trace(go.Scatter(x=[x for x, p in zip(t, pick) if p], y=[y for y, p in zip(c[measured], pick) if p],
                                     mode="markers", marker={"size": 4, "color": colour},
                                     name={"clear": "clear", "cloud": "cloud", "outside": "outside the FOV"}[kind],
                                     showlegend=i == 1), row=i, col=1)
    heading = c["heading"]
    title = f"{document['name']}: the sensor against SPA"
    if heading["fitted"]:
        title += f" (heading fitted: {heading['deg']:.3f}°, the azimuth error is relative)"
    fig.update_layout(title=title, height=1400, template="plotly_white")
    return write_figure(fig, path)


def write_location_plot(document: dict, path: Path) -> Path:
    """The located site, its 95 % ellipse and the site the file states, on latitude/longitude axes."""
    import plotly.graph_objects as go

    loc = document["location"]
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=loc["ellipse"]["longitude_deg"], y=loc["ellipse"]["latitude_deg"], mode="lines",
                             name=f"{loc['ellipse_level']} ellipse", line={"color": CLEAR}))
    fig.add_trace(go.Scatter(x=[loc["longitude_deg"]], y=[loc["latitude_deg"]], mode="markers", name="located",
                             marker={"size": 10, "color": CLEAR}))
    if document.get("site"):
        site = document["site"]
        fig.add_trace(go.Scatter(x=[site["longitude_deg"]], y=[site["latitude_deg"]], mode="markers",
                                 name="the file's site", marker={"size": 10, "symbol": "x", "color": "#d62728"}))
    error = "" if loc["error_km"] is None else f", {loc['error_km']:.2f} km from the file's site"
    fig.update_layout(title=f"{document['name']}: {loc['latitude_deg']:.5f}°, {loc['longitude_deg']:.5f}° "
                            f"(±{loc['sd_latitude_km']:.2f} km N, ±{loc['sd_longitude_km']:.2f} km E, 1σ){error}",
                      xaxis_title="longitude [°]", yaxis_title="latitude [°]", template="plotly_white",
                      yaxis={"scaleanchor": "x", "scaleratio": 1 / max(0.05, _cos_deg(loc["latitude_deg"]))})
    return write_figure(fig, path)


def _cos_deg(deg: float) -> float:
    import math
    return math.cos(math.radians(deg))


def write_figure(fig, path: Path) -> Path:
    """`fig` as a standalone HTML file at `path`, plotly.js written once beside it (the same file serves every
    figure in the folder)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.write_html(path, include_plotlyjs="directory", full_html=True)
    return path
