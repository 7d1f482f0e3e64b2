"""Serve an in-process simulator on a pseudo-terminal, for clients that open a serial port by path.

``sim://`` URLs reach only code that opens ports with ``serial.serial_for_url``. A third-party package
that calls ``serial.Serial(path)`` itself (thorlabs-apt-device does) needs a real tty: this bridge opens a
pty pair, hands out the slave's path, and pumps bytes between the master and the simulator's
:meth:`~drivers.sim.device.SimDevice.receive` / :meth:`~drivers.sim.device.SimDevice.poll` in a thread
(anchors-protocols §5 "pty pair", §6 item 4).

Caveats of a pty (anchors-protocols §2.1): it has no modem lines, so setting RTS/DTR raises ``OSError``
errno 25 (pyserial's own ``open()`` ignores that; an APT init that cycles RTS must too). Binary bytes pass
unchanged once the line is raw, which the bridge sets before anyone opens the slave.

    with PtyBridge(simulator) as bridge:
        stage = SomePackage(serial_port=bridge.path)
"""

from __future__ import annotations

import errno
import logging
import os
import select
import threading
import tty

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())


class PtyBridge:
    """A pty whose far end is a :class:`~drivers.sim.device.SimDevice`.

    Parameters
    ----------
    device : SimDevice
        The simulator's protocol front.
    poll_s : float
        Longest wait for input before the bridge asks the device for volunteered output [s]; this is
        the granularity of unsolicited messages (MOVE_COMPLETED, status updates).

    Attributes
    ----------
    path : str
        Path of the slave end (``/dev/pts/N``) to give the client.

    Notes
    -----
    With the back door's ``faults.disconnected`` set, the bridge drops every byte both ways: the client's
    port stays open (a pty cannot be unplugged) but nothing answers, as on a cut data line.
    """

    def __init__(self, device, *, poll_s: float = 0.001):
        self.device = device
        self.poll_s = poll_s
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # binary-safe from the first byte, before the client configures the line
        os.set_blocking(self._master, False)  # a client that stops reading must not block the bridge
        self.path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"pty-bridge {self.path}", daemon=True)
        self._started = False

    def start(self) -> PtyBridge:
        if not self._started:
            self._started = True
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the pump and close both ends."""
        self._stop.set()
        if self._started:
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1

    def __enter__(self) -> PtyBridge:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                log.warning("%s: client not reading, %d bytes dropped", self.path, len(view))
                return
            view = view[n:]

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], self.poll_s)
                out = b""
                if ready:
                    try:
                        data = os.read(self._master, 4096)
                    except BlockingIOError:
                        data = b""
                    if data and not self.device.faults.disconnected:
                        out += self.device.receive(data)
                if not self.device.faults.disconnected:
                    out += self.device.poll()
                if out:
                    self._write(out)
            except OSError as exc:
                if exc.errno in (errno.EBADF, errno.EIO) and self._stop.is_set():
                    return  # closed under us while stopping
                log.exception("%s: bridge stopped", self.path)
                return
