"""The Monte Carlo engine (bench/study_engine.py) on a real Dask cluster: a `distributed.LocalCluster` started here,
reached through the same `--scheduler tcp://…` address a user gives `sunbench study …`.

What is checked: the study table (one row per simulation, its parameters, seed and outputs) and its summary; the
chunks kept as they finish and reused by a rerun of the same spec (the simulations run again are counted by the
`run_id` each row carries: only the chunks that were missing are recomputed, and their rows equal the first run's);
a changed spec starting afresh and saying so while the earlier spec's chunks stay (a mistyped rerun destroys nothing,
and the earlier spec run again reuses them all); an error in a simulation recorded in words in its row; a chunk whose
task fails on the workers (they cannot import the simulation, as on a cluster without sunbench) retried and reported;
a cluster whose every worker leaves mid-study stopped by the watchdog with the finished chunks kept, and resumed.
"""

import io
import json
import textwrap

import numpy as np
import pandas as pd
import pytest
from clitools import invoke

from bench import study_engine
from bench.study_engine import (
    STATISTICS,
    StudyError,
    StudySpec,
    chunk_dir,
    run_chunk,
    run_study,
    statistics,
    summarise,
)


@pytest.fixture(scope="module")
def scheduler():
    """A one-worker local Dask cluster (its own worker process), as a user would have started elsewhere."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0")
    yield cluster.scheduler_address
    cluster.close()


HORIZON = ("study", "horizon-errors", "--altitude-km", "500,900", "--factors", "mount,altitude", "--draws", "5",
           "--chunk-size", "3", "--solver", "closed-form")


def test_spec_is_the_product_of_the_sweep_times_the_draws():
    spec = StudySpec("s", "bench.study_horizon:simulate_horizon", {"a": (1, 2, 3), "b": ("x", "y")}, {"c": 0.5},
                     draws=4, chunk_size=5)
    rows = spec.rows()
    assert len(spec) == len(rows) == 3 * 2 * 4
    assert [r["sim"] for r in rows] == list(range(24))
    assert [(r["a"], r["b"]) for r in rows[::4]] == [(1, "x"), (1, "y"), (2, "x"), (2, "y"), (3, "x"), (3, "y")]
    # common random numbers: draw d has one seed at every setting, different draws differ
    seeds = np.array([r["seed"] for r in rows]).reshape(6, 4)
    assert (seeds == seeds[0]).all() and len(set(seeds[0])) == 4
    assert [len(c) for c in spec.chunks()] == [5, 5, 5, 5, 4]
    # the hash follows every part of the spec
    changed = [StudySpec("s", spec.simulate, spec.sweep, {"c": 0.6}, draws=4, chunk_size=5),
               StudySpec("s", spec.simulate, spec.sweep, {"c": 0.5}, draws=5, chunk_size=5),
               StudySpec("s", spec.simulate, spec.sweep, {"c": 0.5}, draws=4, chunk_size=6),
               StudySpec("s", spec.simulate, spec.sweep, {"c": 0.5}, draws=4, chunk_size=5, seed=1),
               StudySpec("s", spec.simulate, spec.sweep, {"c": 0.5}, draws=4, chunk_size=5, version="2")]
    assert len({spec.digest, *(c.digest for c in changed)}) == 6
    assert StudySpec("s", spec.simulate, dict(spec.sweep), {"c": 0.5}, draws=4, chunk_size=5).digest == spec.digest


@pytest.mark.parametrize("kwargs, words", [
    ({"sweep": {"a": ()}}, "has no values"),
    ({"sweep": {"a": (1, 1)}}, "repeats a value"),
    ({"sweep": {"a": (float("nan"),)}}, "not a finite number"),
    ({"sweep": {"a": (1,)}, "fixed": {"a": 2}}, "both swept and fixed"),
    ({"fixed": {"seed": 3}}, "reserved"),
    ({"draws": 0}, "`draws`"),
    ({"simulate": "no_colon"}, "module:function"),
])
def test_a_bad_spec_is_refused_in_words(kwargs, words):
    args = {"name": "s", "simulate": "bench.study_horizon:simulate_horizon", **kwargs}
    with pytest.raises(StudyError, match=words):
        StudySpec(**args)


def test_a_simulation_error_is_recorded_in_its_row():
    # at 36 000 km the Earth is 8.7° in radius: a 70° cone never meets it — an error in words, not a lost row
    rows = [{"sim": 0, "setting": 0, "draw": 0, "seed": 1, "altitude_km": 500.0, "factor": "mount"},
            {"sim": 1, "setting": 1, "draw": 0, "seed": 1, "altitude_km": 36000.0, "factor": "mount"}]
    done = run_chunk("bench.study_horizon:simulate_horizon", rows, "r1")
    assert done[0]["error"] == "" and np.isfinite(done[0]["roll_error_deg"])
    assert done[1]["error"].startswith("ValueError: cone 1 does not cross the horizon")
    assert "roll_error_deg" not in done[1] and done[1]["run_id"] == "r1"
    table = pd.DataFrame(done)
    summary = summarise(table, ["altitude_km"], ["factor"])
    lost = summary[(summary["altitude_km"] == 36000.0) & (summary["output"] == "roll_error_deg")].iloc[0]
    assert (lost["errors"], lost["n"], lost["failed"]) == (1, 0, 1)


def test_statistics():
    s = statistics([1.0, -2.0, np.nan, 3.0, -4.0])
    assert (s["n"], s["failed"]) == (4, 1)
    assert s["mean"] == pytest.approx(-0.5) and s["mean_abs"] == pytest.approx(2.5)
    assert s["rms"] == pytest.approx(np.sqrt(30 / 4)) and s["max_abs"] == 4.0
    assert s["p50_abs"] == pytest.approx(2.5) and s["sd"] == pytest.approx(np.std([1, -2, 3, -4], ddof=1))
    assert set(s) == set(STATISTICS)


def test_study_on_an_existing_cluster_through_the_cli(scheduler, tmp_path, monkeypatch):
    out = tmp_path / "h" / "budget.csv"
    r = invoke(*HORIZON, "--out", out, "--scheduler", scheduler)
    assert r.exit_code == 0, r.output
    assert "20 of 20 simulations (20 run now" in r.output and "on 1 worker(s)" in r.output
    table = pd.read_csv(out)
    assert len(table) == 20 and list(table["sim"]) == list(range(20))
    for column in ("sim", "setting", "draw", "seed", "altitude_km", "factor", "mount_error_deg", "roll_error_deg",
                   "pitch_error_deg", "nadir_error_deg", "error", "run_id"):
        assert column in table.columns, column
    assert table["error"].isna().all() and table["run_id"].nunique() == 1
    # the summary: one row per setting and output, the statistics recomputed from the table
    summary = pd.read_csv(out.with_name("budget.summary.csv"))
    row = summary[(summary["altitude_km"] == 900.0) & (summary["factor"] == "mount")
                  & (summary["output"] == "nadir_error_deg")].iloc[0]
    values = table[(table["altitude_km"] == 900.0) & (table["factor"] == "mount")]["nadir_error_deg"]
    assert row["n"] == 5 and row["rms"] == pytest.approx(np.sqrt(np.mean(values ** 2)))
    assert row["p95_abs"] == pytest.approx(np.percentile(values.abs(), 95))
    assert "mount_error_deg" not in set(summary["output"])  # a fixed parameter is no output
    assert out.with_name("budget.html").is_file() and (out.parent / "plotly.min.js").is_file()
    assert "Roll and pitch error" in r.output and "mount" in r.output

    # resume: chunks 1 and 6 lost (an interrupted run never wrote them) — only their 3 + 2 simulations run again
    digest = json.loads((chunk_dir(out) / "spec.json").read_text())["digest"]
    chunks = sorted(chunk_dir(out).glob(f"{digest}-*.csv"))
    assert len(chunks) == 7
    (chunk_dir(out) / f"{digest}-1.csv").unlink()
    (chunk_dir(out) / f"{digest}-6.csv").unlink()
    r = invoke(*HORIZON, "--out", out, "--scheduler", scheduler)
    assert r.exit_code == 0, r.output
    assert "(5 run now" in r.output and "15 kept from an earlier run" in r.output
    again = pd.read_csv(out)
    first_run = table["run_id"].iloc[0]
    rerun = again["run_id"] != first_run
    assert sorted(again.loc[rerun, "sim"]) == [3, 4, 5, 18, 19]  # chunk 1: sims 3–5, chunk 6: 18–19
    pd.testing.assert_frame_equal(again.drop(columns=["run_id", "sim_s"]), table.drop(columns=["run_id", "sim_s"]))

    # everything there: nothing is computed, no cluster needed
    r = invoke(*HORIZON, "--out", out, "--scheduler", "tcp://127.0.0.1:1")
    assert r.exit_code == 0, r.output
    assert "20 of 20 simulations (0 run now, 20 kept" in r.output

    # a mistyped rerun (another spec, a scheduler that does not answer) stops before any work and destroys nothing
    monkeypatch.setattr(study_engine, "CONNECT_TIMEOUT_S", 1.0)
    r = invoke(*HORIZON[:-4], "--draws", "50", "--chunk-size", "3", "--solver", "closed-form", "--out", out,
               "--scheduler", "tcp://127.0.0.1:1")
    assert r.exit_code == 2 and "no Dask scheduler answers" in r.output
    assert sorted(chunk_dir(out).glob(f"{digest}-*.csv")) == chunks

    # a changed spec starts afresh, says which part changed, and keeps the earlier spec's chunks
    r = invoke(*HORIZON[:-4], "--draws", "4", "--chunk-size", "3", "--solver", "closed-form", "--out", out,
               "--scheduler", scheduler)
    assert r.exit_code == 0, r.output
    assert "the study spec changed (draws): starting afresh" in r.output
    assert "the 7 chunk(s) of 1 earlier spec(s) are kept" in r.output
    assert "16 of 16 simulations (16 run now" in r.output
    assert len(list(chunk_dir(out).glob("*.csv"))) == 7 + 6
    # the earlier spec run again: all its chunks reused, nothing computed (no cluster reached), the same table
    r = invoke(*HORIZON, "--out", out, "--scheduler", "tcp://127.0.0.1:1")
    assert r.exit_code == 0, r.output
    assert "20 of 20 simulations (0 run now, 20 kept" in r.output and "spec changed" not in r.output
    pd.testing.assert_frame_equal(pd.read_csv(out), again)


def test_a_chunk_failing_on_the_workers_is_retried_then_reported(scheduler, tmp_path, monkeypatch):
    # a simulation this process can import but the cluster's workers cannot: a cluster without the code
    (tmp_path / "only_here.py").write_text(textwrap.dedent("""
        def simulate(params, seed):
            return {"x": float(seed % 7)}
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = StudySpec("local-only", "only_here:simulate", {"a": (1, 2)}, draws=2, chunk_size=2)
    result = run_study(spec, tmp_path / "r.csv", scheduler=scheduler, progress=False)
    assert sorted(result.failed_chunks) == [0, 1]
    for why in result.failed_chunks.values():
        assert "No module named 'only_here'" in why and "the workers must have sunbench installed" in why
    # Dask ran each chunk twice (retries=1) before giving up: the scheduler's story of the task says so
    from distributed import Client

    with Client(scheduler) as client:
        story = client.story(f"{spec.name}-{spec.digest}-0-{result.run_id}")
    attempts = [s for s in story if s[0] == "scheduler" and s[2:4] == ("waiting", "processing")]
    assert len(attempts) == 2 and any(s[0] == "scheduler" and s[3] == "erred" for s in story)
    assert result.computed == 0 and len(result.table) == 0
    assert not list(chunk_dir(tmp_path / "r.csv").glob("*-*.csv"))


