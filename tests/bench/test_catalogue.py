"""The SQLite catalogue: schema and versions, one writer and read-only readers, whole points, lineage,
crash recovery, fleet queue, calibrations, journal, frames."""

import contextlib
import os
import random
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

import bench.catalogue as catalogue_module
from bench.catalogue import SCHEMA_VERSION, V1_CMOS_DESCRIPTOR, Catalogue, CatalogueError
from bench.descriptor import FieldSpec, ReadingDescriptor
from bench.families.cmos import DESCRIPTOR as CMOS

ROOT = Path(__file__).resolve().parents[2]

PROVENANCE = {"bench_config_hash": "sha256:abc", "software_version": "0.1.0",
              "devices": {"table": "Meade LX200 sim", "sensor": "CMOS sim"}, "simulated": True, "operator": "test"}


def make_run(cat, sensor_id="S1", campaign_id=None, parent_run_id=None, status="running"):
    run_id = cat.create_run(campaign_id=campaign_id, sensor_id=sensor_id, plan_name="grid",
                            plan_args={"repeats": 2}, provenance=PROVENANCE, parent_run_id=parent_run_id,
                            descriptor=CMOS, n_points_planned=4)
    if status != "created":
        cat.set_run_status(run_id, status)
    return run_id


def readings(n=2, **override):
    return [{"repeat": i, "x_px": 320.0 + i, "y_px": 240.0 - i, "peak_dn": 700.0, "n_pixels": 25, "flags": 0,
             "status": "ok", "t_s": 1.5 * i, **override} for i in range(n)]


def record(cat, run_id, key, n=2, **pose):
    pose = {"stage": "grid", "azimuth_deg": 45.0, "zenith_stage_deg": 10.0, "zenith_deg": 10.2,
            "azimuth_body_deg": 44.9, "exposure_ms": 2.5, **pose}
    return cat.record_point(run_id, key, readings=readings(n), **pose)


@pytest.fixture
def db(tmp_path):
    return tmp_path / "lab" / "catalogue.db"


@pytest.fixture
def cat(db):
    with Catalogue(db) as cat:
        yield cat


