"""Monte Carlo studies on Dask: many independent simulations, cut into chunks, run on a cluster, kept as they finish.

A study is a :class:`StudySpec`: a simulation function named by its import path, the values each swept parameter
takes, the fixed parameters, and `draws` random seeds. Its simulations are the cartesian product of the swept values
times the draws (one row each), cut into chunks of `chunk_size` consecutive rows. Each chunk is one Dask task
(``Client.submit``): on a local cluster on every core by default (``distributed.LocalCluster``, one single-threaded
worker process per core), or on an existing cluster when a scheduler address (``tcp://host:8786``) is given. There is
no scheduler or pool of our own.

Resumable: a finished chunk is written at once to ``<out>.chunks/<spec hash>-<k>.csv`` (a temporary file renamed into
place, so a chunk file is whole or absent), and a run of the same spec reuses the chunks already there. The spec's
hash names them; a changed spec (another value, another seed, another chunk size or version) starts afresh and says
so, and the earlier spec's chunks stay (nothing is deleted: run that spec again and they are reused). While chunks
run, a watchdog stops a study whose cluster has had no worker for :data:`NO_WORKER_TIMEOUT_S` (the finished chunks
are kept, so the same command resumes it) and warns when no chunk has finished for :data:`STALL_WARNING_S`.
Results: the table (one row per simulation: its parameters, seed, outputs and, in words, any error), a summary per
parameter setting (:func:`summarise`: mean, mean |x|, RMS, percentiles of |x|) and plots.

Draw d has the same seed at every setting (common random numbers): the same simulated sensor, attitude or noise
draw meets every setting, so a difference between settings is the settings', not the luck of different draws.

A simulation is ``simulate(params: dict, seed: int) -> dict`` of outputs (numbers or words). An exception in it is
recorded in the row's ``error`` column, in words, and its outputs are left empty; a chunk whose task fails (its
worker died, the workers cannot import the simulation) is retried once by Dask (``retries=1``), then reported.

Workers must be able to import the project: a local cluster's worker processes inherit this interpreter's
environment; on an external cluster every worker needs sunbench installed (``pip install sunbench`` or the project
checked out and installed with ``pip install -e .`` in the workers' environment).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import itertools
import json
import logging
import math
import os
import re
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: The columns every row of a study table has besides its parameters and outputs.
BOOK_COLUMNS = ("sim", "setting", "draw", "seed")
TRAILING_COLUMNS = ("error", "run_id", "sim_s")
#: Summary statistics of each numeric output, per parameter setting (:func:`summarise`).
STATISTICS = ("n", "failed", "mean", "sd", "mean_abs", "rms", "p50_abs", "p95_abs", "p99_abs", "max_abs")

#: How long to try reaching an existing cluster's scheduler before saying it does not answer [s].
CONNECT_TIMEOUT_S = 10.0
#: How long the cluster may have no worker while chunks wait before the study stops and says so [s].
NO_WORKER_TIMEOUT_S = 60.0
#: How long without a finished chunk before a warning line, repeated at this interval [s].
STALL_WARNING_S = 600.0
#: How often the wait for chunks asks the scheduler how many workers it has [s].
WATCH_INTERVAL_S = 1.0

_CHUNK_FILE = re.compile(r"^([0-9a-f]{12})-(\d+)\.csv$")
_SCALARS = (bool, int, float, str)


class StudyError(Exception):
    """A study that cannot run as asked: bad spec, unreachable scheduler, unwritable result."""


@dataclass(frozen=True)
class StudySpec:
    """What a study computes, and so what its chunks' hash names.

    Attributes
    ----------
    name : str
        The study's name (``horizon-errors``, ``cmos-plan``).
    simulate : str
        ``"module:function"``: ``function(params, seed) -> dict`` of outputs, imported where the chunk runs.
    sweep : mapping of str to sequence
        Each swept parameter's values (numbers, strings or booleans); the settings are their cartesian product,
        the first parameter varying slowest.
    fixed : mapping of str to scalar
        Parameters every simulation gets.
    draws : int
        Random seeds per setting.
    seed : int
        Seed of the study: draw d's seed is drawn from (seed, d).
    chunk_size : int
        Simulations per chunk (one Dask task, one chunk file).
    version : str
        The simulation's version: bumped when its physics change, so old chunks are not reused.
    """

    name: str
    simulate: str
    sweep: Mapping[str, Sequence] = field(default_factory=dict)
    fixed: Mapping[str, object] = field(default_factory=dict)
    draws: int = 1
    seed: int = 0
    chunk_size: int = 16
    version: str = "1"

    def __post_init__(self) -> None:
        if ":" not in self.simulate:
            raise StudyError(f"`simulate` must be 'module:function', got {self.simulate!r}")
        if not isinstance(self.draws, int) or self.draws < 1:
            raise StudyError(f"`draws` must be a positive integer, got {self.draws!r}")
        if not isinstance(self.chunk_size, int) or self.chunk_size < 1:
            raise StudyError(f"`chunk_size` must be a positive integer, got {self.chunk_size!r}")
        sweep = {}
        for name, values in self.sweep.items():
            values = tuple(values)
            if not values:
                raise StudyError(f"swept parameter {name!r} has no values")
            for v in values:
                _check_scalar(name, v)
            if len(set(values)) != len(values):
                raise StudyError(f"swept parameter {name!r} repeats a value: {list(values)}")
            sweep[name] = values
        for name, v in self.fixed.items():
            _check_scalar(name, v)
            if name in sweep:
                raise StudyError(f"parameter {name!r} is both swept and fixed")
        clash = (set(sweep) | set(self.fixed)) & set(BOOK_COLUMNS + TRAILING_COLUMNS)
        if clash:
            raise StudyError(f"parameter names {sorted(clash)} are reserved for the study table")
        object.__setattr__(self, "sweep", sweep)
        object.__setattr__(self, "fixed", dict(self.fixed))

    def to_dict(self) -> dict:
        return {"name": self.name, "simulate": self.simulate, "sweep": {k: list(v) for k, v in self.sweep.items()},
                "fixed": dict(self.fixed), "draws": self.draws, "seed": self.seed, "chunk_size": self.chunk_size,
                "version": self.version}

    @property
    def digest(self) -> str:
        """12 hex digits of the SHA-256 of the spec's canonical JSON: the name of its chunks."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    def settings(self) -> list[dict]:
        """Every combination of the swept values, the first parameter varying slowest."""
        names = list(self.sweep)
        return [dict(zip(names, combo)) for combo in itertools.product(*self.sweep.values())]

    def draw_seed(self, draw: int) -> int:
        """Draw `draw`'s seed, the same at every setting (common random numbers)."""
        return int(np.random.SeedSequence([int(self.seed) & 0xFFFFFFFF, draw]).generate_state(1)[0])

    def rows(self) -> list[dict]:
        """One row per simulation: its index, setting, draw, seed and every parameter."""
        seeds = [self.draw_seed(d) for d in range(self.draws)]
        rows = []
        for s, setting in enumerate(self.settings()):
            for d in range(self.draws):
                rows.append({"sim": len(rows), "setting": s, "draw": d, "seed": seeds[d], **setting, **self.fixed})
        return rows

    def chunks(self) -> list[list[dict]]:
        rows = self.rows()
        return [rows[i:i + self.chunk_size] for i in range(0, len(rows), self.chunk_size)]

    def __len__(self) -> int:
        return math.prod(len(v) for v in self.sweep.values()) * self.draws