def test_an_unreachable_scheduler_and_a_bad_table_are_user_errors(tmp_path, monkeypatch):
    monkeypatch.setattr(study_engine, "CONNECT_TIMEOUT_S", 1.0)
    r = invoke(*HORIZON, "--out", tmp_path / "x.csv", "--scheduler", "tcp://127.0.0.1:1")
    assert r.exit_code == 2 and "no Dask scheduler answers at tcp://127.0.0.1:1" in r.output
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", dashboard_address=":0") as empty:
        r = invoke(*HORIZON, "--out", tmp_path / "x.csv", "--scheduler", empty.scheduler_address)
    assert r.exit_code == 2 and f"the Dask scheduler at {empty.scheduler_address} has no workers" in r.output
    r = invoke(*HORIZON, "--out", tmp_path / "x.json")
    assert r.exit_code == 2 and "must be a .csv or .parquet file" in r.output
    # Parquet only with pyarrow (not a dependency): on a machine without it, the run is refused before it starts
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "pyarrow" else find_spec(name, *a))
    r = invoke(*HORIZON, "--out", tmp_path / "x.parquet")
    assert r.exit_code == 2 and "Parquet needs pyarrow" in r.output
    assert not (tmp_path / "x.parquet.chunks").exists()


def test_a_local_cluster_is_closed_when_its_client_cannot_start(monkeypatch):
    import distributed

    real_cluster, started = distributed.LocalCluster, []

    def local_cluster(**options):  # a real cluster, without worker processes to keep the test fast
        started.append(real_cluster(**{**options, "n_workers": 0, "processes": False}))
        return started[-1]

    def refused(*args, **kwargs):
        raise OSError("the client could not start")

    monkeypatch.setattr(distributed, "LocalCluster", local_cluster)
    monkeypatch.setattr(distributed, "Client", refused)
    with pytest.raises(OSError, match="could not start"):
        study_engine.open_client(None, 1)
    assert len(started) == 1 and started[0].status.name == "closed"


