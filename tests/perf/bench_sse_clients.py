"""Benchmark: a simulated campaign with 50 connected event-stream clients.

Run: .venv/bin/python tests/perf/bench_sse_clients.py   (or bash scripts/bench.sh)

The real server (``web.app.create_app`` served by ``web.server.BenchServer`` under uvicorn) runs in this
process, in a background thread, on a free loopback port, around a ``BenchService`` on the simulated bench
at time scale ``TIME_SCALE`` (240: simulated time runs 240× faster than wall time, so the campaign below —
about 920 s of simulated bench time — lasts about 3.3 s; at time scale 0 it would be CPU-bound and last
0.6 s). Timing starts when ``POST /api/campaigns`` is sent and ends when the campaign's
``campaign-finished`` event is published (seen on an in-process subscription to the service's bus, so the
measurement itself puts no load on the API).

  baseline — the campaign with no client connected;
  loaded   — the same campaign with 50 clients on ``GET /api/events`` (``SLOW`` of them read slowly: they
             sleep between lines, as a busy browser tab would) and one client polling ``GET /api/status``
             every 100 ms and recording its latency (ten open bench pages' worth: a page polls once a
             second; at 20 ms the poller alone costs the campaign some 3 %, the 50 streams under 1 %).

The clients run in a child process (asyncio + httpx), so their own parsing does not compete with the
server for this process's GIL: the comparison measures what the server pays for its streams.
Targets: loaded / baseline wall time ≤ 1.05; status p99 ≤ 50 ms.

One pair's ratio moves by several per cent from pair to pair on a 2-core machine (two baseline campaigns
alone can differ by 5 %: the simulated bench polls its devices, and a delay of a fraction of a millisecond
can cost a whole poll period), so after one unmeasured warm-up campaign ``PAIRS`` pairs are measured, in
alternating order (baseline first, then loaded first) so that a drift during the run favours neither side.
Every pair's ratio is printed; the verdict is on their median, with the worst pair shown beside it. The
status p99 verdict is on the worst pair. Each campaign also reports the CPU time of the server's event-loop
thread: a steadier view than the wall time of what the clients cost the server.
"""

import asyncio
import multiprocessing as mp
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

TIME_SCALE = 240.0
N_CLIENTS = 50
SLOW = 5  # of the N_CLIENTS, these sleep SLOW_SLEEP_S after every line they read
SLOW_SLEEP_S = 0.02
STATUS_PERIOD_S = 0.100
PAIRS = 5
TOKEN = "bench-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
CAMPAIGN = {"name": "sse-bench", "frames": "none",
            "seed003": {"azimuth_step_deg": 45.0, "repeats": 2, "centre_repeats": 2, "tilt_stage": False}}
