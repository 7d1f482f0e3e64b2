"""The bench service behind the dashboard: queue, cached status, manual commands, bounded event queues."""

import queue
import time

import pytest

from bench.benchfile import BenchFile
from bench.campaign import Campaign, Seed003Procedure
from bench.catalogue import Catalogue
from bench.runner import PreflightRefused
from bench.service import BenchBusy, BenchService, EventBus
from drivers.errors import LimitError

SMALL = Campaign(name="small", frames="none", seed003=Seed003Procedure(
    azimuth_step_deg=90.0, repeats=1, centre_repeats=1, tilt_stage=False))


@pytest.fixture
def service(tmp_path):
    svc = BenchService(BenchFile(), Catalogue(tmp_path / "c.sqlite"), time_scale=0.0, status_period_s=0.05).start()
    yield svc
    svc.close()
    svc.catalogue.close()


def _events_until(q, kind, timeout_s=30.0):
    seen, deadline = [], time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            event = q.get(timeout=0.5)
        except queue.Empty:
            continue
        seen.append(event)
        if event["kind"] == kind:
            return seen
    raise AssertionError(f"no {kind!r} event; saw {[e['kind'] for e in seen]}")


def test_status_is_cached_and_follows_manual_commands(service):
    service.set_lamp(True)
    service.set_shutter(True)
    service.jog(90.0, 30.0)
    status = service.status()
    assert status["table"]["azimuth_deg"] == pytest.approx(90.0, abs=1e-3)
    assert status["source"]["lamp_on"] and status["source"]["shutter_open"]
    frame, spot = service.latest_frame()
    assert frame.shape == (480, 640) and "x_px" in spot
    with pytest.raises(LimitError):
        service.jog(0.0, 80.0)  # outside the zenith soft limits, refused before moving
    assert service.status()["table"]["zenith_deg"] == pytest.approx(30.0, abs=1e-3)


def test_a_submitted_campaign_runs_and_streams_its_progress(service):
    q = service.bus.subscribe()
    campaign_id = service.submit(SMALL)
    events = _events_until(q, "campaign-finished")
    points = [e for e in events if e["kind"] == "point"]
    assert [e["index"] for e in points] == list(range(1, 33)) and points[-1]["total"] == 32
    (run,) = service.catalogue.runs(campaign_id)
    assert run["status"] == "completed"
    assert service.status()["engine"]["index"] == 32


def test_manual_commands_wait_for_the_run_and_violations_are_listed(service, tmp_path):
    q = service.bus.subscribe()
    service.engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == 2 and service.engine.pause())
    service.submit(SMALL)
    _events_until(q, "paused")
    with pytest.raises(BenchBusy):
        service.jog(10.0, 10.0)
    service.resume()
    _events_until(q, "campaign-finished")
    bad = SMALL.model_copy(update={"seed003": SMALL.seed003.model_copy(update={"zenith_stage_deg": (0, 10, 20, 30, 40, 50, 80)})})
    with pytest.raises(PreflightRefused) as info:
        service.submit(bad)
    assert len(info.value.violations) == 4


def test_a_slow_subscriber_loses_old_events_and_never_blocks():
    bus = EventBus(maxsize=3)
    slow = bus.subscribe()
    fast = bus.subscribe()
    t0 = time.perf_counter()
    for i in range(100):
        bus.publish({"kind": "point", "index": i})
        fast.get_nowait()
    assert time.perf_counter() - t0 < 1.0
    assert [slow.get_nowait()["index"] for _ in range(3)] == [97, 98, 99]
    assert bus.dropped == 97
    bus.unsubscribe(slow)
    assert bus.subscribers == 1