# --- schema, versions, opening ----------------------------------------------------------------------------
def test_new_file_has_the_current_schema_version_wal_and_foreign_keys(db):
    with Catalogue(db) as cat:
        assert cat.schema_version == SCHEMA_VERSION == 2
    raw = sqlite3.connect(db)
    assert raw.execute("PRAGMA user_version").fetchone()[0] == 2
    assert raw.execute("PRAGMA journal_mode").fetchone()[0] == "wal"  # WAL is persistent in the file
    tables = {r[0] for r in raw.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    assert {"campaigns", "fleet_queue", "runs", "points", "readings", "calibrations", "events", "run_values",
            "schema_history"} <= tables
    assert raw.execute("SELECT version FROM schema_history").fetchall() == [(1,), (2,)]
    raw.close()


def test_foreign_keys_are_enforced(cat):
    with pytest.raises(CatalogueError, match="FOREIGN KEY"):
        with cat._write("insert an orphan point") as conn:
            conn.execute("INSERT INTO points (run_id, key, stage, azimuth_deg, zenith_stage_deg, zenith_deg, "
                         "azimuth_body_deg, exposure_ms, completed_utc) VALUES (99, 'k', 'g', 0, 0, 0, 0, 1, 'now')")


def test_reopening_keeps_data(db):
    with Catalogue(db) as cat:
        campaign_id = cat.create_campaign("fleet A", "seed003", {"azimuths": 8})
        run_id = make_run(cat, campaign_id=campaign_id)
        record(cat, run_id, "p1")
    with Catalogue(db) as cat:
        assert cat.campaign(campaign_id)["spec"] == {"azimuths": 8}
        assert cat.run(run_id)["n_points_recorded"] == 1
        assert cat.completed_keys([run_id]) == {"p1"}


def test_a_file_from_a_newer_sunbench_is_refused(db):
    Catalogue(db).close()
    raw = sqlite3.connect(db)
    raw.execute("PRAGMA user_version = 7")
    raw.close()
    for readonly in (False, True):
        with pytest.raises(CatalogueError, match=r"version 7 is newer than the version 2"):
            Catalogue(db, readonly=readonly)


def test_an_old_file_is_upgraded_by_the_next_migration(db, monkeypatch):
    with Catalogue(db) as cat:
        run_id = make_run(cat)
    monkeypatch.setitem(catalogue_module._MIGRATIONS, 3, ("ALTER TABLE runs ADD COLUMN bench_name TEXT",))
    monkeypatch.setattr(catalogue_module, "SCHEMA_VERSION", 3)
    with Catalogue(db) as cat:
        assert cat.schema_version == 3
        assert "bench_name" in cat.run(run_id)  # old rows kept, new column there
        assert [r[0] for r in cat._all("SELECT version FROM schema_history ORDER BY version")] == [1, 2, 3]


def test_a_version_1_file_keeps_its_cmos_readings_as_family_values(db, monkeypatch):
    """Schema 2 moved the spot columns of version 1 into each reading's values, under the CMOS descriptor."""
    monkeypatch.setattr(catalogue_module, "SCHEMA_VERSION", 1)
    with Catalogue(db) as cat:  # a file as sunbench wrote it before sensor families
        cat._conn.execute("INSERT INTO runs (sensor_id, plan_name, plan_args_json, created_utc, provenance_json) "
                          "VALUES ('S1', 'grid', '{}', '2026-01-01T00:00:00Z', '{}')")
        cat._conn.execute("INSERT INTO points (run_id, key, stage, azimuth_deg, zenith_stage_deg, zenith_deg, "
                          "azimuth_body_deg, completed_utc) VALUES (1, 'p', 'grid', 45, 10, 10.2, 44.9, 'now')")
        cat._conn.execute("INSERT INTO readings (point_id, repeat, x_px, y_px, peak_dn, n_pixels, flags, status, t_s) "
                          "VALUES (1, 0, 320.123456789012345, 240.25, 700, 25, 4, 'ok', 1.5), "
                          "(1, 1, NULL, NULL, 1023, 0, 0, 'SaturatedSpotError', 2.0)")
        cat._conn.commit()
    monkeypatch.undo()
    with Catalogue(db) as cat:
        assert cat.schema_version == SCHEMA_VERSION
        assert cat.run(1)["family"] == "cmos" and cat.descriptor(1) == CMOS
        ok, saturated = cat.readings(1)
        # every bit of a centroid kept (SQLite's json_object() would round it to 15 digits)
        assert ok.values == {"x_px": 320.123456789012345, "y_px": 240.25, "peak_dn": 700.0, "n_pixels": 25, "flags": 4}
        assert (saturated.status, saturated.value("x_px"), saturated.value("peak_dn")) == ("SaturatedSpotError", None,
                                                                                          1023.0)


def test_the_cmos_descriptor_is_the_one_version_1_stored():
    assert CMOS.to_json() == V1_CMOS_DESCRIPTOR


def test_any_family_readings_are_stored_and_checked_against_the_run_descriptor(cat):
    qd = ReadingDescriptor("quad", (FieldSpec("currents_a", "number", "A", (4,)), FieldSpec("temperature_c", "number",
                                                                                           "degC")))
    run_id = cat.create_run(campaign_id=None, sensor_id="Q1", plan_name="qd-grid", plan_args={},
                            provenance=PROVENANCE, descriptor=qd)
    cat.set_run_status(run_id, "running")
    pose = {"stage": "grid", "azimuth_deg": 0, "zenith_stage_deg": 0, "zenith_deg": 0, "azimuth_body_deg": 0,
            "exposure_ms": None}
    cat.record_point(run_id, "p", readings=[{"t_s": 0.0, "currents_a": [1e-6, 2e-6, 3e-6, 4e-6],
                                             "temperature_c": 21.5}], **pose)
    (reading,) = cat.readings(run_id)
    assert reading.values == {"currents_a": [1e-6, 2e-6, 3e-6, 4e-6], "temperature_c": 21.5}
    assert cat.run(run_id)["family"] == "quad" and cat.descriptor(run_id) == qd
    with pytest.raises(CatalogueError, match="currents_a must be 4 values"):
        cat.record_point(run_id, "q", readings=[{"t_s": 0.0, "currents_a": [1e-6], "temperature_c": 21.5}], **pose)
    with pytest.raises(CatalogueError, match=r"unknown fields \['x_px'\]"):
        cat.record_point(run_id, "q", readings=[{"t_s": 0.0, "x_px": 1.0}], **pose)
    with pytest.raises(CatalogueError, match="an ok quad reading needs temperature_c"):
        cat.record_point(run_id, "q", readings=[{"t_s": 0.0, "currents_a": [1, 2, 3, 4]}], **pose)
    # a failed reading may lack its values
    cat.record_point(run_id, "q", readings=[{"t_s": 0.0, "status": "SaturatedChannel"}], **pose)
    with pytest.raises(CatalogueError, match="same family"):
        cat.create_run(campaign_id=None, sensor_id="Q1", plan_name="grid", plan_args={}, provenance=PROVENANCE,
                       descriptor=CMOS, parent_run_id=run_id)


def test_files_that_are_not_catalogues_are_refused(tmp_path):
    text = tmp_path / "notes.db"
    text.write_text("this is not a database, just some text long enough to fill a header " * 10)
    with pytest.raises(CatalogueError, match="not a"):
        Catalogue(text)
    other = tmp_path / "other.db"
    raw = sqlite3.connect(other)
    raw.execute("CREATE TABLE t (x)")
    raw.close()
    with pytest.raises(CatalogueError, match="not a sunbench catalogue"):
        Catalogue(other)
    raw = sqlite3.connect(other)
    assert raw.execute("PRAGMA journal_mode").fetchone()[0] == "delete"  # someone else's file is left as it was
    raw.close()
    with pytest.raises(CatalogueError, match="no catalogue there"):
        Catalogue(tmp_path / "missing.db", readonly=True)
    assert not (tmp_path / "missing.db").exists()


def test_a_second_writer_is_refused_until_the_first_closes(db):
    first = Catalogue(db)
    with pytest.raises(CatalogueError, match=r"is in use by pid \d+ \(\S+") as refused:
        Catalogue(db)
    assert "readonly" not in str(refused.value)  # said in the words of the command line, not of this API
    assert Catalogue.writer(db).startswith(f"pid {os.getpid()} (")
    with Catalogue(db, readonly=True):  # readers are always welcome
        pass
    first.close()
    assert Catalogue.writer(db) is None
    Catalogue(db).close()


def test_read_only_sees_the_writer_and_cannot_write(db):
    with Catalogue(db) as writer, Catalogue(db, readonly=True) as reader:
        run_id = make_run(writer)
        assert reader.run(run_id)["status"] == "running"
        record(writer, run_id, "p1")
        assert reader.completed_keys(run_id) == {"p1"}  # committed data is visible at once, no reopen
        with pytest.raises(CatalogueError, match="readonly"):
            reader.log_event(run_id, "warning", "from the dashboard")
        with pytest.raises(CatalogueError, match="readonly"):
            reader.record_point(run_id, "p2", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                                azimuth_body_deg=0, exposure_ms=1, readings=readings())
        with pytest.raises(sqlite3.OperationalError, match="readonly"):  # the connection itself refuses
            reader._conn.execute("DELETE FROM events")
        assert writer.completed_keys(run_id) == {"p1"}
        assert len(writer.events(run_id)) == 2


# --- points -------------------------------------------------------------------------------------------
def test_record_point_is_all_or_nothing(cat):
    run_id = make_run(cat)
    record(cat, run_id, "good")
    bad = readings(3)
    bad[2]["repeat"] = 1  # the third reading breaks UNIQUE (point, repeat) after the point and two readings went in
    with pytest.raises(CatalogueError, match=r"reading 2 .*UNIQUE.*not recorded"):
        cat.record_point(run_id, "bad", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1, readings=bad)
    bad = readings(3)
    bad[2]["t_s"] = None  # a reading without its time is refused before anything is written
    with pytest.raises(CatalogueError, match=r"reading 2: t_s .* must be a number"):
        cat.record_point(run_id, "bad", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1, readings=bad)
    bad = readings(3)
    bad[1].update(status="ok", x_px=float("nan"))  # an "ok" reading without a centroid breaks the descriptor
    with pytest.raises(CatalogueError, match="an ok cmos reading needs x_px"):
        cat.record_point(run_id, "bad", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1, readings=bad)
    assert cat.completed_keys(run_id) == {"good"}
    assert [r.key for r in cat.readings(run_id)] == ["good", "good"]
    assert cat._one("SELECT count(*) FROM readings")[0] == 2
    # the key is still free, and the catalogue still works after the rollbacks
    record(cat, run_id, "bad", n=3)
    assert cat.points(run_id)[-1]["n_readings"] == 3


def test_a_failed_centroid_is_stored_with_its_error_name(cat):
    run_id = make_run(cat)
    cat.record_point(run_id, "dark", stage="grid", azimuth_deg=0, zenith_stage_deg=60, zenith_deg=60,
                     azimuth_body_deg=0, exposure_ms=1,
                     readings=[{"x_px": float("nan"), "y_px": float("nan"), "status": "NoSpotError", "t_s": 3.0}])
    (reading,) = cat.readings(run_id)
    assert (reading.status, reading.value("x_px"), reading.repeat) == ("NoSpotError", None, 0)


def test_exposure_may_be_unknown_but_not_zero(cat):
    run_id = make_run(cat)
    record(cat, run_id, "photodiode", exposure_ms=None)  # a sensor without exposure (seed 002's QD)
    assert cat.points(run_id)[0]["exposure_ms"] is None
    with pytest.raises(CatalogueError, match="CHECK"):
        record(cat, run_id, "zero", exposure_ms=0.0)
    assert cat.completed_keys(run_id) == {"photodiode"}


def test_bad_point_values_are_refused_before_anything_is_written(cat):
    run_id = make_run(cat)
    with pytest.raises(CatalogueError, match="zenith_deg must be finite"):
        record(cat, run_id, "p", zenith_deg=float("inf"))
    with pytest.raises(CatalogueError, match=r"unknown fields \['frame'\]"):
        cat.record_point(run_id, "p", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1, readings=[{"t_s": 0.0, "x_px": 1, "y_px": 1,
                                                                       "frame": object()}])
    with pytest.raises(CatalogueError, match="has no readings"):
        cat.record_point(run_id, "p", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1, readings=[])
    assert cat.points(run_id) == []


def test_recording_a_key_twice_is_refused(cat):
    run_id = make_run(cat)
    record(cat, run_id, "p1")
    with pytest.raises(CatalogueError, match="'p1' is already recorded in run 1"):
        record(cat, run_id, "p1")
    assert len(cat.points(run_id)) == 1 and len(cat.readings(run_id)) == 2
    other = make_run(cat, sensor_id="S2")
    record(cat, other, "p1")  # keys are unique per run, not across runs


def test_points_are_not_recorded_in_a_finished_run(cat):
    run_id = make_run(cat)
    cat.set_run_status(run_id, "completed")
    with pytest.raises(CatalogueError, match="run 1 is completed"):
        record(cat, run_id, "late")


def test_readings_are_joined_with_their_point_in_order(cat):
    run_id = make_run(cat)
    record(cat, run_id, "b", azimuth_deg=90.0)
    cat.record_point(run_id, "a", stage="centre", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                     azimuth_body_deg=0, exposure_ms=2, readings=list(reversed(readings(3))))
    rows = cat.readings([run_id])
    assert [(r.key, r.repeat) for r in rows] == [("b", 0), ("b", 1), ("a", 0), ("a", 1), ("a", 2)]
    assert rows[0].azimuth_deg == 90.0 and rows[2].stage == "centre" and rows[2].run_id == run_id


# --- runs -----------------------------------------------------------------------------------------------
def test_run_status_transitions_timestamps_and_journal(cat):
    run_id = make_run(cat, status="created")
    assert cat.run(run_id)["started_utc"] is None
    with pytest.raises(CatalogueError, match="unknown run status 'done'"):
        cat.set_run_status(run_id, "done")
    with pytest.raises(CatalogueError, match="run 1 is created, it cannot become paused"):
        cat.set_run_status(run_id, "paused")
    cat.set_run_status(run_id, "running")
    started = cat.run(run_id)["started_utc"]
    cat.set_run_status(run_id, "paused", "operator")
    cat.set_run_status(run_id, "running")
    assert cat.run(run_id)["started_utc"] == started  # a resume after a pause keeps the first start
    cat.set_run_status(run_id, "aborted", "door opened")
    run = cat.run(run_id)
    assert (run["status"], run["exit_reason"]) == ("aborted", "door opened") and run["ended_utc"] >= started
    with pytest.raises(CatalogueError, match="cannot become running; resume it with a new run"):
        cat.set_run_status(run_id, "running")
    moves = [(e["data"]["from"], e["data"]["to"]) for e in cat.events(run_id) if e["kind"] == "status"]
    assert moves == [(None, "created"), ("created", "running"), ("running", "paused"), ("paused", "running"),
                     ("running", "aborted")]
    with pytest.raises(CatalogueError, match="no run 42"):
        cat.run(42)


def test_provenance_is_required(cat):
    incomplete = {k: v for k, v in PROVENANCE.items() if k != "operator"}
    with pytest.raises(CatalogueError, match="provenance lacks operator"):
        cat.create_run(campaign_id=None, sensor_id="S1", plan_name="grid", plan_args={}, provenance=incomplete,
                       descriptor=CMOS)
    with pytest.raises(CatalogueError, match="'simulated' must be true or false"):
        cat.create_run(campaign_id=None, sensor_id="S1", plan_name="grid", plan_args={}, descriptor=CMOS,
                       provenance={**PROVENANCE, "simulated": "yes"})
    assert cat.runs() == []


def test_lineage_and_completed_keys_across_three_runs(cat):
    first = make_run(cat)
    record(cat, first, "p1")
    record(cat, first, "p2")
    cat.set_run_status(first, "crashed", "killed")
    second = make_run(cat, parent_run_id=first)
    record(cat, second, "p3")
    cat.set_run_status(second, "crashed", "killed")
    third = make_run(cat, parent_run_id=second)
    record(cat, third, "p4")
    assert cat.lineage(third) == [first, second, third]
    assert cat.lineage(first) == [first]
    assert cat.completed_keys(cat.lineage(third)) == {"p1", "p2", "p3", "p4"}
    assert cat.completed_keys(cat.lineage(second)) == {"p1", "p2", "p3"}
    assert [p["key"] for p in cat.points(cat.lineage(third))] == ["p1", "p2", "p3", "p4"]
    assert cat.run(third)["parent_run_id"] == second
    with pytest.raises(CatalogueError, match="a resumed run continues the same sensor"):
        make_run(cat, sensor_id="S9", parent_run_id=third)
    with pytest.raises(CatalogueError, match="no run 77"):
        cat.lineage(77)


def test_mark_interrupted_runs(db):
    with Catalogue(db) as cat:
        campaign_id = cat.create_campaign("fleet", "grid", {})
        cat.enqueue_sensors(campaign_id, ["S1", "S2"])
        running = make_run(cat, "S1", campaign_id)
        cat.set_queue_status(campaign_id, "S1", "running", running)
        paused = make_run(cat, "S2")
        cat.set_run_status(paused, "paused")
        created = make_run(cat, "S3", status="created")
        done = make_run(cat, "S4")
        cat.set_run_status(done, "completed")
    # the engine process is gone; the next one starts
    with Catalogue(db) as cat:
        assert cat.mark_interrupted_runs() == [running, paused]
        statuses = {r["id"]: r["status"] for r in cat.runs()}
        assert statuses == {running: "crashed", paused: "crashed", created: "created", done: "completed"}
        assert "while it was paused" in cat.run(paused)["exit_reason"]
        assert cat.run(paused)["ended_utc"] is not None
        # the sensor goes back to the queue, still linked to the run to resume
        assert cat.next_queued_sensor(campaign_id) == "S1"
        assert cat.queued_run(campaign_id, "S1") == running
        assert cat.mark_interrupted_runs() == []


# --- fleet ----------------------------------------------------------------------------------------------
def test_fleet_queue_order_status_and_rows(cat):
    campaign_id = cat.create_campaign("fleet B", "seed003", {"sensors": 3})
    assert cat.enqueue_sensors(campaign_id, ["SN-3", "SN-1"]) == [0, 1]
    assert cat.enqueue_sensors(campaign_id, ["SN-2"]) == [2]
    with pytest.raises(CatalogueError, match="SN-1 already in campaign 1's queue"):
        cat.enqueue_sensors(campaign_id, ["SN-1"])
    assert cat.next_queued_sensor(campaign_id) == "SN-3"

    run_a = make_run(cat, "SN-3", campaign_id)
    cat.set_queue_status(campaign_id, "SN-3", "running", run_a)
    assert cat.next_queued_sensor(campaign_id) == "SN-1"
    record(cat, run_a, "p1")
    cat.add_calibration(run_a, "seed003", {"x0_px": 320.1}, {"held_out_p95_deg": 0.05}, chosen=True)
    cat.set_run_status(run_a, "completed")
    cat.set_queue_status(campaign_id, "SN-3", "done")  # run_id None keeps the link
    run_b = make_run(cat, "SN-1", campaign_id)
    cat.set_queue_status(campaign_id, "SN-1", "failed", run_b)
    with pytest.raises(CatalogueError, match="run 1 measures sensor SN-3, not SN-2"):
        cat.set_queue_status(campaign_id, "SN-2", "running", run_a)
    with pytest.raises(CatalogueError, match="unknown queue status"):
        cat.set_queue_status(campaign_id, "SN-2", "paused")
    with pytest.raises(CatalogueError, match="SN-9 is not in campaign 1's queue"):
        cat.set_queue_status(campaign_id, "SN-9", "done")

    rows = cat.fleet(campaign_id)
    assert [(r["position"], r["sensor_id"], r["status"], r["run_id"], r["run_status"]) for r in rows] == [
        (0, "SN-3", "done", run_a, "completed"), (1, "SN-1", "failed", run_b, "running"),
        (2, "SN-2", "queued", None, None)]
    assert rows[0]["metrics"] == {"held_out_p95_deg": 0.05} and rows[0]["method"] == "seed003"
    assert rows[0]["n_points_recorded"] == 1 and rows[0]["n_points_planned"] == 4
    assert rows[1]["metrics"] is None and rows[1]["calibration_id"] is None
    assert cat.next_queued_sensor(campaign_id) == "SN-2"
    cat.set_queue_status(campaign_id, "SN-2", "done")
    assert cat.next_queued_sensor(campaign_id) is None
    assert [r["id"] for r in cat.runs(campaign_id)] == [run_a, run_b]
    assert cat.campaigns()[0]["n_runs"] == 2
    with pytest.raises(CatalogueError, match="no campaign 5"):
        cat.fleet(5)


# --- calibrations, journal, values, frames --------------------------------------------------------------
def test_only_one_calibration_is_chosen_per_run(cat):
    run_id = make_run(cat)
    other = make_run(cat, "S2")
    first = cat.add_calibration(run_id, "poly6", {"model": "poly6"}, {"rms_deg": 0.1}, chosen=True)
    cat.add_calibration(other, "poly6", {}, {}, chosen=True)
    second = cat.add_calibration(run_id, "sector", {"model": "sector"}, {"rms_deg": 0.05}, chosen=True)
    third = cat.add_calibration(run_id, "linear", {}, {"rms_deg": 0.5}, chosen=False)
    assert [(c["id"], c["chosen"]) for c in cat.calibrations(run_id)] == [(first, False), (second, True),
                                                                         (third, False)]
    assert cat.calibrations(run_id)[1]["document"] == {"model": "sector"}
    assert cat.calibrations(other)[0]["chosen"]  # another run's choice is its own
    with pytest.raises(CatalogueError, match="UNIQUE"):  # the database itself holds the rule
        with cat._write("choose a second one") as conn:
            conn.execute("UPDATE calibrations SET chosen = 1 WHERE id = ?", (third,))
    with pytest.raises(CatalogueError, match="cannot be stored as JSON"):
        cat.add_calibration(run_id, "poly6", {}, {"rms_deg": float("nan")}, chosen=False)


def test_events_after_id(cat):
    run_id = make_run(cat)
    other = make_run(cat, "S2")
    first = cat.log_event(run_id, "interlock", "lamp housing 71 °C", {"temperature_c": 71.0})
    cat.log_event(other, "warning", "other run")
    last = cat.log_event(run_id, "warning", "slow settle")
    assert [e["id"] for e in cat.events(run_id, after_id=first)] == [last]
    assert cat.events(run_id, after_id=last) == []
    event = cat.events(run_id, after_id=first - 1)[0]
    assert (event["kind"], event["data"], event["run_id"]) == ("interlock", {"temperature_c": 71.0}, run_id)
    bench_event = cat.log_event(None, "engine", "started")
    assert [e["id"] for e in cat.events(None, after_id=last)] == [bench_event]
    with pytest.raises(CatalogueError, match="no run 9"):
        cat.log_event(9, "warning", "nobody")


def test_run_values(cat):
    parent = make_run(cat)
    cat.set_run_value(parent, "exposure_ms", 2.5)
    cat.set_run_value(parent, "tilt_stage", {"alpha_deg": 0.1, "beta_deg": -0.2})
    cat.set_run_value(parent, "exposure_ms", 3.0)
    child = make_run(cat, parent_run_id=parent)
    assert cat.run_value(parent, "exposure_ms") == 3.0
    assert cat.run_values(parent) == {"exposure_ms": 3.0, "tilt_stage": {"alpha_deg": 0.1, "beta_deg": -0.2}}
    assert cat.run_value(child, "exposure_ms", default=-1) == -1
    assert cat.run_value(child, "exposure_ms", inherit=True) == 3.0


def test_frames_dir_layout_and_relative_frame_paths(db, tmp_path):
    with Catalogue(db) as cat:
        run_id = make_run(cat)
        folder = cat.frames_dir(run_id)
        assert folder == db.parent / "catalogue-frames" / f"run-{run_id}" and folder.is_dir()
        frame = folder / "p1-r0.npz"
        frame.write_bytes(b"frame")
        cat.record_point(run_id, "p1", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                         azimuth_body_deg=0, exposure_ms=1,
                         readings=[{"x_px": 1, "y_px": 2, "t_s": 0.0, "frame_path": frame},
                                   {"x_px": 1, "y_px": 2, "t_s": 0.1, "frame_path": "run-1/b.npz"}])
        stored = [r.frame_path for r in cat.readings(run_id)]
        assert stored == ["run-1/p1-r0.npz", "run-1/b.npz"]  # relative to <db stem>-frames/
        assert (cat.frames_root / stored[0]).read_bytes() == b"frame"
        for outside in (tmp_path / "elsewhere.npz", "../up.npz"):
            with pytest.raises(CatalogueError, match="frames folder"):
                cat.record_point(run_id, "p2", stage="grid", azimuth_deg=0, zenith_stage_deg=0, zenith_deg=0,
                                 azimuth_body_deg=0, exposure_ms=1,
                                 readings=[{"x_px": 1, "y_px": 2, "t_s": 0.0, "frame_path": outside}])
        with pytest.raises(CatalogueError, match="no run 8"):
            cat.frames_dir(8)
        second = make_run(cat, "S2")
    with Catalogue(db, readonly=True) as reader:  # a reader names the folder but does not create it
        assert not reader.frames_dir(second).exists()


# --- concurrency and crashes ----------------------------------------------------------------------------
@pytest.mark.parametrize("shared", [False, True], ids=["own read-only catalogue", "the writer's object"])
def test_a_reader_thread_only_ever_sees_whole_points(db, shared):
    with Catalogue(db) as writer:
        run_id = make_run(writer)
        seen, problems = [], []

        def read():
            deadline = time.monotonic() + 10  # a writer that fails early must not leave this loop spinning
            with contextlib.nullcontext(writer) if shared else Catalogue(db, readonly=True) as reader:
                while (not seen or seen[-1] < 40) and time.monotonic() < deadline:
                    points = reader.points(run_id)
                    problems.extend(p["key"] for p in points if p["n_readings"] != 20)
                    seen.append(len(points))

        thread = threading.Thread(target=read, daemon=True)
        interval = sys.getswitchinterval()
        sys.setswitchinterval(1e-5)  # switch threads often, so reads land inside the writer's transactions
        try:
            thread.start()
            for i in range(40):
                record(writer, run_id, f"p{i}", n=20)
            thread.join(timeout=10)
        finally:
            sys.setswitchinterval(interval)
    assert not thread.is_alive() and problems == [] and seen[-1] == 40
    assert seen == sorted(seen)  # never goes backwards


CRASH_SCRIPT = textwrap.dedent("""
    import os, signal, sys
    from bench.catalogue import Catalogue
    from bench.families.cmos import DESCRIPTOR
    path, n_readings, kill_at_point = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    cat = Catalogue(path)
    run_id = cat.create_run(campaign_id=None, sensor_id="S1", plan_name="grid", plan_args={}, descriptor=DESCRIPTOR,
                            provenance={"bench_config_hash": "h", "software_version": "0", "devices": {},
                                        "simulated": True, "operator": "crash test"})
    cat.set_run_status(run_id, "running")
    state = {"point": 0, "readings": 0}

    def trace(sql):  # SQLite calls this as each statement starts: here, inside the open transaction
        if sql.lstrip().startswith("INSERT INTO readings"):
            state["readings"] += 1
            if state["point"] == kill_at_point and state["readings"] == n_readings // 2:
                os.kill(os.getpid(), signal.SIGKILL)

    cat._conn.set_trace_callback(trace)
    while True:
        readings = [{"repeat": r, "x_px": 1.0 * r, "y_px": 2.0, "t_s": 0.01 * r} for r in range(n_readings)]
        state["readings"] = 0
        cat.record_point(run_id, f"p{state['point']}", stage="grid", azimuth_deg=0, zenith_stage_deg=0,
                         zenith_deg=0, azimuth_body_deg=0, exposure_ms=1, readings=readings)
        print(state["point"], flush=True)
        state["point"] += 1
""")


@pytest.mark.parametrize("how", ["inside a transaction", "from outside at a random moment"])
def test_a_killed_writer_leaves_only_whole_points(db, how):
    n = 200
    kill_at_point = 30 if how == "inside a transaction" else -1  # -1: the process never kills itself
    db.parent.mkdir(parents=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen([sys.executable, "-c", CRASH_SCRIPT, str(db), str(n), str(kill_at_point)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    try:
        reported = -1
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:  # it killed itself
                break
            reported = int(line)
            if kill_at_point < 0 and reported == 30:
                time.sleep(random.uniform(0.0, 0.02))  # land anywhere in a point's cycle, not just after print
                proc.send_signal(signal.SIGKILL)
                break
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read()
    assert reported >= 29

    with Catalogue(db) as cat:  # the lock died with the process: a new writer can open at once
        assert cat._one("PRAGMA integrity_check")[0] == "ok"
        points = cat.points(1)
        if kill_at_point >= 0:
            assert len(points) == kill_at_point  # the half-written point is gone, every earlier one is there
        assert len(points) >= reported + 1  # every point reported as recorded survived the kill
        assert all(p["n_readings"] == n for p in points)
        assert len(cat.readings(1)) == n * len(points)
        assert [p["key"] for p in points] == [f"p{i}" for i in range(len(points))]
        assert cat.mark_interrupted_runs() == [1]
        assert cat.run(1)["status"] == "crashed"


def test_a_points_start_time_is_iso_8601_like_every_other_time(cat):
    """The engine hands the start as seconds since the epoch; it is stored as UTC ISO 8601 (issue 10)."""
    import datetime as dt

    run_id = make_run(cat)
    record(cat, run_id, "p1", started_utc=1795474241.28263)
    point = cat.points(run_id)[0]
    assert point["started_utc"] == "2026-11-23T22:50:41.282630Z"
    assert dt.datetime.fromisoformat(point["completed_utc"].replace("Z", "+00:00")).tzinfo is not None
