"""Ports by URL and the one query helper: timeouts, partial bytes, locking, recording."""

import itertools
import json
import threading

import pytest

from drivers.errors import DeviceDisconnected, DeviceTimeout
from drivers.sim import registry
from drivers.sim.device import LineDevice
from drivers.transport import open_port

_names = itertools.count()


class Echo(LineDevice):
    """Answers ``ECHO <line>\\r``; ``SLOW`` answers in two halves, the second on the next poll."""

    def __init__(self):
        super().__init__()
        self.later = b""

    def handle_line(self, line):
        if line == b"SLOW":
            self.later = b"LOW\r"
            return b"S"
        return b"ECHO " + line + b"\r"

    def unsolicited(self):
        out, self.later = self.later, b""
        return out


@pytest.fixture
def echo():
    name = f"echo-{next(_names)}"
    device = Echo()
    url = registry.register(name, device)
    yield device, url
    registry.unregister(name)


def test_query_returns_the_whole_reply(echo):
    _, url = echo
    port = open_port(url, timeout_s=0.2)
    assert port.query(b"hello\r", b"\r") == b"ECHO hello\r"
    assert port.query(b"SLOW\r", b"\r") == b"SLOW\r"  # assembled from two chunks


def test_timeout_carries_the_partial_reply(echo):
    device, url = echo
    port = open_port(url, timeout_s=0.05)
    device.faults.truncate = 1
    with pytest.raises(DeviceTimeout) as info:
        port.query(b"abcdef\r", b"\r")
    assert info.value.received == b"ECHO a"
    device.faults.no_reply = True
    with pytest.raises(DeviceTimeout) as info:
        port.read_exact(4)
    assert info.value.received == b""


def test_stale_input_is_discarded_before_a_query(echo):
    device, url = echo
    port = open_port(url, timeout_s=0.2)
    port.write(b"old\r")  # a reply nobody read
    assert port.query(b"new\r", b"\r") == b"ECHO new\r"


def test_reply_too_long(echo):
    _, url = echo
    port = open_port(url, timeout_s=0.2)
    with pytest.raises(DeviceTimeout, match="too long"):
        port.query(b"x" * 100 + b"\r", b"\r", max_bytes=20)


def test_one_lock_per_port_keeps_threads_apart(echo):
    _, url = echo
    port = open_port(url, timeout_s=0.5)
    wrong = []

    def worker(tag):
        for i in range(200):
            msg = f"{tag}-{i}".encode()
            if port.query(msg + b"\r", b"\r") != b"ECHO " + msg + b"\r":
                wrong.append(msg)

    threads = [threading.Thread(target=worker, args=(t,)) for t in "abc"]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert wrong == []


def test_unknown_and_dead_ports_are_disconnections(echo):
    with pytest.raises(DeviceDisconnected, match="no simulator registered"):
        open_port("sim://nobody-here")
    with pytest.raises(DeviceDisconnected):
        open_port("socket://127.0.0.1:1", timeout_s=0.2)
    device, url = echo
    port = open_port(url)
    device.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        port.query(b"x\r", b"\r")


def test_loop_url_works_too():
    port = open_port("loop://", timeout_s=0.1)
    port.write(b"ping\n")
    assert port.read_until(b"\n") == b"ping\n"


def test_recording_a_session(echo, tmp_path):
    _, url = echo
    log = tmp_path / "session.jsonl"
    port = open_port(url, timeout_s=0.2, record=log)
    port.query(b"one\r", b"\r")
    port.query(b"two\r", b"\r")
    assert port.raw.exchanges() == [(b"one\r", b"ECHO one\r"), (b"two\r", b"ECHO two\r")]
    port.close()
    events = [json.loads(line) for line in log.read_text().splitlines()]
    assert [e["dir"] for e in events][:2] == ["tx", "rx"]
    assert bytes.fromhex(events[0]["hex"]) == b"one\r"
    events_list = []
    port = open_port(url, record=events_list)
    port.query(b"three\r", b"\r")
    assert events_list and events_list[0]["dir"] == "tx"