def sweep_options(defaults: dict, options: dict, sweep: dict) -> tuple[dict, dict]:
    """The study's swept and fixed values: `sweep` as given, then every option of `defaults` (its value in `options`,
    else the default) swept when it is a list of more than one value, fixed otherwise."""
    sweep, fixed = dict(sweep), {}
    for name, default in defaults.items():
        value = options.get(name, default)
        if isinstance(value, (list, tuple)):
            if len(value) > 1:
                sweep[name] = tuple(value)
                continue
            value = value[0]
        fixed[name] = value
    return sweep, fixed


def _check_scalar(name: str, value) -> None:
    if not isinstance(value, _SCALARS) or (isinstance(value, float) and not math.isfinite(value)):
        raise StudyError(f"parameter {name!r}: {value!r} is not a finite number, a string or a boolean")


def resolve(path: str) -> Callable:
    """The function named ``"module:function"``."""
    module, _, name = path.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise StudyError(f"cannot import the simulation {path!r}: {exc}") from exc


def run_chunk(simulate: str, rows: list[dict], run_id: str) -> list[dict]:
    """Run one chunk's simulations (this is the Dask task): each row's parameters and seed, its outputs, its error
    in words (``"ValueError: …"``; outputs then empty), the id of the run and the simulation's wall time [s]."""
    function = resolve(simulate)
    book = set(BOOK_COLUMNS)
    done = []
    for row in rows:
        params = {k: v for k, v in row.items() if k not in book}
        t0 = time.perf_counter()
        try:
            outputs, error = dict(function(params, row["seed"])), ""
        except Exception as exc:  # recorded in words, in the row: one bad simulation does not sink the study
            outputs, error = {}, f"{type(exc).__name__}: {exc}"
        clash = set(outputs) & (set(row) | set(TRAILING_COLUMNS))
        if clash:
            outputs, error = {}, f"the simulation returned reserved or parameter names {sorted(clash)}"
        done.append({**row, **outputs, "error": error, "run_id": run_id, "sim_s": time.perf_counter() - t0})
    return done


