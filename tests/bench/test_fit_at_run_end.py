"""Issue 9 at a run's end: the fit is the robust, self-checking one of `sunbench fit cmos`, the bench geometry
is fitted from the recorded stage angles with the bench file's lengths as measurements, and the detector's
design comes from the bench file."""

import pytest

from bench.benchfile import BenchFile
from bench.campaign import Campaign
from bench.catalogue import Catalogue
from bench.runner import fit_inputs, open_session, run_campaign

DESIGN = {"width_px": 640, "height_px": 480, "pixel_pitch_mm": 0.0099, "pinhole_height_mm": 1.5}


@pytest.fixture
def session(tmp_path):
    bench = BenchFile.model_validate({"simulation": {"time_scale": 0.0, "seed": 5},
                                      "devices": {"sensor": {"kind": "cmos", "design": DESIGN}},
                                      "geometry": {"lever_arm_mm": 136.2, "source_distance_mm": 7100.0,
                                                   "lever_arm_sd_mm": 0.5, "source_distance_sd_mm": 10.0}})
    catalogue = Catalogue(tmp_path / "catalogue.sqlite")
    s = open_session(bench, catalogue)
    yield s
    s.close()
    catalogue.close()


def test_the_fit_at_a_runs_end_is_robust_self_checking_and_fits_the_bench_geometry(session):
    design, prior = fit_inputs(session)
    assert design.pinhole_height_mm == 1.5  # the bench file's word, not the simulator's
    assert (prior.lever_arm_mm, prior.lever_arm_sd_mm, prior.source_distance_sd_mm) == (136.2, 0.5, 10.0)
    (run_id,) = run_campaign(Campaign(name="seed003", frames="none"), session, confirm_mount=lambda *a: True)
    chosen = next(c for c in session.catalogue.calibrations(run_id) if c["chosen"])
    document = chosen["document"]
    assert document["design"]["pinhole_height_mm"] == 1.5
    geometry = document["bench_geometry"]
    assert abs(geometry["lever_arm_mm"]["value"] - 136.2) <= 3 * geometry["lever_arm_mm"]["sd"]
    assert 0.5 < document["quality"]["chi2_dof"] < 3.0 and document["quality"]["warnings"] == []
    assert chosen["metrics"]["heldout_ring"] and chosen["metrics"]["heldout_azimuth"]
    assert chosen["metrics"]["heldout"]["rms_vector_deg"] <= 0.01
    assert document["uncertainty_map"]["max_deg"] < 0.01