RATIO_TARGET = 1.05
P99_TARGET_MS = 50.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def pct(values, q):
    """The q-quantile (0..1) of `values`, nearest rank."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


# -- the clients (child process) ------------------------------------------------------------------------
async def _sse_client(http, base, slow, counts, connected):
    """Read /api/events, counting events, until campaign-finished is read (or the caller gives up)."""
    import httpx

    seen = {"events": 0, "points": 0, "finished": False}
    counts.append(seen)
    try:
        async with http.stream("GET", f"{base}/api/events") as response:
            response.raise_for_status()
            connected()
            async for line in response.aiter_lines():
                if line.startswith("event:"):
                    seen["events"] += 1
                    kind = line[6:].strip()
                    seen["points"] += kind == "point"
                    if kind == "campaign-finished":
                        seen["finished"] = True
                if seen["finished"]:
                    return
                if slow:
                    await asyncio.sleep(SLOW_SLEEP_S)
    except (httpx.HTTPError, asyncio.CancelledError):
        return


async def _status_poller(http, base, latencies, stop):
    while not stop.is_set():
        t0 = time.perf_counter()
        response = await http.get(f"{base}/api/status")
        dt = time.perf_counter() - t0
        response.raise_for_status()
        latencies.append(dt)
        await asyncio.sleep(max(0.0, STATUS_PERIOD_S - dt))


async def _clients_main(base, conn):
    import httpx

    stop = asyncio.Event()
    counts: list[dict] = []
    latencies: list[float] = []
    n_connected = 0
    all_connected = asyncio.Event()

    def connected():
        nonlocal n_connected
        n_connected += 1
        if n_connected == N_CLIENTS:
            all_connected.set()

    timeout = httpx.Timeout(10.0, read=60.0)
    limits = httpx.Limits(max_connections=N_CLIENTS + 5, max_keepalive_connections=N_CLIENTS + 5)
    async with httpx.AsyncClient(timeout=timeout, limits=limits, headers=AUTH) as streams, \
            httpx.AsyncClient(timeout=timeout, headers=AUTH) as poller:
        tasks = [asyncio.create_task(_sse_client(streams, base, i < SLOW, counts, connected))
                 for i in range(N_CLIENTS)]
        await asyncio.wait_for(all_connected.wait(), 30)
        poll_task = asyncio.create_task(_status_poller(poller, base, latencies, stop))
        conn.send("connected")
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(None, conn.recv)  # "stop", once the campaign has finished
        stop.set()
        await poll_task
        slow_tasks, fast_tasks = tasks[:SLOW], tasks[SLOW:]
        # every client ends once it has read campaign-finished (the slow ones a few seconds late)
        done, pending = await asyncio.wait(fast_tasks + slow_tasks, timeout=20)
        for task in pending:
            task.cancel()
        await asyncio.gather(*pending, return_exceptions=True)
    conn.send({"counts": counts, "latencies": latencies, "slow_unfinished": sum(t in pending for t in slow_tasks)})


def clients_process(base, conn):
    asyncio.run(_clients_main(base, conn))


# -- the server and the campaign (this process) --------------------------------------------------------------
class Server:
    def __init__(self, tmp: Path):
        import uvicorn

        from bench.benchfile import BenchFile
        from bench.catalogue import Catalogue
        from bench.service import BenchService
        from web.app import create_app
        from web.server import BenchServer
        from web.settings import WebSettings

        self.service = BenchService(BenchFile(), Catalogue(tmp / "c.sqlite"), time_scale=TIME_SCALE).start()
        port = free_port()
        settings = WebSettings(host="127.0.0.1", port=port, token=TOKEN, public_read=True, sse_keepalive_s=1.0)
        self.app = create_app(self.service, settings=settings)
        self.server = BenchServer(self.app, uvicorn.Config(self.app, host="127.0.0.1", port=port,
                                                           log_level="warning", lifespan="on"))
        self.base = f"http://127.0.0.1:{port}"
        self.thread = threading.Thread(target=self.server.run, name="uvicorn", daemon=True)

    def __enter__(self):
        self.thread.start()
        deadline = time.monotonic() + 15
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the server did not start")
            time.sleep(0.01)
        return self

    def __exit__(self, *exc):
        self.app.state.shutdown.set()  # what BenchServer.handle_exit does on Ctrl+C: the streams end
        self.server.should_exit = True
        self.thread.join(timeout=15)
        stopped = not self.thread.is_alive()
        self.service.close()
        self.service.catalogue.close()
        if not stopped:
            print("WARNING: the server thread did not stop within 15 s")

    def loop_cpu_s(self) -> float:
        """CPU time [s] used so far by the server's thread (its event loop); NaN where the OS cannot tell."""
        if not hasattr(time, "pthread_getcpuclockid"):
            return float("nan")
        return time.clock_gettime(time.pthread_getcpuclockid(self.thread.ident))

    def baseline_campaign(self, http) -> dict:
        cpu0 = self.loop_cpu_s()
        wall = self.run_campaign(http)
        return {"wall": wall, "loop_cpu": self.loop_cpu_s() - cpu0}

    def run_campaign(self, http) -> float:
        """Submit the campaign, return the wall time [s] from the POST to its campaign-finished event."""
        events = self.service.bus.subscribe()
        try:
            t0 = time.perf_counter()
            response = http.post(f"{self.base}/api/campaigns", json=CAMPAIGN, headers=AUTH)
            if response.status_code != 202:
                raise RuntimeError(f"submit refused: {response.status_code} {response.text}")
            campaign_id = response.json()["campaign_id"]
            deadline = time.monotonic() + 60
            while True:
                event = events.get(timeout=max(0.01, deadline - time.monotonic()))
                if event.get("kind") == "error" and event.get("campaign_id") == campaign_id:
                    raise RuntimeError(f"campaign failed: {event['message']}")
                if event.get("kind") == "campaign-finished" and event.get("campaign_id") == campaign_id:
                    return time.perf_counter() - t0
        finally:
            self.service.bus.unsubscribe(events)

    def loaded_campaign(self, http):
        ctx = mp.get_context("spawn")
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=clients_process, args=(self.base, child), daemon=True)
        proc.start()
        try:
            if not parent.poll(60) or parent.recv() != "connected":
                raise RuntimeError("the clients did not connect")
            deadline = time.monotonic() + 10
            while self.service.bus.subscribers < N_CLIENTS:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"only {self.service.bus.subscribers} subscribers")
                time.sleep(0.01)
            time.sleep(0.5)  # let the poller settle
            dropped0, cpu0 = self.service.bus.dropped, self.loop_cpu_s()
            wall = self.run_campaign(http)
            loop_cpu = self.loop_cpu_s() - cpu0
            parent.send("stop")
            if not parent.poll(40):
                raise RuntimeError("the clients did not report")
            result = parent.recv()
            result["dropped"] = self.service.bus.dropped - dropped0
            result["wall"], result["loop_cpu"] = wall, loop_cpu
            return result
        finally:
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()
                proc.join()