# -- chunk files --------------------------------------------------------------------------------------------
def chunk_dir(out: Path) -> Path:
    """Where the chunks of the study written to `out` are kept: ``<out>.chunks/``."""
    return out.with_name(out.name + ".chunks")


def chunk_path(out: Path, digest: str, k: int) -> Path:
    return chunk_dir(out) / f"{digest}-{k}.csv"


def write_chunk(path: Path, rows: list[dict]) -> None:
    """The chunk's rows as CSV, written to a temporary file and renamed into place (whole or absent)."""
    import pandas as pd

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    pd.DataFrame(rows).to_csv(tmp, index=False)
    os.replace(tmp, path)


def _existing_chunks(directory: Path) -> dict[str, set[int]]:
    found: dict[str, set[int]] = {}
    if directory.is_dir():
        for p in directory.iterdir():
            m = _CHUNK_FILE.match(p.name)
            if m:
                found.setdefault(m.group(1), set()).add(int(m.group(2)))
    return found


def prepare_chunks(spec: StudySpec, out: Path) -> tuple[set[int], str | None]:
    """The chunks of `spec` already written under `out` and, when it has none but another spec's chunks are there,
    a note that the spec changed and the study starts afresh.

    Nothing is removed: a chunk file is named by its spec's hash, so another spec's chunks are kept (and reused when
    that spec is run again) and a mistyped or interrupted rerun cannot destroy a finished study. Writes the spec
    beside its chunks (``<hash>.spec.json``, and ``spec.json``: the spec run last).
    """
    directory = chunk_dir(out)
    found = _existing_chunks(directory)
    digest = spec.digest
    done = {k for k in found.get(digest, set()) if k < len(spec.chunks())}
    others = {d: ks for d, ks in found.items() if d != digest}
    note = None
    if others and not done:
        previous = _previous_spec(directory, others)
        changed = _spec_changes(previous, spec.to_dict()) if previous else "an earlier spec"
        count = sum(len(ks) for ks in others.values())
        note = (f"the study spec changed ({changed}): starting afresh as spec {digest}; the {count} chunk(s) of "
                f"{len(others)} earlier spec(s) are kept in {directory} and reused if that spec is run again")
    directory.mkdir(parents=True, exist_ok=True)
    text = json.dumps({**spec.to_dict(), "digest": digest}, indent=1)
    (directory / f"{digest}.spec.json").write_text(text)
    (directory / "spec.json").write_text(text)
    return done, note


