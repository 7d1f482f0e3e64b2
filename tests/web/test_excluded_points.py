"""Points the fit left out (issue 10, item 7): a spot clipped at the detector's edge is never fitted, and frames a
calibration rejected as outliers are named in its document (`rejected`, `row` = reading id). The result plots
draw such points apart, with why (tests/web/test_browser.py); the API says which they are, computed in
bench/results.py."""

import numpy as np
from inprocess import AUTH
from test_pages import _finished_run  # the small seed 003 campaign, run to its end: its run's id

from bench.descriptor import ReadingRecord
from bench.results import fit_residuals, point_means
from bench.runner import EDGE_REASON, bench_data
from calibration.centroid import SpotFlag


def test_points_clipped_at_the_edge_are_marked_as_left_out_of_every_fit(client, service):
    run_id = _finished_run(client)
    catalogue = service.catalogue
    fitted = set(bench_data(catalogue, [run_id]).frame_id.tolist())
    readings = [r for r in catalogue.readings(run_id) if r.ok]
    edge = {r.point_id for r in readings if r.id not in fitted}
    assert edge, "the small campaign's 60° points at azimuth 90° and 270° touch the detector's edge"

    points = client.get(f"/api/runs/{run_id}/points", headers=AUTH).json()["data"]
    assert {p["id"] for p in points if p["excluded"]} == edge
    for p in points:
        if p["id"] in edge:
            assert p["excluded"] == EDGE_REASON == "spot clipped at the detector's edge"
            assert [f["reason"] for f in p["frames_left_out"]] == [EDGE_REASON] * p["n_ok"]
            assert p["x_px"] is not None  # still drawn, where its spot was
        else:
            assert p["frames_left_out"] == []

    for method in ("physical", "seed003"):
        fit = client.get(f"/api/runs/{run_id}/fit", params={"method": method}, headers=AUTH).json()
        left_out = [p for p in fit["data"] if p["excluded"]]
        assert {p["id"] for p in left_out} == edge and all(p["excluded"] == EDGE_REASON for p in left_out)
        assert all(p["key"] for p in fit["data"])


def test_frames_a_calibration_rejected_are_left_out_with_its_reason(client, service):
    run_id = _finished_run(client)
    catalogue = service.catalogue
    record = next(c for c in catalogue.calibrations(run_id) if c["chosen"])
    readings = [r for r in catalogue.readings(run_id) if r.ok and not r.value("flags", 0)]
    target = readings[len(readings) // 2]  # one frame: its point (one repeat) is left out whole
    reason = "its direction disagrees with the physical model by 6.30 px, more than 5 × its centroid noise"
    document = {**record["document"], "rejected": [
        {"row": target.id, "zenith_deg": target.zenith_deg, "azimuth_deg": target.azimuth_body_deg,
         "x_px": target.value("x_px"), "y_px": target.value("y_px"), "offset_px": 6.3, "reason": reason},
        {"row": None, "zenith_deg": 1.0, "azimuth_deg": 2.0, "x_px": 3.0, "y_px": 4.0, "offset_px": 5.0,
         "reason": "a frame of a CSV without row numbers: it cannot be placed"}]}
    catalogue.add_calibration(run_id, record["method"], document, record["metrics"], True)

    fit = fit_residuals(catalogue, run_id)  # the latest record of the chosen method
    by_id = {p["id"]: p for p in fit["data"]}
    point = by_id[target.point_id]
    assert point["excluded"] == reason
    assert point["frames_left_out"] == [{"reading_id": target.id, "reason": reason}]
    assert [p["id"] for p in fit["data"] if p["excluded"] and p["excluded"] != EDGE_REASON] == [target.point_id]
    # the rejection is the calibration's: the run's points say nothing of it
    plain = {p["id"]: p for p in point_means(catalogue, run_id)}
    assert plain[target.point_id]["excluded"] is None
    over_http = client.get(f"/api/runs/{run_id}/fit", headers=AUTH).json()
    assert next(p for p in over_http["data"] if p["id"] == target.point_id)["excluded"] == reason


class _Catalogue:
    """Just what bench/results.py reads: one run, one point of three frames, one calibration."""

    def __init__(self, document):
        self.document = document

    def run(self, run_id):
        return {"id": run_id}

    def points(self, run_id):
        return [{"id": 7, "key": "grid/a", "stage": "grid", "zenith_deg": 0.0, "azimuth_body_deg": 0.0}]

    def readings(self, run_id):
        def frame(reading_id, x, y, flags=0):
            return ReadingRecord(reading_id, 7, run_id, "grid/a", "grid", 0.0, 0.0, 0.0, 0.0, None, reading_id - 1,
                                 "ok", 0.0, values={"x_px": x, "y_px": y, "flags": flags})
        return [frame(1, 100.0, 200.0), frame(2, 102.0, 202.0), frame(3, 130.0, 230.0, int(SpotFlag.ROI_CLIPPED))]

    def calibrations(self, run_id):
        return [{"method": "m", "chosen": True, "document": self.document}]


def test_a_point_with_some_frames_left_out_is_the_mean_of_the_others(monkeypatch):
    import bench.results as results

    class _Calibration:
        x0_px, y0_px = 100.0, 200.0

        def apply(self, x, y):
            return np.zeros_like(x), np.zeros_like(x)
    monkeypatch.setattr(results, "calibration_from_dict", lambda document: _Calibration())
    catalogue = _Catalogue({"rejected": [{"row": 2, "reason": "off by 6 px"}]})
    (point,) = point_means(catalogue, 1)
    assert (point["x_px"], point["excluded"], point["n_ok"]) == (101.0, None, 3)  # the clipped frame left out
    assert point["frames_left_out"] == [{"reading_id": 3, "reason": EDGE_REASON}]
    (fitted,) = fit_residuals(catalogue, 1)["data"]
    assert (fitted["x_px"], fitted["y_px"], fitted["excluded"]) == (100.0, 200.0, None)  # frame 1 alone
    assert fitted["frames_left_out"] == [{"reading_id": 2, "reason": "off by 6 px"},
                                         {"reading_id": 3, "reason": EDGE_REASON}]
    catalogue.document = {"rejected": [{"row": 1, "reason": "off by 6 px"}, {"row": 2, "reason": "off by 6 px"}]}
    (whole,) = fit_residuals(catalogue, 1)["data"]
    assert whole["excluded"] == f"off by 6 px; {EDGE_REASON}" and whole["x_px"] == 332 / 3  # all its spots
