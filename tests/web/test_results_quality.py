"""A calibration's quality, rejected frames and uncertainty map: stored in its document by the fit, served by
GET /api/runs/{id}/calibrations for the results page (which draws them: tests/web/test_browser.py)."""

import json

import pytest
from inprocess import AUTH

from bench.families.cmos import DESCRIPTOR as CMOS
from calibration.models import METHODS
from calibration.synthetic import EXAMPLE_BUILD, synthetic_bench_data
from calibration.uncertainty import uncertainty_document
from web.routes.pages import STATIC_DIR

PROVENANCE = {"bench_config_hash": "sha256:test", "software_version": "test", "devices": {}, "simulated": True,
              "operator": "test"}
QUALITY = {"chi2_dof": 3.4, "repeat_scatter_px": 0.021, "residual_rms_px": 0.038, "frames": 318, "directions": 80,
           "warnings": ["χ²/dof is 3.4: the model misses the data by more than the repeat scatter",
                        "2 frames rejected as outliers"]}
REJECTED = [{"row": 17, "zenith_deg": 30.0, "azimuth_deg": 45.0, "x_px": 301.2, "y_px": 250.9, "offset_px": 6.3,
             "reason": "6.3 px from the model (> 5 σ)"},
            {"row": None, "zenith_deg": 50.0, "azimuth_deg": 270.0, "x_px": 340.0, "y_px": 190.5, "offset_px": 12.0,
             "reason": "glint"}]


@pytest.fixture(scope="module")
def documents():
    """The documents of a physical fit with every new field, and of a seed003 fit as older versions wrote it."""
    data = synthetic_bench_data(EXAMPLE_BUILD, noise_px=0.02, seed=5).direction_means()
    physical, seed003 = METHODS["physical"].fit(data), METHODS["seed003"].fit(data)
    return ({**physical.to_dict(), "sensor_id": "SIM-0001", "quality": QUALITY, "rejected": REJECTED,
             "uncertainty_map": uncertainty_document(physical)},
            {**seed003.to_dict(), "sensor_id": "SIM-0001"})


@pytest.fixture
def run_id(service, documents):
    catalogue = service.catalogue
    run_id = catalogue.create_run(campaign_id=None, sensor_id="SIM-0001", plan_name="seed003", plan_args={},
                                  provenance=PROVENANCE, descriptor=CMOS)
    physical, seed003 = documents
    catalogue.add_calibration(run_id, "seed003", seed003, {"method": "seed003"}, False)
    catalogue.add_calibration(run_id, "physical", physical, {"method": "physical"}, True)
    return run_id


def test_the_calibrations_carry_quality_rejected_frames_and_the_uncertainty_map(client, run_id, documents):
    response = client.get(f"/api/runs/{run_id}/calibrations", headers=AUTH)
    assert response.status_code == 200, response.text
    by_method = {c["method"]: c for c in response.json()["data"]}
    physical = by_method["physical"]
    assert physical["quality"] == QUALITY and physical["rejected"] == REJECTED
    stored = documents[0]["uncertainty_map"]
    assert physical["uncertainty_map"]["sigma_deg"] == stored["sigma_deg"]
    assert physical["uncertainty_map"]["zenith_deg"][-1] == 60 and len(physical["uncertainty_map"]["azimuth_deg"]) == 24
    assert 0 < physical["uncertainty_map"]["rms_deg"] <= physical["uncertainty_map"]["max_deg"]
    # an older document says nothing of these: null, not an empty list that would claim "nothing rejected"
    old = by_method["seed003"]
    assert (old["quality"], old["rejected"], old["uncertainty_map"]) == (None, None, None)
    assert "document" not in physical  # the list stays the summary; the document is a download


def test_empty_quality_and_rejected_lists_stay_empty(client, service, documents):
    run_id = service.catalogue.create_run(campaign_id=None, sensor_id="S", plan_name="seed003", plan_args={},
                                          provenance=PROVENANCE, descriptor=CMOS)
    document = {**documents[0], "quality": {"chi2_dof": None, "repeat_scatter_px": None, "residual_rms_px": 0.01,
                                            "warnings": []}, "rejected": []}
    service.catalogue.add_calibration(run_id, "physical", document, {}, True)
    (record,) = client.get(f"/api/runs/{run_id}/calibrations", headers=AUTH).json()["data"]
    assert record["quality"] == {"chi2_dof": None, "repeat_scatter_px": None, "residual_rms_px": 0.01, "frames": None,
                                 "directions": None, "warnings": []}
    assert record["rejected"] == []


def test_the_documents_new_fields_do_not_disturb_the_fit_route_or_the_downloads(client, run_id, documents):
    fit = client.get(f"/api/runs/{run_id}/fit", headers=AUTH)
    assert fit.status_code == 200 and fit.json()["method"] == "physical"
    document = client.get(f"/api/calibrations/{run_id}/physical.json", headers=AUTH).json()
    assert document["rejected"] == REJECTED
    assert document["uncertainty_map"] == json.loads(json.dumps(documents[0]["uncertainty_map"]))
    assert client.get(f"/api/calibrations/{run_id}/physical.h", headers=AUTH).status_code == 200


def test_the_schema_documents_the_new_fields(client):
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    fields = schemas["CalibrationPublic"]["properties"]
    assert {"quality", "rejected", "uncertainty_map"} <= set(fields)
    assert "1σ pointing uncertainty" in schemas["UncertaintyMapPublic"]["properties"]["sigma_deg"]["description"]


def test_the_results_page_has_the_places_its_script_fills():
    """results.js fills these by id; the browser test checks what it draws in them."""
    html = (STATIC_DIR / "results.html").read_text()
    script = (STATIC_DIR / "results.js").read_text()
    for element in ("quality-section", "quality-warnings", "quality-figures", "rejected-part", "rejected",
                    "uncertainty-section", "uncertainty-plot"):
        assert f'id="{element}"' in html, element
        assert f'"#{element}' in script or f'"{element}"' in script, element