def _previous_spec(directory: Path, others: dict[str, set[int]]) -> dict | None:
    """The spec that `others`' chunks belong to, to say what changed: the spec run last when it is one of them,
    else the one whose chunk was written last."""
    last = _read_spec(directory)
    if last and last.get("digest") in others:
        return last
    newest = max(others, key=lambda d: max((directory / f"{d}-{k}.csv").stat().st_mtime for k in others[d]))
    return _read_spec(directory, f"{newest}.spec.json")


def _read_spec(directory: Path, name: str = "spec.json") -> dict | None:
    try:
        return json.loads((directory / name).read_text())
    except (OSError, ValueError):
        return None


def _spec_changes(old: dict, new: dict) -> str:
    keys = [k for k in new if old.get(k) != new[k]]
    if "sweep" in keys or "fixed" in keys:
        params = []
        for part in ("sweep", "fixed"):
            o, n = old.get(part) or {}, new.get(part) or {}
            params += [k for k in sorted(set(o) | set(n)) if o.get(k) != n.get(k)]
        keys = [k for k in keys if k not in ("sweep", "fixed")] + params
    return ", ".join(keys) or "an earlier spec"


# -- the run ------------------------------------------------------------------------------------------------
@dataclass
class StudyResult:
    """What :func:`run_study` did and made.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per simulation finished (this run's and reused ones), by ``sim``.
    summary : pandas.DataFrame
        :func:`summarise` of `table`.
    computed : int
        Simulations run by this call.
    reused : int
        Simulations read back from chunks written before.
    failed_chunks : dict of int to str
        Chunks whose task failed twice, with the error in words.
    restarted : str or None
        Why the study started afresh: the spec changed (the earlier spec's chunks are kept).
    compute_s : float
        Wall time from the first task submitted to the last result [s] (0 when nothing was computed).
    workers : int
        Workers of the cluster used (0 when nothing was computed).
    """

    spec: StudySpec
    table_path: Path
    summary_path: Path
    plot_path: Path | None
    table: object
    summary: object
    computed: int
    reused: int
    failed_chunks: dict[int, str]
    restarted: str | None
    compute_s: float
    workers: int
    run_id: str

    @property
    def simulations_per_s(self) -> float:
        return self.computed / self.compute_s if self.compute_s > 0 else float("nan")


def summary_path_for(out: Path) -> Path:
    return out.with_name(out.stem + ".summary.csv")


def plot_path_for(out: Path) -> Path:
    return out.with_name(out.stem + ".html")


def check_table_path(out: Path) -> None:
    """Refuse a result path this machine cannot write: only .csv, or .parquet when pyarrow is installed."""
    suffix = out.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise StudyError(f"the results table must be a .csv or .parquet file, got {out.name!r}")
    if suffix == ".parquet" and importlib.util.find_spec("pyarrow") is None:
        raise StudyError("writing Parquet needs pyarrow, which is not installed: name a .csv file instead")


