"""A module on the far end of a real pseudo-terminal, answering the BS2 download protocol.

The host side opens :attr:`FakeStamp.path` with pyserial like any serial port; a thread feeds
what it receives to :class:`pac_sim.stamp_download.StampDownload` and writes back its answers,
recording both directions for byte-exact checks.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import tty

from pac_sim.stamp_download import DownloadFaults, StampDownload


class FakeStamp:
    def __init__(self, faults: DownloadFaults | None = None, mode: str = "bs2",
                 before: bytes = b"") -> None:
        """``mode``: "bs2" answers the download; "echo" only echoes; "silent" says nothing.
        ``before``: bytes a still-running program sent just before the host's first byte
        reached it (with no reset line, the firmware runs until the download begins)."""
        self.mode, self.before = mode, before
        self.download = StampDownload(faults=faults or DownloadFaults())
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave, termios.TCSANOW)
        self.path = os.ttyname(self._slave)
        self.from_host = bytearray()
        self.to_host = bytearray()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.02)
            if not r:
                continue
            try:
                data = os.read(self.master, 256)
            except OSError:
                return
            self.from_host += data
            if self.mode == "silent":
                continue
            out = data if self.mode == "echo" else self.download.feed(data)
            out, self.before = self.before + out, b""
            self.to_host += out
            os.write(self.master, out)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1)
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> FakeStamp:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