LEAVES_ITS_WORKER = """
import time
from pathlib import Path

def simulate(params, seed):
    # setting a=2, while the marker file is there: wait for chunk 0's file, then close the worker this runs on
    marker = Path(params["marker"])
    if params["a"] == 2 and marker.exists():
        while not list(Path(params["chunks"]).glob("*-0.csv")):
            time.sleep(0.02)
        marker.unlink()
        from distributed import get_worker

        worker = get_worker()
        worker.loop.add_callback(worker.close)
        time.sleep(0.5)
    return {"x": 10.0 * params["a"] + seed % 7}
"""


def test_a_cluster_left_without_workers_stops_the_study_and_a_rerun_resumes(tmp_path, monkeypatch):
    from distributed import Client, LocalCluster
    from rich.console import Console

    monkeypatch.setattr(study_engine, "NO_WORKER_TIMEOUT_S", 1.0)
    monkeypatch.setattr(study_engine, "WATCH_INTERVAL_S", 0.1)
    monkeypatch.setattr(study_engine, "STALL_WARNING_S", 0.5)
    (tmp_path / "leaves_its_worker.py").write_text(LEAVES_ITS_WORKER)
    monkeypatch.syspath_prepend(str(tmp_path))
    marker = tmp_path / "leave"
    marker.touch()
    out = tmp_path / "r.csv"
    spec = StudySpec("leaving", "leaves_its_worker:simulate", {"a": (1, 2, 3)},
                     {"marker": str(marker), "chunks": str(chunk_dir(out))}, chunk_size=1)
    # one worker thread in this process (it imports the simulation from tmp_path), reached by its address
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
                      dashboard_address=":0") as cluster:
        said = io.StringIO()
        with pytest.raises(StudyError) as stopped:
            run_study(spec, out, scheduler=cluster.scheduler_address, console=Console(file=said, width=300),
                      progress=False)
        assert not marker.exists()  # the worker did leave, mid-study
        why = str(stopped.value)
        assert f"the Dask scheduler at {cluster.scheduler_address} has had no worker for 1 s" in why
        assert "2 of 3 chunk(s) waited" in why and "the 1 chunk(s) finished by this run are kept" in why
        assert "no chunk has finished for" in said.getvalue() and "0 worker(s)" in said.getvalue()
        assert [p.name for p in chunk_dir(out).glob("*-*.csv")] == [f"{spec.digest}-0.csv"]

        cluster.scale(2)  # a fresh worker (the closed one still counts as one of the two)
        with Client(cluster) as client:
            client.wait_for_workers(1, timeout=10)
        result = run_study(spec, out, scheduler=cluster.scheduler_address, progress=False)
    assert (result.computed, result.reused, result.failed_chunks) == (2, 1, {})
    assert list(result.table["x"]) == [10.0 * a + spec.draw_seed(0) % 7 for a in (1, 2, 3)]