def open_client(scheduler: str | None, workers: int | None):
    """A Dask client: on the cluster at `scheduler` (``tcp://host:port``), or on a new local cluster of `workers`
    single-threaded worker processes (default one per core). Returns (client, cluster or None)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as exc:
            raise StudyError(f"no Dask scheduler answers at {scheduler} (tried for {CONNECT_TIMEOUT_S:g} s): "
                             f"{exc}") from None
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except TimeoutError:
            client.close()
            raise StudyError(f"the Dask scheduler at {scheduler} has no workers (waited {CONNECT_TIMEOUT_S:g} s): "
                             "start some with `dask worker " + scheduler + "`") from None
        return client, None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    try:
        return Client(cluster), cluster
    except BaseException:  # its worker processes must not outlive a client that never came
        cluster.close()
        raise


def run_study(spec: StudySpec, out: Path, *, scheduler: str | None = None, workers: int | None = None,
              console=None, progress: bool = True, plot: Callable | None = None) -> StudyResult:
    """Run `spec`'s simulations not yet done on Dask and write the results beside `out`.

    Parameters
    ----------
    spec : StudySpec
    out : Path
        The results table (.csv, or .parquet with pyarrow); its chunks go to ``<out>.chunks/``, the summary to
        ``<stem>.summary.csv`` and the plots to ``<stem>.html``.
    scheduler : str, optional
        An existing cluster's scheduler address (``tcp://host:8786``); default a local cluster.
    workers : int, optional
        The local cluster's worker processes (default one per core); ignored with `scheduler`.
    console : rich.console.Console, optional
        Where the progress bar and the notes go (default: none).
    progress : bool
        Show a progress bar (rich, advanced as chunks complete).
    plot : callable, optional
        ``plot(table, summary, path) -> path`` for the study's own figure; default :func:`write_summary_plot`.
    """
    import pandas as pd

    out = Path(out)
    check_table_path(out)
    resolve(spec.simulate)  # fail here, not on every worker, when the simulation cannot be imported
    done, restarted = prepare_chunks(spec, out)
    if restarted and console is not None:
        console.print(f"[yellow]{restarted}[/]", highlight=False)
    chunks = spec.chunks()
    todo = [k for k in range(len(chunks)) if k not in done]
    run_id = uuid.uuid4().hex[:12]
    failed: dict[int, str] = {}
    computed, compute_s, n_workers = 0, 0.0, 0
    if todo:
        computed, compute_s, n_workers, failed = _compute(spec, out, chunks, todo, run_id, scheduler, workers,
                                                          console, progress)
    present = sorted(k for k in range(len(chunks)) if chunk_path(out, spec.digest, k).is_file())
    frames = [pd.read_csv(chunk_path(out, spec.digest, k), keep_default_na=True) for k in present]
    table = pd.concat(frames, ignore_index=True).sort_values("sim", kind="stable") if frames else pd.DataFrame()
    if "error" in table:
        table["error"] = table["error"].astype(object).where(table["error"].notna(), "").astype(str)
    reused = len(table) - computed
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() == ".parquet":
        table.to_parquet(out, index=False)
    else:
        table.to_csv(out, index=False)
    summary = summarise(table, list(spec.sweep), list(spec.fixed))
    summary.to_csv(summary_path_for(out), index=False)
    plot_path = None
    if len(table):
        plot_path = (plot or write_summary_plot)(table, summary, plot_path_for(out))
    return StudyResult(spec, out, summary_path_for(out), plot_path, table, summary, computed, reused, failed,
                       restarted, compute_s, n_workers, run_id)


def _compute(spec, out, chunks, todo, run_id, scheduler, workers, console, progress):
    """Submit the chunks `todo`, write each as it completes; (computed, seconds, workers, failed chunks)."""
    from distributed import as_completed

    client, cluster = open_client(scheduler, workers)
    failed: dict[int, str] = {}
    computed = 0
    try:
        n_workers = len(client.scheduler_info().get("workers", {}))
        t0 = time.perf_counter()
        futures = {client.submit(run_chunk, spec.simulate, chunks[k], run_id, key=f"{spec.name}-{spec.digest}-{k}-"
                                 f"{run_id}", retries=1, pure=False): k for k in todo}
        total = sum(len(chunks[k]) for k in todo)
        bar = _ProgressBar(console, progress, f"{spec.name}: {total} simulations on {n_workers} worker(s)", total)
        where = f"the Dask scheduler at {scheduler}" if scheduler else "the local Dask cluster"
        watchdog = _Watchdog(client, where, len(todo), chunk_dir(out), console)
        pending = as_completed(futures)
        with bar as (advance):
            while not pending.is_empty():
                batch = pending.next_batch(block=False)
                if not batch:  # as_completed has no wait with a timeout: poll, the watchdog looking in between
                    watchdog.check()
                    time.sleep(0.05)
                    continue
                for future in batch:
                    k = futures[future]
                    rows = _chunk_rows(future, watchdog) if future.status == "finished" else None
                    if rows is not None:
                        write_chunk(chunk_path(out, spec.digest, k), rows)
                        computed += len(rows)
                    else:
                        failed[k] = _task_error(future)
                    advance(len(chunks[k]))
                    watchdog.finished(kept=k not in failed)
                    future.release()
        compute_s = time.perf_counter() - t0
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return computed, compute_s, n_workers, failed


def _chunk_rows(future, watchdog) -> list[dict] | None:
    """A finished chunk's rows fetched from the worker holding them, or None when the task failed after all; the
    watchdog watches the wait (a worker that leaves first takes the rows along: Dask computes the chunk again, on a
    worker there may no longer be)."""
    while True:
        try:
            return future.result(timeout=WATCH_INTERVAL_S)
        except TimeoutError:
            watchdog.check()
        except Exception:  # the chunk computed again failed, or was lost with the cluster
            return None


class _Watchdog:
    """Watches a wait for chunks: a :class:`StudyError` once the scheduler has had no worker for
    :data:`NO_WORKER_TIMEOUT_S` (the tasks would wait forever), a warning line each :data:`STALL_WARNING_S` without
    a finished chunk."""

    def __init__(self, client, where: str, chunks: int, directory: Path, console) -> None:
        self.client, self.where, self.directory, self.console = client, where, directory, console
        self.chunks, self.left, self.kept = chunks, chunks, 0
        now = time.monotonic()
        self.last_finished = self.last_warned = self.last_asked = now
        self.no_worker_since: float | None = None

    def finished(self, kept: bool) -> None:
        self.left -= 1
        self.kept += kept
        self.last_finished = self.last_warned = time.monotonic()

    def check(self) -> None:
        now = time.monotonic()
        if now - self.last_asked >= WATCH_INTERVAL_S:
            self.last_asked = now
            if self._workers() > 0:
                self.no_worker_since = None
            elif self.no_worker_since is None:
                self.no_worker_since = now
            elif now - self.no_worker_since >= NO_WORKER_TIMEOUT_S:
                raise StudyError(f"{self.where} has had no worker for {NO_WORKER_TIMEOUT_S:g} s while {self.left} of "
                                 f"{self.chunks} chunk(s) waited: study stopped; the {self.kept} chunk(s) finished "
                                 f"by this run are kept in {self.directory}, and the same command resumes the study "
                                 "once the cluster has workers")
        if now - self.last_warned >= STALL_WARNING_S:
            self.last_warned = now
            self._say(f"no chunk has finished for {now - self.last_finished:.0f} s ({self.left} of "
                      f"{self.chunks} left, {self._workers()} worker(s)); still waiting — Ctrl-C keeps the finished "
                      "chunks and the same command resumes")

    def _workers(self) -> int:
        try:
            return len(self.client.nthreads())
        except (OSError, TimeoutError):  # a scheduler that does not answer has no worker for us
            return 0

    def _say(self, text: str) -> None:
        if self.console is not None:
            self.console.print(f"[yellow]warning:[/] {text}", highlight=False)
        else:
            logging.getLogger(__name__).warning(text)


def _task_error(future) -> str:
    try:
        exc = future.exception()
    except Exception as other:  # the future was lost with its worker
        exc = other
    text = f"{type(exc).__name__}: {exc}"
    if isinstance(exc, (ImportError, StudyError)):
        text += " (the workers must have sunbench installed)"
    return text


class _ProgressBar:
    """A rich progress bar over simulations (nothing without a console or when not wanted)."""

    def __init__(self, console, enabled: bool, description: str, total: int) -> None:
        self.bar = None
        if console is not None and enabled:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                TimeRemainingColumn(), console=console, transient=False)
            self.task = self.bar.add_task(description, total=total)

    def __enter__(self):
        if self.bar is None:
            return lambda n: None
        self.bar.__enter__()
        return lambda n: self.bar.advance(self.task, n)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.__exit__(*exc)
        return False


# -- summary and plots ----------------------------------------------------------------------------------------
def output_columns(table, parameters: Sequence[str] = ()) -> list[str]:
    """The numeric outputs of a study table: every numeric column that is neither bookkeeping nor a parameter."""
    skip = set(BOOK_COLUMNS) | set(TRAILING_COLUMNS) | set(parameters)
    return [c for c in table.columns if c not in skip and _is_numeric(table[c])]


def _is_numeric(column) -> bool:
    import pandas as pd

    return pd.api.types.is_numeric_dtype(column) and not pd.api.types.is_bool_dtype(column)


def statistics(values) -> dict:
    """:data:`STATISTICS` of one output over the simulations of a setting: n (finite values), failed (not finite),
    mean, sd (sample), mean |x|, RMS, the 50th/95th/99th percentiles of |x| and max |x| (NaN without values)."""
    x = np.asarray(values, float)
    ok = x[np.isfinite(x)]
    out = {"n": int(ok.size), "failed": int(x.size - ok.size)}
    if ok.size == 0:
        return {**out, **{k: float("nan") for k in STATISTICS[2:]}}
    a = np.abs(ok)
    return {**out, "mean": float(ok.mean()), "sd": float(ok.std(ddof=1)) if ok.size > 1 else float("nan"),
            "mean_abs": float(a.mean()), "rms": float(np.sqrt(np.mean(ok ** 2))),
            "p50_abs": float(np.percentile(a, 50)), "p95_abs": float(np.percentile(a, 95)),
            "p99_abs": float(np.percentile(a, 99)), "max_abs": float(a.max())}


def summarise(table, parameters: Sequence[str], fixed: Sequence[str] = ()):
    """One row per (parameter setting, output): the setting's swept values (`parameters`), the output's name,
    :func:`statistics`, and how many of the setting's simulations ended in an error (``errors``); the `fixed`
    parameters are no outputs."""
    import pandas as pd

    if not len(table):
        return pd.DataFrame(columns=[*parameters, "output", "simulations", "errors", *STATISTICS])
    outputs = output_columns(table, [*parameters, *fixed])
    rows = []
    for _, group in table.groupby("setting", sort=True):
        first = group.iloc[0]
        errors = int((group["error"].astype(str) != "").sum()) if "error" in group else 0
        for name in outputs:
            rows.append({**{p: first[p] for p in parameters}, "output": name, "simulations": len(group),
                         "errors": errors, **statistics(group[name].to_numpy(float))})
    return pd.DataFrame(rows)


def write_summary_plot(table, summary, path: Path) -> Path:
    """The generic figure: each output's RMS against the first swept parameter, a line per combination of the
    others (plotly HTML, :func:`bench.field_plots.write_figure`)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from .field_plots import write_figure

    parameters = [c for c in summary.columns if c not in ("output", "simulations", "errors", *STATISTICS)]
    outputs = list(dict.fromkeys(summary["output"]))[:12]
    fig = make_subplots(rows=max(len(outputs), 1), cols=1, subplot_titles=[f"RMS of {o}" for o in outputs])
    x_name = parameters[0] if parameters else None
    for i, name in enumerate(outputs, start=1):
        part = summary[summary["output"] == name]
        groups = part.groupby(parameters[1:], sort=False) if len(parameters) > 1 else [((), part)]
        for key, g in groups:
            label = ", ".join(f"{p}={v}" for p, v in zip(parameters[1:], key if isinstance(key, tuple) else (key,)))
            fig.add_trace(go.Scatter(x=g[x_name] if x_name else [0] * len(g), y=g["rms"], mode="lines+markers",
                                     name=label or name, legendgroup=label, showlegend=i == 1), row=i, col=1)
        fig.update_xaxes(title_text=x_name or "", row=i, col=1)
    fig.update_layout(height=300 * max(len(outputs), 1), title="study summary", template="plotly_white")
    return write_figure(fig, Path(path))