def report_loaded(result):
    counts = result["counts"]
    fast, slow = counts[SLOW:], counts[:SLOW]
    events = [c["events"] for c in counts]
    lat_ms = [x * 1e3 for x in result["latencies"]]
    print(f"    events per client (all {len(counts)}): min {min(events)}  median {statistics.median(events):g}"
          f"  max {max(events)};  'point' events per client: min {min(c['points'] for c in counts)}"
          f"  max {max(c['points'] for c in counts)}")
    print(f"    slow clients ({len(slow)}, {SLOW_SLEEP_S * 1e3:g} ms sleep per line): events "
          f"{[c['events'] for c in slow]}, saw campaign-finished: {sum(c['finished'] for c in slow)}/{len(slow)}"
          f" (fast: {sum(c['finished'] for c in fast)}/{len(fast)});  bus.dropped during the run: {result['dropped']}")
    p50, p99, worst = pct(lat_ms, 0.5), pct(lat_ms, 0.99), max(lat_ms)
    print(f"    GET /api/status every {STATUS_PERIOD_S * 1e3:g} ms: {len(lat_ms)} requests, p50 {p50:.1f} ms"
          f"  p99 {p99:.1f} ms  max {worst:.1f} ms   target p99 ≤ {P99_TARGET_MS:g} ms:"
          f" {'met' if p99 <= P99_TARGET_MS else 'MISSED'}")
    return p99


def main():
    import httpx

    print(f"campaign: seed003, azimuth step 45°, repeats 2, centre repeats 2, no tilt stage, frames none;"
          f" simulated bench at time scale {TIME_SCALE:g}")
    print(f"loaded: {N_CLIENTS} SSE clients ({SLOW} slow) + 1 status poller, in a child process")
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, Server(Path(tmp)) as server, httpx.Client(timeout=30) as http:
        print(f"server: {server.base} (uvicorn in a thread of this process)")
        warm = server.run_campaign(http)
        print(f"warm-up campaign (not counted): {warm:.2f} s")
        ratios, p99s = [], []
        for pair in range(1, PAIRS + 1):
            if pair % 2:
                base = server.baseline_campaign(http)
                result = server.loaded_campaign(http)
            else:
                result = server.loaded_campaign(http)
                base = server.baseline_campaign(http)
            ratio = result["wall"] / base["wall"]
            ratios.append(ratio)
            order = "no clients first" if pair % 2 else f"{N_CLIENTS} clients first"
            print(f"pair {pair} ({order}): no clients {base['wall']:.3f} s   {N_CLIENTS} clients {result['wall']:.3f} s"
                  f"   ratio {ratio:.3f}  (target ≤ {RATIO_TARGET}: {'met' if ratio <= RATIO_TARGET else 'MISSED'})")
            print(f"    server event-loop CPU during the campaign: no clients {base['loop_cpu'] * 1e3:.0f} ms,"
                  f" {N_CLIENTS} clients {result['loop_cpu'] * 1e3:.0f} ms")
            p99s.append(report_loaded(result))
        median = statistics.median(ratios)
        print(f"ratio: median of {PAIRS} pairs {median:.3f}   target ≤ {RATIO_TARGET}:"
              f" {'met' if median <= RATIO_TARGET else 'MISSED'}   (pairs: {', '.join(f'{r:.3f}' for r in ratios)};"
              f" worst {max(ratios):.3f})")
        print(f"status p99: worst pair {max(p99s):.1f} ms   target ≤ {P99_TARGET_MS:g} ms:"
              f" {'met' if max(p99s) <= P99_TARGET_MS else 'MISSED'}")
    print(f"server shut down; total {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()
