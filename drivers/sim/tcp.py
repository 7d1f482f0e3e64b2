"""Serve simulators on TCP ports, so that other processes reach them as ``socket://host:port``.

One listening socket per device; like a serial line, a device talks to one client at a time (a new client
starts a fresh link). The back door's `disconnected` fault drops the connection and refuses new ones.
"""

from __future__ import annotations

import socket
import socketserver
import threading

_TICK_S = 0.002  # how often an idle connection asks the simulator for volunteered output


class _Link(socketserver.BaseRequestHandler):
    def handle(self):
        device = self.server.device
        if device.faults.disconnected:
            return
        sock = self.request
        sock.settimeout(_TICK_S)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self.server.one_client:
            device.reset_link()
            while not self.server.stopping.is_set() and not device.faults.disconnected:
                try:
                    data = sock.recv(65536)
                    if not data:
                        break
                except TimeoutError:
                    data = b""
                except OSError:
                    break
                out = (device.receive(data) if data else b"") + device.poll()
                if out:
                    try:
                        sock.sendall(out)
                    except OSError:
                        break


class _Server(socketserver.ThreadingTCPServer):
    allow_reuse_address = True
    daemon_threads = True

    def __init__(self, address, device):
        self.device = device
        self.stopping = threading.Event()
        self.one_client = threading.Lock()
        super().__init__(address, _Link)


class SimServer:
    """TCP front for a set of named simulators.

    Parameters
    ----------
    devices : dict of str to SimDevice
    host : str
        Interface to listen on (default loopback only).
    base_port : int
        First port; devices get consecutive ports. 0 lets the OS choose free ports.
    """

    def __init__(self, devices: dict, *, host: str = "127.0.0.1", base_port: int = 0):
        self.devices = devices
        self.host = host
        self.base_port = base_port
        self._servers: dict[str, _Server] = {}
        self._threads: list[threading.Thread] = []

    def start(self) -> dict[str, str]:
        """Start serving; returns name → ``socket://host:port``."""
        for i, (name, device) in enumerate(self.devices.items()):
            port = self.base_port + i if self.base_port else 0
            server = _Server((self.host, port), device)
            self._servers[name] = server
            thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05},
                                      name=f"sim-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)
        return self.urls

    @property
    def urls(self) -> dict[str, str]:
        return {name: f"socket://{self.host}:{s.server_address[1]}" for name, s in self._servers.items()}

    def stop(self) -> None:
        for server in self._servers.values():
            server.stopping.set()
            server.shutdown()
            server.server_close()
        self._servers.clear()

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()
